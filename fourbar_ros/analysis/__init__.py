"""Analysis of recordings, without rclpy: the demo's and the calibration's."""
