"""The harness's Collector (support.ros_support), fed by a thread as the executor feeds it: a wait looks at each
message once, from ``start`` on, and keeps its place across ``clear``. No middleware."""

from __future__ import annotations

import threading

import pytest
from support.ros_support import Collector


def feed(col: Collector[int], values: range, gate: threading.Event) -> threading.Thread:
    """A thread that delivers ``values`` one by one, each after the waiter has looked at the one before."""
    def run() -> None:
        for v in values:
            gate.wait()
            gate.clear()
            col(v)
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def test_each_message_is_looked_at_once_while_they_arrive() -> None:
    col: Collector[int] = Collector('/t')
    looked: list[int] = []
    gate = threading.Event()

    def predicate(v: int) -> bool:
        looked.append(v)
        gate.set()  # the next message comes only now: every arrival wakes the wait again
        return v == 199

    for v in range(5):
        col(v)
    gate.set()
    thread = feed(col, range(5, 200), gate)
    assert col.wait_match(predicate, timeout=30.0, start=2) == 199
    thread.join(timeout=30.0)
    assert looked == list(range(2, 200))  # from start on, each once


def test_a_wait_keeps_its_place_across_clear_and_reports_what_it_saw() -> None:
    col: Collector[int] = Collector('/t')
    for v in range(3):
        col(v)
    col.clear()
    col(7)
    assert col.wait_match(lambda v: v == 7, timeout=5.0) == 7
    assert col.drop_while(lambda v: v < 10) == 1 and len(col) == 0
    with pytest.raises(AssertionError, match=r'0 looked at, none matched; 0 received'):
        col.wait_match(lambda v: True, timeout=0.05)
