"""Watching a run: the live view (Foxglove WebSocket), the scene it and the recorder derive,
a test client."""
