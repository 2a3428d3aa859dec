"""A drive backend for the real-stack bringup tests, named as a user names theirs (``backend:=recording_drive:
RecordingDrive``, ``drive_backend:=...``): the simulated drive at ``$FOURBAR_RECORDING_START`` rad (``float.hex``),
every write appended to ``$FOURBAR_RECORDING_LOG`` as ``monotonic_s position_rad target_rad`` (repr floats).

CLOCK_MONOTONIC is one clock for every process of the machine, so a test compares these times with its own.
"""

from __future__ import annotations

import os
import time

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.drive.backend import SimulatedBackend
from fourbar_ros.motion.limits import JointLimits

START_ENV, LOG_ENV = 'FOURBAR_RECORDING_START', 'FOURBAR_RECORDING_LOG'


class RecordingDrive(SimulatedBackend):
    """SimulatedBackend at the start the environment gives, at the configuration's speed limit at the rocker."""

    def __init__(self, cfg: AntennaConfig) -> None:
        super().__init__(float.fromhex(os.environ[START_ENV]), JointLimits.from_config(cfg).at_rocker(1))
        self._log = open(os.environ[LOG_ENV], 'a', encoding='utf-8')  # noqa: SIM115 - open for the node's life

    def write(self, position: float) -> None:
        """Record (time, the drive's position before, the target), then move as the simulated drive does."""
        self._advance()
        self._log.write(f'{time.monotonic()!r} {self.position!r} {position!r}\n')
        self._log.flush()
        super().write(position)

    def disable(self) -> None:
        """Stop, and close the record."""
        super().disable()
        self._log.close()


def writes(path: str | os.PathLike[str]) -> list[tuple[float, float, float]]:
    """The recorded writes: (monotonic s, position rad, target rad), in order."""
    if not os.path.exists(path):
        return []
    with open(path, encoding='utf-8') as f:
        rows = [line.split() for line in f if line.endswith('\n')]
    return [(float(t), float(q), float(target)) for t, q, target in rows]
