"""The fates of served commands across the controller's lifecycle (rules.command_fate), case by case and as random
sequences of events against the invariants: one final fate per command, never sent while the controller cannot take
it, and the last command reached whenever the controller ends active and the drive follows."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fourbar_ros.rules.command_fate import CommandFates, Fate, FateSettings, Readiness, readiness

S = 1_000_000_000
SETTINGS = FateSettings(hold_timeout=10.0, resume_interrupted=True, reached_tolerance=1e-3, reach_timeout=2.0)


def fates(resume: bool = True, ready: Readiness = Readiness.ACTIVE) -> CommandFates:
    return CommandFates(FateSettings(10.0, resume, 1e-3, 2.0), readiness=ready, measured=True)


@pytest.mark.parametrize(('controllers', 'hardware', 'expected'), [
    ([('jtc', 'active'), ('jsb', 'active')], [('hw', 'active')], Readiness.ACTIVE),
    ([('jtc', 'inactive')], [('hw', 'active')], Readiness.INACTIVE),
    ([('jtc', 'unconfigured')], [], Readiness.INACTIVE),
    ([('jtc', 'active')], [('hw', 'inactive')], Readiness.HARDWARE_INACTIVE),
    ([('jtc', 'inactive')], [('hw', 'inactive')], Readiness.INACTIVE),
    ([('jsb', 'active')], [('hw', 'active')], Readiness.ABSENT),
    ([], [], Readiness.ABSENT),
])
def test_readiness_from_the_managers_activity(controllers: list[tuple[str, str]], hardware: list[tuple[str, str]],
                                              expected: Readiness) -> None:
    assert readiness(controllers, hardware, 'jtc') is expected


def test_a_command_goes_out_at_once_when_the_controller_is_active_and_is_reached() -> None:
    f = fates()
    assert f.receive(0.1, 0)
    f.sent(end_ns=2 * S)
    f.reached(0.1, 1 * S)  # within tolerance, but the motion has not ended
    assert f.current is not None and f.current.fate is Fate.SENT
    f.reached(0.1 + 2e-3, 3 * S)  # ended, outside the tolerance
    assert f.current.fate is Fate.SENT
    f.reached(0.1 + 0.5e-3, 3 * S)
    assert f.current.fate is Fate.REACHED
    assert f.counts[Fate.SENT] == 1 and f.counts[Fate.REACHED] == 1 and f.counts[Fate.HELD] == 0


NOT_SENDABLE = [Readiness.INACTIVE, Readiness.HARDWARE_INACTIVE, Readiness.ABSENT, Readiness.GONE]


@pytest.mark.parametrize('ready', NOT_SENDABLE)
def test_a_command_waits_for_the_controller_and_then_is_due(ready: Readiness) -> None:
    f = fates(ready=ready)
    assert not f.receive(0.1, 0)
    assert f.current is not None and f.current.fate is Fate.HELD
    expected = 'a hardware component inactive' if ready is Readiness.HARDWARE_INACTIVE else f'controller {ready.value}'
    assert f.current.reason == expected
    assert not f.due()
    f.controller(Readiness.ACTIVE, 1 * S)
    assert f.due()


def test_a_command_before_any_measurement_waits_for_one() -> None:
    f = CommandFates(SETTINGS)
    assert not f.receive(0.1, 0)
    assert f.current is not None and f.current.reason == 'no measured driven joint yet'
    f.measured = True
    assert f.due()


def test_a_held_command_expires_after_the_hold_timeout() -> None:
    f = fates(ready=Readiness.INACTIVE)
    f.receive(0.1, 0)
    f.tick(10 * S, None)  # at the timeout: still valid
    assert f.current is not None and f.current.fate is Fate.HELD
    f.tick(10 * S + 1, None)
    assert f.current.fate is Fate.DROPPED and 'hold_timeout 10 s' in f.current.reason
    f.controller(Readiness.ACTIVE, 11 * S)
    assert not f.due()


def test_a_newer_command_supersedes_the_one_held_or_sent() -> None:
    f = fates(ready=Readiness.INACTIVE)
    f.receive(0.1, 0)
    first = f.current
    f.receive(0.2, 1)
    assert first is not None and first.fate is Fate.SUPERSEDED and f.counts[Fate.SUPERSEDED] == 1
    f.controller(Readiness.ACTIVE, 2)
    assert f.due()
    f.sent(10)
    second = f.current
    f.supersede('by an antenna trajectory')
    assert second is not None and second.fate is Fate.SUPERSEDED


def test_a_refused_command_is_dropped_and_the_one_in_force_stays() -> None:
    f = fates()
    assert f.receive(0.1, 0)
    f.sent(10 * S)
    running = f.current
    assert f.receive(0.2, S)  # planned, then refused: nothing went out
    f.refused('cannot stop in time')
    assert f.current is running and running is not None and running.fate is Fate.SENT
    assert f.counts[Fate.DROPPED] == 1 and f.counts[Fate.SUPERSEDED] == 0 and f.pending is None
    f.reached(0.1, 10 * S)
    assert running.fate is Fate.REACHED  # and its fate is still told


def test_the_same_command_again_joins_the_one_in_force() -> None:
    f = fates()
    assert f.receive(0.1, 0)
    f.sent(5 * S)
    cmd = f.current
    assert f.repeat(0.1, S, None)  # the same angle, sent: joined
    assert not f.repeat(0.1 + 0.5e-3, S, None)  # a step within reached_tolerance is still a new command
    assert not f.repeat(float(np.nextafter(0.1, 1.0)), S, None)  # as is one ulp
    f.reached(0.1, 5 * S)
    assert f.repeat(0.1, 6 * S, 0.1 + 0.9e-3)  # reached, the drive still there
    assert not f.repeat(0.1, 7 * S, 0.1 + 5e-3)  # reached, the drive moved off since: a new command
    assert cmd is not None and cmd.repeats == 2 and f.repeats == 2 and cmd.fate is Fate.REACHED
    held = fates(ready=Readiness.INACTIVE)
    held.receive(0.1, 0)
    assert held.repeat(0.1, 8 * S, None) and held.current is not None and held.current.held_ns == 8 * S
    held.tick(8 * S + int(9.9 * S), None)  # the hold counts from the latest arrival
    assert held.current.fate is Fate.HELD


def test_a_drive_moving_off_the_motion_holds_a_new_command_or_drops_it_beside_a_sent_one() -> None:
    f = fates()
    assert f.receive(0.1, 0)
    f.wait('the drive is measured moving')
    assert f.current is not None and f.current.fate is Fate.HELD and not f.due()
    f.unsettled = ''  # the next measurement: at rest
    assert f.due()
    f.sent(S)
    running = f.current
    assert f.receive(0.2, S)
    f.wait('the drive is measured moving')
    assert f.current is running and running.fate is Fate.SENT and f.counts[Fate.DROPPED] == 1


@pytest.mark.parametrize('to', NOT_SENDABLE)
def test_a_sent_command_interrupted_resumes_or_ends_as_the_parameter_says(to: Readiness) -> None:
    resumed = fates()
    resumed.receive(0.1, 0)
    resumed.sent(5 * S)
    resumed.controller(to, 1 * S)
    assert resumed.current is not None and resumed.current.fate is Fate.HELD
    assert resumed.current.reason.startswith(f'interrupted (controller active -> {to.value})')
    resumed.tick(10 * S + 1 * S, None)  # the hold counts from the interruption
    assert resumed.current.fate is Fate.HELD
    resumed.controller(Readiness.ACTIVE, 12 * S)
    assert resumed.due()
    ended = fates(resume=False)
    ended.receive(0.1, 0)
    ended.sent(5 * S)
    ended.controller(to, 1 * S)
    assert ended.current is not None and ended.current.fate is Fate.INTERRUPTED


def test_a_manager_that_appears_without_the_controller_active_interrupts_what_went_out() -> None:
    f = fates(ready=Readiness.NOT_FOLLOWED)
    assert f.receive(0.1, 0)
    f.sent(5 * S)
    f.controller(Readiness.ACTIVE, 1 * S)  # it was active: what went out runs
    assert f.current is not None and f.current.fate is Fate.SENT
    g = fates(ready=Readiness.NOT_FOLLOWED)
    g.receive(0.1, 0)
    g.sent(5 * S)
    g.controller(Readiness.INACTIVE, 1 * S)
    assert g.current is not None and g.current.fate is Fate.HELD


def test_a_command_not_reached_after_the_reach_timeout_is_interrupted_for_good() -> None:
    f = fates()
    f.receive(0.1, 0)
    f.sent(1 * S)
    f.tick(3 * S, 0.05)  # 2 s after the end: not yet
    assert f.current is not None and f.current.fate is Fate.SENT
    f.tick(3 * S + 1, 0.05)
    assert f.current.fate is Fate.INTERRUPTED
    assert 'measured 0.05 rad, -0.05 off' in f.current.reason


def test_measurements_that_stop_interrupt_a_sent_command_until_the_next_one() -> None:
    f = fates()
    f.receive(0.1, 0)
    f.sent(5 * S)
    f.unmeasured('no measured driven joint for 0.6 s', 1 * S)
    assert f.current is not None and f.current.fate is Fate.HELD and not f.due()
    assert f.current.reason.startswith('interrupted (no measured driven joint for 0.6 s)')
    f.measured = True
    assert f.due()


EVENTS = st.one_of(
    st.tuples(st.just('command'), st.floats(-0.1, 0.1)),
    st.tuples(st.just('controller'), st.sampled_from(list(Readiness))),
    st.tuples(st.just('measured'), st.booleans()),
    st.tuples(st.just('wait'), st.floats(0.0, 15.0)),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(EVENTS, max_size=40), st.booleans())
def test_random_lifecycles_keep_the_invariants(events: list[tuple[str, object]], resume: bool) -> None:
    """A drive that follows exactly: what goes out is reached at the motion's end (1 s), if its controller is still
    active then. Invariants: never sent while the controller cannot take it; each command one final fate at most,
    every earlier command final; the last command reached when the controller ends active, measured, and the
    command is still within its hold."""
    f = CommandFates(FateSettings(10.0, resume, 1e-3, 2.0))
    now, position, commands = 0, 0.0, []

    def act() -> None:
        nonlocal position
        if f.due():
            assert f.current is not None
            f.sent(now + S)
        cmd = f.current
        if cmd is not None and cmd.fate is Fate.SENT:
            assert f.readiness.sendable, f'sent while the controller is {f.readiness}'
            if now >= cmd.end_ns:
                position = cmd.theta
                f.reached(position, now)

    for kind, value in events:
        if kind == 'command':
            if f.receive(float(value), now):  # type: ignore[arg-type]
                f.sent(now + S)
            commands.append(f.current)
        elif kind == 'controller':
            f.controller(value, now)  # type: ignore[arg-type]
        elif kind == 'measured':
            f.measured = f.measured or bool(value)
        else:
            now += int(float(value) * S)  # type: ignore[arg-type]
            act()
            f.tick(now, position)
        act()
        finals = [c.fate for c in commands if c is not None]
        assert all(fate.final for fate in finals[:-1]), f'an earlier command not final: {finals}'
    assert sum(f.counts[x] for x in Fate if x.final) <= len(commands)
    if commands and f.readiness.sendable and f.measured:
        cmd = f.current
        assert cmd is not None
        act()
        now += 2 * S
        act()
        assert cmd.fate in (Fate.REACHED, Fate.DROPPED, Fate.INTERRUPTED), f'the last command {cmd}'
        if cmd.fate is Fate.DROPPED:
            assert 'hold_timeout' in cmd.reason, cmd
        if cmd.fate is Fate.INTERRUPTED:
            assert not resume, cmd
