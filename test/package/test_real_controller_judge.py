"""How the real-controller tests attribute the controller's updates to the trajectories they sent (``takeovers``), on
recordings made up here: no ROS needed."""

from __future__ import annotations

from typing import Any

from support.real_controller import takeovers

MS = 1_000_000
PERIOD_S = 0.01


def _state(stamp: int, start: int, ref: float = 0.8, fb: float = 0.8, ref_tfs: int | None = None) -> dict[str, Any]:
    """An update stamped ``stamp`` (ns) following the trajectory that started at ``start`` (ns): its reference and
    feedback positions (rad, at rest by default) and time from start (ns; the reference's may differ)."""
    return {'stamp': stamp, 'ref_tfs': stamp - start if ref_tfs is None else ref_tfs, 'fb_tfs': stamp - start,
            'ref': [[ref], [0.0]], 'fb': [[fb], [0.0]]}


def _sent(received: int, seen: int, stamp: int = 0) -> dict[str, Any]:
    return {'received': received, 'echoed': False, 'stamp': stamp, 'points': [[0.2, 0.8, None, None]], 'seen': seen}


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


def test_of_two_stamps_within_a_millisecond_the_newer_is_followed_from_its_first_sample() -> None:
    """Trajectory 0 (stamped 100 ms) runs from the update of 100 ms; trajectory 1, stamped 0.4 ms later, arrives at
    295 ms and is taken over at the update of 300 ms (its first sample: reference and feedback equal). From there the
    updates follow trajectory 1, though both stamps match them to the millisecond."""
    first, second = 100 * MS, 100 * MS + 400_000
    states = [_state(t * MS, first, 0.80 + t * 1e-4, 0.80 + t * 1e-4 - 1e-5, t * MS - first + 300)
              for t in range(110, 300, 10)]
    states[:0] = [_state(90 * MS, -1000 * MS), _state(first, first)]  # at rest on an older one, then the takeover
    states += [_state(300 * MS, second, 0.83, 0.83)]
    states += [_state(t * MS, second, 0.83 + t * 1e-5, 0.83 + t * 1e-5 - 1e-6, t * MS - second + 200)
               for t in range(310, 500, 10)]
    recording = {'trajectories': [_sent(90 * MS, 80 * MS, first), _sent(295 * MS, 290 * MS, second)],
                 'states': states}
    found = takeovers(recording, True, PERIOD_S)
    k0 = next(i for i, s in enumerate(states) if s['stamp'] == first)
    k1 = next(i for i, s in enumerate(states) if s['stamp'] == 300 * MS)
    assert found.taken == {0: (k0, True), 1: (k1, True)} and not found.unknown, found


def test_an_update_with_equal_times_but_the_reference_off_the_feedback_is_no_exact_takeover() -> None:
    """The takeover's own state is missing (the realtime publisher dropped it) and the next one has reference and
    feedback times equal by chance while moving: it is not the trajectory's first sample, so it is not judged."""
    stamp = 200 * MS
    states = [_state(t * MS, -1000 * MS) for t in range(100, 201, 10)]
    states += [_state(t * MS, stamp, 0.81, 0.805) for t in range(205, 400, 10)]
    recording = {'trajectories': [_sent(195 * MS, 190 * MS, stamp)], 'states': states}
    found = takeovers(recording, True, PERIOD_S)
    k = next(i for i, s in enumerate(states) if s['stamp'] == 205 * MS)
    assert found.taken == {0: (k, False)}, found
