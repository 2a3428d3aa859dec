"""The drive-follows check: off the reference by more than the tolerance for the timeout, and only then."""

from __future__ import annotations

from fourbar_ros.rules.follow_check import FollowCheck

S = 1_000_000_000  # ns per s


def test_a_drive_off_its_reference_for_the_timeout_does_not_follow_and_the_check_starts_afresh() -> None:
    check = FollowCheck(tolerance=0.02, timeout=1.0)
    assert check.update(0.90, 0.85, 0) == ''  # off by 0.05 rad: the clock starts
    assert check.update(0.91, 0.85, S - 1) == ''  # 1 ns short of the timeout
    line = check.update(0.91, 0.85, S)
    assert line.startswith('the drive does not follow: measured 0.85 rad, -0.06 rad off the reference for 1 s'), line
    assert check.off_since_ns is None and check.update(0.91, 0.85, S + 1) == ''  # afresh


def test_a_drive_within_the_tolerance_or_back_within_it_follows() -> None:
    check = FollowCheck(tolerance=0.015625, timeout=1.0)  # 2**-6: the differences below are exact
    assert check.update(0.90, 0.90 - 0.015625, 0) == ''  # at the tolerance (within an ulp of 0.9): follows
    assert check.off_since_ns is None
    assert check.update(0.90, 0.87, 0) == '' and check.off_since_ns == 0
    assert check.update(0.90, 0.89, S // 2) == '' and check.off_since_ns is None  # back: the clock stops
    assert check.update(0.90, 0.85, S) == '' and check.update(0.90, 0.85, 2 * S - 1) == ''
    assert check.update(0.90, 0.85, 2 * S) != ''


def test_a_zero_timeout_checks_nothing() -> None:
    check = FollowCheck(tolerance=0.02, timeout=0.0)
    assert all(check.update(1.0, 0.0, t * S) == '' for t in range(10))
