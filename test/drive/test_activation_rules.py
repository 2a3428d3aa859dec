"""When the drive bridge asks the controller manager to activate its hardware component (``rules.Activation``, pure):
examples, then random sequences of the manager's activity reports (publication sequence numbers, respawns that
restart them), readings (the range's ends, one ulp inside and outside, NaN, inf) with the plugin subscribed or not,
and the manager's answers, checked against what the class promises."""

from __future__ import annotations

import math
from dataclasses import dataclass

from hypothesis import given, settings
from hypothesis import strategies as st

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.drive.rules import (
    ACTIVATED_MARK,
    ACTIVE,
    ANSWER_TIMEOUT_S,
    INACTIVE,
    Activation,
    DriveLimits,
    activated_line,
)

CFG = default_config()
LIMITS = DriveLimits.from_config(CFG)
JOINT, COMPONENT = CFG.driven_joint, CFG.hardware_id
LOW, HIGH = LIMITS.lower, LIMITS.upper
MID = 0.5 * (LOW + HIGH)
#: Readings (rad) inside the range: both ends exactly and one ulp inside each.
INSIDE = [LOW, math.nextafter(LOW, math.inf), MID, math.nextafter(HIGH, -math.inf), HIGH]
#: Readings (rad) refused: one ulp outside each end, far outside, and the non-finite ones.
OUTSIDE = [math.nextafter(LOW, -math.inf), math.nextafter(HIGH, math.inf), LOW - 1.0, HIGH + 1.0,
           math.nan, math.inf, -math.inf]
REFUSED = 'not activating hardware component'


def _activation() -> Activation:
    return Activation(LIMITS, JOINT, COMPONENT)


def test_nothing_is_asked_before_the_manager_reports_the_component_inactive() -> None:
    a = _activation()
    assert a.on_reading(MID, True) is None, 'asked before any report of the manager'
    assert a.on_activity(1, None) is None and a.on_reading(MID, True) is None, 'asked with the component absent'
    assert a.on_activity(2, 'unconfigured') is None and a.on_reading(MID, True) is None, 'asked while unconfigured'
    assert a.manager_state == 'unconfigured' and a.activations == 0


def test_asked_once_after_a_ready_reading_in_range_and_confirmed_by_the_answer() -> None:
    a = _activation()
    assert a.on_activity(1, INACTIVE) is None and a.armed
    assert a.on_reading(MID, False) is None, 'asked before the plugin subscribed to the readings'
    assert a.on_reading(MID, True) == ACTIVE
    assert a.pending and a.on_reading(MID, True) is None, 'asked again while the request is in flight'
    assert a.on_activity(2, INACTIVE) is None and a.on_reading(MID, True) is None, 'asked twice of one manager'
    line = a.on_response(True, ACTIVE)
    assert line == activated_line(COMPONENT, JOINT, MID) and line.startswith(ACTIVATED_MARK)
    assert a.on_activity(3, ACTIVE) is None, 'the report after the answer confirmed it a second time'
    assert (a.activations, a.manager_state, a.pending, a.last_line) == (1, ACTIVE, False, line)


def test_a_lost_answer_is_made_good_by_the_report_of_the_component_active() -> None:
    a = _activation()
    a.on_activity(7, INACTIVE)
    assert a.on_reading(HIGH, True) == ACTIVE
    assert a.on_activity(8, ACTIVE) == activated_line(COMPONENT, JOINT, HIGH)
    assert a.on_response(True, ACTIVE) is None, 'the late answer confirmed it a second time'
    assert a.activations == 1 and not a.pending


def test_a_reading_outside_is_refused_once_per_manager_then_one_inside_activates() -> None:
    a = _activation()
    a.on_activity(1, INACTIVE)
    above = math.nextafter(HIGH, math.inf)
    line = a.on_reading(above, True)
    assert line is not None and line.startswith(REFUSED), line
    assert all(text in line for text in (JOINT, repr(above), repr(LOW), repr(HIGH))), line
    assert a.on_reading(above, True) is None and a.on_reading(math.nan, True) is None, 'refused in a second line'
    assert a.refused == line and a.armed
    assert a.on_reading(HIGH, True) == ACTIVE, 'the end of the range itself is inside it'


def test_a_component_active_without_the_bridges_request_is_left_alone() -> None:
    a = _activation()
    a.on_activity(1, ACTIVE)
    a.on_activity(2, INACTIVE)  # someone deactivated it: not the bridge's to switch on
    assert not a.armed and a.on_reading(MID, True) is None and a.activations == 0


def test_a_failed_request_is_not_repeated_on_the_same_manager_but_on_the_next() -> None:
    a = _activation()
    a.on_activity(1, INACTIVE)
    assert a.on_reading(MID, True) == ACTIVE
    line = a.on_response(False, INACTIVE)
    assert line is not None and COMPONENT in line and 'inactive' in line and not a.pending
    a.on_activity(2, INACTIVE)
    assert a.on_reading(MID, True) is None, 'asked a second time of the manager that refused'
    a.on_activity(1, INACTIVE)  # the sequence restarts: a new manager
    assert a.on_reading(MID, True) == ACTIVE


def test_a_respawned_manager_is_asked_again_only_after_a_fresh_reading() -> None:
    a = _activation()
    a.on_activity(1, INACTIVE)
    assert a.on_reading(MID, True) == ACTIVE and a.on_activity(2, ACTIVE) is not None
    # The manager dies: readings go on while nothing says a new one started.
    assert a.on_reading(MID, True) is None
    assert a.on_activity(2, INACTIVE) is None and a.armed, 'a sequence that does not grow is a new manager'
    assert a.manager_state == INACTIVE and a.activations == 1
    assert a.on_reading(LOW, True) == ACTIVE
    assert a.on_activity(3, ACTIVE) == activated_line(COMPONENT, JOINT, LOW) and a.activations == 2


def test_an_unanswered_request_is_sent_again_after_the_answer_timeout() -> None:
    # A respawned manager reports the component before its service is up; its dead predecessor's service makes the
    # client look ready: the first request can reach no one.
    a = _activation()
    a.on_activity(1, INACTIVE)
    assert a.on_reading(MID, True, 10.0) == ACTIVE
    assert a.on_reading(MID, True, 10.0 + ANSWER_TIMEOUT_S) is None, 'asked again before the answer timeout'
    assert a.on_reading(math.nextafter(HIGH, math.inf), True, 12.0).startswith(REFUSED)  # type: ignore[union-attr]
    assert a.on_reading(LOW, False, 12.0) is None, 'asked again with the service not at hand'
    assert a.on_reading(LOW, True, 12.0) == ACTIVE
    assert a.on_response(True, ACTIVE) == activated_line(COMPONENT, JOINT, LOW)
    assert a.on_response(True, ACTIVE) is None and a.on_reading(LOW, True, 20.0) is None and a.activations == 1


def test_a_request_is_not_sent_again_once_answered_or_reported() -> None:
    for answer in ((True, ACTIVE), (False, INACTIVE)):
        a = _activation()
        a.on_activity(1, INACTIVE)
        assert a.on_reading(MID, True, 0.0) == ACTIVE
        a.on_response(*answer)
        assert a.on_reading(MID, True, 10.0) is None, f'asked again after the answer {answer}'
    a = _activation()
    a.on_activity(1, INACTIVE)
    assert a.on_reading(MID, True, 0.0) == ACTIVE and a.on_activity(2, ACTIVE) is not None
    assert a.on_reading(MID, True, 10.0) is None, 'asked again after the report of the component active'


def test_without_sequence_numbers_every_report_is_a_new_manager() -> None:
    a = _activation()
    a.on_activity(None, ACTIVE)
    a.on_activity(None, INACTIVE)
    assert a.on_reading(MID, True) == ACTIVE, 'a report without a sequence number did not count as a new manager'


def test_a_respawned_manager_without_the_component_yet_is_not_asked() -> None:
    # The first manager reported the component inactive; the bridge had no ready reading. Its successor's first
    # report does not list the component (not loaded yet): nothing is to be asked of it, nor shown as its state.
    a = _activation()
    a.on_activity(5, INACTIVE)
    a.on_activity(1, None)
    assert not a.armed and a.on_reading(MID, True) is None, 'asked of a manager that does not report the component'
    assert a.manager_state == '', f'the dead manager\'s state {a.manager_state!r} shown for its successor'
    a.on_activity(2, INACTIVE)
    assert a.on_reading(MID, True) == ACTIVE


@dataclass
class Life:
    """What the test knows of one manager's life (the spec the class is checked against)."""

    reported: str | None = None  #: the component's state in its latest report (None: absent or not heard)
    shown: str = ''  #: the state in its latest report that gave one ('': none did)
    seen_active: bool = False  #: it reported the component active before any request of the bridge
    requests: int = 0
    confirmations: int = 0
    refusals: int = 0
    outstanding: bool = False  #: a request it has not answered
    requested_at: float = math.nan  #: the reading (rad) the request went out on
    asked_at: float = math.nan  #: when (s) the latest request went out
    lost: bool = False  #: the latest request went unanswered for the answer timeout: to be sent again
    last_sequence: int = 0


STATE = st.sampled_from([INACTIVE, INACTIVE, INACTIVE, ACTIVE, ACTIVE, None, 'unconfigured'])
POSITION = st.one_of(st.sampled_from(INSIDE + OUTSIDE), st.floats(LOW - 0.01, HIGH + 0.01))
READY = st.sampled_from([True, True, True, False])  # the plugin subscribed to the readings and the service up
EVENT = st.one_of(
    st.tuples(st.just('report'), st.integers(1, 3), STATE),  # the same manager; a gap: reports lost (depth 1)
    st.tuples(st.just('report'), st.integers(1, 3), STATE),
    st.tuples(st.just('respawn'), st.integers(0, 10), STATE),  # a new manager, its sequence restarted
    st.tuples(st.just('reading'), POSITION, READY),
    st.tuples(st.just('reading'), POSITION, READY),
    st.tuples(st.just('reading'), POSITION, READY),
    st.tuples(st.just('answer'), st.booleans(), st.sampled_from([ACTIVE, ACTIVE, INACTIVE, ''])),
    st.tuples(st.just('wait'), st.sampled_from([0.5, ANSWER_TIMEOUT_S, 1.5 * ANSWER_TIMEOUT_S]), st.none()),  # s
)


@settings(max_examples=400)
@given(events=st.lists(EVENT, min_size=20, max_size=60))
def test_a_random_sequence_keeps_the_promises(events: list[tuple[str, object, object]]) -> None:
    """Activation is asked only on a ready, finite reading inside the range, published after the present manager
    reported the component inactive (never having reported it active), and once per manager, a failed request
    included, again only once a request went unanswered for the answer timeout (s); a reading outside is refused
    in one line per manager; each activation is confirmed in one line (answer or report, whichever first) naming
    its reading; ``manager_state`` is the present manager's."""
    a = _activation()
    life: Life | None = None  # None: no manager heard yet
    confirmed = 0  # confirmations of the managers before the present one
    now = 0.0  # s
    for kind, x, y in events:
        if kind == 'wait':
            now += float(x)  # type: ignore[arg-type]
            continue
        if kind == 'answer':
            if life is None or not life.outstanding:
                continue  # nobody to answer: a dead manager never does
            ok, label = bool(x), str(y)
            life.outstanding = False
            line = a.on_response(ok, label)
            if ok and label == ACTIVE:
                assert (line is not None) == (life.confirmations == 0), f'answer {ok, label}: {line!r}'
                if line is not None:
                    assert line == activated_line(COMPONENT, JOINT, life.requested_at)
                    life.confirmations, life.shown = life.confirmations + 1, ACTIVE
            else:
                assert line is not None and ACTIVATED_MARK not in line and not a.pending, line
            continue
        if kind in ('report', 'respawn'):
            state = y if y is None else str(y)
            if kind == 'respawn' or life is None:
                # A restarted sequence is one the previous manager's does not exceed.
                sequence = 1 + int(x) % max(life.last_sequence, 1) if life is not None else 1 + int(x)
                confirmed += life.confirmations if life is not None else 0
                life = Life(last_sequence=sequence)
            else:
                sequence = life.last_sequence = life.last_sequence + int(x)
            line = a.on_activity(sequence, state)
            life.reported = state
            life.shown = life.shown if state is None else state
            if state == ACTIVE and life.requests == 0:
                life.seen_active = True
            if line is not None:
                assert state == ACTIVE and life.requests >= 1 and life.confirmations == 0, \
                    f'a confirmation line on {state!r} after {life}'
                assert line == activated_line(COMPONENT, JOINT, life.requested_at)
                life.confirmations += 1
            elif state == ACTIVE and life.requests >= 1:
                assert life.confirmations == 1, f'the report of the component active confirmed nothing: {life}'
            assert a.manager_state == life.shown, f'state {a.manager_state!r} shown after {life}'
            continue
        position, ready = float(x), bool(y)  # type: ignore[arg-type]
        action = a.on_reading(position, ready, now)
        if life is not None and life.outstanding and now - life.asked_at > ANSWER_TIMEOUT_S:
            life.outstanding, life.lost = False, True  # unanswered for the timeout: to be asked again
        eligible = (life is not None and ready and life.reported == INACTIVE and life.confirmations == 0
                    and ((not life.seen_active and life.requests == 0) or life.lost))
        if action == ACTIVE:
            assert eligible and life is not None, f'asked on {position!r} (ready {ready}) after {life}'
            assert LIMITS.in_range(position) and math.isfinite(position), f'asked on {position!r} rad'
            life.requests += 1
            life.outstanding, life.requested_at, life.asked_at, life.lost = True, position, now, False
        elif action is not None:
            assert eligible and life is not None and not LIMITS.in_range(position), \
                f'refused {position!r} (ready {ready}) after {life}: {action!r}'
            assert action.startswith(REFUSED) and life.refusals == 0, f'a second refusal of one manager: {action!r}'
            life.refusals += 1
        else:
            # Not asked: it was not the time, or the reading was outside and already refused for this manager.
            assert not (eligible and LIMITS.in_range(position)), f'not asked on {position!r} rad after {life}'
            assert not (eligible and life is not None and life.refusals == 0), f'{position!r} refused silently'
    assert a.activations == confirmed + (life.confirmations if life is not None else 0), 'activations miscounted'
