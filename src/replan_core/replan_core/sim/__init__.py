"""The simulated world: physics, sensor noise, mode machine, external wrenches and its copy
of the model."""
