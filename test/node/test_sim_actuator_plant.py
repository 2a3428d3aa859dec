"""sim_actuator with the MuJoCo plant as its drive (``drive: mujoco``), over the real middleware: a trajectory is
followed to rest, where the measured position is the target less the servo's static deflection under the load and
the measured effort is the plant's reducer torque, the load model's within the plant's soft-constraint bound; without
the plant offered, ``drive: mujoco`` falls back to the lag drive with one log line.

Timing is never asserted: the drive's rest is waited for with a deadline."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from typing import Any

import pytest
from builtin_interfaces.msg import Duration
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from support.paths import REPO
from support.ros_support import Collector, RosSession
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.config.robot_model import driven_angle
from fourbar_ros.interface.topics import BROADCASTER_JOINT_STATES
from fourbar_ros.node.sim_actuator import LagDrive, SimActuator
from fourbar_ros.rules.simulated_drive import effort_at

pytest.importorskip('mujoco', reason='the plant drive needs the mujoco package (the plant extra)')
from fourbar_ros.plant.mjcf import DriveModel
from fourbar_ros.plant.sim_drive import PlantDrive, plant_drive

pytestmark = pytest.mark.ros

YAML = REPO / 'config' / 'antenna.yaml'
CFG = default_config()
JOINT = CFG.driven_joint
Q0 = driven_angle(CFG)
DRIVE = DriveModel()
#: Servo stiffness seen at the rocker (N m/rad): kp at the motor through the reducer twice (angle and torque).
STIFFNESS = DRIVE.kp * CFG.reducer_ratio ** 2
#: The plant's drive torque at rest against the load model's at the rocker angle held: docs/how-to/mujoco-plant.md
#: measures at most 5.3e-6 relative over the plant tests' cases (the soft closure); the next decade up.
REST_EFFORT_REL = 1e-5
#: At rest: |velocity| below this (rad/s) for a sample to count as resting (the servo's 50 Hz mode decays as
#: e^(-316 t); 1e-9 rad/s is reached within 0.1 s of the reference stopping).
REST_SPEED = 1e-9
_ns = itertools.count()


def _node(ros: RosSession, drives: dict[str, Any] | None) -> tuple[SimActuator, Collector[JointState], Any]:
    ns = f'/sim_plant_{next(_ns)}'
    node = SimActuator(context=ros.context, namespace=ns, drives=drives,
                       parameter_overrides=[Parameter('drive', value='mujoco')],
                       cli_args=['--ros-args', '--params-file', str(YAML)])
    ros.add_node(node)
    states: Collector[JointState] = ros.collect(JointState, f'{ns}/{BROADCASTER_JOINT_STATES.name}')
    pub = ros.publisher(JointTrajectory, f'{ns}/joint_trajectory_controller/joint_trajectory', 10)
    ros.wait_publishers(states)
    ros.wait_subscribers(pub)
    states.wait_count(1)
    return node, states, pub


@pytest.fixture
def plant_node(ros: RosSession) -> Iterator[tuple[SimActuator, Collector[JointState], Any]]:
    node, states, pub = _node(ros, {'mujoco': plant_drive})
    yield node, states, pub
    ros.uncollect(states)
    ros.destroy(pub)
    ros.remove_node(node)


def test_the_plant_follows_a_trajectory_to_rest_and_reports_its_reducer_torque(
        ros: RosSession, plant_node: tuple[SimActuator, Collector[JointState], Any]) -> None:
    node, states, pub = plant_node
    assert node.drive_kind == 'mujoco' and isinstance(node.drive, PlantDrive)
    target = Q0 + 0.05
    msg = JointTrajectory(joint_names=[JOINT])
    msg.points = [JointTrajectoryPoint(positions=[Q0 + 0.025], velocities=[0.04], accelerations=[0.0],
                                       time_from_start=Duration(sec=0, nanosec=700_000_000)),
                  JointTrajectoryPoint(positions=[target], velocities=[0.0], accelerations=[0.0],
                                       time_from_start=Duration(sec=1, nanosec=400_000_000))]
    first = len(states)
    pub.publish(msg)

    # At rest at the target the servo holds the load L off its command by L / (kp r^2) (rad at the rocker, against
    # the load): that, to 1e-3 of it (the load model's torque changes by far less over the deflection), plus an
    # encoder-free float's rounding.
    def resting(m: JointState) -> bool:
        return abs(m.velocity[0]) <= REST_SPEED and m.position[0] > Q0 + 0.04
    rest = states.wait_match(resting, start=first)
    x, e = rest.position[0], rest.effort[0]
    deflection = e / STIFFNESS
    assert abs(x - (target - deflection)) <= 1e-3 * abs(deflection) + 1e-12, (x, target, e, deflection)
    static = effort_at(CFG, x)
    assert abs(e - static) <= REST_EFFORT_REL * abs(static), (e, static)
    # On the way, the rocker moved up to the target and never past it by more than the deflection.
    moving = states.messages[first:states.messages.index(rest) + 1]
    assert max(m.position[0] for m in moving) <= target + 1e-3 * abs(deflection), [m.position[0] for m in moving]
    assert all(math.isfinite(m.effort[0]) for m in moving)


def test_without_the_plant_offered_the_lag_drive_follows(ros: RosSession) -> None:
    node, states, pub = _node(ros, None)
    try:
        assert node.drive_kind == 'lag' and isinstance(node.drive, LagDrive)
        assert node.get_parameter('drive').value == 'mujoco'
    finally:
        ros.uncollect(states)
        ros.destroy(pub)
        ros.remove_node(node)
