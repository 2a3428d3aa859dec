"""Where fourbar_node starts a new motion, judged by the real joint_trajectory_controller's reference.

The package's launch file brings up the controller manager (mock hardware, the shipped controllers) in /takeover
once for the module; beside the launched node a second fourbar_node (``takeover_node``, trajectory mode) reads its
measured driven joint on ``held_joint_states`` and its commands on ``takeover_cmd``, which takeover_probe.py feeds:
it relays joint_state_broadcaster's states with their own stamps, and holds them where a case says. Each case
judges the controller's reference, update by update (``~/controller_state``), from the takeover of the node's plan
to the end of its motion: within the driven rocker's speed, acceleration and jerk limits, and starting where the
drive rests. A third case halts a far move with ``ros2 service call .../halt std_srvs/srv/Trigger`` at cruising
speed: the reference brakes to rest within the limits short of the target, the drive stays there through a
deactivation and activation of the controller and a command while halted (dropped), and moves again after
``.../resume`` and a command.

Runs where the ros2 command line, launch_ros and ros2_control are installed; skipped elsewhere with the reason.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pytest
from support.colcon_support import CliEnv, launch_missing, ros2, ros2_cli_missing
from support.paths import REPO
from support.ros2_control_support import ros2_control_missing

if (_why := ros2_cli_missing() or launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from support.ros_cli_support import Background, fourbar_launch, wait_node  # psutil: with ros2cli

from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.motion.planner import driven_angles

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NAMESPACE = 'takeover'
PROBE = REPO / 'test' / 'support' / 'takeover_probe.py'
JTC = 'joint_trajectory_controller'
NS = 1_000_000_000
#: The node under test: trajectory mode, its status ten times a second (the probe waits on it), its measured joint,
#: commands and antenna angle on topics of the probe's (takeover_probe.py).
NODE_ARGUMENTS = ('-p', 'mode:=trajectory', '-p', 'diagnostics_period:=0.1', '-r', f'__ns:=/{NAMESPACE}',
                  '-r', '__node:=takeover_node', '-r', 'measured_joint_states:=held_joint_states',
                  '-r', 'antenna_angle_cmd:=takeover_cmd', '-r', 'antenna_angle:=takeover_angle')


class Bringup(NamedTuple):
    """The command line's environment, the launch (its output holds the controller's log) and the node under test."""

    cli: CliEnv
    launch: Background
    node: Background


@pytest.fixture(scope='module')
def bringup(ros2_cli: CliEnv, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Bringup]:
    """The package's ros2_control bringup in /takeover (trajectory mode, mock hardware) and ``takeover_node``."""
    if (why := ros2_control_missing(ros2_cli.env)) is not None:
        pytest.skip(why)
    params = tmp_path_factory.mktemp('takeover') / 'antenna.yaml'
    shipped = (ros2_cli.prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml').read_text(encoding='utf-8')
    assert 'hardware_parameters: []' in shipped
    params.write_text(shipped.replace('hardware_parameters: []', "hardware_parameters: ['calculate_dynamics=true']"),
                      encoding='utf-8')
    with fourbar_launch(ros2_cli, NAMESPACE, ['use_ros2_control:=true', 'mode:=trajectory', f'params_file:={params}'],
                        f'Configured and activated {JTC}') as launch:
        node = Background([ros2(), 'run', 'fourbar_ros', 'fourbar_node', '--ros-args', '--params-file', str(params),
                           *NODE_ARGUMENTS], ros2_cli.env, cwd=ros2_cli.cwd)
        try:
            wait_node(ros2_cli.env, f'/{NAMESPACE}/takeover_node')
            yield Bringup(ros2_cli, launch, node)
            assert node.interrupt(group=True) == 0, node.output()[-3000:]
        finally:
            node.kill()


def _probe(b: Bringup, scenario: dict[str, Any], tmp_path: Path) -> tuple[dict[str, Any], str]:
    """The probe's recording of ``scenario``, and what the launch printed meanwhile."""
    printed = len(b.launch.output())
    spec, out = tmp_path / 'scenario.json', tmp_path / 'recording.json'
    spec.write_text(json.dumps(scenario), encoding='utf-8')
    done = subprocess.run([sys.executable, str(PROBE), f'/{NAMESPACE}', str(spec), str(out)], env=b.cli.env,
                          capture_output=True, text=True, timeout=180, check=False)
    assert done.returncode == 0, (done.stdout[-3000:] + done.stderr[-3000:] + '\nthe node printed:\n'
                                  + b.node.output()[-3000:])
    return dict(json.loads(out.read_text(encoding='utf-8'))), b.launch.output()[printed:]


CFG = load_config(REPO / 'config' / 'antenna.yaml')
LIMITS = JointLimits.from_config(CFG)
#: The driven rocker's speed, acceleration and jerk limits (rad/s, rad/s^2, rad/s^3): the motor's over the reduction.
LIMIT = {order: LIMITS.at_rocker(order) for order in (1, 2, 3)}
QUANTITY = {1: ('speed', 'rad/s'), 2: ('acceleration', 'rad/s^2'), 3: ('jerk', 'rad/s^3')}
#: Relative margin over a limit. The controller evaluates the node's quintic segments, which the node plans and checks
#: within the limits themselves (their extremes, not only the points); the reference's velocity and acceleration are
#: that spline's, and a difference quotient over the controller's own sample times (``time_from_start``, whole ns)
#: is the mean of the next derivative over the interval, so within its extreme (mean value theorem). What is left is
#: rounding: ns over 10 ms (1e-7 relative) and float64 (below 1e-8 of the jerk limit on the node's shortest segments).
MARGIN = 1e-6
#: At the takeover the controller's lead-in starts at the drive's measured state: the reference there is the rest
#: position to the bit, but for the rounding of the spline's evaluation at its start (rad).
EXACT_RAD = 1e-9
#: Two updates follow the same trajectory when the trajectory's start (the stamp less ``time_from_start``) agrees to
#: this (ns): the controller's and the header's clocks differ by microseconds.
SAME_START_NS = 1_000_000
PERIOD_NS = NS // 100  # the shipped controller manager's update period (100 Hz)

#: Case 1: antenna angles (rad) of the first and the second command; the node's measured stream holds the states
#: stamped later than HELD_BEFORE_END_S before the first motion's planned end (the drive braking from 0.06 rad/s
#: there), and the second command goes AFTER_END_S after that end: its latest measurement is then 0.33 s old (below
#: the node's measurement_timeout, 0.5 s, after which it would wait for a fresh one).
LATE_FIRST, LATE_THEN = 0.05, 0.0
HELD_BEFORE_END_S, AFTER_END_S = 0.3, 0.03
#: Case 2: the first command's motion is switched off at cruising speed (CRUISE of the limit or faster); the state fed
#: after the switch is the one stamped BEFORE_SWITCH_S before it.
SWITCH_FIRST, SWITCH_THEN = -0.09, 0.02
CRUISE = 0.95
BEFORE_SWITCH_S = 0.03


def _gamma(theta: float) -> float:
    """The driven angle (rad) of antenna angle ``theta`` (rad): where a command's motion ends."""
    return float(driven_angles(CFG, np.array([theta]))[0])


def _start(s: dict[str, Any]) -> int:
    """The start (ns, header clock) of the trajectory an update follows."""
    return int(s['stamp']) - int(s['fb_tfs'])


def _takeover(states: list[dict[str, Any]], since: int) -> int:
    """The index of the first update stamped after ``since`` (ns) that follows another trajectory than the update
    before it."""
    for k in range(1, len(states)):
        if states[k]['stamp'] > since and abs(_start(states[k]) - _start(states[k - 1])) >= SAME_START_NS:
            return k
    raise AssertionError(f'no takeover recorded after {since} ns ({len(states)} updates)')


@dataclass(frozen=True)
class Worst:
    """The largest value of one order (1 speed, 2 acceleration, 3 jerk) over the judged updates, of the reference's own
    fields or of its difference quotients (``how``), and where (ms after the takeover, the update's reference p, v,
    a)."""

    order: int
    value: float
    how: str
    at_ms: float
    reference: tuple[float, float, float]

    @property
    def ratio(self) -> float:
        return self.value / LIMIT[self.order]

    def line(self) -> str:
        name, unit = QUANTITY[self.order]
        p, v, a = self.reference
        return (f'{name} {self.value:.6g} {unit} = {self.ratio:.3g} x the limit {LIMIT[self.order]:.6g} {unit} '
                f'({self.how}, {self.at_ms:+.0f} ms from the takeover; reference there {p:.6f} rad, {v:.6g} rad/s, '
                f'{a:.6g} rad/s^2)')


def _worst(states: list[dict[str, Any]], k0: int) -> list[Worst]:
    """The worst speed, acceleration and jerk of the controller's reference from the update before the takeover
    ``k0`` to the end of the recording: of the reference's own velocity and acceleration at each update, and of the
    difference quotients of its position, velocity and acceleration between successive updates over their sample
    times (the trajectory's own times where both follow the same one, else the time between the two updates)."""
    worst: dict[tuple[int, bool], Worst] = {}
    t0 = states[k0]['stamp']

    def note(order: int, value: float, how: str, s: dict[str, Any]) -> None:
        key = (order, 'difference' in how)
        if key not in worst or value > worst[key].value:
            ref = (s['ref'][0][0], s['ref'][1][0], s['ref'][2][0])
            worst[key] = Worst(order, value, how, (s['stamp'] - t0) / 1e6, ref)

    for prev, s in zip(states[k0 - 1:], states[k0:], strict=False):
        note(1, abs(s['ref'][1][0]), 'reference velocity', s)
        note(2, abs(s['ref'][2][0]), 'reference acceleration', s)
        same = abs(_start(s) - _start(prev)) < SAME_START_NS
        dt = (s['ref_tfs'] - prev['ref_tfs'] if same else s['stamp'] - prev['stamp']) / NS
        assert dt > 0.0, f'updates out of order: {prev} then {s}'
        across = '' if same else ' between two trajectories'
        for order, name in ((1, 'position'), (2, 'velocity'), (3, 'acceleration')):
            i = order - 1
            note(order, abs(s['ref'][i][0] - prev['ref'][i][0]) / dt,
                 f'{name} difference over {dt * 1e3:.2f} ms{across}', s)
    return [worst[k] for k in sorted(worst)]


def _plan_line(plan: dict[str, Any], since: int) -> str:
    first, last = plan['points'][0], plan['points'][-1]
    return (f'{len(plan["points"])} points stamped {(plan["stamp"] - since) / 1e6:+.1f} ms, the first '
            f'[t, p, v, a] = {first}, the last {last}')


def _judge(rec: dict[str, Any], since: tuple[str, int], had: dict[str, Any], context: str, logged: str) -> None:
    """The controller's reference from the takeover of the node's first plan after ``since`` (ns) to the end of the
    recording (``since``: what happened then, and when): it starts where the drive rests, and stays within the rocker's
    limits times 1 + MARGIN. ``had``: the
    latest measurement the node had; ``context``: what the case did; ``logged``: the launch's output meanwhile (the
    controller's log), for the report."""
    said = [f'the controller logged: {line.strip()}' for line in logged.splitlines()
            if JTC in line and ('tolerance' in line or 'Holding' in line)][:5]
    states = rec['states']
    event, at = since
    k0 = _takeover(states, at)
    before, taken = states[k0 - 1], states[k0]
    rest = before['fb'][0][0]
    plans = [t for t in rec['trajectories'] if t['received'] > at]
    worst = _worst(states, k0)
    lines = [context,
             f'the latest measurement the node had: stamped {(had["stamp"] - at) / 1e6:+.1f} ms from {event}, '
             f'{had["position"]!r} rad, {had["velocity"]!r} rad/s',
             *(f'the node sent: {_plan_line(p, at)} from {event}' for p in plans),
             f'the drive rested at {rest!r} rad (velocity {before["fb"][1][0]!r} rad/s) before the takeover; the '
             f'reference there: {taken["ref"][0][0]!r} rad, {taken["ref"][1][0]!r} rad/s, {taken["ref"][2][0]!r} '
             f'rad/s^2; {len(states) - k0} updates judged',
             *(f'worst {w.line()}' for w in worst),
             f'bounds: the limits times 1 + {MARGIN:g}; jerk by differences of the reference acceleration over the '
             f'sample times (between two trajectories: the time between the two updates)', *said]
    report = '\n'.join(lines)
    print(report)
    assert had['velocity'] != 0.0, f'the case needs the drive measured moving:\n{report}'
    assert before['fb'][1][0] == 0.0 and before['ref'][1][0] == 0.0, f'the drive was not at rest:\n{report}'
    gapless = taken['stamp'] - before['stamp'] < 1.5 * PERIOD_NS  # else the takeover's own state was not published
    assert not gapless or abs(taken['ref'][0][0] - rest) <= EXACT_RAD, (
        f'the reference at the takeover is {taken["ref"][0][0] - rest:+.3g} rad from the resting drive:\n{report}')
    over = [w for w in worst if w.ratio > 1.0 + MARGIN]
    assert not over, f'the controller\'s reference went over the limits:\n{report}'


def test_a_measurement_from_before_a_motions_end_starts_the_next_motion_where_the_drive_rests(
        bringup: Bringup, tmp_path: Path) -> None:
    scenario = {'kind': 'late', 'first': LATE_FIRST, 'first_end': _gamma(LATE_FIRST), 'then': LATE_THEN,
                'then_end': _gamma(LATE_THEN), 'held_before_end': HELD_BEFORE_END_S, 'after_end': AFTER_END_S}
    rec, logged = _probe(bringup, scenario, tmp_path)
    ev = rec['events']
    had = [f for f in rec['fed'] if f['sent'] < ev['then']][-1]
    context = (f'theta {LATE_FIRST} rad, then {LATE_THEN} rad {(ev["then"] - ev["first_end"]) / 1e6:.1f} ms after '
               f'the first motion\'s planned end; the measurement was stamped '
               f'{(had["stamp"] - ev["first_end"]) / 1e6:.1f} ms from that end')
    _judge(rec, ('the second command', ev['then']), had, context, logged)


def test_a_measurement_from_before_the_controller_switched_off_and_on_starts_no_motion_from_its_velocity(
        bringup: Bringup, tmp_path: Path) -> None:
    scenario = {'kind': 'switch', 'first': SWITCH_FIRST, 'first_end': _gamma(SWITCH_FIRST), 'then': SWITCH_THEN,
                'then_end': _gamma(SWITCH_THEN), 'cruise': CRUISE * LIMIT[1], 'before_switch': BEFORE_SWITCH_S}
    rec, logged = _probe(bringup, scenario, tmp_path)
    ev, switch = rec['events'], rec['switch_ns']
    had = next(f for f in rec['fed'] if f['sent'] >= ev['fed'])
    context = (f'theta {SWITCH_FIRST} rad; {JTC} deactivated and activated at cruising speed (the switch\'s update '
               f'{(switch - ev["fed"]) / 1e6:+.1f} ms from the feed); the state fed stamped '
               f'{(had["stamp"] - switch) / 1e6:+.1f} ms from the switch; then theta {SWITCH_THEN} rad, '
               f'{(ev["then"] - ev["fed"]) / 1e6:+.1f} ms from the feed')
    assert had['stamp'] < switch
    _judge(rec, ('the feed', ev['fed']), had, context, logged)


#: Case 3, the halt: from theta_min the far move to theta_max (5 s, cruising from 0.43 s to 4.56 s at the plan's top
#: speed); the halt by ``ros2 service call`` once the drive moves at CRUISE of the speed limit or faster; while halted
#: the command HALT_DROPPED; after the resume HALT_THEN (the drive left at rest there for what follows). Where the
#: command line reaches the node after the cruise, the probe resumes and moves again (takeover_probe.HALT_TRIES).
HALT_FROM, HALT_FIRST, HALT_DROPPED, HALT_THEN = CFG.theta_min, CFG.theta_max, 0.05, 0.0


def _received_before(rows: list[dict[str, Any]], t: int) -> dict[str, Any]:
    """The last row received by ``t`` (ns)."""
    return [r for r in rows if r['received'] <= t][-1]


def test_a_halt_by_the_ros2_command_line_brakes_the_drive_to_rest_within_the_limits_and_holds_it_until_resumed(
        bringup: Bringup, tmp_path: Path) -> None:
    scenario = {'kind': 'halt', 'ros2': ros2(), 'from': HALT_FROM, 'from_end': _gamma(HALT_FROM),
                'first': HALT_FIRST, 'first_end': _gamma(HALT_FIRST), 'cruise': CRUISE * LIMIT[1],
                'halted': HALT_DROPPED, 'then': HALT_THEN, 'then_end': _gamma(HALT_THEN)}
    rec, logged = _probe(bringup, scenario, tmp_path)
    ev, calls, statuses, states = rec['events'], rec['calls'], rec['statuses'], rec['states']
    halt, resume = calls['halt'], calls['resume']
    assert halt['rc'] == 0 and 'success=True' in halt['stdout'] and 'halted: braking to rest at' in halt['stdout'], (
        f'{" ".join(halt["argv"])}: exit {halt["rc"]}\n{halt["stdout"]}{halt["stderr"]}')
    # What the node sent from the halt call to the command after the resume: the brake only.
    sent = [t for t in rec['trajectories'] if ev['halt_call'] < t['received'] < ev['then']]
    assert len(sent) == 1, [_plan_line(t, ev['halt_call']) for t in sent]
    brake = sent[0]
    q_rest, q_target = brake['points'][-1][1], _gamma(HALT_FIRST)
    direction = float(np.sign(q_target - _gamma(HALT_FROM)))
    at_call = _received_before(rec['measured'], ev['halt_call'])
    at_brake = _received_before(rec['measured'], brake['received'])  # the drive when the node had braked
    # The controller's reference from the halt call to the deactivation, update by update: the far move's last
    # updates, the brake's takeover (it continues the far move's trajectory, with its stamp and its points up to the
    # departure: no new start to find it by) and the brake.
    k0 = next(k for k, s in enumerate(states) if s['stamp'] > ev['halt_call'])
    k_off = next(k for k, s in enumerate(states) if s['received'] >= ev['deactivate_request'])
    judged = states[:k_off]
    worst = _worst(judged, k0)
    rest = next((k for k in range(k0, k_off) if all(s['fb'][1][0] == 0.0 for s in judged[k:])), None)
    lines = [f'far move theta {HALT_FROM} -> {HALT_FIRST} rad; `{" ".join(halt["argv"][1:])}` started at '
             f'{at_call["velocity"]!r} rad/s, {at_call["position"]!r} rad measured, exited '
             f'{(ev["halt_answered"] - ev["halt_call"]) / 1e9:.3f} s later: {halt["stdout"].strip().splitlines()[-1]}',
             f'the node sent: {_plan_line(brake, ev["halt_call"])} from the call (received '
             f'{(brake["received"] - ev["halt_call"]) / 1e9:.3f} s after it, the drive measured then at '
             f'{at_brake["velocity"]!r} rad/s, {at_brake["position"]!r} rad); far moves before this one whose halt '
             f'came after the cruise: {calls["missed"]}',
             f'{k_off - k0} updates judged from the call to the deactivation (times from the first)',
             *(f'worst {w.line()}' for w in worst)]
    if rest is not None:
        lines.append(f'the drive at rest (feedback velocity 0 from then on) at {judged[rest]["fb"][0][0]!r} rad, '
                     f'{(judged[rest]["stamp"] - ev["halt_call"]) / 1e9:.3f} s after the halt call started, '
                     f'{(judged[rest]["stamp"] - brake["received"]) / 1e9:.3f} s after the brake was sent; '
                     f'{q_target - q_rest:+.4f} rad short of the target')
    report = '\n'.join(lines + [f'the controller logged: {line.strip()}' for line in logged.splitlines()
                                if JTC in line and ('tolerance' in line or 'Holding' in line)][:5])
    print(report)
    assert min(direction * at_call['velocity'], direction * at_brake['velocity']) >= CRUISE * LIMIT[1], (
        f'the drive was not cruising from the call to the brake:\n{report}')
    over = [w for w in worst if w.ratio > 1.0 + MARGIN]
    assert not over, f'the controller\'s reference went over the limits braking:\n{report}'
    assert rest is not None, f'the drive did not come to rest before the deactivation:\n{report}'
    assert abs(judged[rest]['fb'][0][0] - q_rest) <= EXACT_RAD, f'the drive rests off the brake\'s end:\n{report}'
    # on the way: beyond where it was at the call, short of the target
    assert direction * (q_rest - at_call['position']) > 0.0 and direction * (q_target - q_rest) > 0.0, report
    # At rest there through the deactivation and the activation, the command while halted and the resume.
    after = [m for m in rec['measured'] if judged[rest]['stamp'] <= m['stamp'] and m['received'] < ev['then']]
    moved = [m for m in after if m['velocity'] != 0.0 or abs(m['position'] - q_rest) > EXACT_RAD]
    assert after and not moved, (f'{len(moved)} of {len(after)} broadcaster states after the rest off it, the first '
                                 f'{moved[:3]}:\n{report}')
    assert any(m['stamp'] > ev['activated'] for m in after), f'no state after the activation:\n{report}'
    halted, dropped = statuses['halted'], statuses['dropped']
    assert halted['halted'].startswith('yes: by the ~/halt service, ') and halted['command_fate'] == 'interrupted', (
        halted)
    assert int(dropped['halt_dropped']) == int(halted['halt_dropped']) + 1, (halted, dropped)
    assert dropped['command_fate'] == 'interrupted' and dropped['command_theta_rad'] == repr(float(HALT_FIRST)), (
        dropped)
    assert resume['rc'] == 0 and 'success=True' in resume['stdout'] and 'resumed (halted by the ~/halt service' in (
        resume['stdout']), f'{" ".join(resume["argv"])}: exit {resume["rc"]}\n{resume["stdout"]}{resume["stderr"]}'
    # After the resume the command moves the drive to its target, within the limits, and leaves it at rest there.
    k1 = _takeover(states, ev['then'])
    over = [w for w in _worst(states, k1) if w.ratio > 1.0 + MARGIN]
    assert not over, [w.line() for w in over]
    last = rec['measured'][-1]
    assert last['velocity'] == 0.0 and abs(last['position'] - _gamma(HALT_THEN)) <= EXACT_RAD, last
