"""The node's parameter table, the configuration built from it, the rcl-compatible YAML reader, the robot model (URDF)
and the lookup of installed files (share/)."""
