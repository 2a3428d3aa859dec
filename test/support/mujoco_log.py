"""MuJoCo's warnings in a test: collected, not written to MUJOCO_LOG.TXT in the working folder."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator


@contextlib.contextmanager
def mujoco_warnings() -> Iterator[list[str]]:
    """MuJoCo's warnings (an unstable step) collected while the block runs."""
    import mujoco

    seen: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(seen.append)
    try:
        yield seen
    finally:
        mujoco.set_mju_user_warning(previous)
