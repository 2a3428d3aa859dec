"""The wire: message type names and topics, CDR bytes of the messages, header stamps (no ROS)."""
