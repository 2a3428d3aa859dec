"""The executor choice and the spinning helpers of fourbar_ros.runtime.executor.

- MessageInfoCallback: rclpy picks the (msg, info) form for it, and it unpacks both call forms (two
  arguments from the SingleThreadedExecutor, one tuple from rclpy 7.1.6's EventsExecutor).
- executor_kind: option, then $FOURBAR_EXECUTOR, then the default; one line for an unknown name.
- the stop (runtime.stop.STOP) raising KeyboardInterrupt: a signal during spin_once is raised after it returns, never
  inside a callback; a stop that only notes the signal raises nothing.
- Spinner on a real EventsExecutor (in a child process, so a hang fails by a deadline instead of hanging the
  run): a subscription with message info is served, and request_stop() from a callback ends a slice whose
  queue never empties (a zero-period timer). The slice's own deadline alone would not: the events queue only
  looks at its deadline when it is empty. fourbar_node's SIGINT/SIGTERM handler relies on this.
- the node's spin loop (``spin_until_stopped`` under the noting stop, on a real EventsExecutor in a child process)
  ends on a signal that Python handles while the loop's own thread holds the slice future's lock, as it does for
  a moment in every slice (the executor adds and removes its done-callback under it): the handler must not wait
  for that lock. The signal is raised from inside the lock, so the case is hit every time.
- fourbar_node's --executor option and $FOURBAR_EXECUTOR: an unknown name exits 2 with one line.
"""

from __future__ import annotations

import inspect
import os
import signal
import subprocess
import sys
import textwrap
import weakref
from typing import Any

import pytest
from support.bag_support import Tool
from support.paths import REPO
from support.ros_support import lease_domain_id, node_command

from fourbar_ros.runtime.executor import (
    DEFAULT_EXECUTOR,
    EXECUTOR_ENV,
    EXECUTORS,
    ExecutorChoiceError,
    MessageInfoCallback,
    executor_kind,
)
from fourbar_ros.runtime.spin import spin_once
from fourbar_ros.runtime.stop import stop_on_signals


def test_message_info_callback_binds_like_a_two_parameter_function_and_accepts_both_forms() -> None:
    got: list[tuple[Any, Any]] = []
    cb = MessageInfoCallback(lambda msg, info: got.append((msg, info)))
    signature = inspect.signature(cb)
    with pytest.raises(TypeError):
        signature.bind(object())  # rclpy's test for the message-only form fails ...
    signature.bind(object(), object())  # ... and the one for the (msg, info) form passes
    cb('m1', {'k': 1})  # SingleThreadedExecutor
    cb(('m2', {'k': 2}))  # EventsExecutor of rclpy 7.1.6
    assert got == [('m1', {'k': 1}), ('m2', {'k': 2})]


def test_rclpy_subscription_takes_it_as_a_message_info_callback() -> None:
    from rclpy.subscription import Subscription

    class Probe:
        callback = Subscription.callback  # rclpy's own property: its setter classifies the callback

    probe: Any = Probe()
    probe.callback = MessageInfoCallback(lambda msg, info: None)
    assert probe._callback_type is Subscription.CallbackType.WithMessageInfo


def test_executor_kind_option_then_environment_then_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(EXECUTOR_ENV, raising=False)
    assert executor_kind() == DEFAULT_EXECUTOR
    monkeypatch.setenv(EXECUTOR_ENV, 'single')
    assert executor_kind() == 'single'
    assert executor_kind('events') == 'events'  # the option wins
    monkeypatch.setenv(EXECUTOR_ENV, 'multi')
    with pytest.raises(ExecutorChoiceError, match=rf"^{EXECUTOR_ENV}: unknown executor 'multi'"):
        executor_kind()
    with pytest.raises(ExecutorChoiceError, match=r"^executor: unknown executor ''"):
        executor_kind('')


class SignallingExecutor:
    """Stands in for an executor: its spin_once delivers a signal to this process, then runs more Python
    (as a callback would) and records whether it got there."""

    def __init__(self, sig: int) -> None:
        self.sig = sig
        self.finished = False

    def spin_once(self, timeout_sec: float | None = None) -> None:
        signal.raise_signal(self.sig)  # Python runs the handler at the next bytecode, i.e. "in a callback"
        self.finished = True


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_raising_stop_is_raised_after_the_spin_not_inside_it(sig: int) -> None:
    previous = signal.getsignal(sig)
    with stop_on_signals() as stop:
        executor: Any = SignallingExecutor(sig)
        with pytest.raises(KeyboardInterrupt):
            spin_once(executor, 0.1)
        assert executor.finished  # the "callback" ran to its end
        assert stop.requested
        with pytest.raises(KeyboardInterrupt):  # outside a spin: at once, like Python's SIGINT handler
            signal.raise_signal(sig)
    assert signal.getsignal(sig) is previous  # the block's end restores the handler


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_noting_stop_only_sets_the_flag_and_wakes(sig: int) -> None:
    woken: list[bool] = []
    with stop_on_signals(raises=None) as stop:
        stop.on_request(lambda: woken.append(True))
        executor: Any = SignallingExecutor(sig)
        spin_once(executor, 0.1)
        signal.raise_signal(sig)
        assert executor.finished and stop.requested and woken == [True, True]
    assert not stop.requested  # the next user starts afresh


class _Dropped:
    """An object whose weakref callback sends ``sig``: Python swallows the KeyboardInterrupt the handler raises
    there (it only prints "Exception ignored in ..."), as it does in importlib's module-lock cleanup."""


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
@pytest.mark.parametrize('inner', [KeyboardInterrupt, None], ids=['raising', 'noting'])
def test_a_stop_whose_interrupt_python_swallowed_is_kept_by_the_next_stop(
        sig: int, inner: type[KeyboardInterrupt] | None, monkeypatch: pytest.MonkeyPatch) -> None:
    swallowed: list[type[BaseException]] = []  # what Python would print as "Exception ignored in ..."
    monkeypatch.setattr(sys, 'unraisablehook', lambda unraisable: swallowed.append(unraisable.exc_type))
    with stop_on_signals() as outer:  # what commands.main holds around every command
        dropped = _Dropped()
        ref = weakref.ref(dropped, lambda _: signal.raise_signal(sig))
        del dropped  # the callback runs here; its KeyboardInterrupt goes no further
        assert ref() is None and outer.requested and swallowed == [KeyboardInterrupt]
        if inner is None:
            with stop_on_signals(raises=None) as stop:  # a command's own loop: sees the stop at once
                assert stop.requested
        else:
            with pytest.raises(KeyboardInterrupt), stop_on_signals():  # raised on entry, not lost
                pytest.fail('the block ran although a stop had come')
        with pytest.raises(KeyboardInterrupt):  # the outer stop raises again after the inner one
            signal.raise_signal(sig)


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_swallowed_stop_is_raised_at_the_end_of_the_next_spin_of_the_same_stop(
        sig: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """Within one stop (no nested one follows, as in ``fourbar demo`` starting up), a KeyboardInterrupt that Python
    swallowed is raised again when the next ``deferred`` block (a spin) ends: the command does not run on."""
    swallowed: list[type[BaseException]] = []
    monkeypatch.setattr(sys, 'unraisablehook', lambda unraisable: swallowed.append(unraisable.exc_type))
    with stop_on_signals() as stop:
        dropped = _Dropped()
        ref = weakref.ref(dropped, lambda _: signal.raise_signal(sig))
        del dropped
        assert ref() is None and stop.requested and swallowed == [KeyboardInterrupt]  # still printed, as before
        with pytest.raises(KeyboardInterrupt), stop.deferred():
            pass
        with stop.deferred():  # raised once: the next spin runs
            pass


SPINNER_SCRIPT = textwrap.dedent('''
    import sys
    import rclpy
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import Float64
    from fourbar_ros.runtime.executor import MessageInfoCallback, Spinner, create_executor

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node('spinner_probe')
    executor = create_executor('events')
    executor.add_node(node)
    spinner = Spinner(executor, slice_s=0.2)
    infos = []
    node.create_subscription(Float64, 'probe', MessageInfoCallback(lambda m, i: infos.append((m.data, i))), 10)
    pub = node.create_publisher(Float64, 'probe', 10)
    ticks = [0]
    def flood():  # a zero-period timer: the events queue never empties while it runs
        ticks[0] += 1
        if infos and ticks[0] >= 200:
            spinner.request_stop()
    node.create_timer(0.0, flood)
    for _ in range(3000):  # until the message is served (the timer keeps each slice busy)
        pub.publish(Float64(data=1.5))
        spinner.spin_slice()
        if spinner.stopped:
            break
    assert infos and infos[0][0] == 1.5 and 'publication_sequence_number' in infos[0][1], infos[:1]
    assert spinner.stopped and ticks[0] >= 200
    spinner.close()
    executor.shutdown(timeout_sec=0.0)
    node.destroy_node()
    rclpy.shutdown()
    print('stopped after', ticks[0], 'ticks')
''')


@pytest.mark.ros
def test_events_spinner_serves_message_info_and_stops_a_never_empty_queue_on_request() -> None:
    lease = lease_domain_id()
    try:
        env = dict(os.environ, ROS_DOMAIN_ID=str(lease.domain_id))
        done = subprocess.run([sys.executable, '-c', SPINNER_SCRIPT], env=env, cwd=REPO, capture_output=True,
                              text=True, timeout=120, check=False)
    finally:
        lease.release()
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith('stopped after'), done.stdout


#: The node's spin loop under its stop, with the slice future's callback list replaced by one that raises the signal
#: (argv[2]) inside the future's lock, on the third add (argv[1] 'add') or remove ('remove') of a done-callback.
#: A hang dumps every thread's stack and exits 1 after HANG_S.
HANG_S = 20
STOP_IN_LOCK_SCRIPT = textwrap.dedent(f'''
    import faulthandler, signal, sys
    faulthandler.dump_traceback_later({HANG_S}, exit=True)
    from fourbar_ros.runtime.spin import spin_until_stopped
    from fourbar_ros.runtime.stop import STOP
    STOP.install(raises=None)
    import rclpy
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from rclpy.task import Future
    import fourbar_ros.runtime.executor as executor_module

    where, sig = sys.argv[1], int(sys.argv[2])
    class SignalInsideLock(list):
        calls = 0
        def _count(self, name):
            if name == where:
                SignalInsideLock.calls += 1
                if SignalInsideLock.calls == 3:
                    signal.raise_signal(sig)  # Python runs the handler here, with the future's lock held
        def append(self, item):
            self._count('add')
            super().append(item)
        def remove(self, item):
            self._count('remove')
            super().remove(item)
    class ProbeFuture(Future):
        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self._callbacks = SignalInsideLock()
    executor_module.Future = ProbeFuture

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node('stop_in_lock_probe')
    ticks = [0]
    node.create_timer(0.01, lambda: ticks.__setitem__(0, ticks[0] + 1))
    executor = executor_module.create_executor('events')
    executor.add_node(node)
    spin_until_stopped(executor)
    executor.shutdown(timeout_sec=0.0)
    node.destroy_node()
    rclpy.shutdown()
    print(f'stopped by {{STOP.signal}} after {{ticks[0]}} ticks; {{where}} calls {{SignalInsideLock.calls}}')
''')


@pytest.mark.ros
@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
@pytest.mark.parametrize('where', ['add', 'remove'])
def test_the_spin_loop_stops_on_a_signal_handled_inside_the_slice_futures_lock(where: str, sig: int) -> None:
    lease = lease_domain_id()
    try:
        env = dict(os.environ, ROS_DOMAIN_ID=str(lease.domain_id))
        done = subprocess.run([sys.executable, '-c', STOP_IN_LOCK_SCRIPT, where, str(int(sig))], env=env, cwd=REPO,
                              capture_output=True, text=True, timeout=HANG_S + 60, check=False)
    finally:
        lease.release()
    assert done.returncode == 0 and done.stdout.startswith(f'stopped by {int(sig)} '), (
        f'the loop did not stop (status {done.returncode}); it printed {done.stdout!r}; its stacks and errors:\n'
        f'{done.stderr}')
    assert f'{where} calls 3' in done.stdout, done.stdout  # the signal was raised inside the lock


@pytest.mark.ros
@pytest.mark.parametrize('how', ['option', 'environment'])
def test_node_refuses_an_unknown_executor_with_one_line(how: str) -> None:
    lease = lease_domain_id()
    try:
        env = dict(os.environ, ROS_DOMAIN_ID=str(lease.domain_id))
        args = ['--executor', 'multi'] if how == 'option' else []
        if how == 'environment':
            env[EXECUTOR_ENV] = 'multi'
        done = subprocess.run([*node_command(), *args, '--ros-args', '-r', '__ns:=/executor_choice'], env=env,
                              capture_output=True, text=True, timeout=60, check=False)
    finally:
        lease.release()
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('fourbar_node: error: ') and 'multi' in lines[0], done.stderr
    assert all(name in lines[0] for name in EXECUTORS)


@pytest.mark.ros
@pytest.mark.parametrize(('args', 'variable', 'expected'), [
    ([], None, DEFAULT_EXECUTOR),
    ([], 'single', 'single'),
    (['--executor', 'single'], None, 'single'),
    (['--executor', 'events'], 'single', 'events'),  # the option wins over the variable
], ids=['default', 'environment', 'option', 'option_over_environment'])
def test_node_runs_the_chosen_executor(args: list[str], variable: str | None, expected: str) -> None:
    lease = lease_domain_id()
    try:
        env = dict(os.environ, ROS_DOMAIN_ID=str(lease.domain_id), PYTHONUNBUFFERED='1')
        env.pop(EXECUTOR_ENV, None)
        if variable is not None:
            env[EXECUTOR_ENV] = variable
        with Tool([*args, '--ros-args', '-r', '__ns:=/executor_choice'], env, command=node_command()) as node:
            line = node.wait_line('', 60.0)  # the node's first log line, written once it spins (a deadline)
            node.signal(signal.SIGTERM)
            status = node.wait(60.0)
    finally:
        lease.release()
    rest = ''.join(f'{later}\n' for later in node.lines[1:])
    assert f'callbacks run on the {expected} executor' in line, line + rest
    assert status == 0, rest


def test_non_ros_args_drop_every_ros_section() -> None:
    from fourbar_ros.node.run import non_ros_args

    argv = ['fourbar_node', '--executor', 'single', '--ros-args', '-p', 'a:=1', '--', '--x', '--ros-args', '-r', 'b:=c']
    assert non_ros_args(argv) == ['fourbar_node', '--executor', 'single', '--x']
    assert non_ros_args(['fourbar_node', '--ros-args', '--params-file', '/missing.yaml']) == ['fourbar_node']
