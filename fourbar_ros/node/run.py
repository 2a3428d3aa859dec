"""fourbar_node's and fourbar_sim_actuator's ``main``: the command line, then start, spin and tear down.

Nothing here imports rclpy at import time, so a stop while rclpy imports exits 0 (fourbar_ros.runtime.stop).
"""

from __future__ import annotations

import argparse
import itertools
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NoReturn

from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import NODE_EXECUTABLE, SIM_EXECUTABLE
from fourbar_ros.runtime.spin import spin_until_stopped
from fourbar_ros.runtime.stop import STOP

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node

    from fourbar_ros.node.sim_actuator import DriveFactory


def params_files(argv: list[str]) -> list[str]:
    """The ``--params-file`` paths among ``argv``, in order."""
    return [path for flag, path in itertools.pairwise(argv) if flag == '--params-file']


def command_line_names(argv: list[str]) -> list[str]:
    """The parameter names set with ``-p name:=value`` (or ``--param``) among ``argv``."""
    return [arg.split(':=', 1)[0].rsplit(':', 1)[-1] for flag, arg in itertools.pairwise(argv)
            if flag in ('-p', '--param') and ':=' in arg]


def params_file_problem(argv: Sequence[str]) -> str | None:
    """One line if a ``--params-file`` argument cannot be read, is larger than 1 MiB, is not YAML or holds an
    alias (rcl refuses those too), else None.

    Checked before rclpy.init, because rcl would log its own multi-line error first.
    """
    from fourbar_ros.config.rcl_yaml import params_file_problem as file_problem

    for flag, path in itertools.pairwise(argv):
        if flag == '--params-file' and (problem := file_problem(path)) is not None:
            return problem
    return None


class UsageError(ValueError):
    """A bad command-line option of fourbar_node (not a ROS argument)."""


class _OptionParser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


def node_options(argv: Sequence[str], prog: str = NODE_EXECUTABLE,
                 description: str = 'The antenna tilt four-bar node.') -> argparse.Namespace:
    """The options of a node's console script (``fourbar_node``, ``fourbar_sim_actuator``) outside its
    ``--ros-args`` sections (``argv[0]`` is the program); ``--help`` prints them and exits 0."""
    from fourbar_ros.runtime.executor import DEFAULT_EXECUTOR, EXECUTOR_ENV, EXECUTORS

    parser = _OptionParser(prog=prog, description=description,
                           epilog='ROS arguments follow --ros-args, e.g. --ros-args --params-file config/antenna.yaml')
    parser.add_argument('--executor', choices=EXECUTORS, default=None,
                        help=f'rclpy executor that runs the callbacks (default: ${EXECUTOR_ENV}, else '
                             f'{DEFAULT_EXECUTOR}); see docs/reference/cli.md')
    return parser.parse_args(non_ros_args(argv)[1:])


def chosen_executor(argv: Sequence[str], prog: str, description: str) -> str | None:
    """The executor a node's console script runs (its ``--executor``, else $FOURBAR_EXECUTOR, else the default);
    None after printing one line ``<prog>: error: ...`` for a bad option or executor name."""
    from fourbar_ros.runtime.executor import executor_kind

    try:
        return executor_kind(node_options(argv, prog, description).executor)
    except ValueError as exc:  # UsageError, ExecutorChoiceError
        print(f'{prog}: error: {exc}', file=sys.stderr)
        return None


def non_ros_args(argv: Sequence[str]) -> list[str]:
    """``argv`` without its ROS arguments: each ``--ros-args`` up to the next ``--`` (or the end), as rcl reads
    them. Pure, so a bad ROS argument (say an unreadable --params-file) is left to its own one-line check."""
    out: list[str] = []
    in_ros = False
    for arg in argv:
        if in_ros:
            in_ros = arg != '--'
        elif arg == '--ros-args':
            in_ros = True
        else:
            out.append(arg)
    return out


def _quiet_exit() -> SystemExit:
    return SystemExit(0)


def serve_node(prog: str, build: Callable[[], Node], argv: Sequence[str], kind: str,
               refused: tuple[type[BaseException], ...] = ()) -> int:
    """Start rclpy, build the node, spin ``kind``'s executor until a stop, then tear down in order.

    0 on a stop; 2 with one line ``PROG: error: ...`` for a bad ``--params-file`` or when ``build`` raises one
    of ``refused`` (bad parameters). The caller installed ``STOP`` before importing rclpy (the quiet start).
    """
    import rclpy
    import rclpy.utilities
    from rclpy.signals import SignalHandlerOptions

    from fourbar_ros.node.fourbar_node import destroy_node
    from fourbar_ros.runtime.executor import create_executor

    STOP.raises = None  # from here a stop only ends the spin loop; a stop while starting ends it before it runs
    problem = params_file_problem(argv)
    if problem is not None:
        print(f'{prog}: error: {problem}', file=sys.stderr)
        return 2
    try:
        rclpy.init(args=list(argv), signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # e.g. an unreadable --params-file: rcl raises RCLError
        print(f'{prog}: error: {one_line(exc)}', file=sys.stderr)
        return 2
    node: Node | None = None
    executor: Executor | None = None
    try:
        node = build()
        executor = create_executor(kind)
        executor.add_node(node)
        log: Callable[[], Any] = node.get_logger  # rclpy's logger accessor is unannotated
        log().info(f'callbacks run on the {kind} executor')
        spin_until_stopped(executor)
    except refused as exc:
        print(f'{prog}: error: {one_line(exc)}', file=sys.stderr)
        return 2
    finally:
        # Nothing runs callbacks any more (one thread): destroy the node, then shut the context down.
        if executor is not None:
            executor.shutdown(timeout_sec=0.0)
        if node is not None:
            destroy_node(node)
        rclpy.utilities.try_shutdown()
    return 0


def main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_node``: exit 0 on Ctrl-C/SIGTERM (also while starting), 2 with one line on bad
    options or parameters."""
    STOP.install(raises=_quiet_exit)  # until the node is about to be built: rclpy imports take a while
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException

    from fourbar_ros.config.antenna_config import ConfigError
    from fourbar_ros.node.fourbar_node import FourBarNode

    argv = sys.argv if args is None else args
    kind = chosen_executor(argv, NODE_EXECUTABLE, 'The antenna tilt four-bar node.')
    if kind is None:
        STOP.raises = None
        return 2
    return serve_node(NODE_EXECUTABLE,
                      lambda: FourBarNode(params_files=params_files(argv), command_line_names=command_line_names(argv)),
                      argv, kind, (ConfigError, InvalidParameterTypeException, InvalidParameterValueException))


def sim_actuator_main(args: list[str] | None = None, drives: Mapping[str, DriveFactory] | None = None) -> int:
    """Console script ``fourbar_sim_actuator``: exit 0 on Ctrl-C/SIGTERM (also while starting), 2 with one line on
    bad parameters. ``drives``: the drives offered besides the lag (``SimActuator``; the installed script offers the
    MuJoCo plant, ``plant.sim_drive``)."""
    STOP.install(raises=_quiet_exit)
    from fourbar_ros.config.antenna_config import ConfigError
    from fourbar_ros.node.sim_actuator import SimActuator

    argv = sys.argv if args is None else args
    kind = chosen_executor(argv, SIM_EXECUTABLE, 'The simulated actuator: the ros2_control controllers and the '
                           'motor of the tilt drive.')
    if kind is None:
        STOP.raises = None
        return 2
    return serve_node(SIM_EXECUTABLE, lambda: SimActuator(drives=drives), argv, kind, (ConfigError,))


if __name__ == '__main__':
    sys.exit(main())
