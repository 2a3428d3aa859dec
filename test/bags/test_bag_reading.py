"""The one way into a bag: find_topic's choice and errors for each kind, BagReader's one-line read errors, and
`fourbar process` opening its input once. No ROS middleware."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.bag_support import BAG_DIR, run_main

from fourbar_ros.bags.storage import (
    COMMANDS,
    FLOAT64,
    JOINT_STATE,
    MEASURED,
    TRAJECTORIES,
    BagError,
    find_topic,
    open_bag,
)
from fourbar_ros.bags.storage import read as read_module
from fourbar_ros.interface.topics import JOINT_TRAJECTORY

P = Path('bag')


@pytest.mark.parametrize(('kind', 'types', 'topic', 'want'), [
    (COMMANDS, {'/antenna_angle_cmd': FLOAT64, '/ns/antenna_angle_cmd': FLOAT64}, None, '/antenna_angle_cmd'),
    (COMMANDS, {'/ns/antenna_angle_cmd': FLOAT64, '/other': FLOAT64}, None, '/ns/antenna_angle_cmd'),
    (COMMANDS, {'/tilt': FLOAT64}, '/tilt', '/tilt'),
    (MEASURED, {'/joint_state_broadcaster/joint_states': JOINT_STATE, '/measured_joint_states': JOINT_STATE}, None,
     '/measured_joint_states'),
    (MEASURED, {'/r/joint_state_broadcaster/joint_states': JOINT_STATE, '/joint_states': JOINT_STATE}, None,
     '/r/joint_state_broadcaster/joint_states'),
    (TRAJECTORIES, {'/a/antenna_trajectory': JOINT_TRAJECTORY, '/antenna_trajectory': JOINT_TRAJECTORY}, None,
     '/antenna_trajectory'),
    (TRAJECTORIES, {'/a/antenna_trajectory': JOINT_TRAJECTORY, '/b/antenna_trajectory': FLOAT64}, None,
     '/a/antenna_trajectory'),
])
def test_the_topic_of_each_kind(kind: read_module.Kind, types: dict[str, str], topic: str | None, want: str) -> None:
    assert find_topic(P, types, kind, topic) == want


@pytest.mark.parametrize(('kind', 'types', 'topic', 'words'), [
    (COMMANDS, {}, None, 'bag: no command topic /antenna_angle_cmd (the bag has no topics)'),
    (COMMANDS, {'/a/antenna_angle_cmd': FLOAT64, '/b/antenna_angle_cmd': FLOAT64}, None,
     'bag: no command topic /antenna_angle_cmd (topics: /a/antenna_angle_cmd [std_msgs/msg/Float64], '),
    (COMMANDS, {'/antenna_angle_cmd': JOINT_STATE}, None,
     f'bag: the command topic /antenna_angle_cmd has type {JOINT_STATE}, expected {FLOAT64}'),
    (MEASURED, {'/x': JOINT_STATE}, '/nothing', 'bag: no topic /nothing (topics: /x ['),
    (MEASURED, {'/x': FLOAT64}, '/x', f'bag: the measured topic /x has type {FLOAT64}, expected {JOINT_STATE}'),
    (TRAJECTORIES, {'/x': FLOAT64}, None, f'bag: no {JOINT_TRAJECTORY} topic /antenna_trajectory (topics: /x ['),
])
def test_one_line_when_no_topic_fits(kind: read_module.Kind, types: dict[str, str], topic: str | None,
                                     words: str) -> None:
    with pytest.raises(BagError) as err:
        find_topic(P, types, kind, topic)
    assert str(err.value).startswith(words) and '\n' not in str(err.value)


def test_the_first_kind_a_bag_has_else_the_first_kinds_error() -> None:
    with open_bag(BAG_DIR / 'sweep_mcap') as bag:
        assert bag.first((MEASURED, COMMANDS)) == (COMMANDS, '/antenna_angle_cmd')
        with pytest.raises(BagError, match='no measured'):
            bag.first((MEASURED, TRAJECTORIES))


def test_an_error_while_reading_is_one_line_with_the_count(tmp_path: Path) -> None:
    with open_bag(BAG_DIR / 'sweep_mcap') as bag:
        with pytest.raises(BagError) as err, bag.guard():
            for n, _ in enumerate(bag.messages(['/antenna_angle_cmd']), 1):
                if n == 3:
                    raise ValueError('bad bytes\nmore')
        assert str(err.value) == f'{bag.path}: unreadable bag after 3 messages on /antenna_angle_cmd (bad bytes)'


def test_process_opens_its_input_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    opened: list[Path] = []

    class Counting(read_module.Reader):  # type: ignore[misc]
        def open(self) -> None:
            opened.append(Path(str(self.path)))
            super().open()

    monkeypatch.setattr(read_module, 'Reader', Counting)
    rc, lines, _ = run_main(['process', BAG_DIR / 'sweep_mcap', tmp_path / 'out'])
    assert rc == 0, lines
    assert opened == [BAG_DIR / 'sweep_mcap']
