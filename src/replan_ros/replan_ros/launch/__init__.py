"""Starting, supervising and stopping a node graph from a script."""
