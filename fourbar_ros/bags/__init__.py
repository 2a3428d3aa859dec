"""rosbag2 bags without rclpy: storage, offline processing, comparison and calibration recordings."""
