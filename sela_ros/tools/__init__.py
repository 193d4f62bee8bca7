"""Command-line tools over the nodes and the core: the demo, the archive builder, recording."""
