"""A drive the user writes in Python, bridged to ros2_control's topic-based hardware plugin."""
