"""What every part of the bag storage shares: topic and type names, the error, the Jazzy typestore, QoS."""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING, Literal

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.typesys import Stores, get_typestore

from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.topics import COMMAND

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

#: The command topic as a recording at the root namespace holds it.
COMMAND_TOPIC = f'/{COMMAND.name}'
METADATA_VERSION: Literal[9] = 9  # rosbag2 metadata version of ROS 2 Jazzy

# RMW_DURATION_INFINITE as rosbag2 stores it: 2**63 - 1 ns split into seconds and nanoseconds.
_INFINITE_NS = 2**63 - 1
INFINITE = QosTime(_INFINITE_NS // 1_000_000_000, _INFINITE_NS % 1_000_000_000)


class BagError(FourBarError):
    """A bag that is missing, unreadable, lacks the expected topic or type, or cannot be written."""


@lru_cache(maxsize=1)
def jazzy_typestore() -> Typestore:
    """The ROS 2 Jazzy message types of ``rosbags`` (explicitly Jazzy, not the newest distro)."""
    return get_typestore(Stores.ROS2_JAZZY)


def type_hash(msgtype: str, msgdef: str, fmt: str) -> str:
    """RIHS01 hash of ``msgtype`` from its stored definition (``fmt``: 'ros2msg' or 'ros2idl'); Jazzy's if the
    definition is absent or unparsable; '' for a type Jazzy does not know either."""
    from rosbags.typesys import get_types_from_idl, get_types_from_msg

    if msgdef:
        try:
            store = get_typestore(Stores.EMPTY)
            store.register(get_types_from_idl(msgdef) if fmt == 'ros2idl' else get_types_from_msg(msgdef, msgtype))
            return str(store.hash_rihs01(msgtype))
        except Exception:  # an unparsable definition: fall back to the Jazzy type below
            pass
    jazzy = jazzy_typestore()
    if msgtype in jazzy.fielddefs:
        return str(jazzy.hash_rihs01(msgtype))
    return ''


def time_from_ns(ns: int) -> QosTime:
    """A QoS duration (ns; ``>= 2**63 - 1`` is infinite) as rosbag2's ``{sec, nsec}``."""
    ns = min(int(ns), _INFINITE_NS)
    return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)


def recorded_qos(*, reliable: bool = True, transient_local: bool = False) -> Qos:
    """The offered QoS profile ``ros2 bag record`` stores for a publisher with these policies.

    The ROS graph reports an endpoint's history as unknown (depth 0) and unset durations as
    infinite; that is what a Jazzy recorder writes and what ``ros2 bag play`` adapts on replay
    (it keeps reliability and durability and chooses its own history depth).
    """
    return Qos(
        QosHistory.UNKNOWN, 0,
        QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
        INFINITE, INFINITE, QosLiveliness.AUTOMATIC, INFINITE, False)


def parse_offered_qos(text: str) -> tuple[Qos, ...]:
    """The offered QoS profiles stored with a topic in a storage file (rosbag2's YAML text); () if unparsable.

    rosbags exposes no public parser for this text (its Reader parses it while opening a complete bag);
    ``rosbags.rosbag2.metadata.parse_qos`` is that parser, used here and nowhere else.
    """
    from rosbags.rosbag2.metadata import parse_qos

    try:
        return tuple(parse_qos(text))
    except Exception:  # a malformed or foreign QoS text: the topic is still recoverable without it
        return ()
