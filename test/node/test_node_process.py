"""fourbar_node as a user starts it: its console script with ``--ros-args --params-file config/antenna.yaml``,
a separate process on this run's ROS domain id; outputs checked against the core; signals and bad startups.
The joint_states republish is off here (``ONE_JOINT_STATE_PER_COMMAND``): answers are counted per command."""

from __future__ import annotations

import math
import os
import signal
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from support.paths import REPO
from support.ros_support import (
    ONE_JOINT_STATE_PER_COMMAND,
    Collector,
    NodeProcess,
    RosSession,
    node_command,
    sync_probe,
    wait_future,
)

from fourbar_ros.config.antenna_config import ConfigError, load_config
from fourbar_ros.live.node_process import sim_actuator_command
from fourbar_ros.runtime.executor import EXECUTOR_ENV, EXECUTORS

pytestmark = [pytest.mark.ros, pytest.mark.slow]

YAML = REPO / 'config' / 'antenna.yaml'
CFG = load_config(YAML)
LO, HI = CFG.theta_min, CFG.theta_max
#: The node's pose_solver and ``state()`` call the identical scalar functions (``linkage.rocker_angles``,
#: ``linkage.torque_at``) on the same float theta, so their results are compared for equality. TOL bounds only
#: the power-balance identity (two formulas; see test_node.py).
TOL = 1e-12


def state(theta: float) -> Any:
    return CFG.linkage.state(theta, CFG.load_torque, CFG.driven, CFG.branch)


def start(ros: RosSession, *extra: str, params: Path = YAML, executor: str | None = None) -> NodeProcess:
    env = ros.env() if executor is None else ros.env(**{EXECUTOR_ENV: executor})
    proc = NodeProcess(['--ros-args', '--params-file', str(params), *ONE_JOINT_STATE_PER_COMMAND, *extra], env)
    proc.start()
    return proc


def connect(ros: RosSession, proc: NodeProcess, ns: str = '') -> tuple[Any, Collector[Any], Collector[Any]]:
    pub = ros.publisher(Float64, f'{ns}/antenna_angle_cmd')
    js = ros.collect(JointState, f'{ns}/joint_states')
    tq = ros.collect(Float64, f'{ns}/input_torque')
    for wait in (lambda: ros.wait_subscribers(pub), lambda: ros.wait_publishers(js), lambda: ros.wait_publishers(tq)):
        assert proc.running(), proc.stderr
        wait()
    probes = [LO + (HI - LO) * (i + 0.5) / 600 for i in range(600)]

    def matches(col: Collector[Any], msg: Any, probe: float) -> bool:
        s = state(probe)
        return bool(msg.position[0] == s.gamma) if col is js else bool(msg.data == s.input_torque)

    sync_probe(lambda t: pub.publish(Float64(data=t)), [js, tq], probes, matches)
    return pub, js, tq


def disconnect(ros: RosSession, pub: Any, *cols: Collector[Any]) -> None:
    for col in cols:
        ros.uncollect(col)
    ros.destroy(pub)


def assert_clean_exit(proc: NodeProcess, status: int) -> None:
    assert status == 0, proc.stderr
    assert 'Traceback' not in proc.stderr and 'Traceback' not in proc.stdout


def test_console_script_is_used() -> None:
    assert Path(node_command()[0]).name == 'fourbar_node'
    assert Path(sim_actuator_command()[0]).name == 'fourbar_sim_actuator'


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
@pytest.mark.parametrize('executor', EXECUTORS)
def test_process_serves_commands_and_exits_cleanly(ros: RosSession, sig: int, executor: str) -> None:
    proc = start(ros, '-r', f'__ns:=/proc_{sig}_{executor}', executor=executor)
    try:
        pub, js, tq = connect(ros, proc, f'/proc_{sig}_{executor}')
        commands = [LO, 0.0, HI, math.nan, 0.9, 0.05, 0.05, -0.01]
        served = [LO, 0.0, HI, 0.05, 0.05, -0.01]
        for c in commands:
            pub.publish(Float64(data=c))
        jmsgs = js.wait_count(len(served))
        tmsgs = tq.wait_count(len(served))
        for jm, tm, theta in zip(jmsgs, tmsgs, served, strict=True):
            s = state(theta)
            assert list(jm.name) == ['rocker_ab_joint', 'rocker_cd_joint', 'coupler_joint']
            assert list(jm.position) == [s.gamma, s.delta, s.gamma + theta]
            assert list(jm.effort) == [s.input_torque, 0.0, 0.0]
            assert tm.data == s.input_torque
            assert tm.data * s.dgamma_dtheta == pytest.approx(3.5, rel=TOL)
        # Nothing more arrives for the NaN and 0.9 commands: the answers above were in order and complete.
        assert len(js) == len(served) and len(tq) == len(served)
        disconnect(ros, pub, js, tq)
        assert proc.running()
        assert_clean_exit(proc, proc.stop(sig))
    finally:
        proc.kill()


@pytest.mark.parametrize('executor', EXECUTORS)
def test_runtime_parameter_rejection_in_the_process(ros: RosSession, executor: str) -> None:
    proc = start(ros, '-r', f'__ns:=/proc_params_{executor}', '-p', 'diagnostics_period:=0.1', executor=executor)
    try:
        pub, js, tq = connect(ros, proc, f'/proc_params_{executor}')
        client = AsyncParameterClient(ros.node, f'/proc_params_{executor}/fourbar_node')
        assert client.wait_for_services(timeout_sec=30.0)
        response = wait_future(client.set_parameters([Parameter('theta_max', value=0.9)]))
        assert not response.results[0].successful
        assert response.results[0].reason.startswith('theta_max: ') and 'reach' in response.results[0].reason
        got = wait_future(client.get_parameters(['theta_max', 'load_torque']))
        assert [v.double_value for v in got.values] == [HI, 3.5]
        # Still serving with the old limits: 0.1 rad is out of them and is rejected, 0.11 is served.
        pub.publish(Float64(data=0.5))
        pub.publish(Float64(data=0.11))
        msg = js.wait_count(1)[0]
        assert msg.position[0] == state(0.11).gamma
        response = wait_future(client.set_parameters([Parameter('load_torque', value=1.25)]))
        assert response.results[0].successful
        pub.publish(Float64(data=0.11))
        assert tq.wait_count(2)[1].data * state(0.11).dgamma_dtheta == pytest.approx(1.25, rel=TOL)
        disconnect(ros, pub, js, tq)
        assert_clean_exit(proc, proc.stop(signal.SIGINT))
    finally:
        proc.kill()


def test_diagnostics_from_the_process_show_skipped_outputs(ros: RosSession) -> None:
    proc = start(ros, '-r', '__ns:=/proc_diag', '-p', 'diagnostics_period:=0.1')
    try:
        pub = ros.publisher(Float64, '/proc_diag/antenna_angle_cmd')
        js = ros.collect(JointState, '/proc_diag/joint_states')
        ros.wait_subscribers(pub)
        ros.wait_publishers(js)
        probes = [LO + (HI - LO) * (i + 0.5) / 600 for i in range(600)]
        sync_probe(lambda t: pub.publish(Float64(data=t)), [js], probes,
                   lambda col, msg, p: bool(msg.position[0] == state(p).gamma))
        diag = ros.collect(DiagnosticArray, '/diagnostics', 10)
        for c in (0.01, 0.02, math.inf):
            pub.publish(Float64(data=c))
        js.wait_count(2)
        name = 'proc_diag/fourbar_node: antenna tilt linkage'

        def has_inf(msg: DiagnosticArray) -> bool:
            return any(s.name == name and any(kv.key == 'commands_rejected_not_finite' and kv.value == '1'
                                               for kv in s.values) for s in msg.status)

        status = next(s for s in diag.wait_match(has_inf).status if s.name == name)
        values = {kv.key: kv.value for kv in status.values}
        received = int(values['commands_received'])
        # Nobody subscribed to input_torque or linkage_markers: they were skipped for every served command.
        assert int(values['input_torque_published']) == 0 and int(values['markers_published']) == 0
        assert int(values['input_torque_skipped']) == received - 1
        assert float(values['gamma_rad']) == state(0.02).gamma
        assert values['last_command_outcome'] == 'rejected_not_finite' and status.level == b'\x01'
        ros.uncollect(diag)
        disconnect(ros, pub, js)
        assert_clean_exit(proc, proc.stop(signal.SIGTERM))
    finally:
        proc.kill()


BAD_STARTS = [
    ('reducer_ratio: 500', 'reducer_ratio'),
    ('theta_max: 0.9', 'theta_max'),
    ('driven_rocker: both', 'driven_rocker'),
    ('coupler_length: .nan', 'coupler_length'),
]


def _error_line(ros: RosSession, *ros_args: str, env: dict[str, str] | None = None) -> str:
    """Start the node with ``--ros-args ROS_ARGS`` (in ``env``, else the session's); it must exit 2 with one stderr
    line, no traceback: that line."""
    proc = NodeProcess(['--ros-args', *ros_args], ros.env() if env is None else env)
    proc.start()
    try:
        status = proc.wait_exit()
    finally:
        proc.kill()
    lines = proc.stderr.strip().splitlines()
    assert status == 2 and len(lines) == 1 and 'Traceback' not in proc.stderr, (status, proc.stderr)
    return lines[0]


@pytest.mark.parametrize(('line', 'name'), BAD_STARTS)
def test_invalid_startup_parameters_exit_with_one_line(ros: RosSession, tmp_path: Path, line: str,
                                                       name: str) -> None:
    path = tmp_path / 'bad.yaml'
    text = YAML.read_text(encoding='utf-8').replace('/**:\n  ros__parameters:\n',
                                                    f'/**:\n  ros__parameters:\n    {line}\n', 1)
    if line.startswith(name + ':') and f'\n    {name}:' in YAML.read_text(encoding='utf-8'):
        text = '\n'.join(x for x in text.splitlines() if not (x.startswith(f'    {name}:') and x.strip() != line))
    path.write_text(text + '\n', encoding='utf-8')
    with pytest.raises(ConfigError) as loader:
        load_config(path)
    line = _error_line(ros, '--params-file', str(path))
    assert line.startswith(f'fourbar_node: error: {name}: ')
    assert f'{path}: {line.removeprefix("fourbar_node: error: ")}' == str(loader.value)


def test_unreadable_params_file_exits_with_one_line(ros: RosSession, tmp_path: Path) -> None:
    line = _error_line(ros, '--params-file', str(tmp_path / 'missing.yaml'))
    assert line.startswith('fourbar_node: error: ') and 'missing.yaml' in line


def test_malformed_params_file_exits_with_one_line(ros: RosSession, tmp_path: Path) -> None:
    path = tmp_path / 'broken.yaml'
    path.write_text('/**:\n  ros__parameters:\n    load_torque: [1.0\n', encoding='utf-8')
    assert _error_line(ros, '--params-file', str(path)).startswith(f'fourbar_node: error: {path}: not valid YAML')


def test_the_action_interface_without_control_msgs_exits_with_one_line(ros: RosSession, tmp_path: Path) -> None:
    stub = tmp_path / 'control_msgs'  # a control_msgs that cannot be imported, wherever one is installed
    stub.mkdir()
    (stub / '__init__.py').write_text("raise ImportError('no control_msgs here')\n", encoding='utf-8')
    env = ros.env()
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(tmp_path), env.get('PYTHONPATH', '')]))
    line = _error_line(ros, '-p', 'mode:=trajectory', '-p', 'trajectory_interface:=action', env=env)
    assert line.startswith('fourbar_node: error: trajectory_interface: action needs control_msgs'), line
    assert 'no control_msgs here' in line


def test_command_line_override_is_validated_too(ros: RosSession) -> None:
    line = _error_line(ros, '--params-file', str(YAML), '-p', 'theta_min:=0.5')
    assert line.startswith('fourbar_node: error: theta_min')  # 'theta_min, theta_max: ...'


def test_robot_wide_params_file_other_nodes_parameters_are_ignored(ros: RosSession, tmp_path: Path) -> None:
    """A ``/**`` section shared by a whole robot (robot_description etc.) starts the node; an unknown name in a
    section naming this node (a typo) is reported by a warning naming it; so is one given with ``-p``. The node
    must not refuse the file for another node's parameter (``robot_description: unknown parameter``, status 2)."""
    path = tmp_path / 'robot.yaml'
    text = YAML.read_text(encoding='utf-8').replace(
        '/**:\n  ros__parameters:\n',
        '/**:\n  ros__parameters:\n    robot_description: "<robot name=\'r\'/>"\n    publish_frequency: 50.0\n', 1)
    path.write_text(text + '\n/robot/fourbar_node:\n  ros__parameters:\n    frame_lenght: 0.18\n'
                    '/robot/other_node:\n  ros__parameters:\n    other_typo: 1\n', encoding='utf-8')
    proc = NodeProcess(['--ros-args', '--params-file', str(path), '-r', '__ns:=/robot', '-p', 'cli_typo:=2',
                        *ONE_JOINT_STATE_PER_COMMAND], ros.env())
    proc.start()
    try:
        pub, js, tq = connect(ros, proc, '/robot')
        pub.publish(Float64(data=0.05))
        assert js.wait_count(1)[0].position[0] == state(0.05).gamma
        disconnect(ros, pub, js, tq)
        assert_clean_exit(proc, proc.stop(signal.SIGTERM))
    finally:
        proc.kill()
    warnings = [line for line in proc.stderr.splitlines() if line.startswith('[WARN]')]
    assert any('frame_lenght: not a fourbar_node parameter; ignored' in w for w in warnings), proc.stderr
    assert any('cli_typo: not a fourbar_node parameter; ignored' in w for w in warnings), proc.stderr
    for silent in ('robot_description', 'publish_frequency', 'other_typo'):
        assert silent not in proc.stderr
