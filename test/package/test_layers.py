"""The package's layers import one way: core < interface < config < motion < rules < bags < analysis < runtime < drive
< node < live < plant < commands; no cycles; pure core; no ROS in interface, motion, rules, bags and analysis.

Read from the source with ``ast`` (nothing of the package is imported), so a violation is reported even in
modules whose imports would fail here. Lazy imports inside functions count too.
"""

from __future__ import annotations

import ast
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import fourbar_ros

PACKAGE_DIR = Path(fourbar_ros.__file__).parent
#: Lowest first; a module may import only its own layer and the layers before it.
LAYERS = ('core', 'interface', 'config', 'motion', 'rules', 'bags', 'analysis', 'runtime', 'drive', 'node', 'live',
          'plant', 'commands')
#: Third-party modules the core must never import (ROS, YAML, bags, plotting).
IMPURE = ('rclpy', 'rosbags', 'mcap', 'mcap_ros2', 'yaml', 'ruamel', 'matplotlib', 'PIL', 'std_msgs', 'sensor_msgs',
          'diagnostic_msgs', 'visualization_msgs', 'geometry_msgs', 'rcl_interfaces', 'builtin_interfaces',
          'rosgraph_msgs', 'ament_index_python')


def _modules() -> dict[str, Path]:
    """Dotted name -> file for every module of the package."""
    found = {'fourbar_ros': PACKAGE_DIR / '__init__.py'}
    for info in pkgutil.walk_packages([str(PACKAGE_DIR)], prefix='fourbar_ros.'):
        rel = info.name.split('.')[1:]
        path = PACKAGE_DIR.joinpath(*rel)
        found[info.name] = path / '__init__.py' if info.ispkg else path.with_suffix('.py')
    return found


MODULES = _modules()


def _imported_names(name: str, path: Path) -> list[tuple[str, str]]:
    """(module, name) for every ``from fourbar_ros... import name`` in the module (relative ones resolved)."""
    tree = ast.parse(path.read_text(encoding='utf-8'))
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                parts = package.split('.')
                base = '.'.join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
            if base.split('.')[0] == 'fourbar_ros':
                out += [(base, alias.name) for alias in node.names]
    return out


def _imports(name: str, path: Path) -> set[str]:
    """Absolute names of every module ``name`` imports (relative imports resolved)."""
    tree = ast.parse(path.read_text(encoding='utf-8'))
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                parts = package.split('.')
                base = '.'.join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
            out.add(base)
            out.update(f'{base}.{alias.name}' for alias in node.names if f'{base}.{alias.name}' in MODULES)
    return out


def _layer(name: str) -> int | None:
    parts = name.split('.')
    return LAYERS.index(parts[1]) if len(parts) > 1 and parts[1] in LAYERS else None


GRAPH = {name: {m for m in _imports(name, path) if m in MODULES and m != name} for name, path in MODULES.items()}


def test_every_module_lives_in_a_layer() -> None:
    loose = [name for name in MODULES if name != 'fourbar_ros' and _layer(name) is None]
    assert not loose, f'modules outside the layer folders {LAYERS}: {loose}'


def test_no_module_imports_a_higher_layer() -> None:
    upward = [f'{name} -> {dep}' for name, deps in GRAPH.items() for dep in deps
              if (lo := _layer(name)) is not None and (hi := _layer(dep)) is not None and hi > lo]
    assert not upward, 'imports that run up the layers:\n' + '\n'.join(sorted(upward))


def test_package_root_imports_only_the_core() -> None:
    assert all(_layer(dep) == 0 for dep in GRAPH['fourbar_ros'] if dep != 'fourbar_ros')


def test_no_import_cycles() -> None:
    # Tarjan-free check: depth-first search for a back edge, reporting the cycle it closes.
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(name: str) -> None:
        state[name] = 1
        stack.append(name)
        for dep in sorted(GRAPH[name]):
            if dep == 'fourbar_ros' or dep.startswith(name + '.'):
                continue  # a package's face importing its own submodules is not a cycle of modules
            if state.get(dep) == 1:
                cycles.append([*stack[stack.index(dep):], dep])
            elif dep not in state:
                visit(dep)
        stack.pop()
        state[name] = 2

    for name in sorted(GRAPH):
        if name not in state:
            visit(name)
    assert not cycles, 'import cycles:\n' + '\n'.join(' -> '.join(c) for c in cycles)


def test_no_private_name_crosses_a_module() -> None:
    crossing = [f'{name} takes {module}.{imported}' for name, path in MODULES.items()
                for module, imported in _imported_names(name, path) if imported.startswith('_')]
    assert not crossing, 'private names imported from another module:\n' + '\n'.join(crossing)


@pytest.mark.parametrize('name', sorted(n for n in MODULES if _layer(n) == 0))
def test_core_module_imports_nothing_impure(name: str) -> None:
    third_party = {m.split('.')[0] for m in _imports(name, MODULES[name])}
    assert not third_party & set(IMPURE), f'{name} imports {sorted(third_party & set(IMPURE))}'


def test_core_imports_with_ros_yaml_bags_and_plotting_blocked() -> None:
    """Every core module (found by walking fourbar_ros.core) imports in a process where those packages cannot load."""
    core = [*sorted(n for n in MODULES if _layer(n) == 0), 'fourbar_ros']
    script = f"""
import importlib, importlib.abc, sys
BLOCKED = {IMPURE!r}
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname.split('.')[0] in BLOCKED:
            raise ImportError(f'blocked for the purity test: {{fullname}}')
        return None
sys.meta_path.insert(0, Block())
for name in {core!r}:
    importlib.import_module(name)
from fourbar_ros import AntennaLinkage, Branch, Driven
print(AntennaLinkage(0.180, 0.060, 0.102).rocker_angles(0.0, Branch.UPPER).gamma)
"""
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert float(done.stdout) > 0.0


#: Layers that may not import ROS (they run without rclpy; the node wires them in).
ROS_FREE_LAYERS = tuple(LAYERS.index(name) for name in ('interface', 'motion', 'rules', 'bags', 'analysis'))
ROS = tuple(m for m in IMPURE if m not in ('yaml', 'ruamel', 'matplotlib', 'PIL', 'rosbags', 'mcap', 'mcap_ros2'))


@pytest.mark.parametrize('name', sorted(n for n in MODULES if _layer(n) in ROS_FREE_LAYERS))
def test_ros_free_module_imports_no_ros(name: str) -> None:
    third_party = {m.split('.')[0] for m in _imports(name, MODULES[name])}
    assert not third_party & set(ROS), f'{name} imports {sorted(third_party & set(ROS))}'


def test_ros_free_layers_import_with_ros_blocked() -> None:
    """Every module of the ROS-free layers imports in a process where no ROS package can load."""
    motion = sorted(n for n in MODULES if _layer(n) in ROS_FREE_LAYERS)
    assert motion
    script = f"""
import importlib, importlib.abc
import sys
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname.split('.')[0] in {ROS!r}:
            raise ImportError(f'blocked for the purity test: {{fullname}}')
        return None
sys.meta_path.insert(0, Block())
for name in {motion!r}:
    importlib.import_module(name)
"""
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
