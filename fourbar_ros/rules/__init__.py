"""What fourbar_node does with its inputs, without ROS and array-first: the node per message, bags per block."""
