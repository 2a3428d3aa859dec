"""rosbag2 bags: read/write, record, replay, offline processing and comparison, the demo's analysis."""
