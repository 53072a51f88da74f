"""The common base of every role: the exchanged types, rotations and the QP solver as the
core uses it."""
