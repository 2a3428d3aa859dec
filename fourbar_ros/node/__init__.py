"""The rclpy node (fourbar_node) and the pure helpers it adapts: policy, cache, velocity, diagnostics, markers."""
