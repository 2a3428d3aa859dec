"""The linkage on the pole as MuJoCo MJCF, generated from an ``AntennaConfig``: a pure function, no MuJoCo import.

Frame, joints, antenna, drive and reducer (why a rotor hinge, not an actuator's gear): docs/how-to/mujoco-plant.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven

__all__ = ['ANTENNA_BODY', 'ANTENNA_IMU', 'CLOSURE', 'REDUCER', 'SERVO', 'DriveModel', 'mjcf', 'motor_joint']

#: Names in the model besides the robot model's joint names.
SERVO, REDUCER, CLOSURE, ANTENNA_BODY = 'motor_servo', 'reducer', 'closure_c', 'coupler'
#: The antenna's accelerometer: a site on the coupler where the robot model puts its ``antenna`` link (axes the
#: coupler's: x along B -> C, y the joint axes, z up at theta = 0) and an ``<accelerometer>`` sensor of that name.
ANTENNA_IMU = 'antenna_imu'


@dataclass(frozen=True)
class DriveModel:
    """What the configuration does not say: the drive's and the simulation's own parameters.

    timestep: s (implicitfast integrator). rotor_inertia: kg m^2 at the motor (1e-5: a NEMA 17 class stepper's
    rotor plus coupling). kp: N m/rad and kv: N m s/rad at the motor; the defaults put the servo at
    sqrt(kp / rotor_inertia) = 316 rad/s (50 Hz), critically damped for the rotor alone (kv = 2 sqrt(kp J)).
    torque_limit: N m at the motor, or None for an unlimited servo (the configuration's ``motor_torque_limit`` is a
    choice of the caller). reducer_stiffness: N m/rad at the rocker, None for a rigid reducer; reducer_damping:
    N m s/rad at the rocker; backlash: rad at the rocker, total play (compliant reducer only). link_mass: kg and
    link_inertia: kg m^2 of each rocker (and of the coupler without an antenna), weightless. antenna_inertia:
    kg m^2 about the antenna's centre of mass, None for a rod the coupler's length (m h^2 / 12). joint_damping:
    N m s/rad on the linkage's hinges. closure_timeconst: s, the ``solref`` time constant of the closure at C and
    of the rigid reducer (MuJoCo keeps it at least 2 timesteps). stepper_torque: N m at the motor, a stepper's
    pull-out (peak holding) torque instead of the servo (None: the servo); its torque is
    -stepper_torque sin(stepper_teeth (motor - command)) - stepper_damping (motor speed - the command's speed), so
    it pulls out beyond stepper_torque and slips by whole electrical cycles, 2 pi / stepper_teeth (rad at the motor;
    50 teeth: 1.8 deg full steps, 4 per cycle). stepper_damping: N m s/rad at the motor (4e-3: about critical with
    the defaults), on the rotor's speed relative to its field's (``Plant.command_motor``'s speed).
    """

    timestep: float = 1e-3
    rotor_inertia: float = 1e-5
    kp: float = 1.0
    kv: float = 2.0 * math.sqrt(1.0 * 1e-5)
    torque_limit: float | None = None
    reducer_stiffness: float | None = None
    reducer_damping: float = 0.0
    backlash: float = 0.0
    link_mass: float = 0.1
    link_inertia: float = 1e-3
    antenna_inertia: float | None = None
    joint_damping: float = 1e-2
    closure_timeconst: float = 2e-3
    stepper_torque: float | None = None
    stepper_teeth: int = 50
    stepper_damping: float = 4e-3

    def __post_init__(self) -> None:
        positive = {'timestep': self.timestep, 'rotor_inertia': self.rotor_inertia, 'kp': self.kp,
                    'link_mass': self.link_mass, 'link_inertia': self.link_inertia,
                    'closure_timeconst': self.closure_timeconst}
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name}: must be a positive finite number, got {value!r}')
        for name, maybe in (('torque_limit', self.torque_limit), ('reducer_stiffness', self.reducer_stiffness),
                            ('antenna_inertia', self.antenna_inertia), ('stepper_torque', self.stepper_torque)):
            if maybe is not None and not (math.isfinite(maybe) and maybe > 0.0):
                raise ValueError(f'{name}: must be None or a positive finite number, got {maybe!r}')
        for name, value in (('kv', self.kv), ('reducer_damping', self.reducer_damping), ('backlash', self.backlash),
                            ('joint_damping', self.joint_damping), ('stepper_damping', self.stepper_damping)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f'{name}: must be a finite number >= 0, got {value!r}')
        if self.stepper_teeth < 1:
            raise ValueError(f'stepper_teeth: must be at least 1, got {self.stepper_teeth!r}')
        if self.backlash > 0.0 and self.reducer_stiffness is None:
            raise ValueError('backlash: needs a compliant reducer (reducer_stiffness)')


def motor_joint(cfg: AntennaConfig) -> str:
    """The motor's joint name: the driven joint's, as the URDF names its actuator (``<joint>_motor``)."""
    return f'{cfg.driven_joint}_motor'


def _n(value: float) -> str:
    """Shortest text that reads back as the same double."""
    return repr(float(value))


def _xz(x: float, z: float) -> str:
    return f'{_n(x)} 0 {_n(z)}'


def _home(cfg: AntennaConfig) -> tuple[float, float, float, float]:
    """gamma, coupler joint, delta, motor (rad) at mid-range: the keyframe ``home``."""
    theta = 0.5 * (cfg.theta_min + cfg.theta_max)
    gamma, delta = (float(v) for v in cfg.linkage.rocker_angles(theta, cfg.branch))
    q = gamma if cfg.driven is Driven.GAMMA else delta
    return gamma, gamma + theta, delta, cfg.reducer_ratio * (q - cfg.driven_joint_offset)


def mjcf(cfg: AntennaConfig, drive: DriveModel | None = None, model_name: str = 'fourbar_plant') -> str:
    """The MJCF (XML text) of the linkage ``cfg`` describes with its drive (``drive``: defaults of DriveModel).

    Lengths m, masses kg, inertias kg m^2, angles rad, gravity ``cfg.gravity`` m/s^2 along -z. Joint names:
    ``cfg.joint_names`` and ``motor_joint(cfg)``; the servo ``SERVO`` (ctrl: the motor angle, rad; with a stepper, a
    torque actuator whose ctrl is the torque, N m, set each step by ``plant.Plant``); the antenna's
    body ``ANTENNA_BODY`` with the site and accelerometer ``ANTENNA_IMU`` (specific force, m/s^2, in the site's
    frame); keyframe ``home``: at rest at mid-range, unassembled qpos0 aside.
    """
    d = drive or DriveModel()
    gamma_joint, delta_joint, coupler_joint = cfg.joint_names
    motor = motor_joint(cfg)
    H, ab, h, cd = cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length, cfg.rocker_cd_length
    weight = cfg.antenna_mass > 0.0
    coupler_mass = cfg.antenna_mass if weight else d.link_mass
    i_antenna = d.antenna_inertia if d.antenna_inertia is not None else coupler_mass * h * h / 12.0
    i_link, i_coupler = f'{_n(d.link_inertia)} ' * 3, f'{_n(i_antenna)} ' * 3
    com = (0.5 * h + cfg.com_offset_along, cfg.com_offset_normal)
    ratio, offset = cfg.reducer_ratio, cfg.driven_joint_offset
    driven = cfg.driven_joint
    pivot, axis = ('0 0 0', '0 -1 0') if cfg.driven is Driven.GAMMA else (_xz(H, 0.0), '0 1 0')
    solref, solimp = f'{_n(d.closure_timeconst)} 1', '0.9999 0.9999 0.001'
    damping = _n(d.joint_damping)
    vis = 'contype="0" conaffinity="0" group="1"'
    bar = 0.02 * H
    if d.reducer_stiffness is None:
        reducer = (f'    <joint name="{REDUCER}" joint1="{motor}" joint2="{driven}" '
                   f'polycoef="{_n(-ratio * offset)} {_n(ratio)} 0 0 0" solref="{solref}" solimp="{solimp}"/>\n')
        tendon = ''
    else:
        half = 0.5 * d.backlash
        tendon = (f'  <tendon>\n    <fixed name="{REDUCER}" stiffness="{_n(d.reducer_stiffness)}" '
                  f'damping="{_n(d.reducer_damping)}" springlength="{_n(-offset - half)} {_n(-offset + half)}">\n'
                  f'      <joint joint="{motor}" coef="{_n(1.0 / ratio)}"/>\n'
                  f'      <joint joint="{driven}" coef="-1"/>\n    </fixed>\n  </tendon>\n')
        reducer = ''
    limit = ('' if d.torque_limit is None
             else f' forcelimited="true" forcerange="{_n(-d.torque_limit)} {_n(d.torque_limit)}"')
    servo = (f'<position name="{SERVO}" joint="{motor}" kp="{_n(d.kp)}" kv="{_n(d.kv)}"{limit}/>'
             if d.stepper_torque is None else f'<motor name="{SERVO}" joint="{motor}"/>')
    home = ' '.join(_n(v) for v in _home(cfg))
    return f'''<mujoco model="{model_name}">
  <!-- Generated by `fourbar mjcf` from the node's parameters; edit the parameter file, not this. -->
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{_n(d.timestep)}" gravity="0 0 {_n(-cfg.gravity)}" integrator="implicitfast" jacobian="dense">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <geom name="frame" type="capsule" fromto="0 0 0 {_n(H)} 0 0" size="{_n(bar)}" {vis} rgba="0.5 0.5 0.5 1"/>
    <body name="rocker_ab" gravcomp="1">
      <joint name="{gamma_joint}" type="hinge" axis="0 -1 0" damping="{damping}"/>
      <inertial pos="{_xz(0.5 * ab, 0.0)}" mass="{_n(d.link_mass)}" diaginertia="{i_link}"/>
      <geom type="capsule" fromto="0 0 0 {_n(ab)} 0 0" size="{_n(bar)}" {vis} rgba="0.2 0.4 0.8 1"/>
      <body name="{ANTENNA_BODY}" pos="{_xz(ab, 0.0)}" gravcomp="{0 if weight else 1}">
        <joint name="{coupler_joint}" type="hinge" axis="0 1 0" damping="{damping}"/>
        <inertial pos="{_xz(*com)}" mass="{_n(coupler_mass)}" diaginertia="{i_coupler}"/>
        <geom type="capsule" fromto="0 0 0 {_n(h)} 0 0" size="{_n(bar)}" {vis} rgba="0.9 0.6 0.1 1"/>
        <site name="c_coupler" pos="{_xz(h, 0.0)}"/>
        <site name="antenna_com" pos="{_xz(*com)}"/>
        <site name="{ANTENNA_IMU}" pos="{_xz(*com)}"/>
      </body>
    </body>
    <body name="rocker_cd" pos="{_xz(H, 0.0)}" quat="0 0 0 1" gravcomp="1">
      <joint name="{delta_joint}" type="hinge" axis="0 -1 0" damping="{damping}"/>
      <inertial pos="{_xz(0.5 * cd, 0.0)}" mass="{_n(d.link_mass)}" diaginertia="{i_link}"/>
      <geom type="capsule" fromto="0 0 0 {_n(cd)} 0 0" size="{_n(bar)}" {vis} rgba="0.2 0.4 0.8 1"/>
      <site name="c_rocker" pos="{_xz(cd, 0.0)}"/>
    </body>
    <body name="rotor" pos="{pivot}" gravcomp="1">
      <joint name="{motor}" type="hinge" axis="{axis}"/>
      <inertial pos="0 0 0" mass="{_n(d.link_mass)}" diaginertia="{f'{_n(d.rotor_inertia)} ' * 3}"/>
    </body>
  </worldbody>
  <equality>
    <connect name="{CLOSURE}" site1="c_coupler" site2="c_rocker" solref="{solref}" solimp="{solimp}"/>
{reducer}  </equality>
{tendon}  <actuator>
    {servo}
  </actuator>
  <sensor>
    <accelerometer name="{ANTENNA_IMU}" site="{ANTENNA_IMU}"/>
  </sensor>
  <keyframe>
    <key name="home" qpos="{home}" ctrl="{_n(_home(cfg)[3] if d.stepper_torque is None else 0.0)}"/>
  </keyframe>
</mujoco>
'''

