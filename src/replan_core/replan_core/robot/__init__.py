"""The robot: its model, robot files, scaling, variants with model errors, asset names and
frames."""
