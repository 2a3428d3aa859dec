"""Read rosbag2 bags with ``rosbags`` (mcap or sqlite3; no rclpy here): one way in for every bag reader.

``open_bag`` gives a ``BagReader`` (its messages with rosbags' errors as one-line BagErrors); ``find_topic`` picks
the input topic of a kind (commands on ``/antenna_angle_cmd``, measured joint states, antenna trajectories).
docs/how-to/bags.md explains the bags.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rosbags.interfaces import Connection, ConnectionExtRosbag2, Qos
from rosbags.rosbag2 import Reader

from fourbar_ros.bags.storage.adapters import adapter_of_file
from fourbar_ros.bags.storage.common import BagError, jazzy_typestore
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import (
    COMMANDS,
    FLOAT64,
    Kind,
    Storage,
)


class TopicTypeError(BagError):
    """The topic of a kind is in the bag with another message type."""


def find_topic(path: Path, types: dict[str, str], kind: Kind, topic: str | None = None) -> str:
    """The topic of ``kind`` in a bag of topic -> type ``types``: ``topic``, else the first of the kind's names at the
    root, else the one topic (of the kind's type, else of any) ending in one. BagError (one line) if none fits."""
    msgtype = kind.topics[0].msgtype
    if topic is None:
        ends = kind.ends
        candidates = [t for t in types if t.endswith(ends)]
        typed = [t for t in candidates if types[t] == msgtype]
        topic = next((n for n in ends if n in types), None) or next(
            (c[0] for c in (typed, candidates) if len(c) == 1), None)
        if topic is None:
            raise BagError(f'{path}: no {kind.label} topic {ends[0]} ({_describe_topics(types)})')
    elif topic not in types:
        raise BagError(f'{path}: no topic {topic} ({_describe_topics(types)})')
    if types[topic] != msgtype:
        raise TopicTypeError(f'{path}: the {kind.role} topic {topic} has type {types[topic]}, expected {msgtype}')
    return topic


class BagReader:
    """An open bag (``open_bag``): path, topic -> type, storage, and messages with rosbags' errors as BagErrors."""

    def __init__(self, path: Path, reader: Reader) -> None:
        self.path, self.rosbags = path, reader
        self.connections = reader.connections
        self.types = {c.topic: c.msgtype for c in reader.connections}
        self.count = 0  #: messages the latest ``messages`` has given
        self._on = ''

    @property
    def storage(self) -> Storage:
        """The bag's storage plugin; BagError for one the bag tools do not write."""
        return storage_of(self.rosbags)

    def find(self, kind: Kind, topic: str | None = None) -> str:
        """The topic of ``kind`` (``find_topic``)."""
        return find_topic(self.path, self.types, kind, topic)

    def first(self, kinds: Sequence[Kind], topic: str | None = None) -> tuple[Kind, str]:
        """The first of ``kinds`` the bag has and its topic; a given ``topic`` named as some of the kinds is of
        those alone (``/ns/measured_joint_states`` is measured joint states, whatever its type). Else a BagError
        (one line): the first found of a kind with another type (the topic, its type and the one expected), else
        the first kind's."""
        named = [k for k in kinds if topic is not None and k.named(topic)]
        errors: list[BagError] = []
        for kind in named or kinds:
            try:
                return kind, self.find(kind, topic)
            except BagError as exc:
                errors.append(exc)
        if topic is not None and not named and topic in self.types:
            expected = ' or '.join(dict.fromkeys(k.topics[0].msgtype for k in kinds))
            raise TopicTypeError(f'{self.path}: topic {topic} has type {self.types[topic]}, expected {expected}')
        raise next((exc for exc in errors if isinstance(exc, TopicTypeError)), errors[0])

    @contextmanager
    def guard(self) -> Iterator[None]:
        """Raise any error but a BagError in the block as 'unreadable bag after N messages' (one line)."""
        try:
            yield
        except BagError:
            raise
        except Exception as exc:  # rosbags raises ReaderError, OSError, sqlite3, mcap and CDR errors
            raise BagError(f'{self.path}: unreadable bag after {self.count} messages{self._on} '
                           f'({one_line(exc)})') from exc

    def messages(self, topics: Sequence[str] = ()) -> Iterator[tuple[Connection, int, bytes]]:
        """(connection, log time ns, raw CDR) of ``topics`` (default: all) in bag order; counted in ``count``."""
        conns = [c for c in self.connections if not topics or c.topic in topics]
        self.count, self._on = 0, f' on {topics[0]}' if len(topics) == 1 else ''
        with self.guard():
            for message in self.rosbags.messages(connections=conns):
                self.count += 1
                yield message


@contextmanager
def open_bag(path: str | os.PathLike[str] | BagReader) -> Iterator[BagReader]:
    """Open a rosbag2 bag (directory, or a bare ``.mcap``/``.db3`` file) for reading; an open one as it is.

    Raises BagError with one line naming the path and the problem.
    """
    if isinstance(path, BagReader):
        yield path
        return
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
        yield BagReader(p, reader)
    finally:
        with contextlib.suppress(Exception):  # closing a reader that failed mid-read
            reader.close()


def _describe_topics(types: dict[str, str]) -> str:
    if not types:
        return 'the bag has no topics'
    return 'topics: ' + ', '.join(f'{t} [{m}]' for t, m in sorted(types.items()))


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

    ``topic``: the command topic (default: ``find_topic``'s). Raises BagError (one line) for a missing, truncated or
    corrupt bag, a bag without the command topic, a wrong message type, an empty stream or an undecodable message.
    """
    store = jazzy_typestore()
    with open_bag(path) as bag:
        chosen = bag.find(COMMANDS, topic)
        qos = tuple(q for c in bag.connections if c.topic == chosen and isinstance(c.ext, ConnectionExtRosbag2)
                    for q in c.ext.offered_qos_profiles)
        stamps: list[int] = []
        values: list[float] = []
        raws: list[bytes] = []
        for _, stamp, data in bag.messages([chosen]):
            raw = bytes(data)
            try:
                msg: Any = store.deserialize_cdr(raw, FLOAT64)
            except Exception as exc:
                raise BagError(f'{bag.path}: message {len(values)} on {chosen} is not a valid '
                               f'{FLOAT64} ({one_line(exc)})') from exc
            stamps.append(int(stamp))
            values.append(float(msg.data))
            raws.append(raw)
        if not values:
            raise BagError(f'{bag.path}: topic {chosen} has no messages')
        return CommandStream(bag.path, chosen, bag.storage, tuple(stamps), tuple(values), tuple(raws), qos)


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
    store = jazzy_typestore()
    out: dict[str, list[tuple[int, Any]]] = {t: [] for t in topics}
    with open_bag(path) as bag, bag.guard():
        out.update({t: [] for t in bag.types if not topics or t in topics})
        for conn, stamp, data in bag.messages(topics):
            out[conn.topic].append((int(stamp), store.deserialize_cdr(bytes(data), conn.msgtype)))
    return out


def fingerprint(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Everything that defines a bag's content, independent of the storage file's byte layout.

    Metadata version, storage, per topic: type, type hash, message definition, offered QoS and
    serialization format; every message as (topic, stamp_ns, raw CDR bytes) in bag order; and
    the bag's custom data. Two bags with equal fingerprints replay identically.
    """
    p = Path(path)
    with open_bag(p) as bag:
        topics = {}
        for c in bag.connections:
            ext = c.ext
            assert isinstance(ext, ConnectionExtRosbag2)
            topics[c.topic] = (c.msgtype, c.digest, c.msgdef.format.name, c.msgdef.data,
                               ext.serialization_format, tuple(ext.offered_qos_profiles))
        msgs = [(c.topic, int(t), bytes(d)) for c, t, d in bag.messages()]
        meta = bag_metadata(p) if p.is_dir() else {}
        return {'version': meta.get('version'), 'storage': bag.storage,
                'topics': topics, 'messages': msgs, 'custom_data': meta.get('custom_data') or {}}


def bag_metadata(path: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of a bag directory's metadata.yaml."""
    from ruamel.yaml import YAML  # rosbags' own YAML dependency

    data = YAML(typ='safe').load((path / 'metadata.yaml').read_text('utf8'))
    info = data.get('rosbag2_bagfile_information') if isinstance(data, dict) else None
    return info if isinstance(info, dict) else {}
