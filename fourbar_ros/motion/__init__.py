"""Motion of the driven joint: antenna trajectories to driven-joint trajectories, the interpolation-error refinement,
motor limits (check or retime) and jerk-limited planning of plain angle commands. numpy and ruckig, no ROS."""
