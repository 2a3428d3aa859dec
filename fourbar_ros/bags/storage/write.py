"""Write rosbag2 bags atomically: built in a hidden directory next to the target, renamed into place when complete.

A recording flushes what it has, so a killed one leaves its data for ``reindex()``. The format: docs/how-to/bags.md."""

from __future__ import annotations

import contextlib
import itertools
import os
import secrets
import shutil
from collections.abc import Sequence
from pathlib import Path
from types import MappingProxyType, TracebackType
from typing import TYPE_CHECKING

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import StoragePlugin, Writer

from fourbar_ros.bags.storage.adapters import adapter
from fourbar_ros.bags.storage.common import (
    COMMAND_TOPIC,
    METADATA_VERSION,
    BagError,
    jazzy_typestore,
    recorded_qos,
)
from fourbar_ros.bags.storage.mcap_storage import McapChunkWriter
from fourbar_ros.bags.storage.protocol import Columns
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import DEFAULT_STORAGE, FLOAT64, Storage

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore


def fsync_path(path: Path) -> None:
    """fsync a file or directory."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class BagWriter(Writer):
    """rosbags' Writer with the package's mcap storage writer (``McapChunkWriter``: the same file, faster)."""

    STORAGE_PLUGINS = MappingProxyType({**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: McapChunkWriter})


class AtomicBagWriter:
    """A rosbag2 writer (metadata v9) that publishes its bag only when it is complete.

    Use as a context manager. The bag is built under a hidden sibling directory
    ``.NAME.*.partial`` (the bag itself at ``.NAME.*.partial/NAME``) and renamed to ``path`` after a
    clean exit; on any exception, including KeyboardInterrupt, the temporary directory is removed and
    ``path`` never appears. If the process dies without running any cleanup (SIGKILL, power loss),
    the hidden directory stays with whatever ``flush()`` had handed to the OS; ``reindex(path)``
    recovers it.
    """

    def __init__(self, path: str | os.PathLike[str], storage: Storage = DEFAULT_STORAGE) -> None:
        self.path = Path(path)
        self.adapter = adapter(storage)
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
        """Create the temporary bag directory and open the storage; on any exception, nothing is left."""
        try:
            tmp = self._make_work_dir()
            self._writer = BagWriter(tmp / self.path.name, version=METADATA_VERSION,
                                     storage_plugin=self.adapter.plugin)
            self._writer.open()
        except BaseException:
            self.abort()
            raise

    def _make_work_dir(self) -> Path:
        # The name is noted before the directory is made, so a stop landing right after mkdir (as a signal sent
        # the moment the directory appears does) still finds it to remove; tempfile.mkdtemp names it only after.
        while True:
            tmp = self._tmpdir = self.path.parent / f'.{self.path.name}.{secrets.token_hex(8)}.partial'
            try:
                tmp.mkdir(mode=0o700)
                return tmp
            except FileExistsError:  # another's directory of that random name: not ours to remove; draw again
                self._tmpdir = None
            except OSError as exc:
                self._tmpdir = None
                raise BagError(f'{self.path}: cannot write here ({one_line(exc)})') from exc

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
        self.adapter.flush(self.writer)

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

    def write_rows(self, stamps_ns: Sequence[int], columns: Columns) -> None:
        """Write row i's message of every column, a (connection, serialized messages) pair, at ``stamps_ns[i]``
        (ns since the epoch), row by row and in column order: the bag ``write`` called in that order makes, for a
        fraction of its cost per message in mcap."""
        for conn, raws in columns:
            if len(raws) != len(stamps_ns):
                raise BagError(f'{self.path}: {len(stamps_ns)} stamps for {len(raws)} messages on {conn.topic}')
        self.adapter.write_rows(self.writer, stamps_ns, columns)
        for conn, _ in columns:
            self.counts[conn.topic] += len(stamps_ns)

    def set_custom_data(self, key: str, value: str) -> None:
        """Store a string in the bag's metadata ``custom_data``."""
        self.writer.set_custom_data(key, value)

    def commit(self) -> Path:
        """Close the storage, write metadata.yaml, fsync and rename the bag into place (undone when a stop lands
        right after the rename, so an interrupted writer never leaves ``path``)."""
        writer, tmp = self.writer, self._tmpdir
        assert tmp is not None
        built = tmp / self.path.name
        try:
            writer.close()
            self._writer = None
            for f in built.iterdir():
                fsync_path(f)
            fsync_path(built)
            if self.path.exists():
                raise BagError(f'{self.path}: appeared while writing, not overwriting')
            os.rename(built, self.path)
            fsync_path(self.path.parent)
        except BaseException as exc:
            if not built.exists() and self.path.is_dir():  # renamed into place just before a stop landed: undone
                shutil.rmtree(self.path, ignore_errors=True)
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


def float64_cdr(value: float) -> bytes:
    """The CDR bytes of a ``std_msgs/msg/Float64`` holding ``value`` (NaN and inf kept)."""
    store = jazzy_typestore()
    msg = store.types[FLOAT64](data=float(value))
    return bytes(store.serialize_cdr(msg, FLOAT64))


def write_command_bag(path: str | os.PathLike[str], stamps_ns: Sequence[int],
                      values: Sequence[float], storage: Storage = DEFAULT_STORAGE,
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
