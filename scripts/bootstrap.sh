#!/usr/bin/env bash
# Create (or refresh) the project's virtual environment in .venv.
# With a ROS 2 install sourced (rclpy importable), the venv sees it and no ROS wheel is installed over it;
# otherwise ROS 2 Jazzy's wheels come from the package index at the versions pinned in requirements/.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}
stamp="$VENV/.fourbar-bootstrap"
want=$(cat "$0" setup.py requirements/*.txt | sha256sum | cut -d' ' -f1)
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
  exit 0
fi
if "$PYTHON" -c 'import rclpy' >/dev/null 2>&1; then
  echo "bootstrap: using the sourced ROS 2 install (rclpy importable by $PYTHON)"
  "$PYTHON" -m venv --system-site-packages "$VENV"
  ros_reqs=()
else
  echo "bootstrap: no rclpy found; installing ROS 2 Jazzy wheels into $VENV"
  "$PYTHON" -m venv "$VENV"
  ros_reqs=(-r requirements/ros-jazzy.txt)
fi
# setuptools < 80: colcon-core 0.21 requires it (its ament_python build runs setup.py with this setuptools).
"$VENV/bin/python" -m pip install --quiet --upgrade pip==25.3 setuptools==79.0.1 wheel==0.45.1
"$VENV/bin/python" -m pip install --quiet -c requirements/constraints.txt "${ros_reqs[@]}" \
  --config-settings editable_mode=compat -e '.[bags,plot,plant,test]'
"$VENV/bin/python" -c 'import rclpy, numpy, rosbags'  # fail here, not later, if the environment is incomplete
echo "$want" > "$stamp"
echo "bootstrap: $VENV ready"
