#!/usr/bin/env bash
# Install the ROS 2 Jazzy command line (ros2 and its verbs, launch, launch_ros, launch_testing) into .venv
# from a directory of wheels built from the upstream jazzy sources.
#
#   scripts/install_ros_cli.sh WHEEL_DIR        (or ROS_CLI_WHEELS=WHEEL_DIR scripts/install_ros_cli.sh)
#
# Their dependencies from the package index are pinned in requirements/ros-cli.txt; the wheels come only from
# WHEEL_DIR (--no-index: the package index's own `launch` is an unrelated project). Does nothing where `ros2`
# and launch_ros are already importable from a sourced ROS 2 install.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
WHEELS=${1:-${ROS_CLI_WHEELS:-}}
if [ -z "$WHEELS" ] || [ ! -d "$WHEELS" ]; then
  echo "usage: $0 WHEEL_DIR (or set ROS_CLI_WHEELS); got '${WHEELS}'" >&2
  exit 2
fi
if "$VENV/bin/python" -c 'import sys, ros2cli, launch_ros; sys.exit(ros2cli.__file__.startswith(sys.prefix))' \
   >/dev/null 2>&1; then
  echo "install_ros_cli: ros2cli and launch_ros come from the sourced ROS 2 install; nothing to install"
  exit 0
fi
PACKAGES=(ament_venv_prefix_hook launch launch_xml launch_yaml launch_testing launch_pytest launch_ros
  launch_testing_ros ros2launch ros2cli ros2pkg ros2run ros2topic ros2node ros2param ros2service
  ros2interface ros2action ros2lifecycle ros2component ros2multicast ros2doctor rosidl_runtime_py
  composition_interfaces)
"$VENV/bin/python" -m pip install --quiet -c requirements/constraints.txt -r requirements/ros-cli.txt
"$VENV/bin/python" -m pip install --quiet --no-index --find-links "$WHEELS" "${PACKAGES[@]}"
# Fail here, not in the tests, if the command line cannot start.
"$VENV/bin/python" -c 'import launch_ros.actions, launch_testing, ros2cli.cli'
"$VENV/bin/ros2" pkg prefix launch_ros >/dev/null
echo "install_ros_cli: ros2, launch_ros and launch_testing installed into $VENV"
