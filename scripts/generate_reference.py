#!/usr/bin/env python3
"""Write the tables that restate code: the node's topics per mode and its QoS override parameters
(``interface/topics.py``) and its parameters (``config/params.py``) into docs/reference/, the fields `fourbar
compare` compares (``interface/topics.py``) into docs/how-to/bags.md, the SROS2 enclaves (``config/security.py``)
into docs/how-to/security.md, and the package map (each package's and module's docstring summary, in layer order)
into docs/reference/python.md, between the markers

    <!-- generated: NAME -->
    ...
    <!-- end generated -->

    python scripts/generate_reference.py           # rewrite the tables in place
    python scripts/generate_reference.py --check   # exit 1 if a committed table differs from the code

The test suite runs the check, so the docs cannot drift from the code.
"""

from __future__ import annotations

import argparse
import ast
import math
import re
import sys
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from fourbar_ros.config.params import PARAMETERS, ParamSpec  # noqa: E402
from fourbar_ros.config.security import RCLPY_PUBLISH, RCLPY_SERVICES, RCLPY_SUBSCRIBE, bringup_profiles  # noqa: E402
from fourbar_ros.config.security import profiles as security_profiles  # noqa: E402
from fourbar_ros.interface.topics import (  # noqa: E402
    COMPARED,
    QOS_OVERRIDABLE,
    Direction,
    Mode,
    Topic,
    every_endpoint,
    qos_override_parameters,
    services,
)

PACKAGE = REPO / 'fourbar_ros'
MARKER = re.compile(r'(<!-- generated: (?P<name>[a-z_]+) -->\n)(?P<body>.*?)(<!-- end generated -->)', re.DOTALL)


def _qos(topic: Topic) -> str:
    durability = 'transient local' if topic.transient_local else 'volatile'
    return f'{topic.reliability.value.replace("_", " ")}, keep last {topic.depth}, {durability}'


def topics_table() -> str:
    """One table per mode: topic, type, direction, QoS, content; then the mode's services, if any: name, type,
    what a call does."""
    out: list[str] = []
    for mode in Mode:
        out += [f'### `mode: {mode.value}`', '', '| Topic | Type | Dir | QoS | Content |', '|---|---|---|---|---|']
        for e in every_endpoint(mode):
            content = f'only with `{e.optional}`: {e.content}' if e.optional else e.content
            out.append(f'| `{e.topic.name}` | `{e.topic.msgtype}` | {e.direction.value} | {_qos(e.topic)} '
                       f'| {content} |')
        out.append('')
        if services(mode):
            out += ['| Service | Type | Call |', '|---|---|---|']
            out += [f'| `{srv.name}` | `{srv.srvtype}` | {srv.content} |' for srv in services(mode)]
            out.append('')
    return '\n'.join(out)


#: The namespace the QoS override table's parameter names are written for (the README's).
EXAMPLE_NAMESPACE = '/tilt'


def qos_overrides_table() -> str:
    """The QoS override parameters rclpy declares, per endpoint, for a node in EXAMPLE_NAMESPACE."""
    names = qos_override_parameters(EXAMPLE_NAMESPACE)
    per = len(names) // len(QOS_OVERRIDABLE)
    out = [f'| Topic | Dir | Parameters (a node in `{EXAMPLE_NAMESPACE}`) |', '|---|---|---|']
    for k, (topic, direction) in enumerate(QOS_OVERRIDABLE):
        entity = 'subscription' if direction is Direction.IN else 'publisher'
        keys = ', '.join(f'`{n}`' for n in names[k * per:(k + 1) * per])
        out.append(f'| `{topic.name}` | {direction.value} ({entity}) | {keys} |')
    return '\n'.join(out) + '\n'


def compared_fields_list() -> str:
    """The fields of `fourbar compare --ignore`, each with what it covers."""
    return ''.join(f'- `{name}`: {meaning}\n' for name, meaning in COMPARED.items())


_NAMED = {math.pi: 'pi', -math.pi: '-pi', math.pi / 2: 'pi/2'}


def _number(value: float) -> str:
    """A bound or default as it reads best: pi by name, 1e+06 rather than 1000000.0, else the exact repr."""
    if value in _NAMED:
        return _NAMED[value]
    if isinstance(value, float) and math.isfinite(value) and value != 0 and (
            abs(value) < 1e-3 or (value.is_integer() and abs(value) >= 1e4)):
        return f'{value:g}'
    return repr(value)


def _default(p: ParamSpec) -> str:
    if p.type is str:
        return f"`{p.default}`" if p.default != '' else "`''`"
    if p.type is bool:
        return 'true' if p.default else 'false'
    if p.type is list:
        return '`[]`' if not p.default else f'`{p.default!r}`'
    text = _number(p.default)  # type: ignore[arg-type]
    if p.unit == 'rad' and p.default != 0:
        text += f' ({math.degrees(float(p.default)):.6g} deg)'
    return text


def _allowed(p: ParamSpec) -> str:
    if p.choices:
        return ', '.join(f'`{c}`' for c in p.choices)
    if p.minimum is not None or p.maximum is not None:
        lo = '-inf' if p.minimum is None else _number(p.minimum)
        hi = 'inf' if p.maximum is None else _number(p.maximum)
        return f'[{lo}, {hi}]'
    if p.type is list:
        return '`name=value` strings'
    return 'non-empty' if p.type is str and p.default != '' else 'any'


def parameters_table() -> str:
    """Every node parameter: name, type, default, unit, allowed values, when it can change, meaning."""
    types = {float: 'double', int: 'integer', str: 'string', bool: 'bool', list: 'string array'}
    out = ['| Parameter | Type | Default | Unit | Allowed | Set | Meaning |', '|---|---|---|---|---|---|---|']
    for p in PARAMETERS:
        when = 'startup' if p.read_only else 'any time'
        out.append(f'| `{p.name}` | {types[p.type]} | {_default(p)} | {p.unit or "-"} | {_allowed(p)} | {when} '
                   f'| {p.description} |')
    return '\n'.join(out) + '\n'


def layers() -> tuple[str, ...]:
    """The layers, lowest first, as test/package/test_layers.py enforces them (read, not imported)."""
    tree = ast.parse((REPO / 'test' / 'package' / 'test_layers.py').read_text(encoding='utf-8'))
    for node in tree.body:
        if isinstance(node, ast.AnnAssign | ast.Assign) and 'LAYERS' in ast.unparse(node).split('=')[0]:
            assert node.value is not None
            return tuple(ast.literal_eval(node.value))
    raise LookupError('test/package/test_layers.py defines no LAYERS')


def summary(path: Path) -> str:
    """A module's docstring summary: its first paragraph on one line."""
    doc = ast.get_docstring(ast.parse(path.read_text(encoding='utf-8'))) or ''
    return ' '.join(doc.split('\n\n')[0].split())


def package_map() -> str:
    """Every package and module of fourbar_ros, packages in layer order, each with its docstring summary."""
    out = ['| Module | What it holds |', '|---|---|', f'| **`fourbar_ros/`** | {summary(PACKAGE / "__init__.py")} |']

    def package(folder: Path) -> None:
        name = folder.relative_to(PACKAGE).as_posix()
        out.append(f'| **`{name}/`** | {summary(folder / "__init__.py")} |')
        for path in sorted(folder.glob('*.py')):
            if path.name != '__init__.py':
                out.append(f'| `{name}/{path.name}` | {summary(path)} |')
        for sub in sorted(p.parent for p in folder.glob('*/__init__.py')):
            package(sub)

    for layer in layers():
        package(PACKAGE / layer)
    return '\n'.join(out) + '\n'


def _names(names: tuple[str, ...], common: tuple[str, ...] = ()) -> str:
    shown = [n for n in names if n not in common]
    return ', '.join(f'`{n}`' for n in shown) if shown else '-'


def enclaves_table() -> str:
    """The shipped policy's profiles: enclave, node, what it may publish, subscribe to, call and serve (besides
    every node's log, parameter events, /clock and parameter services)."""
    out = ['| enclave | node | may publish | may subscribe to | may call | serves besides its parameters |',
           '|---|---|---|---|---|---|']
    read = (*RCLPY_SUBSCRIBE, '/parameter_events')
    for p in (*security_profiles(), *bringup_profiles()):
        calls = (*p.calls, *(f'{a} (action)' for a in p.action_calls))
        serves = (*p.services, *(f'{a} (action)' for a in p.action_serves))
        out.append(f'| `{p.enclave}` | `{p.node}` | {_names(p.publish, RCLPY_PUBLISH)} | '
                   f'{_names(p.subscribe, read)} | {_names(calls)} | '
                   f'{_names(serves, RCLPY_SERVICES)} |')
    return '\n'.join(out) + '\n'


GENERATORS: dict[str, Callable[[], str]] = {'topics': topics_table, 'qos_overrides': qos_overrides_table,
                                            'parameters': parameters_table, 'compared_fields': compared_fields_list,
                                            'enclaves': enclaves_table, 'package_map': package_map}
DOCS = (REPO / 'docs' / 'reference' / 'topics.md', REPO / 'docs' / 'reference' / 'parameters.md',
        REPO / 'docs' / 'how-to' / 'bags.md', REPO / 'docs' / 'how-to' / 'security.md',
        REPO / 'docs' / 'reference' / 'python.md')


def render(text: str) -> str:
    """``text`` with every generated section rewritten from the code (KeyError for an unknown section name)."""
    return MARKER.sub(lambda m: m.group(1) + GENERATORS[m.group('name')]() + m.group(4), text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or '').splitlines()[0])
    parser.add_argument('--check', action='store_true', help='only compare; exit 1 if a table differs')
    args = parser.parse_args(argv)
    stale = []
    for path in DOCS:
        text = path.read_text(encoding='utf-8')
        new = render(text)
        if new != text:
            stale.append(path)
            if not args.check:
                path.write_text(new, encoding='utf-8')
    for path in stale:
        print(f'{path.relative_to(REPO)}: {"differs from the code" if args.check else "rewritten"}', file=sys.stderr)
    return 1 if args.check and stale else 0


if __name__ == '__main__':
    sys.exit(main())
