"""The node's parameter table, the configuration built from it, and the rcl-compatible YAML reader."""
