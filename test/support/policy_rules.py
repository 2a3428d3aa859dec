"""An SROS2 policy read back as plain sets: what each profile allows, and those names as the node resolves them."""

from __future__ import annotations

import xml.etree.ElementTree as ET

#: {(enclave, node): {'publish'|'subscribe'|'reply'|'request'|'call'|'execute': names}}
Rules = dict[tuple[str, str], dict[str, set[str]]]

#: What an action is made of, per side (rcl's hidden topics and services below ``<action>/_action/``).
_ACTION_SERVICES = ('send_goal', 'cancel_goal', 'get_result')
_ACTION_TOPICS = ('feedback', 'status')


def rules(text: str, namespace: str = '/') -> Rules:
    """Every profile's allowed names per qualifier, checking that each is ALLOW and in ``namespace``."""
    out: Rules = {}
    for enc in ET.fromstring(text).iterfind('enclaves/enclave'):
        for profile in enc.iterfind('profiles/profile'):
            assert profile.attrib['ns'] == namespace, profile.attrib
            allowed = out.setdefault((enc.attrib['path'], profile.attrib['node']), {})
            for group in profile:
                for qualifier, value in group.attrib.items():
                    assert value == 'ALLOW', (enc.attrib['path'], group.tag, qualifier)
                    allowed.setdefault(qualifier, set()).update(item.text or '' for item in group)
    return out


def enclaves(text: str) -> set[str]:
    """The policy's enclave paths."""
    return {e.attrib['path'] for e in ET.fromstring(text).iterfind('enclaves/enclave')}


def resolve(name: str, namespace: str, node: str) -> str:
    """A policy name as rcl resolves it for the node ``namespace``/``node``."""
    ns = namespace.rstrip('/')
    if name.startswith('~/'):
        return f'{ns}/{node}/{name[2:]}'
    return name if name.startswith('/') else f'{ns}/{name}'


def as_graph(allowed: dict[str, set[str]], namespace: str, node: str) -> dict[str, set[str]]:
    """A profile's names resolved, with its actions spelled out as the graph shows them: a caller requests the
    action's services and subscribes to its topics, a server replies and publishes."""
    out = {k: {resolve(n, namespace, node) for n in allowed.get(k, set())}
           for k in ('publish', 'subscribe', 'reply', 'request')}
    for side, (services, topics) in (('call', ('request', 'subscribe')), ('execute', ('reply', 'publish'))):
        for action in allowed.get(side, set()):
            base = f'{resolve(action, namespace, node)}/_action'
            out[services] |= {f'{base}/{s}' for s in _ACTION_SERVICES}
            out[topics] |= {f'{base}/{t}' for t in _ACTION_TOPICS}
    return out
