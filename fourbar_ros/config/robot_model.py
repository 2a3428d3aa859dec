"""URDF robot model of the tilt linkage, generated from the node's validated configuration. No ROS import.

Frames, joints, limits and the ``<ros2_control>`` block: docs/how-to/ros2-control.md."""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import NamedTuple
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, load_config
from fourbar_ros.config.rcl_yaml import ConfigError
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.completion import coupler_joint_position
from fourbar_ros.interface.topics import NODE_NAME

#: Link names below the root (``frame_id``); the root link itself is named by ``frame_id``.
LINKS = ('rocker_ab', 'coupler', 'rocker_cd', 'coupler_c', 'rocker_cd_c', 'antenna')
#: Samples of the tilt range used for the joint limits (plus both ends).
_LIMIT_SAMPLES = 256
#: Bar thickness of the visuals as a fraction of the frame length.
_BAR = 0.04
#: The hardware plugin of the ``<ros2_control>`` block unless one is given: ros2_control's test system.
DEFAULT_HARDWARE_PLUGIN = 'mock_components/GenericSystem'


def _num(value: float) -> str:
    """Shortest text that reads back as the same double (URDF parsers use strtod)."""
    return repr(float(value))


def _xyz(x: float, y: float, z: float) -> str:
    return f'{_num(x)} {_num(y)} {_num(z)}'


class JointLimit(NamedTuple):
    """A URDF ``<limit>``: position range (rad), effort (N m) and velocity (rad/s)."""

    lower: float
    upper: float
    effort: float
    velocity: float


def driven_angle(cfg: AntennaConfig, theta: float = 0.0) -> float:
    """The driven rocker's angle (rad) at antenna angle ``theta`` (rad) clamped into the tilt range; by default
    where a drive rests unless told otherwise: the antenna level (0), or the nearest end of the range."""
    gamma, delta = cfg.linkage.rocker_angles(min(max(theta, cfg.theta_min), cfg.theta_max), cfg.branch)
    return float(gamma if cfg.driven is Driven.GAMMA else delta)


def joint_limits(cfg: AntennaConfig) -> dict[str, JointLimit]:
    """Limits of the three joints (by JointState name) over the configured tilt range, the motor turning at most
    ``motor_speed_limit`` rad/s (motor side) through |``reducer_ratio``|: the driven joint's velocity limit is the
    planner's speed limit (``motion.limits.JointLimits.at_rocker(1)``), its effort limit ``output_torque_limit``
    (N m, the planner's rated torque) and its position range that of [theta_min, theta_max]."""
    lo, hi = cfg.theta_min, cfg.theta_max
    # Scalar solves, the very calls the node makes per command: its published positions lie within these limits.
    thetas = [lo + (hi - lo) * i / _LIMIT_SAMPLES for i in range(_LIMIT_SAMPLES)] + [hi]
    columns: list[list[float]] = [[], [], [], [], [], []]
    for theta in thetas:
        gamma, delta = cfg.linkage.rocker_angles(theta, cfg.branch)
        rates = cfg.linkage.rates_at(theta, gamma, delta)
        for column, value in zip(columns, (gamma, delta, coupler_joint_position(float(gamma), theta),
                                           rates.dgamma_dtheta, rates.ddelta_dtheta, rates.dgamma_dtheta + 1.0),
                                 strict=True):
            column.append(float(value))
    g, d, c, dg, dd, dc = (np.array(column) for column in columns)
    gamma_joint, delta_joint, coupler_joint = cfg.joint_names
    # Position and its rate per unit theta of each joint; the coupler joint is gamma + theta.
    sweep = {gamma_joint: (g, dg), delta_joint: (d, dd), coupler_joint: (c, dc)}
    driven = cfg.driven_joint
    driven_rate = sweep[driven][1]
    speed = cfg.motor_speed_limit / cfg.reduction
    out: dict[str, JointLimit] = {}
    for name, (position, rate) in sweep.items():
        velocity = speed if name == driven else speed * float(np.max(np.abs(np.divide(rate, driven_rate))))
        effort = cfg.output_torque_limit if name == driven else 0.0
        out[name] = JointLimit(float(np.min(position)), float(np.max(position)), effort, velocity)
    return out


def _box(length: float, thickness: float, material: str, rgba: str) -> list[str]:
    """A bar along the link's x axis from its origin, as URDF <visual> lines."""
    return [
        '    <visual>',
        f'      <origin xyz="{_xyz(0.5 * length, 0.0, 0.0)}" rpy="0.0 0.0 0.0"/>',
        f'      <geometry><box size="{_xyz(length, thickness, thickness)}"/></geometry>',
        f'      <material name="fourbar_{material}"><color rgba="{rgba}"/></material>',
        '    </visual>',
    ]


def _link(name: str, body: Iterable[str] = ()) -> list[str]:
    lines = list(body)
    if not lines:
        return [f'  <link name={quoteattr(name)}/>']
    return [f'  <link name={quoteattr(name)}>', *lines, '  </link>']


def _joint(name: str, kind: str, parent: str, child: str, xyz: str, rpy: str = '0.0 0.0 0.0',
           axis: str | None = None, limit: JointLimit | None = None) -> list[str]:
    lines = [f'  <joint name={quoteattr(name)} type="{kind}">',
             f'    <parent link={quoteattr(parent)}/>',
             f'    <child link={quoteattr(child)}/>',
             f'    <origin xyz="{xyz}" rpy="{rpy}"/>']
    if axis is not None:
        lines.append(f'    <axis xyz="{axis}"/>')
    if limit is not None:
        lines.append(f'    <limit lower="{_num(limit.lower)}" upper="{_num(limit.upper)}" '
                     f'effort="{_num(limit.effort)}" velocity="{_num(limit.velocity)}"/>')
    lines.append('  </joint>')
    return lines


def ros2_control_block(cfg: AntennaConfig, limit: JointLimit,
                       hardware_plugin: str = DEFAULT_HARDWARE_PLUGIN) -> list[str]:
    """The ``<ros2_control>`` lines of the driven joint (limits ``limit``), its hardware named ``hardware_id`` with
    ``hardware_parameters`` as its ``<param>`` entries: a position command interface, and an effort one with
    ``effort_feedforward``; the SimpleTransmission joint = motor / ``reducer_ratio`` + ``driven_joint_offset``
    (either sign of the ratio, any offset), for the plugin to load."""

    joint = cfg.driven_joint
    params = [f'      <param name={quoteattr(name.strip())}>{escape(value)}</param>'
              for name, _, value in (entry.partition('=') for entry in cfg.hardware_parameters)]
    return [
        f'  <ros2_control name={quoteattr(cfg.hardware_id)} type="system">',
        # No ': ' nor ' #' in the comments: a ``-p robot_description:=...`` value is parsed as YAML.
        '    <!-- The drive\'s hardware interface goes here (mock_components/GenericSystem echoes the commands); its '
        'parameters come from the parameter hardware_parameters. -->',
        '    <hardware>',
        f'      <plugin>{escape(hardware_plugin)}</plugin>',
        *params,
        '    </hardware>',
        f'    <joint name={quoteattr(joint)}>',
        '      <command_interface name="position">',
        f'        <param name="min">{_num(limit.lower)}</param>',
        f'        <param name="max">{_num(limit.upper)}</param>',
        '      </command_interface>',
        *(['      <command_interface name="effort"/>  <!-- effort_feedforward (position, then effort) -->']
          if cfg.effort_feedforward else []),
        '      <state_interface name="position">',
        f'        <param name="initial_value">{_num(driven_angle(cfg))}</param>',
        '      </state_interface>',
        '      <state_interface name="velocity"/>',
        '      <state_interface name="effort"/>',
        '    </joint>',
        f'    <transmission name={quoteattr(joint + "_transmission")}>',
        '      <plugin>transmission_interface/SimpleTransmission</plugin>',
        f'      <actuator name={quoteattr(joint + "_motor")} role="actuator1"/>',
        f'      <joint name={quoteattr(joint)} role="joint1">',
        f'        <mechanical_reduction>{_num(cfg.reducer_ratio)}</mechanical_reduction>',
        f'        <offset>{_num(cfg.driven_joint_offset)}</offset>',
        '      </joint>',
        '    </transmission>',
        '  </ros2_control>',
    ]


def robot_description(cfg: AntennaConfig, robot_name: str = 'fourbar',
                      hardware_plugin: str = DEFAULT_HARDWARE_PLUGIN) -> str:
    """The URDF (XML text) of the linkage ``cfg`` describes, with its ``<ros2_control>`` block; joint names as the
    node publishes them (``cfg.joint_names``, distinct by the configuration's own validation); the velocity limits
    follow ``motor_speed_limit`` (rad/s, motor side)."""
    gamma_joint, delta_joint, coupler_joint = cfg.joint_names
    root = cfg.frame_id
    if root in LINKS:
        raise ValueError(f'frame_id {root!r} is also a link name of the model ({", ".join(LINKS)})')
    H, ab, h, cd = cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length, cfg.rocker_cd_length
    bar = _BAR * H
    limits = joint_limits(cfg)
    lines = ['<?xml version="1.0"?>',
             '<!-- Generated by `fourbar urdf` from the node\'s parameters; edit the parameter file, not this. -->',
             f'<robot name={quoteattr(robot_name)}>']
    lines += _link(root, _box(H, bar, 'frame', '0.5 0.5 0.5 1.0'))
    lines += _link('rocker_ab', _box(ab, bar, 'rocker', '0.2 0.4 0.8 1.0'))
    lines += _link('coupler', _box(h, bar, 'coupler', '0.9 0.6 0.1 1.0'))
    lines += _link('rocker_cd', _box(cd, bar, 'rocker', '0.2 0.4 0.8 1.0'))
    lines += _link('coupler_c')
    lines += _link('rocker_cd_c')
    lines += _link('antenna')
    lines += _joint(gamma_joint, 'revolute', root, 'rocker_ab', _xyz(0.0, 0.0, 0.0), axis='0.0 -1.0 0.0',
                    limit=limits[gamma_joint])
    lines += _joint(coupler_joint, 'revolute', 'rocker_ab', 'coupler', _xyz(ab, 0.0, 0.0), axis='0.0 1.0 0.0',
                    limit=limits[coupler_joint])
    lines += _joint(delta_joint, 'revolute', root, 'rocker_cd', _xyz(H, 0.0, 0.0), rpy=f'0.0 0.0 {_num(math.pi)}',
                    axis='0.0 -1.0 0.0', limit=limits[delta_joint])
    lines += _joint('c_from_coupler', 'fixed', 'coupler', 'coupler_c', _xyz(h, 0.0, 0.0))
    lines += _joint('c_from_rocker_cd', 'fixed', 'rocker_cd', 'rocker_cd_c', _xyz(cd, 0.0, 0.0))
    lines += _joint('antenna_mount', 'fixed', 'coupler', 'antenna',
                    _xyz(0.5 * h + cfg.com_offset_along, 0.0, cfg.com_offset_normal))
    lines += ros2_control_block(cfg, limits[cfg.driven_joint], hardware_plugin)
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'


def check_robot_model_kept(running: AntennaConfig, proposed: AntennaConfig, changed: Iterable[str]) -> None:
    """Raise ConfigError (one line) where a run-time change from ``running`` to ``proposed`` alters the robot model:
    the controller manager enforces the joint limits it loaded at launch, and robot_state_publisher publishes its
    frames, so a node planning with other lengths, limits or ratio would move the drive where they do not agree. The
    error names each of the ``changed`` parameters that alters the model by itself (every one where none does
    alone)."""
    before = robot_description(running)
    if robot_description(proposed) == before:
        return
    values, wanted = running.as_values(), proposed.as_values()
    names = [n for n in changed if wanted.get(n) != values.get(n)]

    def alters(name: str) -> bool:
        try:
            return robot_description(config_from_values({**values, name: wanted[name]}, [name])) != before
        except (ConfigError, ValueError):  # not valid alone (e.g. one end of the range past the other)
            return True
    at_fault = [n for n in names if alters(n)] or names
    raise ConfigError(f'{", ".join(at_fault)}: feeds the robot model the controller manager and robot_state_publisher '
                      'loaded at launch (joint limits, lengths, ratio), so it cannot change at run time: set it in '
                      'the parameter file and relaunch', at_fault)


def robot_description_for(params: str | Path, node_name: str = NODE_NAME, namespace: str = '/',
                          robot_name: str = 'fourbar',
                          hardware_plugin: str = DEFAULT_HARDWARE_PLUGIN) -> tuple[AntennaConfig, str]:
    """Validated configuration and URDF for the node ``namespace``/``node_name`` started with ``params``.

    Raises ``fourbar_ros.config.antenna_config.ConfigError`` (one line) for a bad file.
    """
    cfg = load_config(params, node_name, namespace)
    return cfg, robot_description(cfg, robot_name, hardware_plugin)
