"""Read and validate rosbag2 bags with ``rosbags`` (mcap or sqlite3; no rclpy here).

Command bags carry ``std_msgs/msg/Float64`` antenna angle commands (radians) on
``/antenna_angle_cmd``: the name the node's relative subscription ``antenna_angle_cmd``
resolves to in the root namespace, so ``ros2 bag play BAG`` reaches a node started without a
namespace (for a namespaced node: ``ros2 bag play BAG --remap /antenna_angle_cmd:=/NS/antenna_angle_cmd``).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rosbags.interfaces import ConnectionExtRosbag2, Qos
from rosbags.rosbag2 import Reader

from fourbar_ros.bags.storage.adapters import adapter_of_file
from fourbar_ros.bags.storage.common import COMMAND_TOPIC, BagError, jazzy_typestore
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import COMMAND, FLOAT64, Storage


@contextmanager
def open_bag(path: str | os.PathLike[str]) -> Iterator[Reader]:
    """Open a rosbag2 bag (directory, or a bare ``.mcap``/``.db3`` file) for reading.

    Raises BagError with one line naming the path and the problem.
    """
    p = Path(path)
    if not p.exists():
        raise BagError(f'{p}: no such bag')
    if p.is_dir() and not (p / 'metadata.yaml').is_file():
        raise BagError(f'{p}: not a rosbag2 bag (no metadata.yaml)')
    try:
        reader = Reader(p)
        reader.open()
    except Exception as exc:  # rosbags raises ReaderError, OSError, sqlite3 and YAML errors
        raise BagError(f'{p}: unreadable bag ({one_line(exc)})') from exc
    try:
        yield reader
    finally:
        with contextlib.suppress(Exception):  # closing a reader that failed mid-read
            reader.close()


def topic_types(reader: Reader) -> dict[str, str]:
    """Topic name -> message type of every connection in an open bag."""
    return {c.topic: c.msgtype for c in reader.connections}


def _describe_topics(types: dict[str, str]) -> str:
    if not types:
        return 'the bag has no topics'
    return 'topics: ' + ', '.join(f'{t} [{m}]' for t, m in sorted(types.items()))


def pick_command_topic(path: Path, types: dict[str, str], topic: str | None) -> str:
    if topic is not None:
        if topic not in types:
            raise BagError(f'{path}: no topic {topic} ({_describe_topics(types)})')
        chosen = topic
    elif COMMAND_TOPIC in types:
        chosen = COMMAND_TOPIC
    else:
        # A recording of a namespaced node (/NS/antenna_angle_cmd) is accepted when unambiguous.
        candidates = [t for t in types if t.rsplit('/', 1)[-1] == COMMAND.name]
        if len(candidates) != 1:
            raise BagError(f'{path}: no command topic {COMMAND_TOPIC} ({_describe_topics(types)})')
        chosen = candidates[0]
    if types[chosen] != FLOAT64:
        raise BagError(f'{path}: topic {chosen} has type {types[chosen]}, expected {FLOAT64}')
    return chosen


@dataclass(frozen=True)
class CommandStream:
    """The antenna angle commands of a bag, in bag order.

    ``stamps_ns``: receive timestamps (ns since the epoch) as recorded; ``values``: theta (rad,
    may be NaN/inf or out of limits: the bag is data, the node judges it); ``raw``: the CDR
    bytes as stored, which a Jazzy rclpy publisher sends unchanged.
    """

    path: Path
    topic: str
    storage: Storage
    stamps_ns: tuple[int, ...]
    values: tuple[float, ...]
    raw: tuple[bytes, ...]
    qos: tuple[Qos, ...] = field(default=())

    def __len__(self) -> int:
        return len(self.values)


def read_commands(path: str | os.PathLike[str], topic: str | None = None) -> CommandStream:
    """Read and validate the command stream of a bag (every message decoded before returning).

    ``topic``: the command topic to use (default: ``/antenna_angle_cmd``, else the one topic
    named ``*/antenna_angle_cmd``). Raises BagError (one line) for a missing, truncated or corrupt
    bag, a bag without the command topic, a wrong message type, an empty stream or an
    undecodable message.
    """
    p = Path(path)
    store = jazzy_typestore()
    with open_bag(p) as reader:
        chosen = pick_command_topic(p, topic_types(reader), topic)
        conns = [c for c in reader.connections if c.topic == chosen]
        qos: list[Qos] = []
        for c in conns:
            if isinstance(c.ext, ConnectionExtRosbag2):
                qos.extend(c.ext.offered_qos_profiles)
        stamps: list[int] = []
        values: list[float] = []
        raws: list[bytes] = []
        try:
            for _, stamp, data in reader.messages(connections=conns):
                raw = bytes(data)
                try:
                    msg: Any = store.deserialize_cdr(raw, FLOAT64)
                except Exception as exc:
                    raise BagError(f'{p}: message {len(values)} on {chosen} is not a valid '
                                   f'{FLOAT64} ({one_line(exc)})') from exc
                stamps.append(int(stamp))
                values.append(float(msg.data))
                raws.append(raw)
        except BagError:
            raise
        except Exception as exc:
            raise BagError(f'{p}: unreadable bag after {len(values)} messages '
                           f'({one_line(exc)})') from exc
        storage = storage_of(reader)
    if not values:
        raise BagError(f'{p}: topic {chosen} has no messages')
    return CommandStream(p, chosen, storage, tuple(stamps), tuple(values), tuple(raws), tuple(qos))


def storage_of(reader: Reader) -> Storage:
    """Storage plugin of an open bag; BagError for one the bag tools do not write."""
    path = Path(str(reader.path))
    if path.is_file():
        found = adapter_of_file(path)
        if found is not None:
            return found.storage
        name = path.suffix
    else:
        name = str(bag_metadata(path).get('storage_identifier', ''))
    try:
        return Storage(name)
    except ValueError:
        raise BagError(f'{path}: storage {name!r} is not one of {", ".join(map(str, Storage))}') from None


def read_messages(path: str | os.PathLike[str],
                  topics: Sequence[str] = ()) -> dict[str, list[tuple[int, Any]]]:
    """Decode every message of ``topics`` (default: all) as ``topic -> [(stamp_ns, msg), ...]``.

    Every requested topic (default: every topic of the bag) has an entry, empty without messages.

    Raises BagError (one line) for unreadable bags or messages.
    """
    p = Path(path)
    store = jazzy_typestore()
    out: dict[str, list[tuple[int, Any]]] = {t: [] for t in topics}
    with open_bag(p) as reader:
        conns = [c for c in reader.connections if not topics or c.topic in topics]
        for c in conns:
            out.setdefault(c.topic, [])
        try:
            for conn, stamp, data in reader.messages(connections=conns):
                out.setdefault(conn.topic, []).append(
                    (int(stamp), store.deserialize_cdr(bytes(data), conn.msgtype)))
        except Exception as exc:
            raise BagError(f'{p}: unreadable bag ({one_line(exc)})') from exc
    return out


def fingerprint(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Everything that defines a bag's content, independent of the storage file's byte layout.

    Metadata version, storage, per topic: type, type hash, message definition, offered QoS and
    serialization format; every message as (topic, stamp_ns, raw CDR bytes) in bag order; and
    the bag's custom data. Two bags with equal fingerprints replay identically.
    """
    p = Path(path)
    with open_bag(p) as reader:
        topics = {}
        for c in reader.connections:
            ext = c.ext
            assert isinstance(ext, ConnectionExtRosbag2)
            topics[c.topic] = (c.msgtype, c.digest, c.msgdef.format.name, c.msgdef.data,
                               ext.serialization_format, tuple(ext.offered_qos_profiles))
        msgs = [(c.topic, int(t), bytes(d)) for c, t, d in reader.messages()]
        meta = bag_metadata(p) if p.is_dir() else {}
        return {'version': meta.get('version'), 'storage': storage_of(reader),
                'topics': topics, 'messages': msgs, 'custom_data': meta.get('custom_data') or {}}


def bag_metadata(path: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of a bag directory's metadata.yaml."""
    from ruamel.yaml import YAML  # rosbags' own YAML dependency

    data = YAML(typ='safe').load((path / 'metadata.yaml').read_text('utf8'))
    info = data.get('rosbag2_bagfile_information') if isinstance(data, dict) else None
    return info if isinstance(info, dict) else {}
