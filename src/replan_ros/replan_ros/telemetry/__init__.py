"""What the nodes report about themselves: /diagnostics and the per-tick budget."""
