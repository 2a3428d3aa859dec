"""The package's launch files refuse a launch argument they do not declare, before anything starts. No ROS import.

``ros2 launch FILE name:=value`` makes every pair a launch configuration, declared or not (a misspelled name would
be ignored without a word). A launch file puts ``OpaqueFunction(function=refuse_undeclared(FILE, arguments))`` first:
an undeclared name raises ``UnknownLaunchArgumentError``, which ``ros2 launch`` prints as one line, then exits 1.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, Protocol

#: Launch configurations that launch and launch_ros set themselves, never an argument of a launch file: ``ros2
#: launch --launch-prefix`` / ``--launch-prefix-filter`` (added to its argv as ``launch-prefix:=...``),
#: PushRosNamespace, SetParameter / SetParametersFromFile, SetRemap.
LAUNCH_OWN = frozenset({'launch-prefix', 'launch-prefix-filter', 'ros_namespace', 'global_params', 'ros_remaps'})


class UnknownLaunchArgumentError(RuntimeError):
    """A launch argument the launch file does not declare; the message is the one line ``ros2 launch`` prints."""


class Declared(Protocol):
    """What the check reads of a ``DeclareLaunchArgument``: its name."""

    @property
    def name(self) -> str: ...


def command_line_names(argv: Iterable[str]) -> list[str]:
    """The names of the ``name:=value`` pairs in ``argv`` (a launch context's ``argv``: ``ros2 launch``'s launch
    arguments), in order, each once; anything else in ``argv`` is not a launch argument."""
    names: list[str] = []
    for item in argv:
        name, sep, _ = item.partition(':=')
        if sep and name not in names:
            names.append(name)
    return names


def undeclared(configurations: Iterable[str], argv: Sequence[str], declared: Iterable[str]) -> list[str]:
    """The command-line names of ``argv`` that ``declared`` does not hold, sorted; none when a name in
    ``configurations`` (the launch configurations before the file's own arguments are declared) came neither from
    the command line nor from launch itself (``LAUNCH_OWN``).

    Such a name was set by a launch file that includes this one: its arguments' values, what it passes on. An
    included file sees those, and the command line's names are then the including file's, not this one's (it
    answers for them). Included by a file that sets nothing of its own, the command line is checked here."""
    given = command_line_names(argv)
    if not set(configurations) <= {*given, *LAUNCH_OWN}:
        return []
    known = {*declared, *LAUNCH_OWN}
    return sorted(name for name in given if name not in known)


def refusal(launch_file: str, unknown: Iterable[str], declared: Iterable[str]) -> str:
    """The one line that refuses ``unknown`` arguments: them, and the arguments ``launch_file`` takes (sorted)."""
    names = sorted(unknown)
    what = 'argument' if len(names) == 1 else 'arguments'
    return (f'{launch_file}: unknown launch {what} {", ".join(names)}; it takes: '
            f'{", ".join(sorted(set(declared)))}')


def refuse_undeclared(launch_file: str, arguments: Iterable[Declared]) -> Callable[[Any], list[object]]:
    """The function of an ``OpaqueFunction`` put first in ``launch_file``'s description: it raises
    ``UnknownLaunchArgumentError`` (nothing of the description after it runs) when the command line names an
    argument none of ``arguments`` declares; else it adds nothing. ``context`` is the launch context (duck-typed:
    ``launch_configurations`` and ``argv``)."""
    declared = [a.name for a in arguments]

    def check(context: Any) -> list[object]:
        configurations: Mapping[str, str] = context.launch_configurations
        unknown = undeclared(configurations, list(context.argv), declared)
        if unknown:
            raise UnknownLaunchArgumentError(refusal(launch_file, unknown, declared))
        return []

    return check
