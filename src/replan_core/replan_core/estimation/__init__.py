"""The state estimate from the sensors: contact forces, attitude, base and feet."""
