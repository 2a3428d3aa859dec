"""fourbar_mujoco_drive: the drive bridge on the MuJoCo plant (``PlantBackend``), its wind, IMU and truth.

Parameters, topics and what the plant reports: docs/how-to/mujoco-plant.md#the-plant-as-a-drive.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64

from fourbar_ros.config.antenna_config import AntennaConfig, default_config, load_config
from fourbar_ros.core.errors import one_line
from fourbar_ros.drive.backend import Reading
from fourbar_ros.drive.bridge_node import BackendError, DriveBridge
from fourbar_ros.interface.topics import ANTENNA_SENSOR_IMU
from fourbar_ros.node.qos import qos

if TYPE_CHECKING:  # mujoco is imported where the plant is built: a missing one is one line, exit 2
    from fourbar_ros.plant.backend import PlantBackend

__all__ = ['ANTENNA_LINK', 'PLANT_PARAMETERS', 'TRUTH_TOPIC', 'WIND_TOPIC', 'MujocoDrive']

#: The robot model's link the IMU is fixed to (``fourbar_ros.config.robot_model.LINKS``): the Imu's frame_id.
ANTENNA_LINK = 'antenna'
#: Relative topics: the wind in (std_msgs/Float64, N m on the antenna, + theta), the truth out (JointState).
WIND_TOPIC, TRUTH_TOPIC = 'wind_torque', 'plant/joint_states'
#: The plant's own parameters (name, default, description); all but wind_torque read at startup only.
PLANT_PARAMETERS: tuple[tuple[str, float | int, str], ...] = (
    ('stepper_torque', math.nan, "the stepper's pull-out torque, N m at the motor (NaN: the configuration's "
                                 'motor_torque_limit; 0: a position servo instead)'),
    ('microsteps', 16, "the stepper driver's microsteps per full step"),
    ('encoder_counts', 0, 'an encoder on the driven rocker, counts per revolution (0: none, the drive reports '
                          'its step count, open loop)'),
    ('reducer_stiffness', 0.0, 'N m/rad at the rocker (0: a rigid reducer)'),
    ('reducer_damping', 0.0, 'N m s/rad at the rocker, of a compliant reducer'),
    ('backlash', 0.0, 'rad at the rocker, total play (needs reducer_stiffness; undamped, the play can rattle on '
                      'for good once shaken: give reducer_damping)'),
    ('wind_torque', math.nan, 'steady wind on the antenna, N m, + theta (NaN: -load_torque, the design load); '
                              'settable at run time, also by the wind_torque topic'),
)
_RELIABLE: Callable[..., Any] = QoSProfile  # rclpy's constructors are unannotated
_PARAMETER: Callable[..., Parameter] = Parameter


class _Deferred:
    """Stands in as the bridge's backend until the node's parameters exist: ``enable`` builds the plant."""

    def __init__(self, build: Callable[[], PlantBackend]) -> None:
        self._build = build

    def enable(self) -> None:
        self._build().enable()

    def read(self) -> Reading:
        raise RuntimeError('the plant is not built')

    def write(self, position: float) -> None:
        raise RuntimeError('the plant is not built')

    def disable(self) -> None:
        """Nothing was built."""


class MujocoDrive(DriveBridge):
    """The bridge over a ``PlantBackend`` (``backend`` given: tests; else built from the parameters, stepped on
    ``clock``), publishing the antenna's Imu and the plant's truth at ``state_rate``."""

    def __init__(self, backend: PlantBackend | None = None, clock: Callable[[], float] = time.monotonic,
                 **kwargs: Any) -> None:
        self._plant_clock = clock
        self._built: PlantBackend | None = backend
        self.wind_refused = 0  #: wind_torque messages refused (not finite)
        super().__init__(backend=backend if backend is not None else _Deferred(self._build), clock=clock, **kwargs)
        if backend is not None:
            self._declare_plant_parameters()
        plant_backend = self._built
        assert plant_backend is not None  # built by enable() in the bridge's constructor
        self.plant_backend: PlantBackend = plant_backend
        self.backend = plant_backend
        self.backend_name = type(plant_backend).__name__
        guard = self.problems.guard
        self.add_on_set_parameters_callback(guard.wrap('set_parameters', self._on_set_parameters))
        self.add_post_set_parameters_callback(guard.wrap('after_set_parameters', self._after_set_parameters))
        cfg = plant_backend.cfg
        self._joints = [*cfg.joint_names, f'{cfg.driven_joint}_motor']
        self.imu = self.create_publisher(Imu, ANTENNA_SENSOR_IMU.name, qos(ANTENNA_SENSOR_IMU))
        self.truth = self.create_publisher(JointState, TRUTH_TOPIC, 10)
        self.create_subscription(Float64, WIND_TOPIC, guard.wrap('wind', self._on_wind),
                                 _RELIABLE(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        rate = float(self.get_parameter('state_rate').value)
        self.create_timer(1.0 / rate, guard.wrap('plant', self._on_plant),
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    # -- building ---------------------------------------------------------------------------------------------------

    def _declare_plant_parameters(self) -> dict[str, Any]:
        values = {}
        for name, default, description in PLANT_PARAMETERS:
            descriptor = ParameterDescriptor(description=description, read_only=name != 'wind_torque')
            values[name] = self.declare_parameter(name, default, descriptor).value
        return values

    def _build(self) -> PlantBackend:
        p = self._declare_plant_parameters()
        config_file = str(self.get_parameter('config_file').value)
        cfg: AntennaConfig = load_config(config_file) if config_file else default_config()
        start = float(self.get_parameter('simulated_position').value)
        try:
            from fourbar_ros.plant.backend import PlantBackend, stepper_drive
            from fourbar_ros.plant.mjcf import DriveModel
        except ImportError as exc:
            raise BackendError(f'the MuJoCo plant needs the mujoco package: {one_line(exc)}') from None
        try:
            pull_out, stiffness = float(p['stepper_torque']), float(p['reducer_stiffness'])
            stepper = stepper_drive(cfg, None if math.isnan(pull_out) else pull_out).stepper_torque
            drive = DriveModel(stepper_torque=None if pull_out == 0.0 else stepper,
                               reducer_stiffness=stiffness if stiffness > 0.0 else None,
                               reducer_damping=float(p['reducer_damping']), backlash=float(p['backlash']))
            counts, wind = int(p['encoder_counts']), float(p['wind_torque'])
            self._built = PlantBackend(cfg, drive, None if math.isnan(start) else start, self._plant_clock,
                                       counts if counts > 0 else None, int(p['microsteps']),
                                       None if math.isnan(wind) else wind)
        except ValueError as exc:
            raise BackendError(f'plant: {one_line(exc)}') from None
        return self._built

    # -- the wind ---------------------------------------------------------------------------------------------------

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for param in params:
            if param.name == 'wind_torque' and not isinstance(param.value, float):
                return SetParametersResult(successful=False, reason='wind_torque: a double (N m, NaN: the design load)')
            if param.name == 'wind_torque' and math.isinf(param.value):
                return SetParametersResult(successful=False, reason=f'wind_torque: {param.value} is not finite')
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, params: list[Parameter]) -> None:
        for param in params:
            if param.name == 'wind_torque':
                wind = float(param.value)
                self.plant_backend.set_wind_torque(-self.plant_backend.cfg.load_torque if math.isnan(wind) else wind)

    def _on_wind(self, msg: Float64) -> None:
        result = self.set_parameters([_PARAMETER('wind_torque', value=float(msg.data))])[0]
        if not result.successful:
            self.wind_refused += 1
            self.problems.warn('wind', f'wind refused ({self.wind_refused} so far): {result.reason}')

    # -- outputs ----------------------------------------------------------------------------------------------------

    def _on_plant(self) -> None:
        """The Imu (specific force m/s^2 in the antenna's axes) and the truth, of one state, one stamp."""
        backend = self.plant_backend
        ax, ay, az = backend.antenna_acceleration()
        stamp = self.get_clock().now().to_msg()
        imu = Imu()
        imu.header.stamp = stamp
        imu.header.frame_id = ANTENNA_LINK
        imu.orientation_covariance[0] = -1.0  # no orientation (REP-145)
        imu.angular_velocity_covariance[0] = -1.0  # no gyro
        imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z = ax, ay, az
        self.imu.publish(imu)
        plant, cfg = backend.plant, backend.cfg
        qpos, qvel = plant.data.qpos, plant.data.qvel
        model = plant.model
        truth = JointState()
        truth.header.stamp = stamp
        truth.name = list(self._joints)
        truth.position = [float(qpos[model.joint(j).qposadr[0]]) for j in self._joints]
        truth.velocity = [float(qvel[model.joint(j).dofadr[0]]) for j in self._joints]
        efforts = {cfg.driven_joint: plant.drive_torque, self._joints[-1]: plant.motor_torque}
        truth.effort = [float(efforts.get(j, 0.0)) for j in self._joints]
        self.truth.publish(truth)

    def diagnostic_status(self) -> DiagnosticStatus:
        """The bridge's status with the plant's truth: simulated time s, true rocker angle and theta rad, drive
        torque N m, slipped cycles, wind N m, lost time s, winds refused."""
        status = super().diagnostic_status()
        b = self.plant_backend
        truth = {'plant_time': b.simulated_time, 'true_rocker_angle': b.true_rocker_angle, 'theta': b.theta,
                 'drive_torque': b.drive_torque, 'slipped_cycles': b.slipped_cycles, 'wind_torque': b.wind_torque,
                 'lost_time': b.lost_time, 'wind_refused': self.wind_refused}
        status.values = [*status.values, *(KeyValue(key=k, value=repr(v)) for k, v in truth.items())]
        return status
