"""Live ROS tools (rclpy): record and replay bags, read the graph and a node's parameters, run the node."""
