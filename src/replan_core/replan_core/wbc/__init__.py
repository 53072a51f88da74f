"""The whole-body controller and its per-tick protocol: plans to joint torques."""
