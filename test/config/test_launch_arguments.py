"""fourbar_ros.config.launch_arguments alone: which command-line names are refused, the one line that says so, and
the check as an OpaqueFunction's function runs it (a stand-in for the launch context: its configurations and argv).
Through ``ros2 launch``: test/package/test_launch.py."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest

from fourbar_ros.config.launch_arguments import (
    LAUNCH_OWN,
    UnknownLaunchArgumentError,
    command_line_names,
    refusal,
    refuse_undeclared,
    undeclared,
)

DECLARED = ('namespace', 'mode', 'hardware')


@dataclass(frozen=True)
class Argument:
    name: str


@dataclass
class Context:
    """What the check reads of a launch context."""

    argv: list[str]
    launch_configurations: dict[str, str] = field(default_factory=dict)

    @classmethod
    def command_line(cls, *argv: str) -> Context:
        """The context ``ros2 launch FILE ARGV`` gives the file's first entity: each pair a configuration."""
        return cls(list(argv), {n: v for n, _, v in (a.partition(':=') for a in argv)})


def test_command_line_names_are_the_pairs_names_each_once_in_order() -> None:
    assert command_line_names(['mode:=forward', 'not_a_pair', 'a:=b:=c', 'mode:=trajectory', ':=x']) == \
        ['mode', 'a', '']


def test_undeclared_names_are_sorted_and_declared_or_launchs_own_ones_pass() -> None:
    argv = ['zeta:=1', 'mode:=forward', 'alpha:=2', 'launch-prefix:=gdb']
    assert undeclared(command_line_names(argv), argv, DECLARED) == ['alpha', 'zeta']
    argv = ['mode:=forward', *(f'{name}:=x' for name in sorted(LAUNCH_OWN))]
    assert undeclared(command_line_names(argv), argv, DECLARED) == []


def test_nothing_is_refused_when_an_including_launch_file_set_configurations() -> None:
    """The parent's argument 'world' (declared there, its default set) and the name it was given on the command
    line: the parent's business, not this file's."""
    assert undeclared(['world', 'mode'], ['world:=moon'], DECLARED) == []
    # launch_ros's own configurations (PushRosNamespace in the parent) do not count as the parent's
    assert undeclared(['ros_namespace', 'hardwre'], ['hardwre:=bridge'], DECLARED) == ['hardwre']


def test_the_refusal_is_one_line_naming_the_unknown_and_the_sorted_declared() -> None:
    assert refusal('x.launch.py', ['hardwre'], DECLARED) == \
        'x.launch.py: unknown launch argument hardwre; it takes: hardware, mode, namespace'
    assert refusal('x.launch.py', ['b', 'a'], [*DECLARED, 'mode']) == \
        'x.launch.py: unknown launch arguments a, b; it takes: hardware, mode, namespace'


def test_the_check_raises_for_an_undeclared_argument_and_adds_nothing_otherwise() -> None:
    check = refuse_undeclared('x.launch.py', [Argument(n) for n in DECLARED])
    assert check(Context.command_line('mode:=forward', 'launch-prefix:=gdb')) == []
    assert check(Context.command_line()) == []
    with pytest.raises(UnknownLaunchArgumentError) as err:
        check(Context.command_line('use_ros2_control:=true', 'mode:=forward'))
    assert str(err.value) == refusal('x.launch.py', ['use_ros2_control'], DECLARED)
    assert isinstance(err.value, RuntimeError)  # as the launch file's other refusals: ros2 launch exits 1
