"""The code blocks of README.md and every document under docs/, run as a reader would run them, so the docs
cannot drift.

Blocks are read with pytest-codeblocks' parser (``pytest_codeblocks.extract_from_file``) and follow its Markdown
conventions: a block's expected output is the next block after ``<!--pytest-codeblocks:expected-output-->``;
``<!--pytest.mark...-->`` comments put marks on the next block. The plugin's own runner is not used: a shell
block here runs in bash with ``-e -o pipefail`` (a failing line fails the block; a documented failure is shown
with ``|| echo "exit status $?"``), from a directory holding the checkout's files (so ``config/...``,
``test/data/...`` and ``.venv/bin/...`` resolve and nothing is written into the checkout), with this environment's
``bin`` first on PATH, and its output is stdout and stderr together, as a terminal shows them.

- ``sh``/``bash`` and ``python`` blocks run; the output, where the document gives one, must match exactly, or
  with ``<!--pytest.mark.figures_within(rel=R, abs=A)-->`` each number within ``A + R |number|`` (the rest of the
  text exactly): for figures that depend on the CPU's sin and cos in their last digits; the document says so.
- ``text`` blocks (diagrams, synopses, sample outputs of runs that differ every time) are not commands.
- ``<!--pytest.mark.quickstart-->`` blocks are the ROS quick start, run in order by test_quickstart.py.
- ``<!--pytest.mark.skip(reason="...")-->`` blocks are not run here; the document must say so where a reader
  sees it: ``(not run by the tests: <reason>)``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from support.paths import REPO

pytest.importorskip('pytest_codeblocks', reason='the documentation tests read Markdown with pytest-codeblocks')
from pytest_codeblocks import CodeBlock, extract_from_file

DOCS = [REPO / 'README.md', *sorted((REPO / 'docs').rglob('*.md'))]
RUN = {'sh', 'bash', 'python'}
#: A number in an output (what figures_within compares): sign, digits, fraction, exponent.
NUMBER = re.compile(r'([-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?)')


def blocks() -> list[tuple[Path, CodeBlock]]:
    """Every fenced block of the documents, with its file."""
    return [(path, block) for path in DOCS for block in extract_from_file(path)]


def marks(block: CodeBlock) -> list[Any]:
    """The block's marks, evaluated as pytest-codeblocks evaluates them."""
    return [eval(mark, {'pytest': pytest, 'sys': sys}) for mark in block.marks]  # our own docs


def _mark_names(block: CodeBlock) -> set[str]:
    return {m.name for m in marks(block)}


def _id(path: Path, block: CodeBlock) -> str:
    return f'{path.relative_to(REPO)}:{block.lineno}'


def test_every_block_is_run_text_or_visibly_not_run() -> None:
    for path, block in blocks():
        where = _id(path, block)
        assert block.syntax in RUN | {'text'}, f'{where}: a block must say sh, bash, python or text'
        if block.syntax == 'text':
            assert not block.marks and block.expected_output is None, where
        for mark in marks(block):
            if mark.name == 'skip':
                reason = mark.kwargs['reason']
                visible = ' '.join(path.read_text(encoding='utf-8').split())  # Markdown joins the lines
                assert f'(not run by the tests: {reason})' in visible, (
                    f'{where}: say "(not run by the tests: {reason})" where a reader sees it')


def _runnable() -> list[Any]:
    return [pytest.param(path, block, marks=marks(block), id=_id(path, block)) for path, block in blocks()
            if block.syntax in RUN and 'quickstart' not in _mark_names(block)]


def _workdir(tmp_path: Path) -> Path:
    """A directory with the checkout's files (links) and .venv = this environment."""
    for entry in REPO.iterdir():
        if not entry.name.startswith('.') and entry.name != 'out':
            (tmp_path / entry.name).symlink_to(entry)
    (tmp_path / '.venv').symlink_to(Path(sys.prefix))
    return tmp_path


def same_output(got: str, want: str, rel: float = 0.0, abs_: float = 0.0) -> bool:
    """Text equal, numbers within ``abs_ + rel |want|`` (exactly equal when both are 0)."""
    g, w = NUMBER.split(got), NUMBER.split(want)
    if len(g) != len(w):
        return False
    for k, (a, b) in enumerate(zip(g, w, strict=True)):
        if k % 2 == 0:
            if a != b:
                return False
        elif a != b and not abs(float(a) - float(b)) <= abs_ + rel * abs(float(b)):
            return False
    return True


@pytest.mark.parametrize(('path', 'block'), _runnable())
def test_block(path: Path, block: CodeBlock, tmp_path: Path, request: pytest.FixtureRequest) -> None:
    cwd = _workdir(tmp_path)
    if block.syntax == 'python':
        code = [sys.executable, '-c', block.code]
    else:
        code = ['bash', '-e', '-o', 'pipefail', '-c', block.code]
    env = {**os.environ, 'PATH': os.pathsep.join([str(Path(sys.executable).parent), os.environ.get('PATH', '')])}
    env.pop('ROS_DOMAIN_ID', None)
    out = subprocess.run(code, cwd=cwd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, timeout=300, check=False)
    assert out.returncode == 0, f'{_id(path, block)} failed ({out.returncode}):\n{block.code}\n{out.stdout}'
    if block.expected_output is None:
        return
    tolerance = request.node.get_closest_marker('figures_within')
    rel, abs_ = (tolerance.kwargs.get('rel', 0.0), tolerance.kwargs.get('abs', 0.0)) if tolerance else (0.0, 0.0)
    assert same_output(out.stdout, block.expected_output, rel, abs_), (
        f'{_id(path, block)}: the output differs from the document\n--- document\n{block.expected_output}'
        f'--- now\n{out.stdout}')


def test_same_output_compares_text_exactly_and_numbers_within_the_tolerance() -> None:
    assert same_output('K1 = 3.000000000000989\n', 'K1 = 3.000000000000989\n')
    assert not same_output('K1 = 3.0000000000009\n', 'K1 = 3.000000000000989\n')
    assert same_output('K1 = 3.0000000000009\n', 'K1 = 3.000000000000989\n', rel=1e-13)
    assert not same_output('K2 = 3.0000000000009\n', 'K1 = 3.000000000000989\n', rel=1e-13)
    assert not same_output('error 4.441e-16 rad\n', 'error 8.882e-16 rad\n', rel=0.1)
    assert same_output('error 4.441e-16 rad\n', 'error 8.882e-16 rad\n', abs_=1e-15)


def test_documented_joint_names_are_the_nodes() -> None:
    """The topics reference and the robot model name the joints the node publishes (the parameters' defaults)."""
    from fourbar_ros.config.antenna_config import default_config

    ab, cd, coupler = default_config().joint_names
    topics = (REPO / 'docs' / 'reference' / 'topics.md').read_text(encoding='utf-8')
    model = (REPO / 'docs' / 'how-to' / 'ros2-control.md').read_text(encoding='utf-8')
    assert (f'`gamma_joint` (default `{ab}`), `delta_joint` (`{cd}`) and\n  `coupler_joint` (`{coupler}`)'
            in topics)
    assert f'joint `{ab}`' in model and f'joint `{cd}`' in model and f'joint `{coupler}`' in model
    assert 'joint `gamma_joint`' not in model and 'joint `delta_joint`' not in model


def test_documented_keys_absent_before_the_first_command_are_the_nodes() -> None:
    """The diagnostics keys the diagnostics reference lists as absent until the first command: exactly those a
    status before any command lacks and one after a served command has."""
    from fourbar_ros.config.antenna_config import default_config
    from fourbar_ros.rules.diagnostics import Counters, summarize
    from fourbar_ros.rules.policy import decide

    cfg = default_config()
    before = {k for k, _ in summarize(cfg, None, None, None, Counters(), 0, 0).values}
    decision = decide(0.05, cfg.theta_min, cfg.theta_max, cfg.out_of_limits, cfg.linkage.reach())
    after = {k for k, _ in summarize(cfg, decision, 0.05, cfg.linkage.state(0.05, cfg.load_torque), Counters(),
                                     1, 0).values}
    text = (REPO / 'docs' / 'reference' / 'diagnostics.md').read_text(encoding='utf-8')
    paragraph = text[text.index('Absent until the first command arrives'):]
    paragraph = paragraph[:paragraph.index('\n\n')]
    documented = set(re.findall(r'`([a-z_]+)`', paragraph)) - {'waiting for the first command'}
    assert documented == after - before
