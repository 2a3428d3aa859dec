"""The SROS2 permissions policy of the package's nodes: who may move the antenna.

Generated from the interface table (``interface.every_endpoint``: with what a parameter may turn on), so the policy
and the topics the nodes use cannot drift apart. One enclave per node and mode: ``fourbar_node`` in ``open_loop``
may not write to any controller, in ``trajectory`` only to ``<trajectory_controller>/joint_trajectory``, in
``forward`` only to ``<forward_controller>/commands``; ``sim_actuator`` reads both controllers' topics and writes
the broadcaster's joint states. Besides a node's own topics, each profile allows what every rclpy node needs: its
parameter and type-description services, ``/rosout``, ``/parameter_events`` (publish) and ``/clock``
(``use_sim_time``).

Topic names are as the launch file remaps them (``measured_joint_states`` is read on
``joint_state_broadcaster/joint_states``). ``config/security/policy.xml`` is ``policy_xml()`` for the root
namespace; for another one::

    python3 -m fourbar_ros.config.security --namespace /tilt > policy.xml

The format is sros2's policy format 0.2.0 (``sros2/policy/schemas/policy.xsd``); ``ros2 security
create_permission`` turns it into DDS permissions. No ROS import.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from xml.sax.saxutils import escape, quoteattr

from fourbar_ros.config.sim_actuator_params import NODE_NAME as SIM_NODE_NAME
from fourbar_ros.interface.topics import (
    BROADCASTER_JOINT_STATES,
    DEFAULT_FORWARD_CONTROLLER,
    DEFAULT_TRAJECTORY_CONTROLLER,
    MEASURED_JOINT_STATES,
    NODE_NAME,
    Direction,
    Mode,
    every_endpoint,
    forward_topic,
    trajectory_topic,
)

__all__ = ['ENCLAVE_ROOT', 'LAUNCH_REMAPPINGS', 'POLICY_FILE', 'RCLPY_PUBLISH', 'RCLPY_SERVICES', 'RCLPY_SUBSCRIBE',
           'Profile', 'enclave', 'policy_xml', 'profiles']

#: The shipped policy, inside share/fourbar_ros (the root namespace, the default controller names).
POLICY_FILE = 'config/security/policy.xml'
#: The enclaves' common prefix: ``/fourbar_ros/fourbar_node/<mode>`` and ``/fourbar_ros/sim_actuator``.
ENCLAVE_ROOT = '/fourbar_ros'
#: The version of sros2's policy format.
POLICY_VERSION = '0.2.0'

#: What every rclpy node (Jazzy) writes: its log and its parameter events.
RCLPY_PUBLISH = ('/parameter_events', '/rosout')
#: What every rclpy node may read: the clock, with ``use_sim_time``.
RCLPY_SUBSCRIBE = ('/clock',)
#: The services every rclpy node (Jazzy) offers: parameters and ``~/get_type_description``
#: (``start_type_description_service``, on by default).
RCLPY_SERVICES = ('~/describe_parameters', '~/get_parameter_types', '~/get_parameters', '~/get_type_description',
                  '~/list_parameters', '~/set_parameters', '~/set_parameters_atomically')
#: The launch file's remappings of the node's topics (an actuator mode reads the broadcaster's joint states).
LAUNCH_REMAPPINGS = {MEASURED_JOINT_STATES.name: BROADCASTER_JOINT_STATES.name}


@dataclass(frozen=True)
class Profile:
    """One node's permissions in one enclave: the topics it publishes and subscribes to (sorted, names as the node
    resolves them after the launch file's remappings; relative ones in the profile's namespace)."""

    enclave: str
    node: str
    publish: tuple[str, ...]
    subscribe: tuple[str, ...]
    services: tuple[str, ...] = RCLPY_SERVICES


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
        out.append(Profile(enclave(mode), NODE_NAME, tuple(sorted(publish)), tuple(sorted(subscribe))))
    sim_in = {trajectory_topic(trajectory_controller).name, forward_topic(forward_controller).name}
    out.append(Profile(enclave(None), SIM_NODE_NAME, tuple(sorted({*RCLPY_PUBLISH, BROADCASTER_JOINT_STATES.name})),
                       tuple(sorted({*RCLPY_SUBSCRIBE, *sim_in}))))
    return tuple(out)


def _list(tag: str, item: str, qualifiers: str, names: Sequence[str]) -> list[str]:
    return [f'          <{tag} {qualifiers}>', *(f'            <{item}>{escape(n)}</{item}>' for n in names),
            f'          </{tag}>']


def policy_xml(namespace: str = '/', trajectory_controller: str = DEFAULT_TRAJECTORY_CONTROLLER,
               forward_controller: str = DEFAULT_FORWARD_CONTROLLER) -> str:
    """The policy (XML text) for the nodes in ``namespace`` with these controller names."""
    ns = '/' + namespace.strip().strip('/')
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             '<!-- SROS2 permissions of fourbar_ros\'s nodes, generated by fourbar_ros.config.security from the',
             '     interface table: one enclave per node and mode. -->',
             f'<policy version="{POLICY_VERSION}">', '  <enclaves>']
    for p in profiles(trajectory_controller, forward_controller):
        lines += [f'    <enclave path={quoteattr(p.enclave)}>', '      <profiles>',
                  f'        <profile ns={quoteattr(ns)} node={quoteattr(p.node)}>']
        lines += _list('topics', 'topic', 'publish="ALLOW"', p.publish)
        lines += _list('topics', 'topic', 'subscribe="ALLOW"', p.subscribe)
        lines += _list('services', 'service', 'reply="ALLOW"', p.services)
        lines += ['        </profile>', '      </profiles>', '    </enclave>']
    lines += ['  </enclaves>', '</policy>', '']
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the policy: ``python3 -m fourbar_ros.config.security [--namespace NS] [--trajectory-controller NAME]
    [--forward-controller NAME]``."""
    parser = argparse.ArgumentParser(prog='python3 -m fourbar_ros.config.security',
                                     description='print the SROS2 policy of fourbar_ros\'s nodes')
    parser.add_argument('--namespace', default='/', help='the nodes\' namespace (default: /)')
    parser.add_argument('--trajectory-controller', default=DEFAULT_TRAJECTORY_CONTROLLER)
    parser.add_argument('--forward-controller', default=DEFAULT_FORWARD_CONTROLLER)
    args = parser.parse_args(argv)
    sys.stdout.write(policy_xml(args.namespace, args.trajectory_controller, args.forward_controller))
    return 0


if __name__ == '__main__':
    sys.exit(main())
