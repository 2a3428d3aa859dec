"""Extract the rosdep keys that resolve for ROS 2 Jazzy on Ubuntu 24.04 (noble) from a rosdistro checkout.

    python test/data/rosdep/extract_keys.py ROSDISTRO_CHECKOUT > test/data/rosdep/jazzy_noble_keys.txt

Reads rosdep/base.yaml and rosdep/python.yaml (system and pip keys: kept when their ``ubuntu`` entry names
packages for noble, directly, through ``'*'`` or under an installer such as ``pip``) and jazzy/distribution.yaml
(ROS package names: the ``release: packages:`` of every repository with a release entry, or the repository's name).
Only the resulting key list is kept in the repository (test/package/test_rosdep_keys.py reads it); rosdep resolves a key
the same way (``rosdep resolve KEY --rosdistro jazzy --os ubuntu:noble``).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import yaml

CODENAME = 'noble'


def _names_packages(rule: Any) -> bool:
    """True if a rule (list, installer mapping or codename mapping) installs something."""
    if isinstance(rule, list):
        return bool(rule)
    if isinstance(rule, dict):
        if 'packages' in rule:
            return bool(rule['packages'])
        if CODENAME in rule:
            return rule[CODENAME] is not None and _names_packages(rule[CODENAME])
        if '*' in rule:
            return rule['*'] is not None and _names_packages(rule['*'])
        installers = {'apt', 'pip', 'source'} & set(rule)
        return any(_names_packages(rule[i]) for i in installers)
    return False


def system_keys(path: Path) -> set[str]:
    """Keys of a rosdep YAML file with a rule for Ubuntu noble."""
    data = yaml.safe_load(path.read_text(encoding='utf-8'))
    return {key for key, rules in data.items() if isinstance(rules, dict) and _names_packages(rules.get('ubuntu'))}


def ros_packages(path: Path) -> set[str]:
    """Released package names of a rosdistro distribution.yaml."""
    data = yaml.safe_load(path.read_text(encoding='utf-8'))
    names: set[str] = set()
    for repo, entry in data['repositories'].items():
        release = entry.get('release')
        if not release or not release.get('version'):
            continue
        names.update(release.get('packages') or [repo])
    return names


def main(root: str) -> int:
    base = Path(root)
    keys = system_keys(base / 'rosdep' / 'base.yaml') | system_keys(base / 'rosdep' / 'python.yaml')
    keys |= ros_packages(base / 'jazzy' / 'distribution.yaml')
    sys.stdout.write(''.join(f'{k}\n' for k in sorted(keys)))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1]))
