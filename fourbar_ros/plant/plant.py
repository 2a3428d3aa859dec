"""The generated model in MuJoCo: assemble it at a drive angle, command the motor, step, read (rad, N m, s).

theta as the package signs it; what a reading after ``step`` is of: docs/how-to/mujoco-plant.md.
"""

from __future__ import annotations

import math

import mujoco  # type: ignore[import-untyped]
import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.plant.mjcf import ANTENNA_BODY, ANTENNA_IMU, SERVO, DriveModel, mjcf, motor_joint

__all__ = ['Plant']


class Plant:
    """The linkage with its drive as a MuJoCo simulation at a fixed timestep (``drive.timestep``)."""

    def __init__(self, cfg: AntennaConfig, drive: DriveModel | None = None, xml: str | None = None) -> None:
        """Compile the model of ``cfg`` (or ``xml``, a model ``mjcf`` made and then edited: same names) and assemble
        it at rest at mid-range, the servo holding there."""
        self.cfg = cfg
        self.drive = drive or DriveModel()
        self.xml = mjcf(cfg, self.drive) if xml is None else xml
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        gamma_joint, delta_joint, coupler_joint = cfg.joint_names
        joint = self.model.joint
        self._qpos = {name: int(joint(name).qposadr[0])
                      for name in (gamma_joint, delta_joint, coupler_joint, motor_joint(cfg))}
        self._gamma, self._delta, self._coupler = (self._qpos[n] for n in cfg.joint_names)
        self._driven = self._qpos[cfg.driven_joint]
        self._motor = self._qpos[motor_joint(cfg)]
        self._motor_dof = int(joint(motor_joint(cfg)).dofadr[0])
        self._driven_dof = int(joint(cfg.driven_joint).dofadr[0])
        self._antenna = int(self.model.body(ANTENNA_BODY).id)
        self._servo = int(self.model.actuator(SERVO).id)
        self._sites = (int(self.model.site('c_coupler').id), int(self.model.site('c_rocker').id))
        imu = [i for i in range(self.model.nsensor) if self.model.sensor(i).name == ANTENNA_IMU]
        self._imu = int(self.model.sensor(imu[0]).adr[0]) if imu else None  # an edited model may lack it
        self._command = 0.0  # the motor angle commanded (rad)
        self._command_speed = 0.0  # its rate (rad/s), for the stepper's damping
        self.set_drive_angle(self.drive_angle_at(0.5 * (cfg.theta_min + cfg.theta_max)))

    # -- conversions ------------------------------------------------------------------------------------------------

    def drive_angle_at(self, theta: float) -> float:
        """The driven rocker's angle (rad) at antenna angle theta (rad), by the core's kinematics."""
        gamma, delta = (float(v) for v in self.cfg.linkage.rocker_angles(theta, self.cfg.branch))
        return gamma if self.cfg.driven is Driven.GAMMA else delta

    def motor_angle_for(self, rocker_angle: float) -> float:
        """The motor angle (rad) that puts the driven rocker at ``rocker_angle`` (rad) through a rigid reducer."""
        return self.cfg.reducer_ratio * (rocker_angle - self.cfg.driven_joint_offset)

    # -- state and commands -----------------------------------------------------------------------------------------

    def set_drive_angle(self, rocker_angle: float) -> None:
        """Assemble the linkage at rest with the driven rocker at ``rocker_angle`` (rad; the core's ``from_rocker``
        places the rest), the motor where the reducer puts it and the servo commanded there; time 0."""
        cfg = self.cfg
        inverse = cfg.linkage.from_rocker(rocker_angle, cfg.driven, cfg.measured_branch)
        theta, other = float(inverse.theta), float(inverse.other)
        gamma, delta = (rocker_angle, other) if cfg.driven is Driven.GAMMA else (other, rocker_angle)
        mujoco.mj_resetData(self.model, self.data)
        qpos = self.data.qpos
        qpos[self._gamma], qpos[self._delta], qpos[self._coupler] = gamma, delta, gamma + theta
        qpos[self._motor] = self.motor_angle_for(rocker_angle)
        self.command_motor(float(qpos[self._motor]))
        mujoco.mj_forward(self.model, self.data)

    def command_motor(self, motor_angle: float, speed: float = 0.0) -> None:
        """The position command (rad at the motor): the servo's, or the stepper's (its electrical angle over
        ``stepper_teeth``; a whole step is a quarter of an electrical cycle), whose field turns at ``speed`` rad/s
        at the motor (a step generator's rate: the stepper's damping acts on the rotor's speed relative to it)."""
        self._command = motor_angle
        self._command_speed = speed
        if self.drive.stepper_torque is None:
            self.data.ctrl[self._servo] = motor_angle

    def command_rocker(self, rocker_angle: float) -> None:
        """Command the motor to the angle that puts the driven rocker at ``rocker_angle`` (rad)."""
        self.command_motor(self.motor_angle_for(rocker_angle))

    def set_wind_torque(self, torque: float) -> None:
        """An external torque on the antenna (N m, in the sense of increasing theta): the wind. The package's
        ``load_torque`` L, what the drive must supply, is a wind of -L."""
        # Increasing theta turns the coupler about +y (the model's frame: x along A->D, z up).
        self.data.xfrc_applied[self._antenna, 3:] = (0.0, torque, 0.0)

    def step(self, n: int = 1) -> None:
        """Advance ``n`` timesteps (a stepper: one at a time, its torque set from the state each step began in)."""
        peak = self.drive.stepper_torque
        if peak is None:
            mujoco.mj_step(self.model, self.data, nstep=n)
            return
        teeth, damping = self.drive.stepper_teeth, self.drive.stepper_damping
        qpos, qvel, ctrl = self.data.qpos, self.data.qvel, self.data.ctrl
        for _ in range(n):
            error = float(qpos[self._motor]) - self._command
            slip = float(qvel[self._motor_dof]) - self._command_speed
            ctrl[self._servo] = -peak * math.sin(teeth * error) - damping * slip
            mujoco.mj_step(self.model, self.data)

    def forward(self) -> None:
        """Recompute the forces of the present state (after ``step``, to read them at the state it ended in)."""
        mujoco.mj_forward(self.model, self.data)

    # -- readings ---------------------------------------------------------------------------------------------------

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return float(self.data.time)

    @property
    def timestep(self) -> float:
        """The fixed step (s)."""
        return float(self.model.opt.timestep)

    @property
    def rocker_angle(self) -> float:
        """The driven rocker's angle (rad): the robot model's ``cfg.driven_joint`` position."""
        return float(self.data.qpos[self._driven])

    @property
    def rocker_velocity(self) -> float:
        """The driven rocker's angular velocity (rad/s)."""
        return float(self.data.qvel[self._driven_dof])

    @property
    def motor_angle(self) -> float:
        """The rotor's angle (rad at the motor)."""
        return float(self.data.qpos[self._motor])

    @property
    def motor_velocity(self) -> float:
        """The rotor's angular velocity (rad/s at the motor)."""
        return float(self.data.qvel[self._motor_dof])

    @property
    def theta(self) -> float:
        """The antenna angle (rad): the coupler joint's position less gamma."""
        return float(self.data.qpos[self._coupler] - self.data.qpos[self._gamma])

    @property
    def drive_torque(self) -> float:
        """The torque the reducer applies to the driven rocker (N m, in the sense of increasing rocker angle): the
        package's ``input_torque`` at rest.

        The motor joint has no spring, damper or other constraint of its own, so whatever acts on it besides the
        servo is the reducer (its equality, or its tendon's spring and damper); the reducer's Jacobian row is
        (1 at the motor, -ratio at the rocker) up to a factor, so the rocker gets -ratio times the motor's share.
        """
        motor = self._motor_dof
        data = self.data
        on_motor = data.qfrc_constraint[motor] + data.qfrc_spring[motor] + data.qfrc_damper[motor]
        return float(-self.cfg.reducer_ratio * on_motor)

    @property
    def motor_command(self) -> float:
        """The motor angle commanded (rad at the motor)."""
        return self._command

    @property
    def slipped_cycles(self) -> int:
        """A stepper's slip: whole electrical cycles (2 pi / ``stepper_teeth`` rad at the motor) between the rotor and
        its command, the nearest integer (0 while it holds within a half cycle; 0 for the servo)."""
        if self.drive.stepper_torque is None:
            return 0
        cycle = 2.0 * math.pi / self.drive.stepper_teeth
        return round((self.motor_angle - self._command) / cycle)

    @property
    def motor_torque(self) -> float:
        """The servo's torque on the rotor (N m at the motor)."""
        return float(self.data.actuator_force[self._servo])

    @property
    def antenna_acceleration(self) -> tuple[float, float, float]:
        """The antenna's accelerometer ``ANTENNA_IMU`` (m/s^2, in the coupler's axes: x along B -> C, y the joint
        axes, z up at theta = 0): the specific force, its acceleration less gravity, so at rest (-g sin theta, 0,
        g cos theta). Like the forces, of the state the last ``step`` began in; ``forward()`` recomputes it.
        KeyError for a model without the sensor."""
        if self._imu is None:
            raise KeyError(f'the model has no accelerometer {ANTENNA_IMU!r}')
        ax, ay, az = (float(v) for v in self.data.sensordata[self._imu:self._imu + 3])
        return ax, ay, az

    @property
    def closure_gap(self) -> float:
        """How far the closure at C is violated (m): the distance between C on the coupler and C on rocker CD."""
        xpos = self.data.site_xpos
        return float(np.linalg.norm(xpos[self._sites[0]] - xpos[self._sites[1]]))

    @property
    def max_speed(self) -> float:
        """The largest joint speed (rad/s; the motor's divided by |ratio|, so all are rocker-side)."""
        qvel = np.abs(np.array(self.data.qvel, dtype=np.float64))
        qvel[self._motor_dof] /= abs(self.cfg.reducer_ratio)
        return float(np.max(qvel))
