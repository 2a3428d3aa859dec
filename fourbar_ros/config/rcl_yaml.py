"""Reading a ROS 2 parameter file the way rcl's YAML parameter parser reads it (no ROS import).

What rcl accepts and the bounds on hostile input: docs/reference/parameters.md and docs/how-to/design.md."""

from __future__ import annotations

import math
import re
import sys
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.topics import NODE_NAME

#: Largest parameter file read (bytes): 1 MiB, a few hundred times a real one; larger files are refused unread.
MAX_FILE_BYTES = 1 << 20

#: Deepest nesting of YAML mappings and sequences accepted (a real file nests fewer than 10 levels).
MAX_DEPTH = 64


class ConfigError(FourBarError):
    """Invalid parameter file or parameter values; the message is one line naming the parameter(s) or the file.

    ``names`` lists the parameters at fault (empty when the file itself is at fault).
    """

    def __init__(self, message: str, names: Iterable[str] = ()) -> None:
        super().__init__(message)
        self.names: tuple[str, ...] = tuple(names)


def read_text(path: str | Path, limit: int = MAX_FILE_BYTES) -> str:
    """The UTF-8 text of a parameter file, reading at most ``limit`` + 1 bytes.

    Raises ``ConfigError`` (one line) if the file cannot be read, is larger than ``limit`` bytes (also endless
    files such as /dev/zero) or is not UTF-8.
    """
    try:
        with open(path, 'rb') as f:
            data = f.read(limit + 1)
    except OSError as exc:
        raise ConfigError(f'{path}: cannot read: {exc.strerror or exc}') from None
    if len(data) > limit:
        raise ConfigError(f'{path}: larger than {limit} bytes, the limit for a parameter file; not read')
    try:
        return data.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise ConfigError(f'{path}: not UTF-8 text (byte {exc.start})') from None


_TRUE = frozenset({'Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On', 'ON'})
_FALSE = frozenset({'N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off', 'Off', 'OFF'})
_INT_RE = re.compile(r'\s*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)')
# Unambiguous patterns (no two quantifiers can share a digit), so a long near-number fails in linear time.
_DEC_RE = re.compile(r'\s*[+-]?(\d+(?:\.\d*)?|\.\d+)([eE][+-]?\d+)?')
_HEX_RE = re.compile(r'\s*[+-]?0[xX]([0-9a-fA-F]+(?:\.[0-9a-fA-F]*)?|\.[0-9a-fA-F]+)([pP][+-]?\d+)?')
_SPECIAL_RE = re.compile(r'\s*[+-]?(inf|infinity|nan(\([0-9A-Za-z_]*\))?)', re.IGNORECASE)
_YAML_SPECIAL = {'.nan': math.nan, '.NaN': math.nan, '.NAN': math.nan}
_YAML_SPECIAL.update({f'{sign}.{inf}': (-math.inf if sign == '-' else math.inf)
                      for sign in ('', '+', '-') for inf in ('inf', 'Inf', 'INF')})


def _nonzero_mantissa(text: str) -> bool:
    """True if a decimal or hex float literal has a non-zero digit before its exponent."""
    body = text.strip().lstrip('+-')
    if body[:2] in ('0x', '0X'):
        return any(c in '123456789abcdefABCDEF' for c in re.split('[pP]', body[2:])[0])
    return any(c in '123456789' for c in re.split('[eE]', body)[0])


def rcl_scalar(text: str, quoted: bool) -> bool | int | float | str:
    """The value rcl's YAML parameter parser gives a scalar (``get_value`` in rcl_yaml_param_parser).

    Quoted scalars are strings. Plain ones are tried as a bool word (true/yes/on/y ...), a C ``strtol``
    integer (base prefix 0x or 0 for octal), a C ``strtod`` double (also 1e-3, inf, nan, hex floats,
    .nan/.inf), else a string. This differs from PyYAML's YAML 1.1 rules (``1e-3`` and ``1_000``).
    """
    if quoted:
        return text
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    m = _INT_RE.fullmatch(text)
    if m:
        digits = m.group(2)
        base = 16 if digits[:2] in ('0x', '0X') else 8 if len(digits) > 1 and digits[0] == '0' else 10
        significant = (digits[2:] if base == 16 else digits).lstrip('0')
        if len(significant) <= 22:  # an int64 has at most 19 decimal, 22 octal or 16 hex digits
            value = int(digits, base)
            value = -value if m.group(1) == '-' else value
            if -(2**63) <= value < 2**63:  # otherwise strtol sets ERANGE and rcl tries a double
                return value
    if text in _YAML_SPECIAL:
        return _YAML_SPECIAL[text]
    if _DEC_RE.fullmatch(text) or _SPECIAL_RE.fullmatch(text):
        number = float(text.strip())
    elif _HEX_RE.fullmatch(text):
        stripped = text.strip()
        sign = -1.0 if stripped.startswith('-') else 1.0
        body = stripped.lstrip('+-')
        try:
            number = sign * float.fromhex(body if 'p' in body.lower() else body + 'p0')
        except OverflowError:
            return text  # strtod overflow: ERANGE, so rcl keeps the string
    else:
        return text
    if not _SPECIAL_RE.fullmatch(text) and (
            math.isinf(number) or (abs(number) < sys.float_info.min and (number != 0.0 or _nonzero_mantissa(text)))):
        return text  # strtod overflow or underflow (also to a subnormal): ERANGE, so rcl keeps the string
    return number


_NO_KEY = object()

#: Characters that can open or close a flow collection, start a quoted scalar or a comment, or end a line.
_FLOW_SYNTAX = re.compile(r"[\[\]{}'\"#\n]")


def _flow_depth_problem(text: str, source: str) -> ConfigError | None:
    """A ConfigError when flow collections (``[``, ``{``) nest deeper than MAX_DEPTH, found before the YAML parser
    runs: a parser may scan a whole run of brackets ahead before it yields the first event (libyaml does, to find
    possible simple keys), and fail on its own depth limit, or the caller's stack, with its own message.

    A lexical scan: quoted scalars and comments are skipped; outside flow collections a bracket opens one only at
    the start of a line's content or after ``: ``, ``- ``, ``? ``; inside one every bracket is an indicator."""
    depth = 0
    line = 1
    pos = 0
    for m in _FLOW_SYNTAX.finditer(text):
        i = m.start()
        if i < pos:  # inside a quoted scalar or comment already skipped
            continue
        c = m.group()
        if c == '\n':
            line += 1
        elif c == '#':
            if i == 0 or text[i - 1] in ' \t\n':
                end = text.find('\n', i)
                pos = len(text) if end < 0 else end
        elif c in '\'"':
            if depth == 0 and i > 0 and text[i - 1] not in ' \t\n[{,:-?':
                continue  # a quote inside a plain scalar
            j = i + 1
            while True:
                j = text.find(c, j)
                if j < 0:
                    return None  # unterminated: the parser reports it
                if c == '"' and (j - i - 1 - len(text[i + 1:j].rstrip('\\'))) % 2:
                    j += 1  # an escaped quote
                    continue
                if c == "'" and text.startswith("''", j):
                    j += 2
                    continue
                break
            line += text.count('\n', i, j)
            pos = j + 1
        elif c in '[{':
            if depth == 0:
                k = i - 1
                while k >= 0 and text[k] in ' \t':
                    k -= 1
                if not (k < 0 or text[k] == '\n' or (text[k] in ':-?' and k + 1 < i)):
                    continue  # part of a plain scalar
            depth += 1
            if depth > MAX_DEPTH:
                return ConfigError(f'{source}: line {line}: nested more than {MAX_DEPTH} levels deep')
        elif depth:  # ] or }
            depth -= 1
    return None


def parse(text: str, source: str = '<string>') -> Any:
    """The YAML document as dicts, lists and rcl-typed scalars (None for an empty document).

    Built from PyYAML's event stream (libyaml when available), as rcl builds its values from libyaml's events:
    an alias is refused where it appears, nothing is ever expanded, and nesting deeper than ``MAX_DEPTH``
    is refused, so the result is never larger than the text. Raises ``ConfigError`` (one line).
    """
    too_deep = _flow_depth_problem(text, source)
    if too_deep is not None:
        raise too_deep
    import yaml  # PyYAML, only for its parser; imported here to keep `import fourbar_ros.config.antenna_config` light

    loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
    scalar_event, mapping_start, sequence_start = yaml.ScalarEvent, yaml.MappingStartEvent, yaml.SequenceStartEvent
    ends = (yaml.MappingEndEvent, yaml.SequenceEndEvent)
    root: Any = None
    documents = 0
    # One entry per open collection: [container, pending mapping key or _NO_KEY].
    stack: list[list[Any]] = []

    def line(event: Any) -> int:
        return int(event.start_mark.line) + 1 if event.start_mark is not None else 0

    events: Iterator[Any] = iter(yaml.parse(text, Loader=loader))  # Any: the subclasses' fields are untyped
    try:
        for event in events:
            cls = type(event)
            if cls is scalar_event:
                top = stack[-1] if stack else None
                if top is not None and top[1] is _NO_KEY and type(top[0]) is dict:
                    top[1] = event.value  # a key: its text, as rcl takes it
                    continue
                quoted = event.style in ("'", '"')
                if not quoted and event.value == '':
                    raise ConfigError(f'{source}: no value at line {line(event)}')
                value: Any = rcl_scalar(event.value, quoted)
            elif cls is mapping_start or cls is sequence_start:
                if len(stack) >= MAX_DEPTH:
                    raise ConfigError(f'{source}: line {line(event)}: nested more than {MAX_DEPTH} levels deep')
                value = {} if cls is mapping_start else []
                top = stack[-1] if stack else None
                if top is not None and top[1] is _NO_KEY and type(top[0]) is dict:
                    raise ConfigError(f'{source}: line {line(event)}: a mapping key must be a scalar')
                stack.append([value, _NO_KEY])
            elif cls in ends:
                value = stack.pop()[0]
                top = stack[-1] if stack else None
            elif cls is yaml.AliasEvent:
                raise ConfigError(f'{source}: line {line(event)}: YAML aliases (*{event.anchor}) are not '
                                  'supported in parameter files (rcl refuses them too)')
            else:
                if cls is yaml.DocumentStartEvent:
                    documents += 1
                    if documents > 1:
                        raise ConfigError(f'{source}: line {line(event)}: more than one YAML document')
                continue
            if cls is mapping_start or cls is sequence_start:
                continue  # attached to its parent when it ends
            if top is None:
                root = value
            elif type(top[0]) is list:
                top[0].append(value)
            else:
                top[0][top[1]] = value
                top[1] = _NO_KEY
    except yaml.YAMLError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else 'syntax error'
        where = getattr(exc, 'problem_mark', None)
        at = f' (line {where.line + 1})' if where is not None else ''
        raise ConfigError(f'{source}: not valid YAML: {first}{at}') from None
    return root


def _flatten(prefix: str, mapping: Mapping[str, Any], out: dict[str, object]) -> None:
    """rcl's nesting rule: ``a: {b: 1}`` under ros__parameters is the parameter ``a.b``."""
    for key, value in mapping.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            _flatten(name + '.', value, out)
        else:
            out[name] = value


def section_pattern(key: str) -> list[str]:
    """The namespace tokens of a section key (``name`` is ``/name``): ``'/ns/*/node'`` -> ``['ns', '*', 'node']``."""
    return [t for t in ('/' + key.strip().lstrip('/')).split('/') if t]


def matches_node(key: str, fqn: str) -> bool:
    """rcl's rule: does section ``key`` (``/**``, ``/ns/name``, ``name`` = ``/name``, ``/*/name``,
    ``/**/name``) apply to the node with fully qualified name ``fqn``? ``*`` is one namespace level,
    ``**`` any number of them."""
    pattern = section_pattern(key)
    target = [t for t in fqn.split('/') if t]

    def match(p: list[str], t: list[str]) -> bool:
        if not p:
            return not t
        if p[0] == '**':
            return any(match(p[1:], t[i:]) for i in range(len(t) + 1))
        return bool(t) and (p[0] == '*' or p[0] == t[0]) and match(p[1:], t[1:])

    return match(pattern, target)


def _node_sections(doc: Mapping[str, Any], prefix: str = '') -> Iterator[tuple[str, Any]]:
    """(node key, section) in file order; nested mappings without ros__parameters are namespace levels."""
    for key, section in doc.items():
        name = f'{prefix}/{key.strip("/")}' if prefix else key
        if isinstance(section, dict) and 'ros__parameters' not in section and all(
                isinstance(v, dict) for v in section.values()) and section:
            yield from _node_sections(section, name)
        else:
            yield name, section


def node_sections(text: str, source: str = '<string>', node_name: str = NODE_NAME,
                  namespace: str = '/') -> list[tuple[str, dict[str, object]]]:
    """(section key, its flattened parameters) for each section that applies to ``namespace``/``node_name``,
    in file order. Raises ``ConfigError`` if the file is not a parameter file or no section applies."""
    doc = parse(text, source)
    if not isinstance(doc, dict):
        raise ConfigError(f"{source}: expected a mapping with a '/**:' or '{node_name}:' section")
    fqn = f"{namespace.rstrip('/')}/{node_name}"
    sections: list[tuple[str, dict[str, object]]] = []
    for key, section in _node_sections(doc):
        if not matches_node(key, fqn):
            continue
        if not isinstance(section, dict) or not isinstance(section.get('ros__parameters'), dict):
            raise ConfigError(f"{source}: section {key!r} has no 'ros__parameters:' mapping")
        values: dict[str, object] = {}
        _flatten('', section['ros__parameters'], values)
        sections.append((key, values))
    if not sections:
        raise ConfigError(f"{source}: no '/**:' or '{fqn}' section with 'ros__parameters:'")
    return sections


def values_from_yaml(text: str, source: str = '<string>', node_name: str = NODE_NAME,
                     namespace: str = '/') -> dict[str, object]:
    """The parameter values the node ``namespace``/``node_name`` receives from a ROS 2 parameter file.

    Scalars are typed as rcl types them (see ``rcl_scalar``); the sections that apply to the node
    (``/**``, its name, wildcards) are merged in file order, a later one overriding an earlier one.
    """
    values: dict[str, object] = {}
    for _, section in node_sections(text, source, node_name, namespace):
        values.update(section)
    return values


def params_file_problem(path: str) -> str | None:
    """One line saying why rcl could not use ``path`` as a ``--params-file`` (unreadable, too large, not YAML,
    an alias, nested too deep), or None. The node calls it before rclpy.init, whose own error is multi-line."""
    try:
        parse(read_text(path), path)
    except ConfigError as exc:
        return str(exc)
    return None
