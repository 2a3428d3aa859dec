"""Module docstrings are short and point to the documents; every module a comment or document names exists."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest
from support.paths import REPO

PACKAGE = REPO / 'fourbar_ros'
MODULES = {p.relative_to(REPO).as_posix(): p for p in sorted(PACKAGE.rglob('*.py'))}
MAX_LINES = 6


def _docstring(path: Path) -> str:
    return ast.get_docstring(ast.parse(path.read_text(encoding='utf-8'))) or ''


@pytest.mark.parametrize('name', sorted(MODULES))
def test_a_module_docstring_is_short_and_starts_with_a_summary_line(name: str) -> None:
    lines = _docstring(MODULES[name]).splitlines()
    assert lines and lines[0].strip(), f'{name}: no docstring'
    assert len(lines) <= MAX_LINES, f'{name}: {len(lines)} docstring lines; the explanation belongs in docs/'
    assert len(lines) == 1 or not lines[1].strip(), f'{name}: the first line is not the whole summary'


@pytest.mark.parametrize('name', sorted(n for n in MODULES if n.endswith('/__init__.py')))
def test_a_package_docstring_is_one_line_and_lists_no_module(name: str) -> None:
    doc = _docstring(MODULES[name])
    folder = MODULES[name].parent
    own = {p.stem for p in folder.glob('*.py') if p.name != '__init__.py'} | {
        p.parent.name for p in folder.glob('*/__init__.py')}
    assert len(doc.splitlines()) == 1, f'{name}: the package map (docs/reference/python.md) lists its modules'
    assert not [m for m in own if re.search(rf'\b{m}\.py\b|`{m}`', doc)], f'{name}: names its modules'


def _named_modules(text: str) -> set[str]:
    """The dotted ``fourbar_ros.…`` names and ``fourbar_ros/….py`` paths in ``text``."""
    dotted = set(re.findall(r'\bfourbar_ros(?:\.[A-Za-z_]\w*)+', text))
    paths = {p[:-3].replace('/', '.') for p in re.findall(r'\bfourbar_ros(?:/\w+)+\.py\b', text)}
    return dotted | paths


def _exists(name: str) -> bool:
    """A module, a package, or a name in one (the longest prefix that is a module, at most one name after it)."""
    parts = name.split('.')
    for k in (len(parts), len(parts) - 1):
        if k and ((REPO.joinpath(*parts[:k]).with_suffix('.py')).is_file()
                  or (REPO.joinpath(*parts[:k]) / '__init__.py').is_file()):
            return True
    return False


FILES = [*PACKAGE.rglob('*.py'), *(REPO / 'test').rglob('*.py'), *(REPO / 'benchmarks').rglob('*.py'),
         *(REPO / 'scripts').rglob('*.py'), REPO / 'README.md', *(REPO / 'docs').rglob('*.md')]


def test_every_module_named_exists() -> None:
    """A module renamed or moved leaves no comment, docstring or document naming it."""
    missing = [f'{f.relative_to(REPO)}: {name}' for f in FILES
               for name in sorted(_named_modules(f.read_text(encoding='utf-8'))) if not _exists(name)]
    assert not missing, '\n'.join(missing)


def _prose(path: Path) -> str:
    """A document, or a Python file's comments and strings."""
    text = path.read_text(encoding='utf-8')
    if path.suffix != '.py':
        return text
    tokens = tokenize.generate_tokens(io.StringIO(text).readline)
    return '\n'.join(t.string for t in tokens if t.type in (tokenize.COMMENT, tokenize.STRING))


def test_every_module_named_by_its_layer_exists() -> None:
    """``layer.module`` in prose names a module of that layer: a module moved to another layer leaves no old name."""
    modules = {'.'.join(p.relative_to(PACKAGE).with_suffix('').parts).removesuffix('.__init__')
               for p in MODULES.values()}
    leaves = {m.rpartition('.')[2] for m in modules}
    layers = {m.partition('.')[0] for m in modules if '.' in m}
    wrong = []
    for path in FILES:
        for chain in re.findall(r'(?<![\w.])\w+(?:\.\w+)+', _prose(path)):
            parts = [*chain.removeprefix('fourbar_ros.').split('.'), '']
            if parts[0] in layers and parts[1] in leaves | layers and f'{parts[0]}.{parts[1]}' not in modules:
                wrong.append(f'{path.relative_to(REPO)}: {chain}')
    assert not wrong, '\n'.join(wrong)
