"""fourbar_node's interface as plain data: name, topics, message types, QoS, compared fields, bag storages (no ROS).

Types are written ``package/msg/Type`` (rosbag2's and rosbags' form); the topics: docs/reference/topics.md."""

from __future__ import annotations

import enum
from dataclasses import dataclass

#: The node's default name (launch file, parameter-file sections, ``fourbar urdf --node-name``).
NODE_NAME = 'fourbar_node'
#: The executables (setup.py's console scripts; ``ros2 run fourbar_ros <name>``): the node, the simulated actuator.
NODE_EXECUTABLE = 'fourbar_node'
SIM_EXECUTABLE = 'fourbar_sim_actuator'

FLOAT64 = 'std_msgs/msg/Float64'
JOINT_STATE = 'sensor_msgs/msg/JointState'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray'
JOINT_TRAJECTORY = 'trajectory_msgs/msg/JointTrajectory'
FLOAT64_MULTI_ARRAY = 'std_msgs/msg/Float64MultiArray'
IMU = 'sensor_msgs/msg/Imu'
BOOL = 'std_msgs/msg/Bool'
TRIGGER = 'std_srvs/srv/Trigger'

#: Keep-last depth of the command subscription and the per-command outputs: how far a burst may run ahead.
STREAM_DEPTH = 1000
#: Keep-last depth of markers and diagnostics (only the latest state matters).
STATUS_DEPTH = 10


class Reliability(enum.Enum):
    """QoS reliability, named as rclpy's ``ReliabilityPolicy`` members are."""

    RELIABLE = 'reliable'
    BEST_EFFORT = 'best_effort'


@dataclass(frozen=True)
class Topic:
    """One endpoint of the node: name, message type, keep-last depth, reliability, durability (transient local: a
    late subscriber gets the latest; else volatile)."""

    name: str
    msgtype: str
    depth: int
    reliability: Reliability = Reliability.RELIABLE
    transient_local: bool = False


#: Antenna angle commands in (rad). Reliable: a sample a publisher sends before the node's subscription has matched
#: it is resent once the match completes (a script that publishes one command as soon as it sees the subscription
#: loses nothing). The node takes the payload raw and decodes it itself, so a payload that is not a Float64 (an
#: empty one) is counted and skipped instead of stalling the reliable stream from its publisher.
COMMAND = Topic('antenna_angle_cmd', FLOAT64, STREAM_DEPTH)
#: Joint positions (rad), velocities (rad/s) and efforts (N m), per command and republished at joint_state_rate.
JOINT_STATES = Topic('joint_states', JOINT_STATE, STREAM_DEPTH)
#: The driven rocker's torque (N m), per command.
INPUT_TORQUE = Topic('input_torque', FLOAT64, STREAM_DEPTH)
#: Actuator modes: the measured driven joint in. Relative, so it can be remapped; the launch file remaps it to
#: BROADCASTER_JOINT_STATES (joint_state_broadcaster with ``use_local_topics: true``).
MEASURED_JOINT_STATES = Topic('measured_joint_states', JOINT_STATE, STREAM_DEPTH)
#: Where joint_state_broadcaster publishes the hardware's joints with ``use_local_topics: true`` (the shipped
#: controllers YAML sets it), and where the simulated actuator publishes its measured joint.
BROADCASTER_JOINT_STATES = Topic('joint_state_broadcaster/joint_states', JOINT_STATE, 10)
#: Actuator modes: the antenna angle theta completed from the measured driven joint (rad).
ANTENNA_ANGLE = Topic('antenna_angle', FLOAT64, STREAM_DEPTH)
#: Actuator modes: its rate d theta/dt by the chain rule (rad/s), when the measurement has a velocity.
ANTENNA_RATE = Topic('antenna_rate', FLOAT64, STREAM_DEPTH)
#: Actuator modes: the load torque on the antenna the measured effort holds (N m about theta, + in the sense of
#: increasing theta), when the measurement has an effort.
LOAD_TORQUE = Topic('load_torque', FLOAT64, STREAM_DEPTH)
#: Actuator modes, optional (``antenna_sensor_type``): an antenna angle sensor strapped to the antenna, read for the
#: live model check (node.model_check). Best effort: it matches a sensor publishing either way (sensor drivers
#: commonly publish best effort), and a reading lost is only one comparison fewer.
ANTENNA_SENSOR_FLOAT64 = Topic('antenna_angle_sensor', FLOAT64, 100, Reliability.BEST_EFFORT)
ANTENNA_SENSOR_IMU = Topic('antenna_angle_sensor', IMU, 100, Reliability.BEST_EFFORT)
#: ``antenna_sensor_type`` -> the sensor's topic (``none``: no subscription).
ANTENNA_SENSORS: dict[str, Topic] = {'float64': ANTENNA_SENSOR_FLOAT64, 'imu': ANTENNA_SENSOR_IMU}
SENSOR_NONE = 'none'
#: What the node publishes for each measurement (actuator modes), in publishing order.
PER_MEASUREMENT_OUTPUTS = (JOINT_STATES, ANTENNA_ANGLE, ANTENNA_RATE, LOAD_TORQUE)
#: The linkage drawing, every marker_period s when subscribed and changed.
MARKERS = Topic('linkage_markers', MARKER_ARRAY, STATUS_DEPTH)
#: The node's status, every diagnostics_period s.
DIAGNOSTICS = Topic('/diagnostics', DIAGNOSTIC_ARRAY, STATUS_DEPTH)

#: Antenna trajectories in (actuator modes): a JointTrajectory of the one joint ANTENNA_JOINT, positions theta rad,
#: optional velocities rad/s and accelerations rad/s^2. Reliable: a trajectory is one message, not a stream.
ANTENNA_TRAJECTORY = Topic('antenna_trajectory', JOINT_TRAJECTORY, STATUS_DEPTH)
#: Actuator modes: the halt from a button (the node's own name: ``~/halt``), true halts, false does nothing (only the
#: ``~/resume`` service resumes, so a bouncing button never does). Reliable, as ``ros2 topic pub`` and rclpy publish
#: by default (a best-effort publisher does not match it).
HALT_TOPIC = Topic('~/halt', BOOL, STATUS_DEPTH)


@dataclass(frozen=True)
class Service:
    """A service the node serves: name, service type, what a call does."""

    name: str
    srvtype: str
    content: str


#: Actuator modes: the operator's halt and its end (``rules.halt``).
HALT_SERVICE = Service('~/halt', TRIGGER, 'halt: the command in force ends (held: dropped; sent: interrupted, not '
                       'resumed), a running motion brakes to rest within the motor\'s limits (at rest nothing is '
                       'sent), and every new command and antenna trajectory is dropped until `~/resume`; answers '
                       'success, also when already halted (the message says which)')
RESUME_SERVICE = Service('~/resume', TRIGGER, 'clear the halt: nothing moves, the next command does; success false '
                         'when not halted')


def services(mode: Mode) -> tuple[Service, ...]:
    """The services fourbar_node serves in ``mode`` besides rclpy's own (parameters, type description)."""
    return () if mode is Mode.OPEN_LOOP else (HALT_SERVICE, RESUME_SERVICE)


@dataclass(frozen=True)
class Kind:
    """A kind of input topic: what errors call it (``label`` when none is found, ``role`` when one has another
    type) and its topics (name, type), by preference."""

    label: str
    topics: tuple[Topic, ...]
    role: str

    @property
    def ends(self) -> tuple[str, ...]:
        """The endings of its topics' names ('/name'), by preference: the root's topics, and any namespace's."""
        return tuple(f'/{t.name}' for t in self.topics)

    def named(self, topic: str) -> bool:
        """Whether ``topic`` goes by one of the kind's names (at the root or in a namespace)."""
        return topic.endswith(self.ends)


#: The kinds of input a bag's offline processing looks for, by preference.
COMMANDS = Kind('command', (COMMAND,), 'command')
MEASURED = Kind(f'measured {JOINT_STATE}', (MEASURED_JOINT_STATES, BROADCASTER_JOINT_STATES), 'measured')
TRAJECTORIES = Kind(JOINT_TRAJECTORY, (ANTENNA_TRAJECTORY,), 'antenna trajectory')

#: The joint name an antenna trajectory carries: the antenna angle theta.
ANTENNA_JOINT = 'antenna_joint'
#: Keep-last depth of the controllers' command topics (as the sim actuator subscribes).
CONTROLLER_DEPTH = 10


def trajectory_topic(controller: str) -> Topic:
    """Driven-joint trajectories out (trajectory mode): ``<controller>/joint_trajectory``, as
    joint_trajectory_controller reads them."""
    return Topic(f'{controller}/joint_trajectory', JOINT_TRAJECTORY, CONTROLLER_DEPTH)


def trajectory_action(controller: str) -> str:
    """The FollowJointTrajectory action of joint_trajectory_controller: ``<controller>/follow_joint_trajectory``
    (trajectory mode, ``trajectory_interface: action``)."""
    return f'{controller}/follow_joint_trajectory'


#: Where the default of the ``controller_manager`` parameter points (config.params).
DEFAULT_CONTROLLER_MANAGER = 'controller_manager'
ACTIVITY_TYPE = 'controller_manager_msgs/msg/ControllerManagerActivity'
#: Keep-last depth of the node's subscription to the manager's activity (the manager publishes with depth 1): with
#: depth 1 a controller switched off and on again between two callbacks reached the node as one "active" (the off
#: dropped), and the node took the controller's hold for its running trajectory.
ACTIVITY_DEPTH = 20


#: Every node's log (rcl_interfaces/msg/Log), where the controller manager says why it deactivated a controller.
#: Volatile: rcl publishes it transient local, and a late joiner needs no old lines.
ROSOUT = Topic('/rosout', 'rcl_interfaces/msg/Log', 100)


def activity_topic(manager: str) -> Topic:
    """The controller manager's lifecycle states of its controllers and hardware (``<manager>/activity``, reliable,
    transient local), as the actuator modes read them."""
    return Topic(f'{manager}/activity', ACTIVITY_TYPE, ACTIVITY_DEPTH, transient_local=True)


def forward_topic(controller: str) -> Topic:
    """Driven-joint setpoints out (forward mode): ``<controller>/commands`` (one position, rad), as
    forward_command_controller reads them."""
    return Topic(f'{controller}/commands', FLOAT64_MULTI_ARRAY, CONTROLLER_DEPTH)


class Mode(enum.Enum):
    """fourbar_node's ``mode``: where a served command goes."""

    OPEN_LOOP = 'open_loop'  #: the commanded pose on joint_states (no hardware)
    TRAJECTORY = 'trajectory'  #: driven-joint trajectories for joint_trajectory_controller
    FORWARD = 'forward'  #: a driven-joint setpoint stream for forward_command_controller


class Direction(enum.Enum):
    """Which way a message goes, seen from the node."""

    IN = 'in'
    OUT = 'out'


@dataclass(frozen=True)
class Endpoint:
    """One topic of the node in one mode: the topic, its direction, and what it carries and when; ``optional``: the
    parameter value that creates it (empty: always there)."""

    topic: Topic
    direction: Direction
    content: str
    optional: str = ''


#: Where the defaults of the ``trajectory_controller`` and ``forward_controller`` parameters send (config.params).
DEFAULT_TRAJECTORY_CONTROLLER = 'joint_trajectory_controller'
DEFAULT_FORWARD_CONTROLLER = 'forward_position_controller'

_COMMAND_IN = Endpoint(COMMAND, Direction.IN, 'commanded antenna angle theta, rad (+ tilts the antenna down); taken '
                       'raw: a payload that is not a Float64 is counted (`commands_malformed`) and skipped')
_TORQUE_OUT = Endpoint(INPUT_TORQUE, Direction.OUT, 'the torque the driven rocker needs for the commanded angle, '
                       'N m, + in the sense of increasing rocker angle; once per served command, never republished')
_STATUS_OUT = (
    Endpoint(DIAGNOSTICS, Direction.OUT, 'one status `<node>: antenna tilt linkage` (`<node>` the node\'s full name, '
             'no leading slash) every `diagnostics_period` s, keys in the diagnostics reference'),
    Endpoint(MARKERS, Direction.OUT, 'frame AD, rockers, coupler BC, joints and antenna arrow in `frame_id` (ns '
             '`fourbar`, ids 0-4), at most every `marker_period` s, when subscribed and changed'),
)
_MEASURED = (
    Endpoint(ANTENNA_TRAJECTORY, Direction.IN, f'antenna trajectories: joint `{ANTENNA_JOINT}`, positions theta '
             'rad, optional velocities rad/s and accelerations rad/s^2'),
    Endpoint(MEASURED_JOINT_STATES, Direction.IN, 'the measured driven joint (position rad, velocity rad/s, '
             f'effort N m); the launch file remaps it to `{BROADCASTER_JOINT_STATES.name}`'),
    Endpoint(HALT_TOPIC, Direction.IN, 'the halt from a button: `true` halts as the `~/halt` service does, '
             '`false` does nothing (only the `~/resume` service resumes)'),
    Endpoint(JOINT_STATES, Direction.OUT, 'per measurement, every joint at its stamp: [driven, other rocker, '
             'coupler] positions rad (the measured one, then completed exactly), velocities rad/s (chain rule; '
             'empty without a measured velocity), efforts [measured, 0, 0] N m'),
    Endpoint(ANTENNA_ANGLE, Direction.OUT, 'per measurement: the measured antenna angle theta, rad'),
    Endpoint(ANTENNA_RATE, Direction.OUT, 'per measurement with a velocity: d theta/dt, rad/s'),
    Endpoint(LOAD_TORQUE, Direction.OUT, 'per measurement with an effort: the load the measured effort holds, N m '
             'about theta, + in the sense of increasing theta'),
)


_SENSOR_CONTENT = {
    'float64': 'the antenna angle from a sensor on the antenna (an inclinometer), rad in theta\'s sense, '
               'timed by its arrival; compared with the angle completed from the measured joint (`model_mismatch_*` '
               'in diagnostics)',
    'imu': 'an IMU on the antenna, axes as the coupler frame; the tilt from gravity, atan2(-a_x, hypot(a_y, a_z)) of '
           '`linear_acceleration` (as `fourbar calibrate`), timed by its header stamp; compared as the Float64 form',
}


def sensor_endpoint(antenna_sensor_type: str) -> Endpoint | None:
    """The antenna angle sensor's endpoint for the ``antenna_sensor_type`` parameter's value (None for ``none``)."""
    topic = ANTENNA_SENSORS.get(antenna_sensor_type)
    if topic is None:
        return None
    return Endpoint(topic, Direction.IN, _SENSOR_CONTENT[antenna_sensor_type],
                    optional=f'antenna_sensor_type: {antenna_sensor_type}')


def activity_endpoint(manager: str) -> Endpoint:
    """The actuator modes' watch of the controller they feed (``manager``: the ``controller_manager`` parameter)."""
    return Endpoint(activity_topic(manager), Direction.IN, 'the controller manager\'s lifecycle states of its '
                    'controllers and hardware components: whether the controller the node feeds is active',
                    optional='controller_manager_msgs installed and `controller_manager` not empty')


def manager_log_endpoint() -> Endpoint:
    """The actuator modes' read of the controller manager's error lines (rules.manager_errors)."""
    return Endpoint(ROSOUT, Direction.IN, 'the log: the controller manager\'s ERROR lines naming the controller the '
                    'node feeds, the reason it gives when the manager deactivated it (`controller_deactivated`)',
                    optional='controller_manager_msgs installed and `controller_manager` not empty')


def endpoints(mode: Mode, trajectory_controller: str = DEFAULT_TRAJECTORY_CONTROLLER,
              forward_controller: str = DEFAULT_FORWARD_CONTROLLER,
              antenna_sensor_type: str = SENSOR_NONE, controller_manager: str = '') -> tuple[Endpoint, ...]:
    """Every topic fourbar_node reads or writes in ``mode`` (the controller names, the antenna sensor's type and
    the controller manager it watches as its parameters give them; the sensor and the manager only in the actuator
    modes; an empty ``controller_manager``: no watch, as where controller_manager_msgs is missing)."""
    if mode is Mode.OPEN_LOOP:
        pose = Endpoint(JOINT_STATES, Direction.OUT, 'per served command, the commanded pose: joints [`gamma_joint`, '
                        '`delta_joint`, `coupler_joint`], positions [gamma, delta, gamma + theta] rad, velocities '
                        'rad/s by finite difference (empty when not meaningful), efforts [driven rocker torque N m '
                        'in its column, 0.0 elsewhere]; the last pose again every 1/`joint_state_rate` s, freshly '
                        'stamped, velocities 0.0')
        return (_COMMAND_IN, pose, _TORQUE_OUT, *_STATUS_OUT)
    if mode is Mode.TRAJECTORY:
        out = Endpoint(trajectory_topic(trajectory_controller), Direction.OUT, 'driven-joint trajectories for '
                       'joint_trajectory_controller: positions rad, velocities rad/s, accelerations rad/s^2 (effort '
                       'N m only with `effort_feedforward`); checked against the controller\'s own checks first')
    else:
        out = Endpoint(forward_topic(forward_controller), Direction.OUT, 'driven-joint setpoints for '
                       'forward_command_controller: one position rad per message, at `control_rate` while moving')
    sensor = sensor_endpoint(antenna_sensor_type)
    watch = (activity_endpoint(controller_manager), manager_log_endpoint()) if controller_manager else ()
    return (_COMMAND_IN, *_MEASURED, *((sensor,) if sensor is not None else ()), *watch, out, _TORQUE_OUT,
            *_STATUS_OUT)


def every_endpoint(mode: Mode, trajectory_controller: str = DEFAULT_TRAJECTORY_CONTROLLER,
                   forward_controller: str = DEFAULT_FORWARD_CONTROLLER) -> tuple[Endpoint, ...]:
    """``endpoints`` with every optional one (each form of the antenna sensor, the default controller manager's
    activity): the reference tables and the security policy, which must allow what a parameter may turn on."""
    out = list(endpoints(mode, trajectory_controller, forward_controller,
                         controller_manager=DEFAULT_CONTROLLER_MANAGER))
    if mode is not Mode.OPEN_LOOP:
        at = 1 + len(_MEASURED)  # where endpoints() puts the sensor: after the command and the measured ones
        out[at:at] = [e for e in map(sensor_endpoint, ANTENNA_SENSORS) if e is not None]
    return tuple(out)


#: The endpoints whose QoS parameters may override, in every mode: (topic, direction). The node creates them with
#: rclpy's ``QoSOverridingOptions.with_default_policies()``, so rclpy declares a read-only parameter
#: ``qos_overrides.<resolved topic>.<publisher|subscription>.<policy>`` for each policy of QOS_OVERRIDE_POLICIES.
QOS_OVERRIDABLE: tuple[tuple[Topic, Direction], ...] = (
    (COMMAND, Direction.IN), (JOINT_STATES, Direction.OUT), (INPUT_TORQUE, Direction.OUT), (MARKERS, Direction.OUT))
#: The policies ``with_default_policies`` declares (durability and the others stay as the node sets them).
QOS_OVERRIDE_POLICIES = ('history', 'depth', 'reliability')


def qos_override_parameters(namespace: str = '/') -> tuple[str, ...]:
    """rclpy's QoS override parameter names for the node in ``namespace`` (topics not remapped), in the order of
    QOS_OVERRIDABLE and QOS_OVERRIDE_POLICIES."""
    names = []
    for topic, direction in QOS_OVERRIDABLE:
        resolved = topic.name if topic.name.startswith('/') else f'{namespace.rstrip("/")}/{topic.name}'
        entity = 'subscription' if direction is Direction.IN else 'publisher'
        names += [f'qos_overrides.{resolved}.{entity}.{policy}' for policy in QOS_OVERRIDE_POLICIES]
    return tuple(names)


#: What the node publishes for each served command, in publishing order.
PER_COMMAND_OUTPUTS = (JOINT_STATES, INPUT_TORQUE)
#: The outputs a recording of the node holds by default (``fourbar record``, ``fourbar demo``).
RECORDED_OUTPUTS = (JOINT_STATES, INPUT_TORQUE, DIAGNOSTICS)

#: The fields ``fourbar compare`` compares (and ``--ignore`` may drop), with what each covers (bags.compare).
COMPARED: dict[str, str] = {
    'stamps': 'JointState and JointTrajectory header stamps, and every message\'s log time',
    'positions': 'JointState positions and trajectory point positions',
    'velocities': 'JointState velocities (and whether one is present), trajectory point velocities and '
                  'accelerations',
    'efforts': 'JointState efforts and trajectory point efforts',
    **{t.name: f'the data of each Float64 topic named `{t.name}`' for t in (INPUT_TORQUE, ANTENNA_ANGLE, ANTENNA_RATE,
                                                                           LOAD_TORQUE)},
}
COMPARED_FIELDS = tuple(COMPARED)
#: ``fourbar compare``'s default tolerance: units in the last place of each value's scale (docs/how-to/bags.md).
DEFAULT_ULPS = 16.0


class Storage(enum.Enum):
    """rosbag2 storage plugins the bag tools read and write; the value is the plugin's identifier as
    metadata.yaml and ``--storage`` spell it."""

    MCAP = 'mcap'
    SQLITE3 = 'sqlite3'

    def __str__(self) -> str:
        return self.value


DEFAULT_STORAGE = Storage.MCAP


def sibling_topic(command_topic: str, name: str) -> str:
    """The topic ``name`` in the namespace of ``command_topic`` (``/ns/antenna_angle_cmd`` -> ``/ns/NAME``,
    ``antenna_angle_cmd`` -> ``NAME``): where the node's relative names put its outputs."""
    head = command_topic.rsplit('/', 1)[0] if '/' in command_topic else ''
    return f'{head}/{name}' if head or command_topic.startswith('/') else name
