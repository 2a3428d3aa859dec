"""How the real-controller tests attribute the controller's updates to the trajectories they sent (``takeovers``), on
recordings made up here: no ROS needed."""

from __future__ import annotations

from typing import Any

from support.real_controller import takeovers

MS = 1_000_000
PERIOD_S = 0.01


def _state(stamp: int, start: int) -> dict[str, Any]:
    """An update stamped ``stamp`` (ns) following the trajectory that started at ``start`` (ns)."""
    return {'stamp': stamp, 'ref_tfs': stamp - start, 'fb_tfs': stamp - start}


def _sent(received: int, seen: int) -> dict[str, Any]:
    return {'received': received, 'echoed': False, 'stamp': 0, 'points': [[0.2, 0.8, None, None]], 'seen': seen}


def test_a_late_takeover_is_credited_to_the_trajectory_sent_before_it_not_to_the_next() -> None:
    """A delivery under load: trajectory 0, sent at 0 ms, is taken over at the update of 300 ms; the judge sees that
    update's state and sends trajectory 1 (refused by the controller) 5 ms later, within the 10 ms by which an update
    may precede the arrival of what it takes. The update the judge had already seen cannot have taken trajectory 1."""
    takeover = 300 * MS
    states = [_state(t * MS, -1000 * MS) for t in range(-50, 300, 10)]
    states += [_state(t * MS, takeover) for t in range(300, 700, 10)]
    recording = {'trajectories': [_sent(0, -60 * MS), _sent(takeover + 5 * MS, takeover)], 'states': states}
    found = takeovers(recording, True, PERIOD_S)
    k = next(i for i, s in enumerate(states) if s['stamp'] == takeover)
    assert found.taken == {0: (k, True)} and not found.unknown, found
