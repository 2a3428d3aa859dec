"""A witness that does not share the formula: MuJoCo's static equilibrium of the closed linkage gives the torque the
drive supplies, and the core (the node's torque), `fourbar solve`'s printed torque and it agree.

The model is built from the pose only (no statics of the package): the linkage at rest in MuJoCo's x-z plane (the
planar convention's (x, y) is (x, 0, y): the frame AD horizontal, +z up, gravity -z), two open chains from the
world, A -> rocker AB -> coupler BC (carrying the antenna) and D -> rocker DC, joined by a ``<connect>`` equality at
C. The antenna is an ``<inertial>`` of the coupler at its centre of mass as ``core.loads`` and
``config.robot_model`` place it: the coupler's midpoint plus ``com_offset_along`` along B->C and
``com_offset_normal`` along n = (sin theta, cos theta). The load torque is, by the package's convention, what the
drive must supply about theta (+ in the sense of increasing theta): the surroundings apply its opposite to the
antenna, a pure torque ``xfrc_applied`` on the coupler about +y (increasing theta turns the coupler about +y). A
stiff ``<position>`` actuator holds the driven rocker (hinge axis chosen so the joint angle increases with gamma or
delta) at the pose's angle; the simulation steps to rest and ``actuator_force`` is the torque the drive supplies, in
the sense of increasing driven rocker angle, N m at the rocker: the package's ``input_torque``.

Masses that are not the antenna's: the rockers have 0.1 kg and 1e-2 kg m^2 so the stiff drive's step is stable
(the position gain is explicit: TIMESTEP sqrt(KP / inertia) = 0.63 < 2 even for a driven rocker that carries nothing
else, as DC does; with 1e-3 kg m^2 a delta-driven case oscillated), and their weight is cancelled exactly
(``gravcomp="1"``: MuJoCo applies the opposite of their weight); without a weight (no antenna mass) gravity is off
and the coupler gets 0.1 kg for the same reason. At rest (no velocity) inertia adds no force, so the drive holds the
antenna's weight and the load torque only.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pytest
from support.cli_support import fourbar
from support.mujoco_log import mujoco_warnings

from fourbar_ros.config.antenna_config import AntennaConfig, load_config
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.loads import pose
from fourbar_ros.rules.outputs import JointStateRule, driven_index

try:
    import mujoco
except ImportError:  # each test skips, saying why (a module-level skip would fail a run that names this file)
    mujoco = None
pytestmark = pytest.mark.skipif(mujoco is None, reason='the MuJoCo witness needs the mujoco package (pip install '
                                'mujoco, pinned in requirements/constraints.txt)')

#: Step (s), drive stiffness (N m/rad) and damping (N m s/rad), joint damping (N m s/rad), steps to rest: settles
#: every case below to |qvel| < 1e-9 rad/s in 0.6 s of simulated time. The connect constraint's solref/solimp make
#: it as stiff as this step allows (time constant 10 steps, impedance 0.9999).
TIMESTEP, KP, KV, DAMPING, STEPS = 2e-4, 1e5, 10.0, 1.0, 3000
SOLREF, SOLIMP = '0.002 1', '0.9999 0.9999 0.001'
LINK_MASS, LINK_INERTIA = 0.1, 1e-2  # kg, kg m^2: the rockers (and the coupler without an antenna)
ANTENNA_INERTIA = 1e-4  # kg m^2 about the antenna's centre of mass (no static effect)

#: MuJoCo's constraints are soft: at rest the connect equality is violated in proportion to the force it carries
#: (up to 6e-8 m here) and the drive rests off its setpoint by force / KP (4e-5 rad at 4 N m, a 1e-4 relative error
#: in the torque; after the one setpoint correction below, within 5e-9 rad of the pose's angle). Measured with
#: mujoco 4.0.0 over CASES: within 4.4e-7 relative (1.0e-6 N m) of the core; over 60 more random cases in the same
#: ranges, within 3.3 % of the bound. The bound, REL_TOL relative plus ABS_TOL, leaves a factor ~30 for other MuJoCo
#: versions and platforms and is far below a modelling error: the centre of mass at B instead of the midpoint, the
#: load's sign or the normal offset's sign each move these torques by 1.4e-2 to 3 relative.
REL_TOL, ABS_TOL = 1e-4, 1e-5  # dimensionless, N m
#: The rest state the bound assumes (checked for every case).
REST_QVEL, REST_GAP, REST_ROCKER = 1e-8, 1e-6, 1e-6  # rad/s, m (|C_coupler - C_rocker|), rad (driven off the pose)


class Case(NamedTuple):
    mass: float      # kg
    load: float      # N m about theta, what the drive must supply
    along: float     # m, centre of mass beyond the coupler's midpoint along B->C
    normal: float    # m, along n
    theta_deg: float
    driven: str


CASES = [
    Case(0.0, 3.5, 0.0, 0.0, -6.0, 'gamma'),     # the design wind load alone, at its worst angle
    Case(0.0, -1.0, 0.0, 0.0, 7.0, 'delta'),
    Case(2.0, 2.0, 0.0, 0.0, 3.4377, 'gamma'),   # ~0.06 rad
    Case(4.0, 0.0, 0.0, 0.0, -5.2139, 'gamma'),  # ~-0.091 rad: the weight alone
    Case(1.0, -1.0, 0.02, 0.01, 5.7, 'gamma'),
    Case(3.0, 1.0, -0.01, 0.03, -5.7, 'delta'),
    Case(0.5, 0.0, 0.03, -0.02, 6.9, 'delta'),
    Case(4.0, 3.5, 0.0, 0.02, 0.0, 'gamma'),     # theta = 0: the weight has no lever (the normal offset is vertical)
]


@pytest.fixture(name='mujoco_warnings')
def _mujoco_warnings() -> Iterator[list[str]]:
    """MuJoCo's warnings (an unstable step) collected over the test."""
    with mujoco_warnings() as seen:
        yield seen


def params_file(folder: Path, case: Case) -> Path:
    path = folder / 'witness.yaml'
    path.write_text('/**:\n  ros__parameters:\n'
                    f'    antenna_mass: {case.mass!r}\n    load_torque: {case.load!r}\n'
                    f'    com_offset_along: {case.along!r}\n    com_offset_normal: {case.normal!r}\n'
                    f'    driven_rocker: {case.driven}\n', encoding='utf-8')
    return path


def _xz(point: Any) -> str:
    """A planar point (x, y) as MuJoCo's 'x 0 z' (exact doubles)."""
    return f'{float(point[0])!r} 0 {float(point[1])!r}'


def mjcf(cfg: AntennaConfig, theta: float) -> str:
    """The linkage of ``cfg`` at antenna angle theta (rad) as MJCF: qpos = 0 is the pose."""
    link = cfg.linkage
    gamma, delta = (float(v) for v in link.rocker_angles(theta, cfg.branch))
    a, d = np.zeros(2), np.array([link.frame, 0.0])
    b = a + link.rocker_ab * np.array([math.cos(gamma), math.sin(gamma)])
    c = d + link.rocker_cd * np.array([-math.cos(delta), math.sin(delta)])
    u, n = np.array([math.cos(theta), -math.sin(theta)]), np.array([math.sin(theta), math.cos(theta)])
    com = b + (0.5 * link.coupler + cfg.com_offset_along) * u + cfg.com_offset_normal * n
    weight = cfg.antenna_mass > 0.0 and cfg.gravity > 0.0
    coupler_mass = cfg.antenna_mass if weight else LINK_MASS
    gravity = cfg.gravity if weight else 0.0
    i_link, i_antenna = f'{LINK_INERTIA} ' * 3, f'{ANTENNA_INERTIA} ' * 3
    # Hinge axes: -y at A makes the joint angle gamma's increase (it lifts B), +y at D delta's (it lifts C).
    return f'''<mujoco model="fourbar_witness">
  <option timestep="{TIMESTEP}" gravity="0 0 {-gravity!r}" integrator="implicitfast">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <body name="rocker_ab" pos="0 0 0" gravcomp="1">
      <joint name="gamma" type="hinge" axis="0 -1 0" damping="{DAMPING}"/>
      <inertial pos="{_xz(0.5 * b)}" mass="{LINK_MASS}" diaginertia="{i_link}"/>
      <body name="coupler" pos="{_xz(b)}">
        <joint name="coupler" type="hinge" axis="0 1 0" damping="{DAMPING}"/>
        <inertial pos="{_xz(com - b)}" mass="{coupler_mass!r}" diaginertia="{i_antenna}"/>
        <site name="c_coupler" pos="{_xz(c - b)}"/>
      </body>
    </body>
    <body name="rocker_cd" pos="{_xz(d)}" gravcomp="1">
      <joint name="delta" type="hinge" axis="0 1 0" damping="{DAMPING}"/>
      <inertial pos="{_xz(0.5 * (c - d))}" mass="{LINK_MASS}" diaginertia="{i_link}"/>
      <site name="c_rocker" pos="{_xz(c - d)}"/>
    </body>
  </worldbody>
  <equality>
    <connect site1="c_coupler" site2="c_rocker" solref="{SOLREF}" solimp="{SOLIMP}"/>
  </equality>
  <actuator>
    <position name="drive" joint="{cfg.driven.value}" kp="{KP}" kv="{KV}"/>
  </actuator>
</mujoco>
'''


def mujoco_torque(cfg: AntennaConfig, theta: float, warnings: list[str]) -> float:
    """The torque (N m, + in the sense of increasing driven rocker angle) the drive supplies at rest."""
    model = mujoco.MjModel.from_xml_string(mjcf(cfg, theta))
    data = mujoco.MjData(model)
    # Only the antenna weighs: the rockers' weight is compensated, and the coupler is the antenna.
    weighing = float(np.sum(model.body_mass * (1.0 - model.body_gravcomp)))
    assert weighing == (cfg.antenna_mass if cfg.has_gravity_load else LINK_MASS)
    assert (model.opt.gravity[2] != 0.0) == cfg.has_gravity_load
    mujoco.mj_forward(model, data)
    site_c = (model.site('c_coupler').id, model.site('c_rocker').id)
    assert np.linalg.norm(data.site_xpos[site_c[0]] - data.site_xpos[site_c[1]]) < 1e-15  # the pose closes
    # The surroundings apply -load_torque about theta, i.e. about +y.
    data.xfrc_applied[model.body('coupler').id, 3:] = (0.0, -cfg.load_torque, 0.0)
    driven = model.joint(cfg.driven.value).qposadr[0]
    for correction in range(2):
        if correction:  # hold the rocker at the pose's angle, not force / KP off it: move the setpoint once
            data.ctrl[0] = data.actuator_force[0] / KP
        for _ in range(STEPS):
            mujoco.mj_step(model, data)
    assert not warnings, warnings
    assert float(np.max(np.abs(data.qvel))) < REST_QVEL
    assert abs(float(data.qpos[driven])) < REST_ROCKER
    assert float(np.linalg.norm(data.site_xpos[site_c[0]] - data.site_xpos[site_c[1]])) < REST_GAP
    return float(data.actuator_force[0])


@pytest.mark.parametrize('case', CASES, ids=[f'{c.mass}kg-{c.load}Nm-{c.theta_deg}deg-{c.driven}' for c in CASES])
def test_mujoco_core_and_solve_agree_on_the_drive_torque(case: Case, tmp_path: Path,
                                                         mujoco_warnings: list[str]) -> None:
    params = params_file(tmp_path, case)
    cfg = load_config(params)
    theta = math.radians(case.theta_deg)
    assert cfg.theta_min <= theta <= cfg.theta_max and cfg.driven is Driven(case.driven)
    core = pose(cfg, theta).input_torque
    node = JointStateRule(cfg).effort(pose(cfg, theta))[driven_index(cfg)]
    out = fourbar('solve', '--params', params, '--theta', repr(theta), '--json')
    assert out.returncode == 0, out.stderr
    printed = json.loads(out.stdout)['input_torque']
    witness = mujoco_torque(cfg, theta, mujoco_warnings)
    # solve and the node make the same calls on the same floats: equal doubles.
    assert printed == core == node
    # MuJoCo's soft constraints: REL_TOL relative plus ABS_TOL (see their definition).
    assert abs(witness - core) <= REL_TOL * abs(core) + ABS_TOL, (witness, core, (witness - core) / core)
