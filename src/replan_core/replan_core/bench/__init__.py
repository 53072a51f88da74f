"""Benchmarks of the core algorithms (ROS-free), run from ``scripts/bench_*.sh``."""
