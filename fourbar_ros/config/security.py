"""The SROS2 permissions policy of the package's nodes and its bringup: who may move the antenna. No ROS import.

fourbar_node's profiles come from its interface table (``interface.topics.every_endpoint``), the bringup's from what
ros2_control and robot_state_publisher use; sros2's policy format 0.2.0; the enclaves and how to use them:
docs/how-to/security.md."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from xml.sax.saxutils import escape, quoteattr

from fourbar_ros.config.params import PARAMETERS_BY_NAME
from fourbar_ros.config.sim_actuator_params import NODE_NAME as SIM_NODE_NAME
from fourbar_ros.interface.topics import (
    BROADCASTER_JOINT_STATES,
    DEFAULT_CONTROLLER_MANAGER,
    DEFAULT_FORWARD_CONTROLLER,
    DEFAULT_TRAJECTORY_CONTROLLER,
    JOINT_STATES,
    MEASURED_JOINT_STATES,
    NODE_NAME,
    Direction,
    Mode,
    activity_topic,
    every_endpoint,
    forward_topic,
    services,
    trajectory_action,
    trajectory_topic,
)

__all__ = ['BRINGUP_ENCLAVES', 'ENCLAVE_ROOT', 'LAUNCH_REMAPPINGS', 'POLICY_FILE', 'RCLPY_PUBLISH', 'RCLPY_SERVICES',
           'RCLPY_SUBSCRIBE', 'Profile', 'bringup_profiles', 'enclave', 'policy_xml', 'profiles']

#: The shipped policy, inside share/fourbar_ros (the root namespace, the default controller names).
POLICY_FILE = 'config/security/policy.xml'
#: The enclaves' common prefix: ``/fourbar_ros/fourbar_node/<mode>``, ``/fourbar_ros/sim_actuator`` and the
#: bringup's (BRINGUP_ENCLAVES).
ENCLAVE_ROOT = '/fourbar_ros'
#: The version of sros2's policy format.
POLICY_VERSION = '0.2.0'

#: What every node (rclpy and rclcpp, Jazzy) writes: its log and its parameter events.
RCLPY_PUBLISH = ('/parameter_events', '/rosout')
#: What every node may read: the clock, with ``use_sim_time``.
RCLPY_SUBSCRIBE = ('/clock',)
#: The services every node (Jazzy) offers: parameters and ``~/get_type_description``
#: (``start_type_description_service``, on by default).
RCLPY_SERVICES = ('~/describe_parameters', '~/get_parameter_types', '~/get_parameters', '~/get_type_description',
                  '~/list_parameters', '~/set_parameters', '~/set_parameters_atomically')
#: The launch file's remappings of the node's topics (an actuator mode reads the broadcaster's joint states).
LAUNCH_REMAPPINGS = {MEASURED_JOINT_STATES.name: BROADCASTER_JOINT_STATES.name}

#: The hardware component's name unless given: the ``hardware_id`` parameter's default.
DEFAULT_HARDWARE_ID = str(PARAMETERS_BY_NAME['hardware_id'].default)
#: The other processes of the launch file's bringup: their enclaves (an enclave is a process's: the controller
#: manager's holds its hardware components' and controllers' nodes too).
BRINGUP_ENCLAVES = {'controller_manager': f'{ENCLAVE_ROOT}/controller_manager',
                    'spawner': f'{ENCLAVE_ROOT}/spawner',
                    'robot_state_publisher': f'{ENCLAVE_ROOT}/robot_state_publisher'}
#: What the nodes of ros2_control (controller_manager 4.46, ros2_controllers 4.42) and robot_state_publisher
#: (Jazzy) use besides the common ones, as a running bringup shows them (the tests compare): rclcpp nodes also
#: read their parameter events, and ros2_control's serve their logger levels.
_RCLCPP_SUBSCRIBE = ('/clock', '/parameter_events')
_LOGGER_SERVICES = ('~/get_logger_levels', '~/set_logger_levels')
_MANAGER_SERVICES = ('~/cleanup_controller', '~/configure_controller', '~/list_controller_types',
                     '~/list_controllers', '~/list_hardware_components', '~/list_hardware_interfaces',
                     '~/load_controller', '~/reload_controller_libraries', '~/set_hardware_component_state',
                     '~/switch_controller', '~/unload_controller')
_MANAGER_PUBLISH = ('/diagnostics', '~/activity', '~/introspection_data/full', '~/introspection_data/names',
                    '~/introspection_data/values', '~/statistics/full', '~/statistics/names', '~/statistics/values')
#: What the launch file's spawners call (spawner 4.46 with a controller name and ``--controller-manager`` only).
_SPAWNER_CALLS = ('list_controllers', 'load_controller', 'configure_controller', 'switch_controller')


@dataclass(frozen=True)
class Profile:
    """One node's permissions in one enclave: the topics it publishes and subscribes to, the services it serves
    and calls, the actions it calls and serves (sorted, names as the node resolves them after the launch file's
    remappings; relative ones in the profile's namespace, ``~/`` the node's own)."""

    enclave: str
    node: str
    publish: tuple[str, ...]
    subscribe: tuple[str, ...]
    services: tuple[str, ...] = RCLPY_SERVICES
    calls: tuple[str, ...] = ()
    action_calls: tuple[str, ...] = ()
    action_serves: tuple[str, ...] = ()


def enclave(mode: Mode | None) -> str:
    """The enclave of fourbar_node in ``mode``, or of the simulated actuator (None)."""
    return f'{ENCLAVE_ROOT}/{SIM_NODE_NAME}' if mode is None else f'{ENCLAVE_ROOT}/{NODE_NAME}/{mode.value}'


def profiles(trajectory_controller: str = DEFAULT_TRAJECTORY_CONTROLLER,
             forward_controller: str = DEFAULT_FORWARD_CONTROLLER) -> tuple[Profile, ...]:
    """fourbar_node's profile in each mode, then the simulated actuator's."""
    out = []
    for mode in Mode:
        publish, subscribe = set(RCLPY_PUBLISH), set(RCLPY_SUBSCRIBE)
        for e in every_endpoint(mode, trajectory_controller, forward_controller):
            name = LAUNCH_REMAPPINGS.get(e.topic.name, e.topic.name)
            (publish if e.direction is Direction.OUT else subscribe).add(name)
        actions = (trajectory_action(trajectory_controller),) if mode is Mode.TRAJECTORY else ()
        served = tuple(sorted({*RCLPY_SERVICES, *(srv.name for srv in services(mode))}))
        out.append(Profile(enclave(mode), NODE_NAME, tuple(sorted(publish)), tuple(sorted(subscribe)), served,
                           action_calls=actions))
    sim_in = {trajectory_topic(trajectory_controller).name, forward_topic(forward_controller).name}
    sim_out = {*RCLPY_PUBLISH, BROADCASTER_JOINT_STATES.name, activity_topic(DEFAULT_CONTROLLER_MANAGER).name}
    out.append(Profile(enclave(None), SIM_NODE_NAME, tuple(sorted(sim_out)),
                       tuple(sorted({*RCLPY_SUBSCRIBE, *sim_in}))))
    return tuple(out)


def bringup_profiles(trajectory_controller: str = DEFAULT_TRAJECTORY_CONTROLLER,
                     forward_controller: str = DEFAULT_FORWARD_CONTROLLER,
                     hardware_id: str = DEFAULT_HARDWARE_ID) -> tuple[Profile, ...]:
    """The launch file's other nodes with ``use_ros2_control:=true``: the controller manager with its hardware
    component ``hardware_id`` and its controllers (one process, one enclave), the spawners, robot_state_publisher."""
    manager, spawner, rsp = (BRINGUP_ENCLAVES[k] for k in ('controller_manager', 'spawner', 'robot_state_publisher'))
    own = (*RCLPY_SERVICES, *_LOGGER_SERVICES)

    def controller(name: str, publish: tuple[str, ...], subscribe: tuple[str, ...] = (), services: tuple[str, ...] = (),
                   serves: tuple[str, ...] = ()) -> Profile:
        return Profile(manager, name, tuple(sorted({*RCLPY_PUBLISH, '~/transition_event', *publish})),
                       tuple(sorted({*_RCLCPP_SUBSCRIBE, *subscribe})), tuple(sorted({*own, *services})),
                       action_serves=serves)
    out = [
        Profile(manager, DEFAULT_CONTROLLER_MANAGER, tuple(sorted({*RCLPY_PUBLISH, *_MANAGER_PUBLISH})),
                tuple(sorted({*_RCLCPP_SUBSCRIBE, 'robot_description'})), tuple(sorted({*own, *_MANAGER_SERVICES}))),
        Profile(manager, hardware_id, RCLPY_PUBLISH, _RCLCPP_SUBSCRIBE, tuple(sorted(own))),
        controller('joint_state_broadcaster', ('~/dynamic_joint_states', '~/joint_states')),
        controller(trajectory_controller, ('~/controller_state',), ('~/joint_trajectory', '~/speed_scaling_input'),
                   ('~/query_state',), ('~/follow_joint_trajectory',)),
        controller(forward_controller, (), ('~/commands',)),
    ]
    calls = tuple(f'{DEFAULT_CONTROLLER_MANAGER}/{c}' for c in sorted(_SPAWNER_CALLS))
    for name in ('joint_state_broadcaster', trajectory_controller, forward_controller):
        out.append(Profile(spawner, f'spawner_{name}', RCLPY_PUBLISH, RCLPY_SUBSCRIBE, calls=calls))
    out.append(Profile(rsp, 'robot_state_publisher', tuple(sorted({*RCLPY_PUBLISH, '/tf', '/tf_static',
                                                                    'robot_description'})),
                       tuple(sorted({*_RCLCPP_SUBSCRIBE, JOINT_STATES.name}))))
    return tuple(out)


def _list(tag: str, item: str, qualifiers: str, names: Sequence[str]) -> list[str]:
    if not names:  # sros2's schema wants one item or more
        return []
    return [f'          <{tag} {qualifiers}>', *(f'            <{item}>{escape(n)}</{item}>' for n in names),
            f'          </{tag}>']


def policy_xml(namespace: str = '/', trajectory_controller: str = DEFAULT_TRAJECTORY_CONTROLLER,
               forward_controller: str = DEFAULT_FORWARD_CONTROLLER, hardware_id: str = DEFAULT_HARDWARE_ID) -> str:
    """The policy (XML text) for the nodes in ``namespace`` with these controller names and hardware component."""
    ns = '/' + namespace.strip().strip('/')
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             '<!-- SROS2 permissions of fourbar_ros\'s nodes and its launch file\'s ros2_control bringup, generated',
             '     by fourbar_ros.config.security: one enclave per node and mode, one per other process. -->',
             f'<policy version="{POLICY_VERSION}">', '  <enclaves>']
    by_enclave: dict[str, list[Profile]] = {}
    for p in (*profiles(trajectory_controller, forward_controller),
              *bringup_profiles(trajectory_controller, forward_controller, hardware_id)):
        by_enclave.setdefault(p.enclave, []).append(p)
    for path, group in by_enclave.items():
        lines += [f'    <enclave path={quoteattr(path)}>', '      <profiles>']
        for p in group:
            lines.append(f'        <profile ns={quoteattr(ns)} node={quoteattr(p.node)}>')
            lines += _list('topics', 'topic', 'publish="ALLOW"', p.publish)
            lines += _list('topics', 'topic', 'subscribe="ALLOW"', p.subscribe)
            lines += _list('services', 'service', 'reply="ALLOW"', p.services)
            lines += _list('services', 'service', 'request="ALLOW"', p.calls)
            lines += _list('actions', 'action', 'call="ALLOW"', p.action_calls)
            lines += _list('actions', 'action', 'execute="ALLOW"', p.action_serves)
            lines.append('        </profile>')
        lines += ['      </profiles>', '    </enclave>']
    lines += ['  </enclaves>', '</policy>', '']
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the policy: ``python3 -m fourbar_ros.config.security [--namespace NS] [--trajectory-controller NAME]
    [--forward-controller NAME] [--hardware-id NAME]``."""
    parser = argparse.ArgumentParser(prog='python3 -m fourbar_ros.config.security',
                                     description='print the SROS2 policy of fourbar_ros\'s nodes and bringup')
    parser.add_argument('--namespace', default='/', help='the nodes\' namespace (default: /)')
    parser.add_argument('--trajectory-controller', default=DEFAULT_TRAJECTORY_CONTROLLER)
    parser.add_argument('--forward-controller', default=DEFAULT_FORWARD_CONTROLLER)
    parser.add_argument('--hardware-id', default=DEFAULT_HARDWARE_ID,
                        help='the hardware component (the hardware_id parameter; default: %(default)s)')
    args = parser.parse_args(argv)
    sys.stdout.write(policy_xml(args.namespace, args.trajectory_controller, args.forward_controller,
                                args.hardware_id))
    return 0


if __name__ == '__main__':
    sys.exit(main())
