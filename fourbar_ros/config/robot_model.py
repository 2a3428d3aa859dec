"""URDF robot model of the tilt linkage, generated from the node's configuration. No ROS import.

One source of truth: the lengths come from the same validated configuration the node uses
(``fourbar_ros.config.antenna_config.load_config``), so the model cannot drift from the solver.

Conventions (REP-103, metres, radians, z up). The linkage lies in the x-z plane of the root link
(the node's ``frame_id``): pivot A at its origin, pivot D at (frame length, 0, 0); a point (x, y) of the
planar convention (x along A->D, y up) is (x, 0, y) here.

=====================  ==========  ================================================================
joint (JointState)     type        from -> to; position
=====================  ==========  ================================================================
``gamma_joint``        revolute    root -> ``rocker_ab`` at A, axis -y: position gamma, 0 along A->D,
                                   positive lifts B (z > 0)
``coupler_joint``      revolute    ``rocker_ab`` -> ``coupler`` at B, axis +y: position gamma + theta,
                                   the coupler frame's x axis points along B->C
``delta_joint``        revolute    root -> ``rocker_cd`` at D (frame turned by pi about z, so its x
                                   points along D->A at zero), axis -y: position delta, positive lifts C
``c_from_coupler``     fixed       ``coupler`` -> ``coupler_c``: C reached through A, B
``c_from_rocker_cd``   fixed       ``rocker_cd`` -> ``rocker_cd_c``: C reached through D
``antenna_mount``      fixed       ``coupler`` -> ``antenna``: the antenna's centre of mass (coupler
                                   midpoint plus ``com_offset_along`` / ``com_offset_normal``)
=====================  ==========  ================================================================

The loop is closed kinematically, not in the tree: ``coupler_c`` and ``rocker_cd_c`` coincide exactly when
the published joint positions solve the linkage (the node publishes all three). Joints are revolute with
limits spanning the configured tilt range [theta_min, theta_max]; the driven rocker's effort limit is
``output_torque_limit`` (N m).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import TypeVar
from xml.sax.saxutils import quoteattr

from fourbar_ros.config.antenna_config import AntennaConfig, load_config
from fourbar_ros.config.interface import NODE_NAME
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.numeric import FloatArray

#: Link names below the root (``frame_id``); the root link itself is named by ``frame_id``.
LINKS = ('rocker_ab', 'coupler', 'rocker_cd', 'coupler_c', 'rocker_cd_c', 'antenna')
#: Samples of the tilt range used for the joint limits (plus both ends).
_LIMIT_SAMPLES = 256
#: Bar thickness of the visuals as a fraction of the frame length.
_BAR = 0.04
#: The joints are not speed-limited by the model; URDF needs a value (rad/s).
_VELOCITY_LIMIT = 10.0


def _num(value: float) -> str:
    """Shortest text that reads back as the same double (URDF parsers use strtod)."""
    return repr(float(value))


def _xyz(x: float, y: float, z: float) -> str:
    return f'{_num(x)} {_num(y)} {_num(z)}'


def joint_ranges(cfg: AntennaConfig) -> dict[str, tuple[float, float]]:
    """(lower, upper) rad of gamma, gamma + theta and delta over the configured tilt range."""
    thetas = [cfg.theta_min + (cfg.theta_max - cfg.theta_min) * i / _LIMIT_SAMPLES for i in range(_LIMIT_SAMPLES)]
    thetas.append(cfg.theta_max)
    values: dict[str, list[float]] = {'gamma': [], 'coupler': [], 'delta': []}
    for theta in thetas:
        gamma, delta = cfg.linkage.rocker_angles(theta, cfg.branch)
        values['gamma'].append(float(gamma))
        values['coupler'].append(float(gamma) + theta)
        values['delta'].append(float(delta))
    return {k: (min(v), max(v)) for k, v in values.items()}


#: A float or a float64 array: coupler_joint_position serves the node (one command) and fourbar process (blocks).
Angles = TypeVar('Angles', float, FloatArray)


def coupler_joint_position(gamma: Angles, theta: Angles) -> Angles:
    """Position (rad) of ``coupler_joint``: the coupler's angle from rocker AB, gamma + theta."""
    return gamma + theta


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
           axis: str | None = None, limit: tuple[float, float, float] | None = None) -> list[str]:
    lines = [f'  <joint name={quoteattr(name)} type="{kind}">',
             f'    <parent link={quoteattr(parent)}/>',
             f'    <child link={quoteattr(child)}/>',
             f'    <origin xyz="{xyz}" rpy="{rpy}"/>']
    if axis is not None:
        lines.append(f'    <axis xyz="{axis}"/>')
    if limit is not None:
        lower, upper, effort = limit
        lines.append(f'    <limit lower="{_num(lower)}" upper="{_num(upper)}" effort="{_num(effort)}" '
                     f'velocity="{_num(_VELOCITY_LIMIT)}"/>')
    lines.append('  </joint>')
    return lines


def robot_description(cfg: AntennaConfig, robot_name: str = 'fourbar') -> str:
    """The URDF (XML text) of the linkage ``cfg`` describes; joint names as the node publishes them
    (``cfg.joint_names``, distinct by the configuration's own validation)."""
    gamma_joint, delta_joint, coupler_joint = cfg.joint_names
    root = cfg.frame_id
    if root in LINKS:
        raise ValueError(f'frame_id {root!r} is also a link name of the model ({", ".join(LINKS)})')
    H, ab, h, cd = cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length, cfg.rocker_cd_length
    bar = _BAR * H
    ranges = joint_ranges(cfg)
    driven_effort = cfg.output_torque_limit
    effort = {'gamma': driven_effort if cfg.driven is Driven.GAMMA else 0.0,
              'delta': driven_effort if cfg.driven is Driven.DELTA else 0.0}
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
    lo, hi = ranges['gamma']
    lines += _joint(gamma_joint, 'revolute', root, 'rocker_ab', _xyz(0.0, 0.0, 0.0), axis='0.0 -1.0 0.0',
                    limit=(lo, hi, effort['gamma']))
    lo, hi = ranges['coupler']
    lines += _joint(coupler_joint, 'revolute', 'rocker_ab', 'coupler', _xyz(ab, 0.0, 0.0), axis='0.0 1.0 0.0',
                    limit=(lo, hi, 0.0))
    lo, hi = ranges['delta']
    lines += _joint(delta_joint, 'revolute', root, 'rocker_cd', _xyz(H, 0.0, 0.0), rpy=f'0.0 0.0 {_num(math.pi)}',
                    axis='0.0 -1.0 0.0', limit=(lo, hi, effort['delta']))
    lines += _joint('c_from_coupler', 'fixed', 'coupler', 'coupler_c', _xyz(h, 0.0, 0.0))
    lines += _joint('c_from_rocker_cd', 'fixed', 'rocker_cd', 'rocker_cd_c', _xyz(cd, 0.0, 0.0))
    lines += _joint('antenna_mount', 'fixed', 'coupler', 'antenna',
                    _xyz(0.5 * h + cfg.com_offset_along, 0.0, cfg.com_offset_normal))
    lines.append('</robot>')
    return '\n'.join(lines) + '\n'


def robot_description_for(params: str | Path, node_name: str = NODE_NAME, namespace: str = '/',
                          robot_name: str = 'fourbar') -> tuple[AntennaConfig, str]:
    """Validated configuration and URDF for the node ``namespace``/``node_name`` started with ``params``.

    Raises ``fourbar_ros.config.antenna_config.ConfigError`` (one line) for a bad file.
    """
    cfg = load_config(params, node_name, namespace)
    return cfg, robot_description(cfg, robot_name)
