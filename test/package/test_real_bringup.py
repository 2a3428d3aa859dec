"""The package's launch file with ``use_ros2_control:=true`` on the real controller manager (mock hardware), in the
root namespace and in one, in trajectory and forward mode: the spawners activate the controllers, a command moves
the joint, joint_states carries the completed linkage, SIGINT ends everything with status 0; and the controller
manager clamps a trajectory sent straight to the controller past the joint's limit. With ``hardware:=bridge`` and
``hardware:=mujoco`` (the drive bridge, and the bridge on the MuJoCo plant) the launch line as typed activates the
hardware on the bridge's first reading and a command moves the drive.

Runs where the ros2 command line, launch_ros and ros2_control are installed; skipped elsewhere with the reason.
"""

from __future__ import annotations

import time

import pytest
from support.colcon_support import CliEnv, launch_missing, ros2, ros2_cli_missing
from support.ros2_control_support import ros2_control_missing

if (_why := ros2_cli_missing() or launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from support.ros_cli_support import (  # psutil: with ros2cli
    PUB_ONCE,
    TIMEOUT,
    Background,
    echo_once,
    echoed_messages,
    publish_until_echoed,
    run,
    wait_node,
)

from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.config.robot_model import driven_angle, joint_limits

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.fixture
def install(ros2_cli: CliEnv) -> CliEnv:
    """The run's sourced install for the command line (conftest's ``ros2_cli``)."""
    return ros2_cli


def _wait_measured_at(install: CliEnv, launch: Background, ns: str, q: float) -> None:
    """Wait for the broadcaster's measured driven joint within 1e-3 rad of ``q``; else fail with the launch's output
    (what the node, the bridge and the controllers logged meanwhile)."""
    def at_target(text: str) -> bool:
        return any(abs(d['position'][0] - q) < 1e-3 for d in echoed_messages(text) if d.get('position'))
    follow = Background([ros2(), 'topic', 'echo', f'{ns}/joint_state_broadcaster/joint_states',
                         'sensor_msgs/msg/JointState'], install.env, cwd=install.cwd)
    try:
        follow.wait_output(at_target, f'the measured joint at the commanded angle {q} rad')
    except AssertionError as exc:
        output = launch.stdout[-6000:] + launch.stderr[-4000:]
        raise AssertionError(f'{exc}\nthe launch\'s output: {output}') from None
    finally:
        follow.kill()


def _assert_clean_stop(launch: Background) -> None:
    """SIGINT ends ros2 launch with status 0, no traceback and no process left."""
    assert launch.interrupt(group=True) == 0, launch.stdout[-2000:] + launch.stderr[-2000:]
    assert 'Traceback' not in launch.stdout + launch.stderr, launch.stdout[-3000:] + launch.stderr[-3000:]
    assert not launch.descendants(), 'a process outlived ros2 launch'


@pytest.mark.parametrize(('namespace', 'mode'), [('', 'trajectory'), ('tilt', 'trajectory'), ('tilt', 'forward')])
def test_the_bringup_moves_the_joint(install: CliEnv, namespace: str, mode: str) -> None:
    # The launch file's bringup on the real controller manager with the mock hardware: the spawners activate the
    # broadcaster and the mode's controller, a command moves the mock joint to the commanded angle, and joint_states
    # carries the whole linkage, completed from the measured joint.
    if (why := ros2_control_missing(install.env)) is not None:
        pytest.skip(why)
    cfg = load_config(install.prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml')
    ns = f'/{namespace}' if namespace else ''
    controller = 'forward_position_controller' if mode == 'forward' else 'joint_trajectory_controller'
    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', f'namespace:={namespace or "/"}',
                         'use_ros2_control:=true', f'mode:={mode}', 'rviz:=false'], install.env, cwd=install.cwd)
    try:
        wait_node(install.env, f'{ns}/fourbar_node')
        launch.wait_output(lambda t: f'Configured and activated {controller}' in t, f'{controller} active')
        target = 0.05
        q = float(cfg.linkage.rocker_angles(target, cfg.branch)[0 if cfg.driven_joint == cfg.gamma_joint else 1])
        echo = echo_once(install.env, f'{ns}/joint_states', 'sensor_msgs/msg/JointState')
        try:
            state = publish_until_echoed(install.env, echo, f'{ns}/antenna_angle_cmd', target)
        finally:
            echo.kill()
        other = cfg.delta_joint if cfg.driven_joint == cfg.gamma_joint else cfg.gamma_joint
        assert state['name'] == [cfg.driven_joint, other, cfg.coupler_joint] and len(state['effort']) == 3, state

        _wait_measured_at(install, launch, ns, q)
        _assert_clean_stop(launch)
    finally:
        launch.kill()


def test_a_trajectory_past_the_limit_is_clamped_by_the_controller_manager(install: CliEnv) -> None:
    # Straight to the trajectory controller's topic, not through the node: to 1.2 rad, past the driven joint's upper
    # limit, at a speed within its velocity limit. The controller follows it (it checks no position limit); the
    # controller manager (the shipped enforce_command_limits) clamps the command to the URDF's upper limit, so the
    # mock joint, which measures its last command, stops there.
    if (why := ros2_control_missing(install.env)) is not None:
        pytest.skip(why)
    cfg = load_config(install.prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml')
    limit = joint_limits(cfg)[cfg.driven_joint]
    start = driven_angle(cfg)  # the mock's initial position: the antenna level
    target, duration = 1.2, 8.0
    assert target > limit.upper and (target - start) / duration < limit.velocity
    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', 'use_ros2_control:=true',
                         'mode:=trajectory', 'rviz:=false'], install.env, cwd=install.cwd)
    follow = Background([ros2(), 'topic', 'echo', '/joint_state_broadcaster/joint_states',
                         'sensor_msgs/msg/JointState'], install.env, cwd=install.cwd)
    try:
        launch.wait_output(lambda t: 'Configured and activated joint_trajectory_controller' in t,
                           'joint_trajectory_controller active')

        def measured(text: str) -> list[float]:
            return [float(d['position'][0]) for d in echoed_messages(text) if d.get('position')]

        # Sent again (from where the joint is, the same target and duration) until the joint leaves its start: on a
        # loaded machine the controller's side of discovery can lag past the publisher's keep-alive, and the one
        # trajectory is lost. 1e-9 rad: the mock measures its commands exactly.
        deadline = time.monotonic() + 4 * TIMEOUT
        sends = 0
        while not any(abs(q - start) > 1e-9 for q in measured(follow.output())):
            assert time.monotonic() < deadline, (f'the joint never left {start!r} rad after {sends} trajectories; '
                                                 f'it measured {sorted(set(measured(follow.output())))[:5]}')
            out = run([ros2(), *PUB_ONCE, '/joint_trajectory_controller/joint_trajectory',
                       'trajectory_msgs/msg/JointTrajectory',
                       f'{{joint_names: [{cfg.driven_joint}], points: [{{positions: [{target!r}], '
                       f'time_from_start: {{sec: {int(duration)}}}}}]}}'], install.env)
            assert out.returncode == 0, out.stdout + out.stderr
            sends += 1
        # A clamp gives the limit's double exactly; 1e-12 rad leaves room for the velocity clamp's rounding.
        follow.wait_output(lambda t: any(abs(q - limit.upper) <= 1e-12 for q in measured(t)),
                           f'the joint at its upper limit {limit.upper!r} rad', timeout=duration + 30.0)
        seen = measured(follow.output())
        assert max(seen) <= limit.upper + 1e-12, f'past the upper limit {limit.upper!r} rad: {max(seen)!r}'
        assert launch.interrupt(group=True) == 0, launch.stdout[-2000:] + launch.stderr[-2000:]
    finally:
        follow.kill()
        launch.kill()


@pytest.mark.parametrize('hardware', ['bridge', 'mujoco'])
def test_the_bridge_bringup_moves_the_drive(install: CliEnv, hardware: str) -> None:
    # The launch line as typed with the drive bridge on the topic-based plugin (the bridge's simulated drive, or the
    # MuJoCo plant's stepper): the hardware starts inactive, the bridge activates it on its first reading, the
    # spawners follow, and a command moves the drive's reported joint to the commanded angle.
    if (why := ros2_control_missing(install.env)) is not None:
        pytest.skip(why)
    if hardware == 'mujoco':
        pytest.importorskip('mujoco')
    cfg = load_config(install.prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml')
    ns = '/tilt_drive'
    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', 'namespace:=tilt_drive',
                         'use_ros2_control:=true', f'hardware:={hardware}', 'rviz:=false'], install.env,
                        cwd=install.cwd)
    try:
        launch.wait_output(lambda t: 'hardware component active' in t, 'the bridge activating the hardware')
        launch.wait_output(lambda t: 'Configured and activated joint_trajectory_controller' in t,
                           'joint_trajectory_controller active')
        target = 0.05
        q = float(cfg.linkage.rocker_angles(target, cfg.branch)[0 if cfg.driven_joint == cfg.gamma_joint else 1])
        echo = echo_once(install.env, f'{ns}/joint_states', 'sensor_msgs/msg/JointState')
        try:
            publish_until_echoed(install.env, echo, f'{ns}/antenna_angle_cmd', target)
        finally:
            echo.kill()
        _wait_measured_at(install, launch, ns, q)
        _assert_clean_stop(launch)
    finally:
        launch.kill()
