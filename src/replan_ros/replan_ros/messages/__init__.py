"""Message conversion: core types to and from ROS messages (rclpy classes and hand-written CDR)."""
