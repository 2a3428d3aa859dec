"""Hostile parameter files: endless, too large, alias bombs, deep nesting; each refused quickly with one line and
bounded memory, by the loader and by `fourbar solve/check --params` (no ROS)."""

from __future__ import annotations

import inspect
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from support.paths import REPO

from fourbar_ros.config.antenna_config import ConfigError, load_config
from fourbar_ros.config.rcl_yaml import MAX_DEPTH, MAX_FILE_BYTES, parse, read_text

VALID = '/**:\n  ros__parameters:\n    load_torque: 2.5\n'

#: Peak RSS a refused command may reach: the interpreter with numpy (~40-60 MB here) plus at most the 1 MiB read
#: and its parse; an unbounded reader grows past this within a second on /dev/zero or an alias bomb.
RSS_BOUND_KB = 300 * 1024
#: Address-space cap on the child, so that a regression fails (MemoryError) instead of exhausting the machine.
AS_CAP = 4 * 1024**3

_MEASURE = '''
import resource, subprocess, sys, time
def cap():
    resource.setrlimit(resource.RLIMIT_AS, ({cap}, {cap}))
t0 = time.monotonic()
p = subprocess.run(sys.argv[1:], capture_output=True, text=True, preexec_fn=cap, timeout=120)
dt = time.monotonic() - t0
rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(json.dumps({{'rc': p.returncode, 'out': p.stdout, 'err': p.stderr, 'rss_kb': rss, 's': dt}}))
'''


def alias_bomb() -> str:
    """Nine levels of nine aliases: 9**9 (387 million) strings once expanded, 1 kB as text."""
    lines = ['/**:', '  ros__parameters:', '    l0: &l0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        lines.append(f'    l{i}: &l{i} [' + ','.join([f'*l{i - 1}'] * 9) + ']')
    return '\n'.join(lines) + '\n'


def big_valid_file() -> str:
    """A valid parameter file padded with a comment to 1.5 MiB: refused for its size alone."""
    return '#' + 'x' * (3 * MAX_FILE_BYTES // 2) + '\n' + VALID


def run_measured(*args: str) -> dict[str, object]:
    """Run `fourbar ARGS` in a child with a capped address space; its exit status, output, peak RSS and time."""
    code = 'import json\n' + _MEASURE.format(cap=AS_CAP)
    out = subprocess.run([sys.executable, '-c', code, sys.executable, '-m', 'fourbar_ros.commands', *args],
                         capture_output=True, text=True, cwd=REPO, timeout=180, check=True)
    result: dict[str, object] = json.loads(out.stdout)
    return result


@pytest.fixture(scope='module')
def hostile(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    d = tmp_path_factory.mktemp('hostile')
    (d / 'bomb.yaml').write_text(alias_bomb(), encoding='utf-8')
    (d / 'big.yaml').write_text(big_valid_file(), encoding='utf-8')
    return {'dev_zero': '/dev/zero', 'alias_bomb': str(d / 'bomb.yaml'), 'big': str(d / 'big.yaml')}


WORDS = {'dev_zero': f'larger than {MAX_FILE_BYTES} bytes', 'big': f'larger than {MAX_FILE_BYTES} bytes',
         'alias_bomb': 'aliases'}


@pytest.mark.parametrize('command', [['solve', '--theta', '0.05'], ['check']])
@pytest.mark.parametrize('case', ['dev_zero', 'alias_bomb', 'big'])
def test_cli_refuses_hostile_params_quickly_with_bounded_memory(hostile: dict[str, str], command: list[str],
                                                                case: str) -> None:
    r = run_measured(*command, '--params', hostile[case])
    err = str(r['err'])
    assert r['rc'] == 2, err[-500:]
    assert r['out'] == ''
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f'fourbar {command[0]}: error: {hostile[case]}: ')
    assert WORDS[case] in lines[0]
    assert int(str(r['rss_kb'])) < RSS_BOUND_KB, r
    print(f'{command[0]} --params {case}: peak RSS {int(str(r["rss_kb"])) / 1024:.1f} MB, {float(str(r["s"])):.2f} s')


_LOADER_CHECK = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, ({cap}, {cap}))
from fourbar_ros.config.antenna_config import ConfigError, load_config, unknown_in_node_sections
from fourbar_ros.config.rcl_yaml import params_file_problem
path = sys.argv[1]
for f in (load_config, unknown_in_node_sections):
    try:
        f(path)
    except ConfigError as exc:
        print(exc)
print(params_file_problem(path))
"""


@pytest.mark.parametrize('case', ['dev_zero', 'alias_bomb', 'big'])
def test_loader_and_node_check_refuse_hostile_files(hostile: dict[str, str], case: str) -> None:
    # In a child with a capped address space: a regression must fail the test, not exhaust the machine.
    out = subprocess.run([sys.executable, '-c', _LOADER_CHECK.format(cap=AS_CAP), hostile[case]],
                         capture_output=True, text=True, cwd=REPO, timeout=120, check=False)
    assert out.returncode == 0, out.stderr[-500:]
    lines = out.stdout.splitlines()
    assert len(lines) == 3  # load_config, unknown_in_node_sections, params_file_problem: one line each
    assert all(line.startswith(f'{hostile[case]}: ') and WORDS[case] in line for line in lines), lines


def test_read_text_limit_is_exact(tmp_path: Path) -> None:
    path = tmp_path / 'p.yaml'
    path.write_bytes(b'#' * MAX_FILE_BYTES)
    assert len(read_text(path)) == MAX_FILE_BYTES
    path.write_bytes(b'#' * (MAX_FILE_BYTES + 1))
    with pytest.raises(ConfigError, match='larger than'):
        read_text(path)


def test_not_utf8_and_directories_are_one_line(tmp_path: Path) -> None:
    path = tmp_path / 'p.yaml'
    path.write_bytes(VALID.encode() + b'\xff\n')
    with pytest.raises(ConfigError, match='not UTF-8'):
        load_config(path)
    with pytest.raises(ConfigError, match='cannot read'):
        load_config(tmp_path)


def test_alias_refused_anchor_accepted_as_rcl_does() -> None:
    # rcl: "Will not support aliasing"; an anchor without an alias is read as if it were absent.
    assert parse('/**:\n  ros__parameters:\n    a: &x 1.5\n    b: 2.0\n') == {
        '/**': {'ros__parameters': {'a': 1.5, 'b': 2.0}}}
    with pytest.raises(ConfigError, match=r'line 4: YAML aliases \(\*x\) are not supported'):
        parse('/**:\n  ros__parameters:\n    a: &x 1.5\n    b: *x\n', 'p.yaml')


def test_nesting_is_bounded() -> None:
    ok = '[' * MAX_DEPTH + ']' * MAX_DEPTH
    assert parse(ok) is not None
    deep = '[' * (MAX_DEPTH + 1) + ']' * (MAX_DEPTH + 1)
    with pytest.raises(ConfigError, match=f'nested more than {MAX_DEPTH} levels'):
        parse(deep)
    # Far deeper than Python's recursion limit: still one line, no RecursionError.
    with pytest.raises(ConfigError, match='nested more than'):
        parse('[' * 100_000)


def _at_stack_depth(frames: int, call: Callable[[], object]) -> object:
    return call() if frames <= 0 else _at_stack_depth(frames - 1, call)


@pytest.mark.parametrize('loader', ['CSafeLoader', 'SafeLoader'])
@pytest.mark.parametrize('opening', ['[', '{"a": ', '- ['])
def test_deep_flow_nesting_is_refused_before_the_parser_whatever_the_stack(
        loader: str, opening: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # The parser must not see it: a libyaml that scans a bracket run ahead fails on its own limit ("while increasing
    # flow level"), and a deep caller stack must not change the message. Both loaders, a stack near its limit.
    import yaml
    if loader == 'SafeLoader':
        monkeypatch.delattr(yaml, 'CSafeLoader', raising=False)
    frames = sys.getrecursionlimit() - len(inspect.stack()) - 50
    for text in (opening * 100_000, opening * (MAX_DEPTH + 1)):
        with pytest.raises(ConfigError, match=f'nested more than {MAX_DEPTH} levels') as err:
            _at_stack_depth(frames, lambda t=text: parse(t))  # type: ignore[misc]
        assert '\n' not in str(err.value)


@pytest.mark.parametrize('text', [
    'a: b[c]\n',                                   # brackets inside plain scalars open nothing
    'a: "' + '[' * 200 + '"\n',                     # nor inside quoted ones
    "a: '" + "{''" * 200 + "'\n",
    'a: x # ' + '[' * 200 + '\n',                   # nor in comments
    'a: ' + '[' * (MAX_DEPTH - 1) + ']' * (MAX_DEPTH - 1) + '\n',  # with the mapping: MAX_DEPTH levels
])
def test_brackets_that_open_nothing_are_not_counted(text: str) -> None:
    import yaml
    assert parse(text) == yaml.safe_load(text)


@pytest.mark.parametrize('text', ['a: 1\n---\nb: 2\n', '? [1, 2]\n: 3\n', 'a: [1\n'])
def test_other_malformed_documents_are_one_line(text: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse(text, 'p.yaml')
    assert str(err.value).startswith('p.yaml: ') and '\n' not in str(err.value)


@pytest.mark.parametrize(('text', 'expected'), [
    ('1' * 100_000 + 'x', '1' * 100_000 + 'x'),          # a near-number (quadratic backtracking would take hours)
    ('0x' + '1' * 100_000 + 'g', '0x' + '1' * 100_000 + 'g'),
    ('1' * 5000, '1' * 5000),                             # strtol and strtod overflow (int() would raise here)
    ('0' * 5000 + '17', 15),                              # octal with leading zeros, as strtol reads it
    ('0x1p99999', '0x1p99999'),                           # hex float overflow (float.fromhex would raise)
    ('1' * 30, 1.1111111111111111e29),                    # beyond int64: strtol ERANGE, then a double
])
def test_long_scalars_are_typed_in_linear_time(text: str, expected: object) -> None:
    from fourbar_ros.config.rcl_yaml import rcl_scalar

    got = rcl_scalar(text, False)
    assert type(got) is type(expected) and got == expected
