"""PLCopen motion function blocks, one module per type."""
