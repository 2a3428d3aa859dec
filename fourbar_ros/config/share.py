"""Where the package's shared files are: the installed share/fourbar_ros/, else the package data or source tree.

The installed files: docs/reference/cli.md; in a checkout, config/ beside the package and fourbar_ros/data/."""

from __future__ import annotations

import sys
from pathlib import Path

PACKAGE = 'fourbar_ros'
_PACKAGE_DIR = Path(__file__).resolve().parent.parent
#: share/ folder -> its place inside the installed package (package_data), for files that are both.
_PACKAGE_DATA = {'bags': 'data'}


def _installed_share() -> Path | None:
    """share/fourbar_ros of the ament index (a colcon install or a sourced ROS workspace), if indexed."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:
        return None
    try:
        return Path(get_package_share_directory(PACKAGE, print_warning=False))
    except (PackageNotFoundError, ValueError, OSError):  # OSError: AMENT_PREFIX_PATH unset (no ROS environment)
        return None


def share_candidates(relative: str) -> list[Path]:
    """The places ``relative`` (a path inside share/fourbar_ros, e.g. 'config/antenna.yaml') is looked for, in order.

    The ament index first, then the share/ of this Python environment (pip's data_files), then the package data
    and the source tree.
    """
    places: list[Path] = []
    share = _installed_share()
    if share is not None:
        places.append(share / relative)
    places.append(Path(sys.prefix) / 'share' / PACKAGE / relative)
    head, _, rest = relative.partition('/')
    if head in _PACKAGE_DATA and rest:
        places.append(_PACKAGE_DIR / _PACKAGE_DATA[head] / rest)
    places.append(_PACKAGE_DIR.parent / relative)
    return places


def share_path(relative: str) -> Path:
    """Absolute path of ``relative`` inside share/fourbar_ros: the first of ``share_candidates`` that exists.

    If none exists, the first candidate, so an error names where the file was expected.
    """
    places = share_candidates(relative)
    return next((p for p in places if p.exists()), places[0])
