"""The CoM plan of a re-plan: the LIP, the support polygons and the jerk QP's formulations."""
