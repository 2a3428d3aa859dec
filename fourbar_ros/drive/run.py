"""fourbar_drive_bridge's ``main``: start, spin until SIGINT/SIGTERM (exit 0), disable the backend, tear down.

No rclpy at import time, so a stop while rclpy imports exits 0 (fourbar_ros.runtime.stop).
"""

from __future__ import annotations

import importlib
import sys
from typing import TYPE_CHECKING

from fourbar_ros.core.errors import one_line
from fourbar_ros.runtime.stop import STOP

if TYPE_CHECKING:
    from rclpy.executors import Executor

    from fourbar_ros.drive.bridge_node import DriveBridge

PROG = 'fourbar_drive_bridge'
#: The node ``main`` builds, 'module:Class' (a ``DriveBridge``, called with no arguments), imported once rclpy is.
BRIDGE = 'fourbar_ros.drive.bridge_node:DriveBridge'


def _quiet_exit() -> SystemExit:
    return SystemExit(0)


def main(args: list[str] | None = None, node_class: str = BRIDGE, prog: str = PROG) -> int:
    """Console script ``fourbar_drive_bridge`` (or ``prog``, the bridge ``node_class``): 0 on a stop, 2 with one
    line for bad parameters or backend."""
    STOP.install(raises=_quiet_exit)  # until the node is about to be built: rclpy imports take a while
    import rclpy
    import rclpy.utilities
    from rclpy.signals import SignalHandlerOptions

    from fourbar_ros.config.antenna_config import ConfigError
    from fourbar_ros.drive.bridge_node import BackendError
    from fourbar_ros.runtime.executor import create_executor, executor_kind
    from fourbar_ros.runtime.spin import spin_until_stopped

    argv = sys.argv if args is None else args
    STOP.raises = None  # from here a stop only ends the spin loop
    try:
        rclpy.init(args=list(argv), signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # e.g. an unreadable --params-file
        print(f'{prog}: error: {one_line(exc)}', file=sys.stderr)
        return 2
    node: DriveBridge | None = None
    executor: Executor | None = None
    try:
        module, _, name = node_class.partition(':')
        bridge: type[DriveBridge] = getattr(importlib.import_module(module), name)
        node = bridge()
        executor = create_executor(executor_kind())
        executor.add_node(node)
        spin_until_stopped(executor)
    except (ConfigError, BackendError) as exc:
        print(f'{prog}: error: {one_line(exc)}', file=sys.stderr)
        return 2
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=0.0)
        if node is not None:
            node.close()
        rclpy.utilities.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
