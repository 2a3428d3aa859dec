"""The small protocol each storage adapter (mcap, sqlite3) implements, like ``rosbags``' storage plugins.

Reading a complete bag and writing one go through ``rosbags`` (its Reader and Writer pick the plugin);
an adapter adds what rosbags does not offer: flushing an open writer, writing many messages in one call, and
scanning what a killed recording left in a storage file (``reindex``).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import StoragePlugin, Writer

from fourbar_ros.interface.topics import Storage


@dataclass(frozen=True)
class FoundTopic:
    """A topic as found in a storage file: what ``AtomicBagWriter.add_topic`` needs to write it again.

    ``cid``: the file's own id of the topic (mcap channel id, sqlite3 topic id); ``digest``: RIHS01 hash.
    """

    cid: int
    name: str
    msgtype: str
    msgdef: str
    digest: str
    serialization_format: str
    qos: tuple[Qos, ...]


#: A stored message: (topic id of the file, receive time in ns since the epoch, CDR bytes).
StoredMessage = tuple[int, int, bytes]

#: Rows of messages for ``StorageAdapter.write_rows``: one (connection, CDR bytes per row) per column.
Columns = Sequence[tuple[Connection, Sequence[bytes | memoryview]]]


@dataclass
class ScanState:
    """How far a scan got: ``kept_bytes`` of complete records (mcap) or the file size (sqlite3), and why
    reading stopped before the end (``dropped``; None when the whole file was readable)."""

    kept_bytes: int = 0
    dropped: str | None = None


class StorageAdapter(Protocol):
    """One rosbag2 storage: which one, its file suffix and rosbags plugin, and what rosbags leaves out."""

    storage: Storage
    suffix: str  #: storage file suffix: '.mcap' or '.db3'
    plugin: StoragePlugin

    def flush(self, writer: Writer) -> None:
        """Hand every message written so far to the OS (no fsync)."""

    def write_rows(self, writer: Writer, stamps_ns: Sequence[int], columns: Columns) -> None:
        """Write row i's message of every column at ``stamps_ns[i]`` (ns since the epoch), row by row and in
        column order: the bag is the one ``writer.write`` called in that order makes."""

    def scan(self, file: Path, state: ScanState) -> Iterator[FoundTopic | StoredMessage]:
        """Yield topics (when first seen) and messages of every complete record of ``file``, in stored order;
        stop quietly at the first incomplete or corrupt one (noted in ``state``)."""


def write_one_by_one(writer: Writer, stamps_ns: Sequence[int], columns: Columns) -> None:
    """``StorageAdapter.write_rows`` through ``writer.write``, message by message."""
    conns = [conn for conn, _ in columns]
    write = writer.write
    for stamp, row in zip(stamps_ns, zip(*(raws for _, raws in columns), strict=True), strict=True):
        for conn, raw in zip(conns, row, strict=True):
            write(conn, stamp, raw)
