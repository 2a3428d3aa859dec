"""Lease a ROS_DOMAIN_ID nobody on this host uses (lock file + DDS discovery ports). No rclpy."""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

from fourbar_ros.core.errors import FourBarError


class DomainError(FourBarError):
    """No ROS_DOMAIN_ID is free on this host."""


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(('', port))
        except OSError:
            return False
    return True


def domain_in_use(domain_id: int, participants: int = 8) -> bool:
    """True if a DDS participant of ``domain_id`` runs on this host.

    Checks the first ``participants`` unicast discovery ports of the RTPS port mapping
    (7400 + 250 d + 10 + 2 i), which a running participant holds exclusively.
    """
    base = 7400 + 250 * domain_id + 10
    return not all(_port_free(base + 2 * i) for i in range(participants))


#: Domain ids a fourbar run may take: safe on Linux (discovery ports outside the ephemeral range) and
#: clear of the ranges developers use by hand; the test suite leases from the same ids and lock files.
FREE_DOMAIN_IDS: tuple[int, ...] = (*range(90, 102), *range(215, 233))
DOMAIN_LOCK_DIR = Path(tempfile.gettempdir()) / 'fourbar_ros_domain_locks'


@contextlib.contextmanager
def free_domain_id(candidates: Sequence[int] = FREE_DOMAIN_IDS,
                   lock_dir: Path = DOMAIN_LOCK_DIR) -> Iterator[int]:
    """Reserve a ROS_DOMAIN_ID nobody on this host uses, for the duration of the ``with`` block.

    A domain is free when no other fourbar run holds its lock file (``<lock_dir>/<id>.lock``,
    flock, shared with the test suite) and no DDS participant holds its discovery ports.
    """
    lock_dir.mkdir(parents=True, exist_ok=True)
    start = os.getpid() % len(candidates)
    for domain in list(candidates[start:]) + list(candidates[:start]):
        try:
            fd = os.open(lock_dir / f'{domain}.lock', os.O_CREAT | os.O_RDWR, 0o666)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        try:
            if domain_in_use(domain):
                continue
            yield domain
            return
        finally:
            os.close(fd)  # drops the flock
    raise DomainError(f'no free ROS_DOMAIN_ID among {candidates[0]}..{candidates[-1]}')
