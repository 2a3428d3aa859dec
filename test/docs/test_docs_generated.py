"""The reference tables that restate code (topics per mode, parameters) are what scripts/generate_reference.py makes
of the code today."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from types import ModuleType

import pytest
from support.paths import REPO

from fourbar_ros.config.params import PARAMETERS
from fourbar_ros.interface.topics import Mode, endpoints


def _generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location('generate_reference', REPO / 'scripts' / 'generate_reference.py')
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


GENERATOR = _generator()


@pytest.mark.parametrize('path', GENERATOR.DOCS, ids=lambda p: p.name)
def test_committed_tables_are_the_generated_ones(path: Path) -> None:
    text = path.read_text(encoding='utf-8')
    assert GENERATOR.MARKER.search(text), f'{path}: no generated section'
    assert GENERATOR.render(text) == text, f'{path}: run python scripts/generate_reference.py'


def test_every_parameter_and_every_topic_is_in_the_tables() -> None:
    params = (REPO / 'docs' / 'reference' / 'parameters.md').read_text(encoding='utf-8')
    topics = (REPO / 'docs' / 'reference' / 'topics.md').read_text(encoding='utf-8')
    assert all(f'| `{p.name}` |' in params for p in PARAMETERS)
    assert all(f'| `{e.topic.name}` |' in topics for m in Mode for e in endpoints(m))


def test_a_stale_table_is_found(tmp_path: Path) -> None:
    text = (REPO / 'docs' / 'reference' / 'parameters.md').read_text(encoding='utf-8')
    stale = text.replace('| `frame_length` | double | 0.18 |', '| `frame_length` | double | 0.2 |')
    assert stale != text and GENERATOR.render(stale) == text


def _slug(heading: str) -> str:
    """A heading's anchor as GitHub makes it: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r'[^\w\- ]', '', heading.strip().lower())
    return text.replace(' ', '-')


def test_every_link_between_the_documents_resolves() -> None:
    """Each fact lives in one document and the others link to it: every relative link names a file of the
    repository and, with '#', one of its headings."""
    docs = [REPO / 'README.md', *sorted((REPO / 'docs').rglob('*.md'))]
    broken = []
    for doc in docs:
        text = doc.read_text(encoding='utf-8')
        for target in re.findall(r'\]\(([^)\s]+)\)', text):
            if re.match(r'[a-z]+:', target):
                continue
            path, _, anchor = target.partition('#')
            file = (doc.parent / path).resolve() if path else doc
            if not file.exists():
                broken.append(f'{doc.relative_to(REPO)}: {target} (no such file)')
            elif anchor and file.suffix == '.md':
                headings = re.findall(r'^#+ (.+)$', file.read_text(encoding='utf-8'), re.MULTILINE)
                if anchor not in {_slug(h) for h in headings}:
                    broken.append(f'{doc.relative_to(REPO)}: {target} (no such heading)')
    assert not broken, '\n'.join(broken)
