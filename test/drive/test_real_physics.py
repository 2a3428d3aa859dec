"""The MuJoCo plant as the drive behind the real controller manager, the topic-based hardware plugin and
joint_trajectory_controller, with fourbar_node (trajectory mode, the plant's antenna Imu as its sensor) in front: the
torque the node publishes is the plant's at rest over the range, the antenna's true angle rests within what the
reducer's backlash, compliance and the stepper's deflection allow, the sweep keeps to the motor's speed limit, the
node's own moves neither slip the stepper nor trip the slip stop, and a gust that slips the stepper stops the motion.

One bringup for the module: the controller manager, ``fourbar_mujoco_drive`` (a compliant reducer with 1 mrad of play
at the rocker, the design load as the steady wind) and the spawner as child processes; fourbar_node in-process.
Skipped, with the reason, where ros2_control, the topic plugin or mujoco is not installed.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import pytest
import yaml

pytest.importorskip('rclpy')
pytest.importorskip('mujoco', reason='the MuJoCo plant needs the mujoco package (pip install mujoco)')

from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from support.drive_stack import (
    CFG,
    COMMANDS,
    STATES,
    Processes,
    manager_executable,
    publish_description,
    topic_plugin_missing,
)
from support.paths import REPO
from support.ros2_control_support import with_ros2_control
from support.ros_support import Collector, RosSession

from fourbar_ros.config.controllers import CONTROLLERS_FILE
from fourbar_ros.drive.rules import ACTIVATED_MARK
from fourbar_ros.interface.topics import BROADCASTER_JOINT_STATES, COMMAND, INPUT_TORQUE, MEASURED_JOINT_STATES
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.plant.backend import MICROSTEPS
from fourbar_ros.plant.mjcf import DriveModel
from fourbar_ros.plant.plant_node import TRUTH_TOPIC, WIND_TOPIC
from fourbar_ros.rules.command_fate import Fate
from fourbar_ros.rules.diagnostics import Level

pytestmark = [pytest.mark.ros, pytest.mark.slow]

YAML = REPO / 'config' / 'antenna.yaml'
NAMESPACE = '/real_physics'
MANAGER = f'{NAMESPACE}/controller_manager'
JOINT, MOTOR = CFG.driven_joint, f'{CFG.driven_joint}_motor'
RATIO = CFG.reducer_ratio
#: The plant's reducer: stiffness N m/rad, damping N m s/rad and total play rad, all at the rocker (a soft worm or
#: planetary stage). Undamped, the play rattles on for good once a gust has shaken it; 3000 N m/rad went unstable at
#: the plant's 1 ms step under the bridge's commands (docs/how-to/mujoco-plant.md, the plant's parameters).
STIFFNESS, DAMPING, BACKLASH = 1000.0, 1.0, 1e-3
DRIVE = DriveModel(stepper_torque=CFG.motor_torque_limit, reducer_stiffness=STIFFNESS, reducer_damping=DAMPING,
                   backlash=BACKLASH)
PULL_OUT, TEETH = CFG.motor_torque_limit, DRIVE.stepper_teeth  # N m at the motor; teeth of the rotor
CYCLE = 2.0 * math.pi / TEETH  # rad at the motor: one electrical cycle, what a slip moves the rotor by
MICROSTEP = 2.0 * math.pi / TEETH / 4.0 / MICROSTEPS / RATIO  # rad at the rocker: the count's resolution
PLUGIN_THRESHOLD = 1e-5  # rad: JointStateTopicSystem's default trigger_joint_command_threshold
#: The closure at C and the rigid joints are soft in MuJoCo: theta within 1.4e-6 rad of the core for the rocker held,
#: the drive torque within 5.3e-6 relative (docs/how-to/mujoco-plant.md, the model); rounded up.
SOFT_THETA, SOFT_TORQUE = 2e-6, 1e-5
AT_REST = 1e-7  # rad/s at the rocker (the motor's over the ratio): every joint of the truth below it is at rest
#: The sweep: both exact ends of the range and three angles inside, visited in this order from the start (level).
SWEEP = (CFG.theta_min, -0.05, 0.03, CFG.theta_max, 0.0)
TIMEOUT = 60.0
#: s: the window of the rotor's mean speed; the longest move of the sweep (0.1222 -> 0) lasts about 1.5 s.
WINDOW = 0.5


def theta_of(truth: JointState) -> float:
    """The antenna's true angle (rad): the coupler joint's position less gamma's."""
    p = dict(zip(truth.name, truth.position, strict=True))
    return p[CFG.coupler_joint] - p[CFG.gamma_joint]


def stamp_ns(msg: JointState) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def at_rest(truth: JointState) -> bool:
    v = dict(zip(truth.name, truth.velocity, strict=True))
    return all(abs(v[j] / (RATIO if j == MOTOR else 1.0)) <= AT_REST for j in v)


def core_theta(q: float) -> float:
    """The antenna angle (rad) the core gives for the driven joint at q (rad)."""
    return float(CFG.linkage.from_rocker(q, CFG.driven, CFG.measured_branch).theta)


def core_torque(theta: float) -> float:
    """The driven rocker's torque (N m, + rocker angle) for the design load at theta (rad): the node's input_torque."""
    return float(CFG.linkage.input_torque(theta, CFG.load_torque, CFG.driven, CFG.branch))


def advantage(theta: float) -> float:
    """d q/d theta of the driven rocker at theta (rad/rad)."""
    return float(CFG.linkage.mechanical_advantage(theta, CFG.driven, CFG.branch))


@dataclass
class Stack:
    """The bringup: processes, the in-process node, and what the test side hears."""

    ros: RosSession
    processes: Processes
    node: FourBarNode
    commands: Any  # Publisher[Float64]: antenna_angle_cmd
    wind: Any  # Publisher[Float64]: the plant's wind_torque
    torque: Collector[Float64]  # the node's input_torque
    truth: Collector[JointState]  # the plant's plant/joint_states
    measured: Collector[JointState]  # the broadcaster's: the drive's count

    def command(self, theta: float) -> None:
        """Publish a command and wait until the node gave it a fate."""
        assert self.node.actuation is not None
        fates = self.node.actuation.fates
        before = sum(fates.counts.values())
        self.commands.publish(Float64(data=theta))
        self.ros.wait_for(lambda: sum(fates.counts.values()) > before, TIMEOUT, f'the command {theta!r} taken')

    def status(self) -> tuple[Level, str, dict[str, str]]:
        with self.ros.paused():  # not halfway through a callback
            s = self.node.diagnostic_status()
        return Level(s.level[0]), s.message, {kv.key: kv.value for kv in s.values}


@pytest.fixture(scope='module')
def stack(ros: RosSession, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Stack]:
    env = with_ros2_control(ros.env(PYTHON=sys.executable))
    if (why := topic_plugin_missing(env)) is not None:
        pytest.skip(why)
    tmp = tmp_path_factory.mktemp('real_physics')
    processes = Processes(tmp)
    publish_description(ros, NAMESPACE)
    initial_state = tmp / 'initial_state.yaml'
    initial_state.write_text(f'{MANAGER}:\n  ros__parameters:\n    hardware_components_initial_state:\n'
                             f'      inactive: [{CFG.hardware_id}]\n', encoding='utf-8')
    node: FourBarNode | None = None
    try:
        processes.start('controller_manager', [
            manager_executable(env, 'ros2_control_node'), '--ros-args', '-r', f'__ns:={NAMESPACE}',
            '--params-file', str(REPO / CONTROLLERS_FILE), '--params-file', str(initial_state)], env)
        processes.start('plant', [sys.executable, '-m', 'fourbar_ros.plant.run', '--ros-args',
                                  '-r', f'__ns:={NAMESPACE}', '-p', f'config_file:={YAML}',
                                  '-p', f'hardware_component:={CFG.hardware_id}',
                                  '-p', f'joint_commands_topic:={COMMANDS}', '-p', f'joint_states_topic:={STATES}',
                                  '-p', f'reducer_stiffness:={STIFFNESS!r}', '-p', f'reducer_damping:={DAMPING!r}',
                                  '-p', f'backlash:={BACKLASH!r}'], env)
        ros.wait_for(lambda: ACTIVATED_MARK in processes.log('plant'), TIMEOUT, 'the plant activating the hardware')
        spawner = processes.start('spawner', [sys.executable, manager_executable(env, 'spawner'),
                                              'joint_state_broadcaster', 'joint_trajectory_controller', '-c', MANAGER],
                                  env)
        ros.wait_for(lambda: spawner.poll() is not None, TIMEOUT, 'the spawner')
        assert spawner.returncode == 0, processes.log('spawner')
        node = FourBarNode(context=ros.context, namespace=NAMESPACE, parameter_overrides=[
            Parameter('mode', value='trajectory'), Parameter('antenna_sensor_type', value='imu'),
            Parameter('joint_state_rate', value=0.0), Parameter('resume_interrupted', value=False)],
            cli_args=['--ros-args', '--params-file', str(YAML),
                      '-r', f'{MEASURED_JOINT_STATES.name}:={BROADCASTER_JOINT_STATES.name}'])
        ros.add_node(node)
        torque = ros.collect(Float64, f'{NAMESPACE}/{INPUT_TORQUE.name}')
        stack = Stack(ros, processes, node, ros.publisher(Float64, f'{NAMESPACE}/{COMMAND.name}'),
                      ros.publisher(Float64, f'{NAMESPACE}/{WIND_TOPIC}', 10), torque,
                      ros.collect(JointState, f'{NAMESPACE}/{TRUTH_TOPIC}'),
                      ros.collect(JointState, f'{NAMESPACE}/{BROADCASTER_JOINT_STATES.name}'))
        ros.wait_subscribers(stack.commands)
        ros.wait_subscribers(stack.wind)
        ros.wait_publishers(torque)
        ros.wait_for(lambda: node._torque_pub.get_subscription_count() > 0, TIMEOUT, 'the node matching input_torque')
        stack.measured.wait_count(1, TIMEOUT)
        stack.truth.wait_match(at_rest, TIMEOUT)
        yield stack
    except AssertionError as exc:
        raise AssertionError(f'{exc}\n{processes.logs()}') from None
    finally:
        if node is not None:
            ros.remove_node(node)
        processes.close()


def slipped(truth: JointState, count: float) -> int:
    """Whole electrical cycles the rotor (the truth's motor joint) stands off the count (rad at the driven joint)."""
    motor = dict(zip(truth.name, truth.position, strict=True))[MOTOR]
    return round((motor - RATIO * (count - CFG.driven_joint_offset)) / CYCLE)


def window_speed(rotor: list[tuple[int, float]]) -> float:
    """The largest mean |speed| (rad/s) over WINDOW s of (stamp ns, angle rad) samples; 0 for a shorter record."""
    best, j = 0.0, 0
    for t, p in rotor:
        while j < len(rotor) and rotor[j][0] - t < WINDOW * 1e9:
            j += 1
        if j == len(rotor):
            break
        best = max(best, abs(rotor[j][1] - p) / ((rotor[j][0] - t) * 1e-9))
    return best


def driven(theta: float) -> float:
    """The driven joint's angle (rad) for theta (rad)."""
    return float(CFG.linkage.rocker_angles(theta, CFG.branch)[0 if CFG.driven_joint == CFG.gamma_joint else 1])


@dataclass(frozen=True)
class Visit:
    """One commanded angle of the sweep, at rest after its move."""

    theta: float  # rad, commanded
    published: float  # N m at the rocker: the node's input_torque for the command
    truth: JointState  # the plant's first message at rest after the command was reached
    count: float  # rad: the drive's count (the broadcaster's driven joint) then
    tracking: float  # rad: the largest |true theta - planned theta| during the move, by the truth's stamps
    planned_speed: float  # rad/s at the motor: the largest |planned velocity| x ratio, by the truth's stamps
    rotor_speed: float  # rad/s: the largest |velocity| of the truth's rotor during the move
    rotor_mean: float  # rad/s: the largest mean |speed| of the rotor over WINDOW s within the move
    rotor_torque: float  # N m at the motor: the largest |stepper torque| of the truth during the move

    @property
    def true_theta(self) -> float:
        return theta_of(self.truth)

    def effort(self, joint: str) -> float:
        return float(dict(zip(self.truth.name, self.truth.effort, strict=True))[joint])


def _set_slip_stop(stack: Stack, mismatch: float) -> None:
    with stack.ros.paused():
        result = stack.node.set_parameters([Parameter('slip_stop_mismatch', value=mismatch)])[0]
    assert result.successful, result.reason


@dataclass
class Sweep:
    """The sweep's visits, and what the slip stop made of its moves: the stops and the largest |window mean| (rad)."""

    visits: list[Visit]
    slip_stops: int = 0
    worst_mean: float = 0.0


@pytest.fixture(scope='module')
def sweep(stack: Stack) -> Sweep:
    """The sweep commanded through the node, the slip stop on as shipped: each angle reached, then the plant at
    rest."""
    actuation, check = stack.node.actuation, stack.node.model_check
    assert actuation is not None and check is not None
    _set_slip_stop(stack, CFG.slip_stop_mismatch)
    out, stops = Sweep([]), check.slip.stops
    update = check.slip.update

    def watched(cfg: Any, reading: Any) -> Any:  # the window's mean after each reading, for the figure
        event = update(cfg, reading)
        out.worst_mean = max(out.worst_mean, abs(check.slip.mean or 0.0))
        return event

    check.slip.update = watched  # type: ignore[method-assign]
    try:
        for theta in SWEEP:
            torques, truths = len(stack.torque), len(stack.truth)
            stack.command(theta)
            published = stack.torque.wait_count(torques + 1, TIMEOUT)[torques].data
            cmd = actuation.fates.current
            assert cmd is not None and cmd.theta == theta, (theta, cmd)
            stack.ros.wait_for(lambda c=cmd: c.fate.final, TIMEOUT, f'the command {theta!r} final')
            assert cmd.fate is Fate.REACHED, (theta, cmd, f'slip stops {check.slip.stops - stops}', check.slip.stopped)
            motion = actuation.motion
            start = len(stack.truth)
            rest = stack.truth.wait_match(at_rest, TIMEOUT, start=start)
            count = stack.measured.messages[-1].position[0]
            worst = planned = rotor_speed = rotor_torque = 0.0
            rotor: list[tuple[int, float]] = []  # (stamp ns, rad) of the truth's rotor during the move
            if motion is not None:
                end = motion.start_ns + round(motion.duration * 1e9)
                for m in stack.truth.messages[truths:start]:
                    stamp = stamp_ns(m)
                    if motion.start_ns <= stamp <= end:
                        state = motion.state_at(stamp)
                        worst = max(worst, abs(theta_of(m) - core_theta(state.position)))
                        planned = max(planned, abs(state.velocity) * RATIO)
                        i = m.name.index(MOTOR)
                        rotor.append((stamp, m.position[i]))
                        rotor_speed, rotor_torque = max(rotor_speed, abs(m.velocity[i])), max(rotor_torque,
                                                                                               abs(m.effort[i]))
            out.visits.append(Visit(theta, published, rest, count, worst, planned, rotor_speed, window_speed(rotor),
                                    rotor_torque))
    finally:
        del check.slip.update
        out.slip_stops = check.slip.stops - stops
    return out


def test_the_node_s_own_moves_do_not_trip_the_slip_stop(sweep: Sweep) -> None:
    # On the compliant reducer the accelerometer, read while the drive moves, sees the antenna's own acceleration
    # and its ringing besides the tilt: the window's mean stays within slip_stop_mismatch on every move of the sweep.
    print(f'\nslip stop over the sweep: {sweep.slip_stops} stops, the largest window mean {sweep.worst_mean:.4f} rad '
          f'(slip_stop_mismatch {CFG.slip_stop_mismatch} rad over {CFG.slip_stop_time} s)')
    assert sweep.slip_stops == 0 and sweep.worst_mean <= CFG.slip_stop_mismatch, sweep.worst_mean


def test_the_published_torque_is_the_plants_at_rest_over_the_range(sweep: Sweep) -> None:
    # The node publishes input_torque for the commanded angle (N m at the rocker); the plant's driven-joint effort is
    # what its reducer applies to the rocker. Its motor joint's effort, the stepper's torque (N m at the motor), is
    # printed beside it x ratio, not asserted: at rest by speed the rotor still rings on the compliant reducer, and
    # its inertia times that acceleration is no part of what the truth reports.
    # The plant rests at its true angle, a little off the command (the reducer's play and twist, the stepper's
    # deflection), where its torque is the core's at that angle within the model's softness; so the published torque
    # differs from the plant's by at most the core's torque change between the two angles, plus that softness.
    lines = []
    for v in sweep.visits:
        rocker, motor = v.effort(JOINT), v.effort(MOTOR)
        at_true = core_torque(v.true_theta)
        lines.append(f'theta {v.theta:+.6f} rad (true {v.true_theta:+.6f}): published {v.published:.6f} N m, '
                     f'plant {rocker:.6f} N m at the rocker ({rocker / v.published - 1:+.2e} rel), motor '
                     f'{motor:.6e} N m x {RATIO:g} = {motor * RATIO:.6f} ({motor * RATIO / v.published - 1:+.2e} rel); '
                     f'the core at the true angle {at_true:.6f} ({rocker / at_true - 1:+.2e} rel)')
        assert v.published == pytest.approx(core_torque(v.theta), rel=1e-12), lines[-1]  # the node's own core
        assert abs(rocker - at_true) <= SOFT_TORQUE * abs(at_true), lines[-1]
        bound = abs(core_torque(v.theta) - at_true) + SOFT_TORQUE * abs(at_true)
        assert abs(v.published - rocker) <= bound, f'{lines[-1]}; bound {bound!r} N m'
    print('\n' + '\n'.join(lines))


def test_the_true_angle_rests_within_the_backlash_of_the_command(sweep: Sweep) -> None:
    # The count rests within the plugin's threshold and half a microstep of the command. With the design load always
    # on one side of the play, the rotor rests behind its count by the stepper's deflection
    # asin(T / (ratio pull-out)) / teeth (T the torque it carries, N m at the rocker) and the rocker behind the rotor
    # by half the play and the reducer's twist T/k; through the linkage, theta by that over |d q/d theta|, plus the
    # closure's softness. The node's own moves never slip the stepper: the rotor rests in the count's detent.
    lines = []
    for v in sweep.visits:
        torque, cycles = abs(v.effort(JOINT)), slipped(v.truth, v.count)
        behind = BACKLASH / 2 + torque / STIFFNESS + math.asin(torque / (RATIO * PULL_OUT)) / (TEETH * RATIO)
        count_bound = PLUGIN_THRESHOLD + MICROSTEP / 2
        bound = (behind + count_bound) / abs(advantage(v.theta)) + SOFT_THETA
        error = v.true_theta - v.theta
        lines.append(f'theta {v.theta:+.6f} rad: true {v.true_theta:+.7f}, error {error:+.3e} rad (bound {bound:.3e}, '
                     f'predicted {-behind / advantage(v.theta):+.3e}); the count off the command by '
                     f'{v.count - driven(v.theta):+.2e} rad, the rotor {cycles} cycles off the count; tracking during '
                     f'the move {v.tracking:.3e} rad')
        assert abs(v.count - driven(v.theta)) <= count_bound, lines[-1]
        assert cycles == 0, lines[-1]
        assert abs(error) <= bound, lines[-1]
    print('\n' + '\n'.join(lines))


def test_the_sweep_stays_within_the_motor_s_limits(sweep: Sweep) -> None:
    # What reaches the motor: the node plans within motor_speed_limit, and the controller manager holds its commands
    # to the robot model's velocity limit (the same, at the joint) per update. The rotor, unslipped, stays within a
    # quarter electrical cycle of its field, so over WINDOW s its mean speed exceeds the limit by at most one update's
    # travel more and half a cycle of lag change: v (1 + T/W) + (pi / teeth) / W, T the manager's update period.
    # The rotor's own peak speed (it rings about its field on the compliant reducer) and the stepper's torque (its
    # field's pull plus its damping; the pull-out bounds the pull alone) are printed, not bounded: on the two moves
    # with the most load (to theta_max and back to level) the stepper works at about its pull-out.
    manager = yaml.safe_load((REPO / CONTROLLERS_FILE).read_text(encoding='utf-8'))['/**/controller_manager']
    period = 1.0 / manager['ros__parameters']['update_rate']  # s
    bound = CFG.motor_speed_limit * (1.0 + period / WINDOW) + (math.pi / TEETH) / WINDOW
    lines = []
    for v in sweep.visits:
        lines.append(f'theta {v.theta:+.6f} rad: planned {v.planned_speed:.4f} rad/s, rotor mean over {WINDOW} s '
                     f'{v.rotor_mean:.4f} rad/s (bound {bound:.4f}; motor_speed_limit {CFG.motor_speed_limit:.4f}), '
                     f'peak {v.rotor_speed:.4f}; stepper {v.rotor_torque:.3e} N m of pull-out {PULL_OUT:g} '
                     f'({v.rotor_torque / PULL_OUT:.1%}); tracking {v.tracking:.3e} rad of theta')
    print('\n' + '\n'.join(lines))
    for v, line in zip(sweep.visits, lines, strict=True):
        assert v.planned_speed <= CFG.motor_speed_limit * (1 + 1e-12), line
        assert 0.0 < v.rotor_mean <= bound, line


#: The gust: a steady wind of three design loads (N m on the antenna, + theta), against the motion or, reversed, with
#: it: well beyond what the stepper holds anywhere in the range (pull-out x ratio x d q/d theta: 4.1 to 6.8 N m).
GUST = -3.0 * CFG.load_torque
#: Electrical cycles the gust slips the rotor by before it ends: 0.025 to 0.041 rad of theta over the range, beyond
#: slip_stop_mismatch (0.02 rad: 73 to 121 cycles). The reversed gust ends within BACK cycles of the count: at most
#: 0.008 rad of theta, with the play, twist and deflection (< 5e-3 rad of theta) within slip_stop_mismatch.
SLIP, BACK = 150, 30


def test_a_gust_that_slips_the_stepper_stops_the_motion(stack: Stack) -> None:
    # A gust against a running motion slips the stepper: the node stops the motion (the command interrupted, ERROR);
    # with the antenna left 150 cycles off the count, a new command is dropped; once a reversed gust has blown it back
    # within 30 cycles and the sensor agrees for slip_stop_time, a new command goes out.
    node, ros = stack.node, stack.ros
    actuation, check = node.actuation, node.model_check
    assert actuation is not None and check is not None
    _set_slip_stop(stack, CFG.slip_stop_mismatch)
    assert all(abs(GUST) > PULL_OUT * RATIO * abs(advantage(t)) for t in (CFG.theta_min, CFG.theta_max))

    def cycles() -> int:
        """The rotor's slip now: the truth's latest motor angle against the latest count."""
        return slipped(stack.truth.messages[-1], stack.measured.messages[-1].position[0])

    def blow(torque: float, until: Callable[[], bool], what: str, *more: tuple[Callable[[], bool], str]) -> None:
        """A wind of ``torque`` N m until ``until`` (and then each of ``more``); then the design load again, the
        plant at rest, and the slip stop's window all of readings at rest (a stop may clear, or come, on the
        misreadings of a shaken antenna before)."""
        stack.wind.publish(Float64(data=torque))
        try:
            for predicate, name in ((until, what), *more):
                ros.wait_for(predicate, TIMEOUT, name)
        except AssertionError as exc:
            raise AssertionError(f'{exc}; the rotor {cycles() - before} cycles off the count; the node: '
                                 f'{stack.status()[1]}') from None
        finally:
            stack.wind.publish(Float64(data=-CFG.load_torque))
        rest = stack.truth.wait_match(at_rest, TIMEOUT, start=len(stack.truth))
        settled = stamp_ns(rest) + round(CFG.slip_stop_time * 1e9)
        ros.wait_for(lambda: (check.slip.last_ns or 0) >= settled, TIMEOUT, 'a window of readings at rest')

    start, stops = len(stack.truth), check.slip.stops
    before = cycles()
    stack.command(CFG.theta_max if stack.measured.messages[-1].position[0] < driven(0.05) else CFG.theta_min)
    target = actuation.fates.current
    assert target is not None
    up = target.theta == CFG.theta_max
    ros.wait_for(lambda: actuation.fates.current is target and target.fate is Fate.SENT, TIMEOUT, 'the command sent')
    stack.truth.wait_match(lambda m: not at_rest(m), TIMEOUT, start=start)
    gust = GUST if up else -GUST
    at_stop: list[int] = []

    def stopped() -> bool:
        if check.slip.stops > stops:
            at_stop.append(cycles() - before)  # the truth and the count as last heard (100 Hz each)
        return bool(at_stop)
    blow(gust, stopped, 'the slip stop', (lambda: abs(cycles() - before) >= SLIP, f'{SLIP} cycles slipped'))
    slip = cycles() - before
    level, message, values = stack.status()
    seen = (f'{values.get("slip_stops")} stops, the first with the rotor {at_stop[0]} cycles off the count; the '
            f'command {target}; after the gust the rotor {slip} cycles off the count, the '
            f'window\'s mean {check.slip.mean!r} rad: {message}')
    print(f'\n{seen}')
    assert target.fate is Fate.INTERRUPTED and 'the drive may have slipped' in target.reason, seen
    assert level is Level.ERROR and message.startswith('motion stopped: '), seen
    assert values['command_fate'] == 'interrupted', values
    # The rotor slipped the way the gust pushed (theta and the motor turn the same way here). The first stop may come
    # before it does: the accelerometer of an antenna shaken by the gust misreads its tilt by more than the threshold.
    assert CFG.reducer_ratio * advantage(0.0) > 0 and slip * gust > 0, seen

    dropped = actuation.fates.counts[Fate.DROPPED]
    stack.command(0.0)
    assert actuation.fates.counts[Fate.DROPPED] == dropped + 1 and actuation.fates.current is target, (
        actuation.fates.current, seen)

    blow(-gust, lambda: abs(cycles() - before) <= BACK, f'the rotor back within {BACK} cycles of the count')
    back = cycles() - before
    assert not check.slip.stopped, (back, check.slip.mean, check.slip.stopped)
    print(f'blown back to {back} cycles off the count: the mean {check.slip.mean!r} rad; {stack.status()[1]}')
    sent = actuation.fates.counts[Fate.SENT]
    stack.command(0.0)
    now = actuation.fates.current
    assert actuation.fates.counts[Fate.SENT] == sent + 1 and now is not None and now.theta == 0.0, (now, back)
