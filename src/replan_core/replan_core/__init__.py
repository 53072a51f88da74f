"""ROS-free core of the quadruped MPC re-planning stack."""
