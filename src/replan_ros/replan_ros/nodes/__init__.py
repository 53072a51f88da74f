"""The rclpy nodes, one per file (each converts messages, calls the core, publishes), and
their one main()."""
