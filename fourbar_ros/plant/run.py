"""fourbar_mujoco_drive's ``main``: the drive bridge's (``fourbar_ros.drive.run``) on the MuJoCo plant's node.

No rclpy or mujoco at import time, so a stop while they import exits 0 (fourbar_ros.runtime.stop).
"""

from __future__ import annotations

import sys

from fourbar_ros.drive.run import main as bridge_main

PROG = 'fourbar_mujoco_drive'
#: The node ``main`` builds: ``fourbar_ros.plant.plant_node.MujocoDrive``.
NODE_CLASS = 'fourbar_ros.plant.plant_node:MujocoDrive'


def main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_mujoco_drive``: 0 on a stop, 2 with one line for bad parameters or no mujoco."""
    return bridge_main(args, NODE_CLASS, PROG)


if __name__ == '__main__':
    sys.exit(main())
