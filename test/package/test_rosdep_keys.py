"""package.xml is something `rosdep install` can satisfy on ROS 2 Jazzy: every dependency key resolves (checked
against the published rosdep key lists kept in test/data/rosdep/, or the package's own rosdep source file
rosdep/fourbar_ros.yaml for keys rosdistro lacks), and every third-party module the package or its tests import has
its key."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest
from support.paths import REPO, TEST_DATA

KEYS_FILE = TEST_DATA / 'rosdep' / 'jazzy_noble_keys.txt'
#: The package's own rosdep source file (keys rosdistro lacks), and the platforms it must serve (Jazzy's).
OWN_SOURCE = REPO / 'rosdep' / 'fourbar_ros.yaml'
PLATFORMS = ('ubuntu', 'debian')

#: Top-level import name -> rosdep key. ROS packages import under their own name (rclpy, std_msgs, ...), which
#: is their key; every other third-party module is listed here. None: no rosdep key exists (see NO_KEY).
IMPORT_KEYS: dict[str, str | None] = {
    'numpy': 'python3-numpy',
    'yaml': 'python3-yaml',
    'rosbags': 'python3-rosbags-pip',
    'ruamel': 'python3-ruamel.yaml',
    'matplotlib': 'python3-matplotlib',
    'PIL': 'python3-pil',
    'mcap': 'mcap-ros2-support',      # the pip package mcap comes with mcap-ros2-support; no key of its own
    'mcap_ros2': 'mcap-ros2-support',
    'ruckig': 'python3-ruckig-pip',   # the package's own key (rosdep/fourbar_ros.yaml)
    'pytest': 'python3-pytest',
    'hypothesis': 'python3-hypothesis',
    'catkin_pkg': 'python3-catkin-pkg',
    'psutil': 'python3-psutil',
    'lxml': 'python3-lxml',
    'rosdep2': 'python3-rosdep',      # the rosdep file checked by rosdep's own code
    'mujoco': 'python3-mujoco-pip',   # rosdistro's pip key (the torque witness; skipped where missing)
    'mpmath': None,
    'pylinkage': None,                 # benchmark peers, imported only by benchmarks (skipped where missing)
    'mechanism': None,
    'pytest_codeblocks': None,         # the documentation tests' Markdown parser (skipped where missing)
}
#: Modules without a rosdep key: tests that import them must skip where they are missing (the reference values
#: they compute are also kept as data in the repository).
NO_KEY = {name for name, key in IMPORT_KEYS.items() if key is None}
#: ROS packages (their import name is their key).
ROS_PACKAGES = {
    'rclpy', 'rcl_interfaces', 'ament_index_python', 'builtin_interfaces', 'std_msgs', 'sensor_msgs',
    'diagnostic_msgs', 'visualization_msgs', 'trajectory_msgs', 'geometry_msgs', 'rosgraph_msgs', 'launch',
    'launch_ros', 'launch_testing', 'launch_testing_ros', 'ros2cli', 'control_msgs', 'controller_manager_msgs',
    'lifecycle_msgs', 'std_srvs',
}
#: The project's own packages and the tests' helper package (test/support); each test file's own name is local too.
LOCAL = {'fourbar_ros', 'benchmarks', 'support', 'conftest', 'test'}


def published_keys() -> set[str]:
    return {line.strip() for line in KEYS_FILE.read_text(encoding='utf-8').splitlines() if line.strip()}


def own_keys() -> dict[str, object]:
    import yaml

    keys: dict[str, object] = yaml.safe_load(OWN_SOURCE.read_text(encoding='utf-8'))
    return keys


def resolvable_keys() -> set[str]:
    """Keys rosdep resolves once the package's source file is registered: rosdistro's and the file's."""
    return published_keys() | set(own_keys())


def package() -> object:
    from catkin_pkg.package import parse_package

    return parse_package(str(REPO / 'package.xml'))


def third_party_imports(paths: list[Path]) -> dict[str, list[str]]:
    """Top-level module name -> files importing it, for modules neither stdlib nor local."""
    local = LOCAL | {p.stem for p in paths}
    found: dict[str, list[str]] = {}
    for path in paths:
        tree = ast.parse(path.read_text(encoding='utf-8'), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top in sys.stdlib_module_names or top in local or top == '__future__':
                    continue
                found.setdefault(top, []).append(str(path.relative_to(REPO)))
    return found


def _test_sources() -> list[Path]:
    """The tests' Python files in every folder under test/ (conftest, helpers, tests), not the data's scripts."""
    return sorted(p for p in (REPO / 'test').rglob('*.py') if TEST_DATA not in p.parents)


def key_of(module: str) -> str | None:
    if module in ROS_PACKAGES:
        return module
    if module not in IMPORT_KEYS:
        raise AssertionError(f'{module}: imported but has no rosdep key in IMPORT_KEYS (find its key in '
                             f'{KEYS_FILE.relative_to(REPO)}, add it here and to package.xml)')
    return IMPORT_KEYS[module]


def test_key_list_is_the_extracted_published_list() -> None:
    keys = published_keys()
    assert len(keys) > 3000  # the whole list, not a hand-picked subset
    assert {'rclpy', 'python3-numpy', 'python3-rosbags-pip'} <= keys
    assert 'python3-mpmath' not in keys  # the reason package.xml must not name it


def test_every_dependency_key_resolves_for_jazzy() -> None:
    pkg = package()
    keys = resolvable_keys()
    groups = ('build_depends', 'buildtool_depends', 'build_export_depends', 'exec_depends', 'test_depends',
              'doc_depends')
    missing = sorted({d.name for g in groups for d in getattr(pkg, g) if d.name not in keys})
    assert not missing, f'package.xml keys that do not resolve for Jazzy (ubuntu noble): {missing}'


def test_every_runtime_import_has_an_exec_depend() -> None:
    pkg = package()
    exec_keys = {d.name for d in pkg.exec_depends}  # type: ignore[attr-defined]
    imports = third_party_imports(sorted((REPO / 'fourbar_ros').rglob('*.py')))
    assert {'rclpy', 'numpy'} <= set(imports)
    problems = []
    for module, files in sorted(imports.items()):
        key = key_of(module)
        if key is None:
            problems.append(f'{module} (imported by {files[0]}) has no rosdep key: the installed package cannot use it')
        elif key not in exec_keys:
            problems.append(f'{module} (imported by {files[0]}): add <exec_depend>{key}</exec_depend>')
    assert not problems, '; '.join(problems)


def test_every_test_import_has_a_key_or_is_known_to_have_none() -> None:
    pkg = package()
    declared = {d.name for d in pkg.exec_depends + pkg.test_depends}  # type: ignore[attr-defined]
    imports = third_party_imports(_test_sources())
    problems = []
    for module, files in sorted(imports.items()):
        key = key_of(module)
        if key is not None and key not in declared:
            problems.append(f'{module} (imported by {files[0]}): add <test_depend>{key}</test_depend>')
    assert not problems, '; '.join(problems)


@pytest.mark.parametrize('module', sorted(NO_KEY))
def test_modules_without_a_key_are_not_declared(module: str) -> None:
    text = (REPO / 'package.xml').read_text(encoding='utf-8')
    assert f'>python3-{module}<' not in text


def test_the_own_source_file_defines_only_keys_rosdistro_lacks_each_a_bare_pinned_pip_package() -> None:
    keys = own_keys()
    assert keys, 'rosdep/fourbar_ros.yaml defines no key'
    assert not set(keys) & published_keys(), 'a key rosdistro defines must not be redefined'
    pinned = {line.split('==')[0] for line in
              (REPO / 'requirements' / 'constraints.txt').read_text(encoding='utf-8').splitlines() if '==' in line}
    for key, rule in keys.items():
        assert isinstance(rule, dict) and set(PLATFORMS) <= set(rule), f'{key}: needs {PLATFORMS}'
        for platform in PLATFORMS:
            packages = rule[platform]['pip']['packages']  # type: ignore[index]
            # bare: rosdep detects an installed pip package by its bare name only
            assert packages and all(p in pinned for p in packages), \
                f'{key} on {platform}: {packages} must be bare names pinned in requirements/constraints.txt'


#: The registration line as the how-to gives it (its first line runs below with ``sudo tee`` replaced).
HOW_TO = REPO / 'docs' / 'how-to' / 'ros2-control.md'
SOURCES_LIST = '/etc/ros/rosdep/sources.list.d/50-fourbar-ros.list'
#: Jazzy's platforms (REP 2000) and the version names rosdep matches.
JAZZY_PLATFORMS = (('ubuntu', 'noble'), ('debian', 'bookworm'))


def _registration_line() -> str:
    lines = [line for line in HOW_TO.read_text(encoding='utf-8').splitlines() if SOURCES_LIST in line]
    header = OWN_SOURCE.read_text(encoding='utf-8')
    assert len(lines) == 1 and f'#   {lines[0]}' in header, (
        f'the how-to gives {len(lines)} registration lines; the source file\'s header must give the same one')
    return lines[0]


def test_the_registration_line_works_from_any_directory_and_rosdep_resolves_and_detects_ruckig(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The how-to's line, run from a directory that is not the clone (HOME holding ~/ws/src/fourbar_ros as the
    quick start clones it), writes a sources line rosdep parses; rosdep loads the file it names and resolves
    python3-ruckig-pip on Jazzy's platforms to a pip package, and its pip check finds the installed ruckig in
    what `pip freeze` prints."""
    import subprocess
    from importlib.metadata import version

    sources_list = pytest.importorskip('rosdep2.sources_list', reason='rosdep (python3-rosdep) is not installed')
    from rosdep2.lookup import RosdepDefinition
    from rosdep2.platforms.pip import PipInstaller, pip_detect

    monkeypatch.setenv('ROS_PYTHON_VERSION', '3')  # as a sourced ROS 2 environment sets it (rosdep's pip lookup)
    home = tmp_path / 'home'
    (home / 'ws' / 'src').mkdir(parents=True)
    (home / 'ws' / 'src' / 'fourbar_ros').symlink_to(REPO)
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    line = _registration_line().replace(f'sudo tee {SOURCES_LIST}', 'cat')
    done = subprocess.run(['bash', '-c', line], cwd=elsewhere, env={'HOME': str(home), 'PATH': '/usr/bin:/bin'},
                          capture_output=True, text=True, timeout=30, check=False)
    assert done.returncode == 0, f'{line!r} from {elsewhere}: {done.stderr}'
    [source] = sources_list.parse_sources_data(done.stdout)
    assert source.type == 'yaml' and Path(source.url.removeprefix('file://')).resolve() == OWN_SOURCE.resolve()
    data = sources_list.download_rosdep_data(source.url)
    installed = version('ruckig')
    for os_name, os_version in JAZZY_PLATFORMS:
        definition = RosdepDefinition('python3-ruckig-pip', data['python3-ruckig-pip'], source.url)
        installer, rule = definition.get_rule_for_platform(os_name, os_version, ['apt', 'pip'], 'apt')
        packages = PipInstaller().resolve(rule)
        assert installer == 'pip' and packages == ['ruckig'], (os_name, installer, rule)
        detected = pip_detect(packages, exec_fn=lambda _cmd: f'numpy==2.4.6\nruckig=={installed}\n')
        assert detected == ['ruckig'], f'rosdep does not see ruckig=={installed} in pip freeze: {detected}'
    # the pinned form would not be seen: rosdep would install it again on every run
    assert pip_detect([f'ruckig=={installed}'], exec_fn=lambda _cmd: f'ruckig=={installed}\n') == []


def test_ruckig_resolves_through_the_own_key() -> None:
    # rosdistro's `ruckig` is the C++ library; the Python module needs the pip key.
    assert 'ruckig' in published_keys() and 'python3-ruckig-pip' not in published_keys()
    assert 'python3-ruckig-pip' in {d.name for d in package().exec_depends}  # type: ignore[attr-defined]
    assert key_of('ruckig') in own_keys()
