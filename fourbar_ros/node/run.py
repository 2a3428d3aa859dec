"""How every fourbar process starts, spins and stops: fourbar_node's ``main`` with its command line, and the one
SIGINT/SIGTERM handling that the node and every ``fourbar`` command use.

Nothing here imports rclpy at import time: ``main`` holds a stop that arrives while rclpy and the message packages
are still importing (a launch file or supervisor stopping the node right after starting it) and exits 0 then,
instead of a KeyboardInterrupt traceback or status -15.

The stop (``STOP``, one per process, as signal handlers are) always notes the signal and wakes what waits on it.
What happens next is chosen where it is installed:

- ``raises=None``: nothing more; loops look at ``STOP.requested`` (the node's spin loop, ``fourbar record``).
  rclpy's own handlers shut the context down from the signal while a callback may still run, so
  ``get_subscription_count``, ``publish`` or the next wait set raise RCLError ("context is invalid"); a flag
  lets the loop return and ``main`` destroy the node and shut down, in order.
- ``raises=KeyboardInterrupt`` (``fourbar process``, ``replay``, ``demo``): raised at once, as Python's default
  SIGINT handler does, so cleanup code runs; but never inside an executor's callback: while ``spin_once`` runs
  (the only place callbacks run) the signal is only noted and raised when it returns (at most its timeout
  later), because rclpy 7.1.6's EventsExecutor logs an exception raised in a callback as FATAL with a traceback.
- ``raises=SystemExit`` with status 0: the node's quiet start, until the node is about to be built.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any, NoReturn

from fourbar_ros.config.interface import NODE_EXECUTABLE, SIM_EXECUTABLE
from fourbar_ros.core.errors import one_line

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node

#: The signals every fourbar process treats as "stop".
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: Longest time (s) the node's spin loop waits for work before it looks at the stop flag again.
STOP_POLL_S = 0.1


class Stop:
    """The process's SIGINT/SIGTERM handler (see the module docstring)."""

    def __init__(self) -> None:
        self.signal: int | None = None
        self.raises: Callable[[], BaseException] | None = None
        self._wakers: list[Callable[[], None]] = []
        self._in_callbacks = False
        self._pending = False
        self._raised: BaseException | None = None  # the last exception the handler raised, until it is seen
        self._next_unraisable_hook: Callable[[Any], object] | None = None

    def reset(self, raises: Callable[[], BaseException] | None = None) -> None:
        """Forget earlier signals and wakers; raise ``raises()`` on the next one (None: only note it)."""
        self.signal = None
        self.raises = raises
        self._wakers.clear()
        self._in_callbacks = self._pending = False

    def __call__(self, signum: int, frame: object) -> None:
        self.signal = signum
        for wake in self._wakers:
            wake()
        if self.raises is not None:
            if self._in_callbacks:
                self._pending = True
            else:
                self._raised = exc = self.raises()
                raise exc

    def _unraisable(self, unraisable: Any) -> None:
        """``sys.unraisablehook`` while installed: an exception the handler raised that Python swallowed (it landed
        in a weakref callback or ``__del__``, e.g. importlib's module-lock cleanup) is raised again at the end of
        the next ``deferred`` block (each spin), so the stop is not lost."""
        if self._raised is not None and unraisable.exc_value is self._raised:
            self._raised = None
            self._pending = True
        if self._next_unraisable_hook is not None:
            self._next_unraisable_hook(unraisable)

    @property
    def requested(self) -> bool:
        """True once a stop signal arrived."""
        return self.signal is not None

    def on_request(self, wake: Callable[[], None]) -> None:
        """Call ``wake()`` from the handler when a stop arrives (e.g. to end a running spin slice). It runs in the
        main thread between any two bytecodes, so it must not wait for a lock that thread may hold."""
        self._wakers.append(wake)

    def install(self, raises: Callable[[], BaseException] | None = None) -> None:
        """Handle SIGINT and SIGTERM in this process from now on (main thread only); see ``reset``."""
        self.reset(raises)
        for signum in STOP_SIGNALS:
            signal.signal(signum, self)
        if sys.unraisablehook != self._unraisable:
            self._next_unraisable_hook = sys.unraisablehook
            sys.unraisablehook = self._unraisable

    @contextlib.contextmanager
    def deferred(self) -> Iterator[None]:
        """A stop that comes inside the block is raised after it, not inside (an executor's callbacks; starting a
        child process, whose handle would be lost with the child running)."""
        self._in_callbacks = True
        try:
            yield
        finally:
            self._in_callbacks = False
        if self._pending and self.raises is not None:
            self._pending = False
            raise self.raises()

    def spin_once(self, executor: Executor, timeout_sec: float) -> None:
        """``executor.spin_once(timeout_sec)``; a signal that came during it is raised after it, not inside."""
        with self.deferred():
            executor.spin_once(timeout_sec=timeout_sec)


#: The one stop of this process.
STOP = Stop()


@contextlib.contextmanager
def stop_on_signals(raises: Callable[[], BaseException] | None = KeyboardInterrupt) -> Iterator[Stop]:
    """``STOP`` handles SIGINT and SIGTERM inside the block (raising ``raises()``, see the module docstring);
    the previous handlers come back after it. For the ``fourbar`` commands, which may run in-process.

    Nested inside another (``commands.main`` holds one around every command), a stop that already came is kept:
    it is raised at once (or, with ``raises=None``, seen by ``STOP.requested``). A KeyboardInterrupt raised from
    the handler can be lost (Python only prints it when it lands in a weakref callback or ``__del__``, e.g.
    importlib's module-lock cleanup while rclpy imports), so what the signal asked is not lost with it."""
    previous = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}
    nested = previous[signal.SIGINT] is STOP
    outer_raises, earlier = (STOP.raises, STOP.signal) if nested else (None, None)
    STOP.install(raises)
    try:
        if earlier is not None:
            STOP.signal = earlier
            if raises is not None:
                raise raises()
        yield STOP
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if nested:
            STOP.raises = outer_raises
        else:
            STOP.reset()


def spin_once(executor: Executor, timeout_sec: float) -> None:
    """One bounded spin under ``STOP`` (a signal during it is raised after it, if the stop raises)."""
    STOP.spin_once(executor, timeout_sec)


def spin_until_stopped(executor: Executor, stop: Stop = STOP, poll_s: float = STOP_POLL_S) -> None:
    """Run callbacks until ``stop`` is requested or the context ends.

    Spins in slices of at most ``poll_s`` s (an EventsExecutor must never wait without a deadline, see
    fourbar_ros.node.executor); a stop also ends the running slice, after the callback in progress. A
    ``StallWatch`` restarts the timers that a backward step of the system clock stalled.
    """
    from fourbar_ros.node.executor import Spinner, StallWatch

    spinner = Spinner(executor, poll_s)
    stop.on_request(spinner.request_stop)
    context_ok: Callable[[], bool] = executor.context.ok
    try:
        with StallWatch(executor).running():  # timers stalled by a step of the system clock
            while not stop.requested and context_ok():
                spinner.spin_slice()
    finally:
        spinner.close()


# --------------------------------------------------------------------------- fourbar_node's command line

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
    from fourbar_ros.node.executor import DEFAULT_EXECUTOR, EXECUTOR_ENV, EXECUTORS

    parser = _OptionParser(prog=prog, description=description,
                           epilog='ROS arguments follow --ros-args, e.g. --ros-args --params-file config/antenna.yaml')
    parser.add_argument('--executor', choices=EXECUTORS, default=None,
                        help=f'rclpy executor that runs the callbacks (default: ${EXECUTOR_ENV}, else '
                             f'{DEFAULT_EXECUTOR}); see docs/reference/cli.md')
    return parser.parse_args(non_ros_args(argv)[1:])


def chosen_executor(argv: Sequence[str], prog: str, description: str) -> str | None:
    """The executor a node's console script runs (its ``--executor``, else $FOURBAR_EXECUTOR, else the default);
    None after printing one line ``<prog>: error: ...`` for a bad option or executor name."""
    from fourbar_ros.node.executor import executor_kind

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

    from fourbar_ros.node.executor import create_executor
    from fourbar_ros.node.fourbar_node import destroy_node

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


def sim_actuator_main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_sim_actuator``: exit 0 on Ctrl-C/SIGTERM (also while starting), 2 with one line on
    bad parameters."""
    STOP.install(raises=_quiet_exit)
    from fourbar_ros.config.antenna_config import ConfigError
    from fourbar_ros.node.sim_actuator import SimActuator

    argv = sys.argv if args is None else args
    kind = chosen_executor(argv, SIM_EXECUTABLE, 'The simulated actuator: the ros2_control controllers and the '
                           'motor of the tilt drive.')
    if kind is None:
        STOP.raises = None
        return 2
    return serve_node(SIM_EXECUTABLE, SimActuator, argv, kind, (ConfigError,))


if __name__ == '__main__':
    sys.exit(main())
