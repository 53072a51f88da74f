"""rclpy nodes of the quadruped MPC re-planning stack."""
