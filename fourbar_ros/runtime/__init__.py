"""The process around rclpy: the stop on SIGINT/SIGTERM, the executor and its spin loop, the callback boundary."""
