"""Run metrics from recorded time series."""
