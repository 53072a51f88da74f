"""How messages travel: QoS by role, reading on demand, taking straight from a DDS queue,
stamped buffers."""
