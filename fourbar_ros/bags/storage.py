"""Read, validate and atomically write rosbag2 bags with ``rosbags`` (no rclpy here).

Command bags carry ``std_msgs/msg/Float64`` antenna angle commands (radians) on
``/antenna_angle_cmd``: the name the node's relative subscription ``antenna_angle_cmd``
resolves to in the root namespace, so ``ros2 bag play BAG`` reaches a node started without a
namespace (for a namespaced node: ``ros2 bag play BAG --remap /antenna_angle_cmd:=/NS/antenna_angle_cmd``).

Every bag this module writes is a rosbag2 bag of metadata version 9 (ROS 2 Jazzy) with the
message definitions (``ros2msg``), type hashes (RIHS01) and offered QoS profiles a
``ros2 bag record`` of the same publishers would store. Writes are atomic: the bag is built in a
hidden temporary directory next to the target and renamed into place only when complete.

A writer can ``flush()`` what it has so far (recordings do it every second by default), so a process
killed mid-recording leaves its data in that hidden directory; ``reindex()`` turns it into a complete
bag (see docs/bags.md).
"""

from __future__ import annotations

import contextlib
import itertools
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any, Literal

from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag2,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2.metadata import parse_qos
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from rosbags.typesys import Stores, get_typestore

from fourbar_ros.core.errors import FourBarError, one_line

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

COMMAND_TOPIC = '/antenna_angle_cmd'
FLOAT64 = 'std_msgs/msg/Float64'
JOINT_STATE = 'sensor_msgs/msg/JointState'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
STORAGES: tuple[str, ...] = ('mcap', 'sqlite3')
DEFAULT_STORAGE = 'mcap'
METADATA_VERSION: Literal[9] = 9  # rosbag2 metadata version of ROS 2 Jazzy

_PLUGINS = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
# RMW_DURATION_INFINITE as rosbag2 stores it: 2**63 - 1 ns split into seconds and nanoseconds.
_INFINITE_NS = 2**63 - 1
INFINITE = QosTime(_INFINITE_NS // 1_000_000_000, _INFINITE_NS % 1_000_000_000)


class BagError(FourBarError):
    """A bag that is missing, unreadable, lacks the expected topic or type, or cannot be written."""


@lru_cache(maxsize=1)
def jazzy_typestore() -> Typestore:
    """The ROS 2 Jazzy message types of ``rosbags`` (explicitly Jazzy, not the newest distro)."""
    return get_typestore(Stores.ROS2_JAZZY)


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


# --------------------------------------------------------------------------- reading

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
        candidates = [t for t in types if t.rsplit('/', 1)[-1] == 'antenna_angle_cmd']
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
    storage: str
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


def storage_of(reader: Reader) -> str:
    """Storage plugin of an open bag: 'mcap' or 'sqlite3'."""
    path = Path(str(reader.path))
    if path.is_file():
        return 'sqlite3' if path.suffix == '.db3' else 'mcap'
    return str(_metadata(path).get('storage_identifier', ''))


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
        meta = _metadata(p) if p.is_dir() else {}
        return {'version': meta.get('version'), 'storage': storage_of(reader),
                'topics': topics, 'messages': msgs, 'custom_data': meta.get('custom_data') or {}}


def _metadata(path: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of a bag directory's metadata.yaml."""
    from ruamel.yaml import YAML  # rosbags' own YAML dependency

    data = YAML(typ='safe').load((path / 'metadata.yaml').read_text('utf8'))
    info = data.get('rosbag2_bagfile_information') if isinstance(data, dict) else None
    return info if isinstance(info, dict) else {}


# --------------------------------------------------------------------------- writing

class AtomicBagWriter:
    """A rosbag2 writer (metadata v9) that publishes its bag only when it is complete.

    Use as a context manager. The bag is built under a hidden sibling directory
    ``.NAME.*.partial`` (the bag itself at ``.NAME.*.partial/NAME``) and renamed to ``path`` after a
    clean exit; on any exception, including KeyboardInterrupt, the temporary directory is removed and
    ``path`` never appears. If the process dies without running any cleanup (SIGKILL, power loss),
    the hidden directory stays with whatever ``flush()`` had handed to the OS; ``reindex(path)``
    recovers it.
    """

    def __init__(self, path: str | os.PathLike[str], storage: str = DEFAULT_STORAGE) -> None:
        self.path = Path(path)
        if storage not in _PLUGINS:
            raise BagError(f'{self.path}: unknown storage {storage!r} (choose from '
                           f'{", ".join(STORAGES)})')
        if self.path.exists() or self.path.is_symlink():
            raise BagError(f'{self.path}: exists already, not overwriting')
        parent = self.path.parent
        if not parent.is_dir():
            raise BagError(f'{self.path}: parent directory {parent} does not exist')
        if not self.path.name or self.path.name in {'.', '..'}:
            raise BagError(f'{self.path}: not a valid bag name')
        self.storage = storage
        self._tmpdir: Path | None = None
        self._writer: Writer | None = None
        self.counts: dict[str, int] = {}

    def __enter__(self) -> AtomicBagWriter:
        self.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()

    def open(self) -> None:
        """Create the temporary bag directory and open the storage."""
        try:
            tmp = Path(tempfile.mkdtemp(prefix=f'.{self.path.name}.', suffix='.partial',
                                        dir=self.path.parent))
        except OSError as exc:
            raise BagError(f'{self.path}: cannot write here ({one_line(exc)})') from exc
        self._tmpdir = tmp
        try:
            self._writer = Writer(tmp / self.path.name, version=METADATA_VERSION,
                                  storage_plugin=_PLUGINS[self.storage])
            self._writer.open()
        except BaseException:
            self.abort()
            raise

    @property
    def work_dir(self) -> Path | None:
        """The hidden ``.NAME.*.partial`` directory the bag is built in (None when not open)."""
        return self._tmpdir

    def flush(self) -> None:
        """Hand every message written so far to the OS, so it survives this process being killed.

        mcap: the open chunk (if it holds messages) is closed and the file buffer flushed;
        sqlite3: the open transaction is committed. No fsync: this protects against the process
        dying (SIGKILL, OOM killer, a crash), not against the machine losing power.
        """
        storage = self.writer.storage
        if isinstance(storage, McapWriter):
            if any(storage.chunk.msgs.values()):
                storage.close_chunk()
            storage.bio.flush()
        elif isinstance(storage, Sqlite3Writer):
            storage.conn.commit()

    @property
    def writer(self) -> Writer:
        if self._writer is None:
            raise BagError(f'{self.path}: bag is not open')
        return self._writer

    def add_topic(self, topic: str, msgtype: str, qos: Sequence[Qos] = (), *,
                  typestore: Typestore | None = None, msgdef: str | None = None,
                  rihs01: str | None = None) -> Connection:
        """Register a topic (CDR) with its offered QoS profiles and message definition."""
        try:
            conn = self.writer.add_connection(
                topic, msgtype, typestore=typestore or jazzy_typestore(), msgdef=msgdef,
                rihs01=rihs01, serialization_format='cdr', offered_qos_profiles=list(qos))
        except BagError:
            raise
        except Exception as exc:
            raise BagError(f'{self.path}: cannot add topic {topic} [{msgtype}] '
                           f'({one_line(exc)})') from exc
        self.counts[topic] = 0
        return conn

    def write(self, conn: Connection, stamp_ns: int, data: bytes | memoryview) -> None:
        """Append one serialized (CDR) message received at ``stamp_ns`` (ns since the epoch)."""
        self.writer.write(conn, int(stamp_ns), data)
        self.counts[conn.topic] += 1

    def set_custom_data(self, key: str, value: str) -> None:
        """Store a string in the bag's metadata ``custom_data``."""
        self.writer.set_custom_data(key, value)

    def commit(self) -> Path:
        """Close the storage, write metadata.yaml, fsync and rename the bag into place."""
        writer, tmp = self.writer, self._tmpdir
        assert tmp is not None
        try:
            writer.close()
            self._writer = None
            built = tmp / self.path.name
            for f in built.iterdir():
                _fsync(f)
            _fsync(built)
            if self.path.exists():
                raise BagError(f'{self.path}: appeared while writing, not overwriting')
            os.rename(built, self.path)
            _fsync(self.path.parent)
        except BaseException as exc:
            self.abort()
            if isinstance(exc, Exception) and not isinstance(exc, BagError):
                raise BagError(f'{self.path}: could not write bag ({one_line(exc)})') from exc
            raise
        shutil.rmtree(tmp, ignore_errors=True)
        self._tmpdir = None
        return self.path

    def abort(self) -> None:
        """Drop everything written so far; ``path`` is left untouched."""
        writer, self._writer = self._writer, None
        if writer is not None:
            with contextlib.suppress(Exception):  # the directory is removed below anyway
                writer.abort()
        tmp, self._tmpdir = self._tmpdir, None
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def float64_cdr(value: float) -> bytes:
    """The CDR bytes of a ``std_msgs/msg/Float64`` holding ``value`` (NaN and inf kept)."""
    store = jazzy_typestore()
    msg = store.types[FLOAT64](data=float(value))
    return bytes(store.serialize_cdr(msg, FLOAT64))


def write_command_bag(path: str | os.PathLike[str], stamps_ns: Sequence[int],
                      values: Sequence[float], storage: str = DEFAULT_STORAGE,
                      topic: str = COMMAND_TOPIC,
                      custom_data: dict[str, str] | None = None) -> Path:
    """Write a command bag: ``values`` (theta, rad) on ``topic`` at ``stamps_ns`` (ns, epoch).

    The topic is recorded as offered by a reliable, volatile publisher.
    """
    if len(stamps_ns) != len(values):
        raise BagError(f'{path}: {len(stamps_ns)} stamps for {len(values)} values')
    if any(b < a for a, b in itertools.pairwise(stamps_ns)):
        raise BagError(f'{path}: stamps must not decrease')
    with AtomicBagWriter(path, storage) as bag:
        conn = bag.add_topic(topic, FLOAT64, [recorded_qos()])
        for key, value in (custom_data or {}).items():
            bag.set_custom_data(key, value)
        for stamp, theta in zip(stamps_ns, values, strict=True):
            bag.write(conn, stamp, float64_cdr(theta))
    return Path(path)


# --------------------------------------------------------------------------- recovering killed recordings

@dataclass(frozen=True)
class _Topic:
    """A topic as found in a storage file: everything AtomicBagWriter.add_topic needs."""

    cid: int
    name: str
    msgtype: str
    msgdef: str
    digest: str
    serialization_format: str
    qos: tuple[Qos, ...]


@dataclass
class ReindexResult:
    """What ``reindex`` recovered: the new bag, its messages per topic, and what was dropped.

    ``source``: the storage file read; ``source_bytes``: its size; ``kept_bytes``: the bytes of its
    complete records (mcap) or its size (sqlite3); ``dropped``: why reading stopped before the end of
    the file (an incomplete last chunk, a corrupt page), or None when the whole file was readable.
    """

    path: Path
    storage: str
    source: Path
    source_bytes: int
    kept_bytes: int
    counts: dict[str, int] = field(default_factory=dict)
    dropped: str | None = None
    removed: Path | None = None

    @property
    def messages(self) -> int:
        """Messages in the rebuilt bag."""
        return sum(self.counts.values())


def partial_dirs(path: str | os.PathLike[str]) -> list[Path]:
    """The hidden work directories ``.NAME.*.partial`` an AtomicBagWriter for ``path`` left behind."""
    p = Path(path)
    if not p.parent.is_dir():
        return []
    return sorted(d for d in p.parent.iterdir()
                  if d.name.startswith(f'.{p.name}.') and d.name.endswith('.partial') and (d / p.name).is_dir())


def _digest(msgtype: str, msgdef: str, fmt: str) -> str:
    """RIHS01 hash of ``msgtype`` from its stored definition (Jazzy's if the definition is absent)."""
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


def _scan_mcap(file: Path, result: ReindexResult) -> Iterator[_Topic | tuple[int, int, bytes]]:
    """Yield topics (when first seen) and messages ``(channel id, log time ns, CDR)`` of every
    complete record; stop quietly at the first incomplete or corrupt one (noted in ``result``)."""
    from mcap.records import Channel as McapChannel
    from mcap.records import Message as McapMessage
    from mcap.records import Schema as McapSchema
    from mcap.stream_reader import StreamReader

    schemas: dict[int, McapSchema] = {}
    size = file.stat().st_size
    with file.open('rb') as f:
        reader = StreamReader(f, record_size_limit=max(size, 1))
        records = reader.records
        while True:
            try:
                record = next(records)
            except StopIteration:
                result.kept_bytes = f.tell()
                return
            except Exception as exc:  # the stream ends (mid-record, or with no footer), or a record is corrupt
                if result.kept_bytes < size:
                    result.dropped = (f'{size - result.kept_bytes} bytes after the last complete record: '
                                      f'{one_line(exc)}')
                return
            result.kept_bytes = f.tell()
            if isinstance(record, McapSchema):
                schemas[record.id] = record
            elif isinstance(record, McapChannel):
                schema = schemas.get(record.schema_id)
                if schema is None:
                    continue
                msgdef = schema.data.decode('utf8', 'replace')
                qos_text = record.metadata.get('offered_qos_profiles', '')
                try:
                    qos = tuple(parse_qos(qos_text))
                except Exception:
                    qos = ()
                yield _Topic(record.id, record.topic, schema.name, msgdef,
                             _digest(schema.name, msgdef, schema.encoding), record.message_encoding, qos)
            elif isinstance(record, McapMessage):
                yield record.channel_id, record.log_time, bytes(record.data)


def _scan_sqlite3(file: Path, result: ReindexResult) -> Iterator[_Topic | tuple[int, int, bytes]]:
    """Like ``_scan_mcap`` for a rosbag2 sqlite3 file (committed rows; sqlite rolls back the rest)."""
    import sqlite3

    con = sqlite3.connect(f'file:{file}?mode=rw', uri=True)  # rw: sqlite rolls a hot journal back
    try:
        defs: dict[str, tuple[str, str, str]] = {}
        try:
            for typ, enc, text, digest in con.execute(
                    'SELECT topic_type, encoding, encoded_message_definition, type_description_hash '
                    'FROM message_definitions'):
                defs[str(typ)] = (str(enc), str(text), str(digest))
        except sqlite3.Error:
            pass  # older schema without definitions
        try:
            rows = list(con.execute('SELECT id, name, type, serialization_format, offered_qos_profiles, '
                                    'type_description_hash FROM topics'))
        except sqlite3.Error:
            rows = [(*r, '') for r in con.execute(
                'SELECT id, name, type, serialization_format, offered_qos_profiles FROM topics')]
        for tid, name, typ, ser, qos_text, digest in rows:
            enc, text, def_digest = defs.get(str(typ), ('ros2msg', '', ''))
            try:
                qos = tuple(parse_qos(str(qos_text)))
            except Exception:
                qos = ()
            yield _Topic(int(tid), str(name), str(typ), text,
                         str(digest or def_digest or _digest(str(typ), text, enc)), str(ser), qos)
        try:
            for tid, stamp, data in con.execute('SELECT topic_id, timestamp, data FROM messages ORDER BY id'):
                yield int(tid), int(stamp), bytes(data)
        except sqlite3.Error as exc:
            result.dropped = one_line(exc)
        result.kept_bytes = result.source_bytes
    finally:
        con.close()


def _storage_file(bag: Path) -> tuple[Path, str]:
    files = sorted(p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3') and p.is_file())
    if not files:
        raise BagError(f'{bag}: no storage file (.mcap or .db3) to reindex')
    if len(files) > 1:
        raise BagError(f'{bag}: {len(files)} storage files; reindex handles single-file bags')
    return files[0], 'mcap' if files[0].suffix == '.mcap' else 'sqlite3'


def _copy(file: Path, storage: str, bag: AtomicBagWriter, result: ReindexResult) -> None:
    """Write every recoverable topic and message of ``file`` into ``bag``, in stored order."""
    scan = _scan_mcap if storage == 'mcap' else _scan_sqlite3
    conns: dict[int, Connection] = {}
    by_name: dict[str, Connection] = {}
    for item in scan(file, result):
        if isinstance(item, _Topic):
            if item.name not in by_name:
                by_name[item.name] = bag.add_topic(
                    item.name, item.msgtype, item.qos, msgdef=item.msgdef or None, rihs01=item.digest or None)
                result.counts[item.name] = 0
            conns[item.cid] = by_name[item.name]
        else:
            cid, stamp, data = item
            conn = conns.get(cid)
            if conn is not None:  # a message of a channel that was never announced cannot be typed
                bag.write(conn, stamp, data)
                result.counts[conn.topic] += 1


def _source_and_target(path: Path) -> tuple[Path, Path, Path | None]:
    """(bag directory to read, where the rebuilt bag goes, work directory to remove afterwards)."""
    if not path.exists() and not path.is_symlink():
        found = partial_dirs(path)
        if not found:
            raise BagError(f'{path}: no such bag and no interrupted recording (.{path.name}.*.partial) '
                           'next to it')
        if len(found) > 1:
            raise BagError(f'{path}: {len(found)} interrupted recordings ({", ".join(d.name for d in found)}); '
                           'pass the one to recover')
        return found[0] / path.name, path, found[0]
    if not path.is_dir():
        raise BagError(f'{path}: not a bag directory')
    if path.name.startswith('.') and path.name.endswith('.partial'):
        inner = [d for d in path.iterdir() if d.is_dir()]
        if len(inner) != 1:
            raise BagError(f'{path}: not a recording work directory (expected one bag inside)')
        return inner[0], path.parent / inner[0].name, path
    if (path / 'metadata.yaml').is_file():
        try:
            with open_bag(path) as reader:
                list(reader.messages())
        except BagError:
            pass  # broken: rebuild it
        else:
            work = partial_dirs(path)
            hint = f'; to recover an interrupted recording, pass {work[0]}' if work else ''
            raise BagError(f'{path}: a complete, readable bag already; nothing to do{hint}')
    return path, path, None


def reindex(path: str | os.PathLike[str]) -> ReindexResult:
    """Turn what a killed recording left into a complete, readable bag, like ``ros2 bag reindex``.

    ``path``: the bag the recording was writing (its hidden ``.NAME.*.partial`` work directory is
    found next to it), that work directory itself, or a bag directory whose metadata.yaml is missing
    or whose mcap file has no summary/footer. Every complete record is copied (mcap: every complete
    chunk; sqlite3: every committed row) into a new bag with metadata.yaml, written atomically; then
    the work directory is removed, or the original bag directory is replaced. Message definitions,
    type hashes and offered QoS come from the storage file; custom data, if any, is not recovered.
    Raises BagError (one line) when there is nothing to recover or the target exists.
    """
    source, target, work = _source_and_target(Path(path))
    file, storage = _storage_file(source)
    result = ReindexResult(target, storage, file, file.stat().st_size, 0)
    in_place = target == source
    build = target if not in_place else target.parent / f'.{target.name}.reindexed'
    if build.exists():
        raise BagError(f'{build}: exists already, not overwriting')
    try:
        with AtomicBagWriter(build, storage) as bag:
            _copy(file, storage, bag, result)
            if not result.counts:
                raise BagError(f'{file}: no complete topic to recover ({result.dropped or "empty"})')
    except BagError:
        raise
    except Exception as exc:
        raise BagError(f'{file}: cannot recover ({one_line(exc)})') from exc
    if in_place:
        old = Path(tempfile.mkdtemp(prefix=f'.{target.name}.', suffix='.original', dir=target.parent))
        os.rename(target, old / target.name)
        os.rename(build, target)
        _fsync(target.parent)
        shutil.rmtree(old, ignore_errors=True)
    elif work is not None:
        shutil.rmtree(work, ignore_errors=True)
        result.removed = work
    return result
