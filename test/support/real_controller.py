"""The real joint_trajectory_controller as the judge of the package's model of it: random trajectories to send
(``random_steps``), and each recorded trajectory's reference, update by update, against the motion model
(``rules.controller_motion``) and the simulated actuator's follower (``rules.simulated_drive``): ``judged``.

The recording is jtc_judge.py's. The takeover of a trajectory is the controller state whose reference and feedback
``time_from_start`` are equal (the first sample of a new trajectory; at every other update the reference is sampled
one period ahead); the measured state there is the state the lead-in starts from. Times are the trajectory's own
(``time_from_start``, from its stamp, or from the takeover for a zero stamp), as the controller samples it.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from fourbar_ros.config.controllers import TrajectoryControllerSettings
from fourbar_ros.interface.stamps import NS_PER_S, from_ns, seconds_to_ns
from fourbar_ros.rules.controller_motion import ControllerPoint, Reference, controller_reference
from fourbar_ros.rules.simulated_drive import TrajectoryFollower

#: The kinds of trajectory: which fields its points give (positions, velocities, accelerations).
KINDS = ('p', 'pv', 'pva', 'v')
#: A far-off time base for the simulated follower's float seconds (its takeover and stamps are relative to it).
_FOLLOWER_BASE_S = 1000


def _point(kind: str, t: float, p: float, v: float, a: float) -> list[float | None]:
    return [t, p if 'p' in kind else None, v if 'v' in kind else None, a if 'a' in kind else None]


def random_trajectory(rng: np.random.Generator, kind: str, low: float, high: float) -> list[list[float | None]]:
    """1-5 points of ``kind`` (KINDS) inside [low, high] rad, the first 0.05-0.5 s out, 0.1-0.5 s apart; the
    last at rest (the controller refuses a moving end)."""
    n = int(rng.integers(1, 6))
    times = np.cumsum(np.concatenate([[rng.uniform(0.05, 0.5)], rng.uniform(0.1, 0.5, n - 1)]))
    positions = rng.uniform(low, high, n)
    velocities = np.append(rng.uniform(-0.2, 0.2, n - 1), 0.0)
    accelerations = rng.uniform(-0.5, 0.5, n)
    return [_point(kind, float(t), float(p), float(v), float(a))
            for t, p, v, a in zip(times, positions, velocities, accelerations, strict=True)]


def random_steps(rng: np.random.Generator, count: int, low: float, high: float) -> list[dict[str, Any]]:
    """``count`` trajectories for jtc_judge.py: every kind; stamps zero, in the future or in the past (never so far
    past that the first point is due at the takeover: see ``judged``); sent from rest or while the previous one
    runs."""
    steps: list[dict[str, Any]] = []
    previous_end = 0.0
    for i in range(count):
        kind = KINDS[i % len(KINDS)]
        points = random_trajectory(rng, kind, low, high)
        first = float(points[0][0])  # type: ignore[arg-type]
        stamp = [None, float(rng.uniform(0.02, 0.2)), -float(rng.uniform(0.0, first - 0.03))][int(rng.integers(3))]
        mid = bool(rng.integers(2)) and i > 0
        after = float(rng.uniform(0.05, 0.3)) if mid else previous_end + 0.2
        steps.append({'points': points, 'stamp': stamp, 'after': after, 'kind': kind, 'mid': mid})
        previous_end = max(stamp or 0.0, 0.0) + float(points[-1][0])  # type: ignore[arg-type]
    return steps


@dataclass(frozen=True)
class Judged:
    """One recorded trajectory against the real controller: its index in the recording, its kind, stamp kind
    ('zero', 'future', 'past'), whether it took over a running one, the updates compared, the largest
    |model - real| and |simulated follower - real| of the reference position (rad), and whether the controller held
    the measured position from the takeover on instead (its tolerance check, which the model leaves out); ``first``
    is the index of its takeover's state in the recording."""

    index: int
    kind: str
    stamp: str
    mid: bool
    updates: int
    model: float
    follower: float
    held: bool = False
    first: int = 0


def seen_around(recording: dict[str, Any], judged: Judged, before: int = 3, after: int = 3) -> str:
    """What the recording holds around a judged trajectory's takeover, for a failure message: the trajectory (its
    stamp and receive time, ns, the stamp relative to the receive time) and the controller's states from ``before``
    updates ahead of the takeover to ``after`` past it (stamps relative to the receive time, ns)."""
    traj = recording['trajectories'][judged.index]
    received = int(traj['received'])
    offset = int(traj['stamp']) - received if traj['stamp'] else 0
    lines = [f'trajectory {judged.index}: stamp {traj["stamp"]} ({offset} ns from its receipt), received {received}, '
             f'seen {traj.get("seen")}, points {traj["points"]}']
    states = recording['states']
    for k in range(max(judged.first - before, 0), min(judged.first + after + 1, len(states))):
        s = states[k]
        lines.append(f'  {"->" if k == judged.first else "  "} state {k}: at {s["stamp"] - received} ns, ref_tfs '
                     f'{s["ref_tfs"]}, fb_tfs {s["fb_tfs"]}, ref {s["ref"][0]}, fb {s["fb"][0]}')
    return '\n'.join(lines)


def _kind(points: list[list[float | None]]) -> str:
    first = points[0]
    return ''.join(c for c, x in zip('pva', first[1:], strict=True) if x is not None)


class _Point(SimpleNamespace):
    """A trajectory point as the follower reads a message's."""


def _field(x: Any) -> list[float]:
    return [] if x is None else list(x) if isinstance(x, list) else [x]


def message_points(points: list[list[Any]]) -> list[_Point]:
    """``[t, p, v, a(, effort)]`` rows (jtc_judge.py's) as trajectory points with a message's fields."""
    out = []
    for row in points:
        sec, nanosec = from_ns(seconds_to_ns(float(row[0])))
        out.append(_Point(positions=_field(row[1]), velocities=_field(row[2]), accelerations=_field(row[3]),
                          effort=_field(row[4] if len(row) > 4 else None),
                          time_from_start=SimpleNamespace(sec=sec, nanosec=nanosec)))
    return out


#: How much earlier, or later, than the judge's receive time the controller takes a passing trajectory over (ns):
#: both receive it from the node, in either order, the controller at its next update, and the judge's callback as
#: its process gets the CPU (tens of ms behind on a loaded machine; the window also starts after the previous
#: takeover).
ECHO_EARLY_NS, ECHO_LATE_NS = 500_000_000, 30_000_000
#: How much earlier than its send time an update may take the judge's own trajectory over (ns): an update is stamped
#: when it starts and takes what arrived before it reads the trajectory, up to one period later.
SENT_EARLY_NS = 10_000_000


def earliest_takeover(traj: dict[str, Any]) -> int:
    """The earliest stamp (ns) of an update that may have taken the recorded trajectory ``traj`` over. The judge's
    own: ``SENT_EARLY_NS`` before it was sent, but after the newest update whose state the judge had received by then
    (``seen``: that update was over before the trajectory went out)."""
    if traj['echoed']:
        return int(traj['received']) - ECHO_EARLY_NS
    return max(int(traj['received']) - SENT_EARLY_NS, int(traj.get('seen', 0)))


def _candidates(states: list[dict[str, Any]], traj: dict[str, Any], since: int, until: int) -> list[int]:
    """Indices of the updates stamped in (since, until) (ns) that could have taken ``traj`` over: the reference and
    feedback ``time_from_start`` equal, and the trajectory's own time there 0 for a zero stamp (its origin is that
    update), else the update's time less the stamp (the controller's clock and the header's differ by microseconds).
    """
    out = []
    for k, s in enumerate(states):
        if s['stamp'] <= since or s['ref_tfs'] != s['fb_tfs']:
            continue
        if s['stamp'] >= until:
            break
        if (s['fb_tfs'] == 0) if traj['stamp'] == 0 else abs(s['fb_tfs'] - (s['stamp'] - traj['stamp'])) < 1_000_000:
            out.append(k)
    return out


def _reference_from(states: list[dict[str, Any]], traj: dict[str, Any], k: int, velocity_state: bool,
                    period: float) -> tuple[float, Reference]:
    """(the trajectory's own time s at update k, the model's reference of ``traj`` taken over at update k)."""
    tau0 = states[k]['fb_tfs'] / NS_PER_S
    position, velocity = states[k]['fb'][0][0], (states[k]['fb'][1] or [None])[0]
    points = [ControllerPoint(*p) for p in traj['points']]
    return tau0, controller_reference(velocity_state, points, 0.0, tau0, position, velocity, period)


def _worst(states: list[dict[str, Any]], model: Reference, start: int, stop: int) -> float:
    """Largest |model - real| of the reference position (rad) over the updates start..stop-1."""
    return max((abs(model.sample(s['ref_tfs'] / NS_PER_S)[0] - s['ref'][0][0]) for s in states[start:stop]),
               default=0.0)


@dataclass(frozen=True)
class Takeovers:
    """Which recorded trajectories the controller took over: ``taken`` maps a trajectory's index to the first recorded
    update following it and whether that update took it over (false where the takeover's state is missing from the
    recording: the controller's realtime publisher drops a state while the previous one is still being sent);
    ``unknown`` holds those the recording cannot tell (no state between its arrival and the next one's); the rest
    were refused."""

    taken: dict[int, tuple[int, bool]]
    unknown: frozenset[int]


def _first_sample(s: dict[str, Any]) -> bool:
    """Whether update ``s`` may be a trajectory's first sample: there the controller sets the trajectory's time to the
    update's (reference and feedback ``time_from_start`` equal to the ns; later updates add the measured period,
    which differs by hundreds of ns) and interpolates from the measured state at zero elapsed time, so the reference
    position is the feedback position exactly."""
    return bool(s['ref_tfs'] == s['fb_tfs'] and s['ref'][0][0] == s['fb'][0][0])


def _start(s: dict[str, Any]) -> int:
    """The start (ns, header clock) of the trajectory an update follows: its time less its ``time_from_start``."""
    return int(s['stamp']) - int(s['fb_tfs'])


def takeovers(recording: dict[str, Any], velocity_state: bool, period: float) -> Takeovers:
    """Every recorded trajectory's fate (``Takeovers``).

    The judge's own trajectories: taken over when an update after its arrival (one period of slack: an update is
    stamped as it starts) follows a trajectory that starts where this one does (its stamp; for a zero stamp, the
    takeover of the latest such one to arrive before); the takeover is the first such update when it is recorded
    (``time_from_start`` 0 for a zero stamp; else the reference and feedback times equal, right after an update of
    the previous one). The node's are seen passing and reach the controller before the judge (by up to
    ``ECHO_EARLY_NS``, after the previous takeover) or a few updates after: one with a stamp of its own is taken over
    at the first update that follows its start (exactly there when that update's reference and feedback times are
    equal); a plan that continues the running one starts where that one does, so several updates can qualify: the one
    the model follows best up to the window's end is taken (a model wrong at every candidate still fails)."""
    states = recording['states']
    trajectories = recording['trajectories']
    arrivals = [earliest_takeover(t) for t in trajectories] + [2**63]
    taken: dict[int, tuple[int, bool]] = {}
    unknown: set[int] = set()
    # The judge's own: each update follows the stamped trajectory that starts where it does and had arrived, else the
    # latest zero-stamped one that arrived before the update's trajectory started (at its takeover). A stamp in the
    # past can equal an earlier zero-stamped trajectory's takeover time to the millisecond: before its own arrival
    # the updates follow that one. Two random stamps can also lie within a millisecond of each other: the newer one
    # replaces the older from its takeover (its first sample: reference and feedback times equal), unless the
    # controller refused it.
    own = [i for i, t in enumerate(trajectories) if not t['echoed']]
    stamped = {t['stamp']: i for i, t in enumerate(trajectories) if not t['echoed'] and t['stamp'] != 0}
    zero = [i for i in own if trajectories[i]['stamp'] == 0]
    follows: dict[int, list[int]] = {}
    for k, s in enumerate(states):
        at = _start(s)
        match = [i for x, i in stamped.items() if abs(at - x) < 1_000_000 and s['stamp'] > arrivals[i]]
        if len(match) > 1:
            match = [max((i for i in match if i in follows or _first_sample(s)), default=match[0])]
        if not match:
            match = [i for i in zero if arrivals[i] < at][-1:]
        if match and s['stamp'] > arrivals[match[0]]:
            follows.setdefault(match[0], []).append(k)
    for i in own:
        if i in follows:
            k = follows[i][0]
            s, before = states[k], states[k - 1] if k > 0 else None
            gapless = before is not None and s['stamp'] - before['stamp'] < 1.5 * period * NS_PER_S
            exact = _first_sample(s) and (
                s['fb_tfs'] == 0 if trajectories[i]['stamp'] == 0 else gapless and k - 1 not in follows[i])
            taken[i] = (k, exact)
        elif not any(arrivals[i] < s['stamp'] < arrivals[i + 1] for s in states):
            unknown.add(i)
    last_stamp = 0
    for i, t in enumerate(trajectories):
        if not t['echoed']:
            continue
        since = max(arrivals[i], last_stamp)
        until = min(arrivals[i + 1], t['received'] + ECHO_LATE_NS)
        found = _candidates(states, t, since, until)
        unique = t['stamp'] != 0 and sum(u['stamp'] == t['stamp'] for u in trajectories) == 1
        exact = True
        if unique:  # the first update that follows its start, wherever the judge saw it pass
            found = [k for k, s in enumerate(states) if s['stamp'] > since and abs(_start(s) - t['stamp']) < 1_000_000
                     ][:1]
            exact = bool(found) and _first_sample(states[found[0]])
        if not found:
            unknown.add(i)
            continue
        if len(found) > 1:
            stop = next((j for j, s in enumerate(states) if s['stamp'] >= until), len(states))
            found = [min(found, key=lambda k: _worst(states, _reference_from(states, t, k, velocity_state,
                                                                               period)[1], k, stop))]
        taken[i] = (found[0], exact)
        last_stamp = states[found[0]]['stamp']
    return Takeovers(taken, frozenset(unknown))


def judged(recording: dict[str, Any], settings: TrajectoryControllerSettings, joint: str,
           period: float) -> list[Judged]:
    """Every recorded trajectory the controller took over at a recorded update (``takeovers``), compared update by
    update until the next one's takeover."""
    states = recording['states']
    trajectories = recording['trajectories']
    velocity_state = 'velocity' in settings.state_interfaces
    found = takeovers(recording, velocity_state, period)
    # A segment ends at the next takeover, or where a trajectory the recording cannot place may have taken over.
    lost = [next((k for k, s in enumerate(states) if s['stamp'] > earliest_takeover(trajectories[i])), len(states))
            for i in found.unknown]
    firsts = sorted([k for k, _ in found.taken.values()] + lost)
    out: list[Judged] = []
    for index, (k, exact) in found.taken.items():
        if not exact:
            continue
        traj = trajectories[index]
        later = [j for j in firsts if j > k]
        upto = later[0] if later else len(states)
        tau0, model = _reference_from(states, traj, k, velocity_state, period)
        position, velocity = states[k]['fb'][0][0], (states[k]['fb'][1] or [None])[0]
        follower = TrajectoryFollower(settings, joint, position, period)
        taken_over: list[Reference] = []
        follower.on_takeover = taken_over.append
        now = _FOLLOWER_BASE_S + tau0
        stamp_ns = 0 if traj['stamp'] == 0 else _FOLLOWER_BASE_S * NS_PER_S
        refusal = follower.receive([joint], message_points(traj['points']), stamp_ns, seconds_to_ns(now))
        assert refusal is None, f'the simulated follower refused what the real controller took: {refusal}'
        follower.reference(now, position, velocity or 0.0)
        assert len(taken_over) == 1, 'the simulated follower did not take the trajectory over at its first update'
        simulated = taken_over[0]  # its takeover at 0, the trajectory's own time at tau0
        worst_follower = max((abs(simulated.sample(s['ref_tfs'] / NS_PER_S - tau0)[0] - s['ref'][0][0])
                              for s in states[k:upto]), default=0.0)
        stamp = 'zero' if traj['stamp'] == 0 else ('future' if traj['stamp'] > traj['received'] else 'past')
        here = states[k]['fb'][0][0]
        held = all(s['ref'][0][0] == here and s['ref'][1][0] == 0.0 for s in states[k + 1:upto])
        out.append(Judged(index, _kind(traj['points']), stamp, k > 0 and states[k - 1]['ref'][1][0] != 0.0, upto - k,
                          _worst(states, model, k, upto), worst_follower, held, k))
    return out
