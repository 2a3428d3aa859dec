"""`fourbar demo` (the README's main job) end to end: fourbar_node in trajectory mode and the simulated actuator
as processes, paced replay of the bundled sweep, recording, summary (checked against the recorded bag), PNG; it
finishes by itself and leaves no node behind, also when interrupted."""

from __future__ import annotations

import contextlib
import importlib.util
import math
import os
import re
import signal
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from support.bag_support import CONFIG, DEMO_BAG, Tool
from support.colcon_support import CliEnv, ros2
from support.ros_support import DomainLease, lease_domain_id, wait_for

from fourbar_ros.analysis.demo import DRIVE_EFFORT
from fourbar_ros.bags.storage import read_commands, read_messages
from fourbar_ros.config.antenna_config import AntennaConfig, load_config
from fourbar_ros.config.robot_model import driven_angle
from fourbar_ros.interface.stamps import seconds_to_ns
from fourbar_ros.interface.topics import BROADCASTER_JOINT_STATES, trajectory_topic
from fourbar_ros.live.node_process import domain_in_use
from fourbar_ros.rules.simulated_drive import effort_at
from fourbar_ros.rules.takeover import ARRIVAL_MARGIN_S

pytestmark = [pytest.mark.ros, pytest.mark.slow]
#: The plant's drive torque at rest against the load model's (relative): docs/how-to/mujoco-plant.md measures at
#: most 5.3e-6 over the plant tests' cases (the soft closure); the next decade up, as the simulated drive's tests.
REST_EFFORT_REL = 1e-5


def _env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'}


@dataclass(frozen=True)
class DemoRun:
    """One `fourbar demo` run to the end with no arguments, started outside the checkout on an exported
    ROS_DOMAIN_ID: its domain, working directory and stdout, and its output directory (the default)."""

    domain_id: int
    cwd: Path
    stdout: str
    stderr: str

    @property
    def out(self) -> Path:
        return self.cwd / 'out' / 'demo'


@pytest.fixture(scope='module')
def demo_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[DemoRun]:
    """The demo run once for the module's checks (it takes about 20 s), on a domain leased for the module.

    No --params, --bag, --out or --domain-id: the defaults come from the source tree (this environment does not
    index fourbar_ros: no AMENT_PREFIX_PATH), the output goes below the directory it was started in, and the domain
    is the exported ROS_DOMAIN_ID (so a user's other terminals see its topics), said in its first line."""
    lease = lease_domain_id()
    try:
        cwd = tmp_path_factory.mktemp('anywhere')
        env = {k: v for k, v in _env().items() if k != 'AMENT_PREFIX_PATH'}
        with Tool(['demo'], {**env, 'ROS_DOMAIN_ID': str(lease.domain_id)}, cwd=cwd) as demo:
            rc = demo.wait(300.0)  # a deadline against hangs; killed with its process group then
            assert rc == 0, demo.lines
            stdout, stderr = demo.stdout, demo.stderr
        yield DemoRun(lease.domain_id, cwd, stdout, stderr)
    finally:
        lease.release()


def test_demo_runs_to_the_end_on_the_exported_domain(demo_run: DemoRun) -> None:
    stdout, out = demo_run.stdout, demo_run.out
    assert not domain_in_use(demo_run.domain_id)  # both node processes are gone
    first = stdout.splitlines()[0]
    assert f' on ROS_DOMAIN_ID {demo_run.domain_id} (from ROS_DOMAIN_ID; this host only); ' in first, first
    lines = {line.split()[0]: line for line in stdout.splitlines() if line.strip()}
    for key in ('command', 'tracking', 'speed', 'torque', 'margin', 'effort', 'counts', 'check', 'replay', 'plot'):
        assert key in lines, stdout
    n = len(read_commands(DEMO_BAG))
    assert lines['command'].startswith(f'command  -6.0000 deg .. +7.0000 deg ({n} served of {n} sent; 0 rejected')
    assert f'{n} received' in lines['command']
    # The node's completion and the demo's check make the identical scalar core calls on the same float measurement
    # (float64 crosses CDR and the bag unchanged): exactly 0, over every completed measurement (none unpaired).
    deviations = [float(x) for x in re.findall(r'= ([0-9.e+-]+) ', lines['check'])]
    assert deviations == [0.0, 0.0] and '(0 unpaired)' in lines['check'], lines['check']
    found = re.findall(r'antenna_angle: ([0-9]+) of ([0-9]+) equal', lines['check'])
    assert found and found[0][0] == found[0][1], lines['check']  # every antenna_angle is a measurement's completion
    png = out / 'demo.png'
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 20_000

    # The summary's figures against the recorded bag, read here without the demo's analysis.
    cfg = load_config(CONFIG)
    recorded = read_messages(out / 'outputs')
    commands = [m.data for _, m in recorded['/antenna_angle_cmd']]
    assert len(commands) == n
    angles = [m.data for _, m in recorded['/antenna_angle']]
    final = commands[-1] - angles[-1]
    # The run ends once the measured antenna angle has settled within the trajectory tolerance of the last command.
    logs = '\n'.join(f'{name}: ...{(out / name).read_text(encoding="utf-8", errors="replace")[-2000:]}'
                     for name in ('node.log', 'sim_actuator.log') if (out / name).exists())
    assert abs(final) <= cfg.trajectory_tolerance, f'{stdout}\n{demo_run.stderr[-3000:]}\n{logs}'
    printed = float(re.findall(r'tracking final (\S+) rad', lines['tracking'])[0])
    assert printed == pytest.approx(final, rel=5e-3, abs=1e-300)  # printed to 3 significant digits
    limit = cfg.motor_speed_limit / cfg.reducer_ratio
    measured = [m for _, m in recorded[f'/{BROADCASTER_JOINT_STATES.name}'] if list(m.name) == [cfg.driven_joint]]
    complete = [m for _, m in recorded['/joint_states']]
    assert complete and all(list(m.name) == [cfg.driven_joint, cfg.delta_joint, cfg.coupler_joint] for m in complete)
    # No measured speed over the limit: the lag drive's own limit, or the plant's servo command moving at most the
    # limit, which its rotor follows no faster (the load's slope dT/dq > 0 over this range only stiffens the servo).
    assert measured and max(abs(m.velocity[0]) for m in measured) <= limit
    points = [p for _, m in recorded[f'/{cfg.trajectory_controller}/joint_trajectory'] for p in m.points]
    assert points and max(abs(p.velocities[0]) for p in points) <= limit  # no planned point over the limit
    margin = float(re.findall(r'margin (-?[0-9.]+)%', lines['speed'])[0])
    assert 0.0 <= margin < 100.0
    counts = lines['counts']
    assert f'{len(measured)} measured joint_states' in counts and f'{len(angles)} antenna_angle' in counts
    _check_effort_line(lines['effort'], cfg)


def _check_effort_line(line: str, cfg: AntennaConfig) -> None:
    """The measured effort against the node's input_torque. At rest at the command (speed at most REST_SPEED, the
    antenna within trajectory_tolerance of it) both are the static torque the linkage needs: the plant's reducer
    torque is the load model's within its soft constraints (REST_EFFORT_REL; the lag drive's is the load model's
    exactly), at an antenna angle at most trajectory_tolerance from the commanded one, so they differ by at most
    REST_EFFORT_REL max|T| + max|dT/dtheta| trajectory_tolerance. (The hinges' damping at REST_SPEED, 1e-8 N m, lies
    within REST_EFFORT_REL's margin over the 5.3e-6 measured.) In motion the difference is the load's change over
    the tracking lag plus the linkage's inertia, which the node's static prediction leaves out: counted, not
    bounded."""
    drive = 'mujoco' if importlib.util.find_spec('mujoco') is not None else 'lag'
    assert line.endswith(f'; drive {drive}: {DRIVE_EFFORT[drive]})'), line
    found = re.findall(r'at rest (\S+) N m over ([0-9]+) measurements, in motion (\S+) N m over ([0-9]+) \((\S+) N m '
                       'off the load model', line)
    assert found, line
    rest, n_rest, motion, n_motion, model = (float(found[0][0]), int(found[0][1]), float(found[0][2]),
                                             int(found[0][3]), float(found[0][4]))
    # The run starts at rest at the first command and ends settled at the last; it moves in between.
    assert n_rest > 0 and n_motion > 0 and math.isfinite(motion) and math.isfinite(model), line
    if drive == 'lag':  # its effort is the load model's at its position, the measured one (no noise, no encoder)
        assert model == 0.0, line
    theta = np.linspace(cfg.theta_min, cfg.theta_max, 2001)
    torque = np.array([effort_at(cfg, driven_angle(cfg, float(t))) for t in theta])
    # The largest slope of a grid this fine, 1.01 times (the torque's curvature between grid points adds far less).
    slope = 1.01 * float(np.max(np.abs(np.diff(torque) / np.diff(theta))))
    bound = REST_EFFORT_REL * float(np.max(np.abs(torque))) + slope * cfg.trajectory_tolerance
    assert rest <= bound, (line, bound)


def test_demo_records_each_trajectory_after_its_first_point_is_due(demo_run: DemoRun) -> None:
    """Each stamped actuator trajectory's first point is due at most ARRIVAL_MARGIN_S after the node's time of
    sending it (it starts at the running motion's point the node's now fell in, or at the measured state
    ARRIVAL_MARGIN_S ahead), so its receive time in the recording (the middleware's, on the same host's system
    clock) is not earlier than that before it. How late it arrives is the machine's load and is not asserted; that
    the replay keeps the recording's executor running while it waits for acknowledgements is
    test/live/test_replay_acks.py's."""
    cfg = load_config(CONFIG)
    topic = f'/{trajectory_topic(cfg.trajectory_controller).name}'
    lags = []
    for log, msg in read_messages(demo_run.out / 'outputs', [topic])[topic]:
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        if stamp:
            first = msg.points[0].time_from_start
            lags.append(log - stamp - first.sec * 10**9 - first.nanosec)
    assert len(lags) > 100, f'{len(lags)} stamped trajectories recorded'
    early = [i for i, lag in enumerate(lags) if lag < -seconds_to_ns(ARRIVAL_MARGIN_S)]
    assert not early, (f'{len(early)} of {len(lags)} stamped trajectories received more than ARRIVAL_MARGIN_S '
                       f'before their first point was due, e.g. trajectory {early[0]}: '
                       f'{-lags[early[0]] * 1e-6:.3f} ms before')


def _nodes(pid: int) -> list[int]:
    """The child processes of ``pid`` that run fourbar_node or the simulated actuator (exec'd, not merely forked;
    Linux's /proc)."""
    found: list[int] = []
    try:
        children = Path(f'/proc/{pid}/task/{pid}/children').read_text().split()
    except OSError:  # the demo itself has exited
        return found
    for child in children:
        with contextlib.suppress(OSError):
            cmdline = Path(f'/proc/{child}/cmdline').read_bytes()
            if any(name in cmdline for name in (b'fourbar_node', b'fourbar_sim_actuator', b'fourbar_ros.node')):
                found.append(int(child))
    return found


@pytest.mark.parametrize('when', ['starting', 'node_started', 'replaying'])
def test_demo_interrupted_cleans_up(when: str, lease: DomainLease, tmp_path: Path) -> None:
    out = tmp_path / 'demo'
    nodes: list[int] = []
    with Tool(['demo', '--params', CONFIG, '--out', out, '--domain-id', str(lease.domain_id)], _env()) as demo:
        if when == 'starting':
            first = demo.wait_line('fourbar demo: fourbar_node (mode trajectory)', 60.0, stdout=True)  # not yet
            assert f' on ROS_DOMAIN_ID {lease.domain_id} (--domain-id; this host only); ' in first, first
        elif when == 'node_started':  # the processes exist; the demo is still setting up its own rclpy
            wait_for(lambda: bool(_nodes(demo.proc.pid)) or demo.proc.poll() is not None, 60.0, 'the node process')
            nodes = _nodes(demo.proc.pid)
        else:
            demo.wait_line('are up; replaying paced', 60.0)
        demo.signal(signal.SIGINT)
        assert demo.wait(60.0) == 130, demo.lines
    # Both node processes are gone (a node still starting holds no discovery port yet: check the pids too).
    assert not domain_in_use(lease.domain_id)
    assert not [pid for pid in nodes if Path(f'/proc/{pid}').exists()], nodes
    if (out / 'outputs').exists():  # interrupted after the recording was complete (while plotting)
        assert len(read_messages(out / 'outputs')['/antenna_angle_cmd']) == len(read_commands(DEMO_BAG))


def test_demo_bad_params_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / 'bad.yaml'
    bad.write_text(CONFIG.read_text().replace('theta_max: 0.', 'theta_max: 1.'))
    with Tool(['demo', '--params', bad, '--out', tmp_path / 'demo'], _env()) as demo:
        assert demo.wait(60.0) == 2
    assert len(demo.lines) == 1 and demo.lines[0].startswith('fourbar demo: error: ')
    assert not (tmp_path / 'demo').exists()


def test_demo_with_no_arguments_from_another_directory(demo_run: DemoRun) -> None:
    """The defaults are the source tree's parameters and bag; the output, and only it, is below the directory the
    demo was started in."""
    if (Path(sys.prefix) / 'share' / 'fourbar_ros').exists():
        pytest.skip('fourbar_ros is installed into this environment\'s share/ (not an editable install)')
    first = demo_run.stdout.splitlines()[0]
    assert first.startswith('fourbar demo: fourbar_node (mode trajectory) and the simulated actuator with '
                            f'{CONFIG} on ROS_DOMAIN_ID '), first
    assert f'replaying {len(read_commands(DEMO_BAG))} commands from {DEMO_BAG}, one every ' in first, first
    assert os.listdir(demo_run.cwd) == ['out'] and sorted(os.listdir(demo_run.cwd / 'out')) == ['demo']


def test_ros2_run_demo_uses_the_installed_share(ros2_cli: CliEnv,
                                                tmp_path_factory: pytest.TempPathFactory) -> None:
    """`ros2 run fourbar_ros fourbar demo` over a colcon install, from an empty directory, with no arguments: it
    takes the installed share's parameters and bag, and Ctrl-C (to the terminal's process group) once it replays
    ends it with 130 and no traceback (the run to the end from these defaults is the test above)."""
    share = ros2_cli.prefix / 'share' / 'fourbar_ros'
    env = {k: v for k, v in ros2_cli.env.items() if k != 'ROS_DOMAIN_ID'}  # the demo leases its own free id
    cwd = tmp_path_factory.mktemp('anywhere')
    with Tool(['run', 'fourbar_ros', 'fourbar', 'demo'], env, command=[ros2()], cwd=cwd) as demo:
        first = demo.wait_line('fourbar demo: fourbar_node (mode trajectory)', 60.0, stdout=True)
        demo.wait_line('are up; replaying paced', 60.0)
        demo.signal(signal.SIGINT, group=True)
        assert demo.wait(60.0) == 130, demo.lines
    params, bag = share / 'config' / 'antenna.yaml', share / 'bags' / 'demo_sweep'
    assert first.startswith(f'fourbar demo: fourbar_node (mode trajectory) and the simulated actuator with {params} '
                            'on ROS_DOMAIN_ID '), first
    assert f'replaying {len(read_commands(bag))} commands from {bag}, one every ' in first, first
    assert not [line for line in demo.lines if 'Traceback' in line], demo.lines
    assert os.listdir(cwd) == ['out']
