"""Analysis of recordings: the demo's series, summary and plot, and the calibration residual plot (no rclpy)."""
