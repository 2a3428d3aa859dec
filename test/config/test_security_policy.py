"""The SROS2 policy (config/security/policy.xml): generated from the interface table, valid against sros2's schema
(Jazzy), every endpoint of every mode allowed in its direction and nothing else besides what an rclpy node needs;
only fourbar_node's actuator enclaves may command the drive; the nodes as created use nothing the policy does not
allow (the bringup's nodes as started: test/package/test_bringup_policy.py). Enforcement by the middleware is
tested where sros2 and the DDS security plugins are installed."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from support.colcon_support import ros2, ros2_cli_missing
from support.paths import REPO, TEST_DATA
from support.policy_rules import as_graph, enclaves, rules

from fourbar_ros.config.security import (
    BRINGUP_ENCLAVES,
    POLICY_FILE,
    RCLPY_PUBLISH,
    RCLPY_SERVICES,
    RCLPY_SUBSCRIBE,
    enclave,
    policy_xml,
)
from fourbar_ros.config.sim_actuator_params import NODE_NAME as SIM_NODE_NAME
from fourbar_ros.interface.topics import (
    BROADCASTER_JOINT_STATES,
    DEFAULT_CONTROLLER_MANAGER,
    MEASURED_JOINT_STATES,
    NODE_NAME,
    ROSOUT,
    Direction,
    Mode,
    activity_topic,
    every_endpoint,
    forward_topic,
    services,
    trajectory_action,
    trajectory_topic,
)
from fourbar_ros.node.controller_watch import activity_type

POLICY = REPO / POLICY_FILE
SCHEMA = TEST_DATA / 'sros2' / 'policy.xsd'
#: policy.xsd imports the xml: namespace's schema by this URL; the tests read a local stand-in instead.
XML_NAMESPACE_URL = 'http://www.w3.org/2001/03/xml.xsd'

def test_the_shipped_policy_is_the_generated_one_and_is_installed() -> None:
    assert POLICY.read_text(encoding='utf-8') == policy_xml('/')
    assert "(f'share/{PACKAGE}/config/security', glob('config/security/*.xml'))" in (
        REPO / 'setup.py').read_text(encoding='utf-8')


def test_the_policy_is_valid_against_sros2s_schema() -> None:
    from lxml import etree

    class Local(etree.Resolver):
        def resolve(self, url: str | None, pubid: str | None, context: object) -> object:
            if url == XML_NAMESPACE_URL:
                return self.resolve_filename(str(TEST_DATA / 'sros2' / 'xml_namespace.xsd'), context)
            return None

    parser = etree.XMLParser(no_network=True)
    parser.resolvers.add(Local())
    schema = etree.XMLSchema(etree.parse(str(SCHEMA), parser))
    for namespace in ('/', '/tilt'):
        document = etree.fromstring(policy_xml(namespace).encode())
        assert schema.validate(document), schema.error_log
    # The schema does refuse something: a topic list without a direction's qualifier value it knows.
    bad = etree.fromstring(policy_xml('/').replace('publish="ALLOW"', 'publish="MAYBE"', 1).encode())
    assert not schema.validate(bad)


@pytest.mark.parametrize('mode', list(Mode), ids=lambda m: m.value)
def test_every_endpoint_of_the_mode_is_allowed_in_its_direction_and_nothing_else(mode: Mode) -> None:
    policy = rules(POLICY.read_text(encoding='utf-8'))
    assert [node for (path, node) in policy if path == enclave(mode)] == [NODE_NAME]
    allowed = policy[enclave(mode), NODE_NAME]
    publish, subscribe = set(RCLPY_PUBLISH), set(RCLPY_SUBSCRIBE)
    for e in every_endpoint(mode):
        # The launch file remaps the measured joint to the broadcaster's topic: the name on the wire.
        name = BROADCASTER_JOINT_STATES.name if e.topic == MEASURED_JOINT_STATES else e.topic.name
        (publish if e.direction is Direction.OUT else subscribe).add(name)
    want = {'publish': publish, 'subscribe': subscribe,
            'reply': {*RCLPY_SERVICES, *(srv.name for srv in services(mode))}}
    if mode is Mode.TRAJECTORY:  # trajectory_interface: action
        want['call'] = {trajectory_action('joint_trajectory_controller')}
    assert allowed == want
    if mode is not Mode.OPEN_LOOP:
        assert activity_topic(DEFAULT_CONTROLLER_MANAGER).name in allowed['subscribe']


def test_only_fourbar_nodes_actuator_enclaves_may_command_the_drive() -> None:
    """Who holds an enclave that may publish to a controller's command topic or call its action is who may move
    the antenna: fourbar_node in an actuator mode, its own controller only; the controllers may only read them."""
    commands = {trajectory_topic('joint_trajectory_controller').name: Mode.TRAJECTORY,
                forward_topic('forward_position_controller').name: Mode.FORWARD,
                trajectory_action('joint_trajectory_controller'): Mode.TRAJECTORY}
    for (path, node), allowed in rules(POLICY.read_text(encoding='utf-8')).items():
        sent = (allowed.get('publish', set()) | allowed.get('call', set())) & set(commands)
        assert all(path == enclave(commands[c]) and node == NODE_NAME for c in sent), (path, node, sent)
    assert rules(POLICY.read_text(encoding='utf-8'))[BRINGUP_ENCLAVES['controller_manager'],
                                                     'joint_trajectory_controller']['execute'] == {
        '~/follow_joint_trajectory'}


def test_the_simulated_actuator_reads_the_controllers_and_writes_the_broadcasters_topic() -> None:
    policy = rules(POLICY.read_text(encoding='utf-8'))
    assert [node for (path, node) in policy if path == enclave(None)] == [SIM_NODE_NAME]
    assert policy[enclave(None), SIM_NODE_NAME] == {
        'publish': {*RCLPY_PUBLISH, BROADCASTER_JOINT_STATES.name, activity_topic(DEFAULT_CONTROLLER_MANAGER).name},
        'subscribe': {*RCLPY_SUBSCRIBE, trajectory_topic('joint_trajectory_controller').name,
                      forward_topic('forward_position_controller').name},
        'reply': set(RCLPY_SERVICES)}
    assert enclaves(POLICY.read_text(encoding='utf-8')) == {
        *(enclave(m) for m in (*Mode, None)), *BRINGUP_ENCLAVES.values()}


def test_another_namespace_and_controller_names_from_the_command_line() -> None:
    out = subprocess.run([sys.executable, '-m', 'fourbar_ros.config.security', '--namespace', 'tilt',
                          '--trajectory-controller', 'tilt_jtc', '--hardware-id', 'tilt_drive'], capture_output=True,
                         text=True, timeout=60, env={**os.environ, 'PYTHONPATH': str(REPO)}, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout == policy_xml('/tilt', 'tilt_jtc', hardware_id='tilt_drive')
    policy = rules(out.stdout, '/tilt')
    assert 'tilt_jtc/joint_trajectory' in policy[enclave(Mode.TRAJECTORY), NODE_NAME]['publish']
    assert '~/joint_trajectory' in policy[BRINGUP_ENCLAVES['controller_manager'], 'tilt_jtc']['subscribe']
    assert (BRINGUP_ENCLAVES['controller_manager'], 'tilt_drive') in policy


# --------------------------------------------------------------------------- the nodes as created

def _used(node: object) -> dict[str, set[str]]:
    """The node's topics and services, resolved; ``/rosout`` too (rcl's logging publisher is not an rclpy
    Publisher, so the node's ``publishers`` list leaves it out)."""
    resolve = node.resolve_service_name  # type: ignore[attr-defined]
    return {'publish': {p.topic_name for p in node.publishers} | {'/rosout'},  # type: ignore[attr-defined]
            'subscribe': {s.topic_name for s in node.subscriptions},  # type: ignore[attr-defined]
            'reply': {resolve(s.srv_name) for s in node.services}}  # type: ignore[attr-defined]


@pytest.fixture(params=[*Mode, None], ids=lambda m: 'sim_actuator' if m is None else m.value)
def created(request: pytest.FixtureRequest, ros: object) -> Iterator[tuple[Mode | None, object]]:
    """fourbar_node in a mode (None: the simulated actuator) as the launch file starts it: the measured joint
    remapped, on sim time (so the /clock subscription exists too); in the actuator modes with the optional antenna
    sensor on (the policy allows what a parameter may turn on)."""
    from rclpy.parameter import Parameter

    from fourbar_ros.node.fourbar_node import FourBarNode
    from fourbar_ros.node.sim_actuator import SimActuator

    mode: Mode | None = request.param
    ns = f'/policy_{"sim" if mode is None else mode.value}'
    args = ['--ros-args', '-p', 'use_sim_time:=true']
    if mode is None:
        node = SimActuator(context=ros.context, namespace=ns,  # type: ignore[attr-defined]
                           cli_args=[*args, '--params-file', str(REPO / 'config' / 'antenna.yaml')])
    else:
        node = FourBarNode(context=ros.context, namespace=ns,  # type: ignore[attr-defined]
                           parameter_overrides=[Parameter('mode', value=mode.value),
                                                Parameter('antenna_sensor_type',
                                                          value='none' if mode is Mode.OPEN_LOOP else 'float64')],
                           cli_args=[*args, '-r', f'{MEASURED_JOINT_STATES.name}:={BROADCASTER_JOINT_STATES.name}'])
    try:
        yield mode, node
    finally:
        node.destroy_node()


@pytest.mark.ros
def test_the_nodes_use_exactly_what_their_enclave_allows(created: tuple[Mode | None, object]) -> None:
    mode, node = created
    ns, name = node.get_namespace(), node.get_name()  # type: ignore[attr-defined]
    assert name == (SIM_NODE_NAME if mode is None else NODE_NAME)
    allowed = rules(policy_xml(ns), ns)[enclave(mode), name]
    allowed.pop('call', None)  # the action: only with trajectory_interface: action (the bringup's test has it)
    if activity_type()[0] is None:  # without controller_manager_msgs neither watches nor says a manager's activity
        for k in ('publish', 'subscribe'):
            allowed[k].discard(activity_topic(DEFAULT_CONTROLLER_MANAGER).name)
        if mode is not None:  # nor reads the manager's log
            allowed['subscribe'].discard(ROSOUT.name)
    want = as_graph(allowed, ns, name)
    del want['request']
    assert _used(node) == want


# --------------------------------------------------------------------------- enforcement

def _security_missing() -> str | None:
    if (why := ros2_cli_missing()) is not None:
        return why
    probe = subprocess.run([ros2(), 'security', '--help'], capture_output=True, text=True, timeout=120, check=False)
    if probe.returncode != 0:
        return 'sros2 (`ros2 security`) is not installed'
    return None


@pytest.mark.ros
def test_enforcement_lets_the_open_loop_enclave_run_only_open_loop(tmp_path: Path) -> None:
    """With ROS_SECURITY_STRATEGY=Enforce, fourbar_node starts in open_loop with the open_loop enclave, and the same
    enclave cannot start it in trajectory mode (its publisher to the controller is refused)."""
    if (why := _security_missing()) is not None:
        pytest.skip(why)
    keystore = tmp_path / 'keystore'

    def security(*args: str) -> None:
        out = subprocess.run([ros2(), 'security', *args], capture_output=True, text=True, timeout=120, check=False)
        assert out.returncode == 0, out.stderr

    security('create_keystore', str(keystore))
    security('create_enclave', str(keystore), enclave(Mode.OPEN_LOOP))
    security('create_permission', str(keystore), enclave(Mode.OPEN_LOOP), str(POLICY))
    env = {**os.environ, 'ROS_SECURITY_ENABLE': 'true', 'ROS_SECURITY_STRATEGY': 'Enforce',
           'ROS_SECURITY_KEYSTORE': str(keystore), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}

    def start(mode: Mode) -> subprocess.CompletedProcess[str]:
        # A node that starts runs until the timeout; one refused by the middleware exits at once.
        code = ('import sys, rclpy\nfrom rclpy.parameter import Parameter\n'
                'from fourbar_ros.node.fourbar_node import FourBarNode\n'
                'rclpy.init(args=sys.argv)\n'
                'node = FourBarNode(parameter_overrides=[Parameter("mode", value=sys.argv[1])])\n'
                'print("started", flush=True)\n')
        return subprocess.run([sys.executable, '-c', code, mode.value, '--ros-args', '--enclave',
                               enclave(Mode.OPEN_LOOP)], capture_output=True, text=True, timeout=120, env=env,
                              check=False)

    allowed = start(Mode.OPEN_LOOP)
    if 'started' not in allowed.stdout and 'security' in allowed.stderr.lower():
        pytest.skip(f'the middleware has no DDS security plugins: {allowed.stderr.strip().splitlines()[-1]}')
    assert 'started' in allowed.stdout, allowed.stderr
    refused = start(Mode.TRAJECTORY)
    assert 'started' not in refused.stdout and refused.returncode != 0
