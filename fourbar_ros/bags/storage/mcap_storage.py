"""The mcap storage adapter: flush an open rosbags writer, scan a file a killed recording left.

Also the package's mcap storage writer (``McapChunkWriter``): rosbags' file, written faster."""

from __future__ import annotations

import struct
from bisect import bisect_right
from collections import defaultdict
from collections.abc import Iterator, Sequence
from io import BytesIO
from itertools import repeat
from pathlib import Path

import numpy as np
from rosbags.interfaces import Connection
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionMode
from rosbags.rosbag2.storage_mcap import McapWriter, PendingChunk

from fourbar_ros.bags.storage.common import BagError, parse_offered_qos, type_hash
from fourbar_ros.bags.storage.protocol import Columns, FoundTopic, ScanState, StoredMessage, write_one_by_one
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import Storage

#: A message record's head: opcode 0x05, record length, channel id, sequence (0), log time, publish time (ns).
_HEAD = struct.Struct('<BQHIQQ')
#: A record's opcode and length; a chunk's start and end times, uncompressed size, CRC (0: none) and the length of
#: its compression's name; a message index's channel id and byte length of its entries; a chunk index's times,
#: offset, length and byte length of its message index offsets; one such offset (channel id, position).
_RECORD, _CHUNK, _INDEX = struct.Struct('<BQ'), struct.Struct('<QQQII'), struct.Struct('<HI')
_QQQQI, _OFFSET = struct.Struct('<QQQQI'), struct.Struct('<HQ')
_U32, _U64, _QQ = struct.Struct('<I'), struct.Struct('<Q'), struct.Struct('<QQ')
#: rosbags' mcap writer closes a chunk once it holds more than this many bytes.
_CHUNK_LIMIT = 2**20


class McapChunkWriter(McapWriter):
    """rosbags' mcap storage writer, writing the same file byte for byte, faster.

    rosbags' writer costs a few microseconds per message in Python calls (a BytesIO per record and per-field
    writes, again for each message's index entry when a chunk closes). Here a record's head is one struct call,
    ``write_rows`` joins a chunk's records into one write, and the open chunk's message index is kept flat
    (``index``) and packed with one struct call per topic when the chunk closes. The writer's state is kept as
    rosbags' ``write`` and ``close_chunk`` keep it (the open chunk's records and time range; the file's time
    range, counts and chunk indexes), so ``write``, ``write_rows`` and any mix of them give the file rosbags'
    writer gives. Installed by ``BagWriter``.
    """

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        super().__init__(path, compression)
        #: The open chunk's message index: per channel id, in the order first written, (log time ns, offset of the
        #: record in the chunk) pairs one after the other (rosbags' ``chunk.msgs`` is left empty).
        self.index: dict[int, list[int]] = {}

    def holds_messages(self) -> bool:
        """Whether the open chunk holds a message."""
        return bool(self.index)

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """Write one message (log and publish time ``timestamp``, ns), as rosbags' writer does."""
        chunk, cid = self.chunk, connection.id
        self.message_start_time = min(timestamp, self.message_start_time)
        self.message_end_time = max(timestamp, self.message_end_time)
        self.channel_stats[cid] += 1
        chunk.message_start_time = min(timestamp, chunk.message_start_time)
        chunk.message_end_time = max(timestamp, chunk.message_end_time)
        bio = chunk.bio
        self.index.setdefault(cid, []).extend((timestamp, bio.tell()))
        bio.write(_HEAD.pack(5, len(data) + 22, cid, 0, timestamp, timestamp))
        bio.write(data)
        if bio.tell() > _CHUNK_LIMIT:
            self.close_chunk()

    def write_rows(self, stamps_ns: Sequence[int], columns: Sequence[tuple[int, Sequence[bytes | memoryview]]]) -> None:
        """Write row i's message of every (channel id, messages) column at ``stamps_ns[i]`` (ns), row by row and
        in column order: what ``write`` called in that order writes, closing a chunk after the same message (the
        first that takes it past 1 MiB)."""
        n, width = len(stamps_ns), len(columns)
        for _, col in columns:
            if len(col) != n:
                raise ValueError(f'{n} stamps for {len(col)} messages')
        if n == 0 or width == 0:
            return
        m = n * width
        raws: list[bytes | memoryview] = [b''] * m
        times: list[int] = [0] * m
        for k, (_, col) in enumerate(columns):  # row-major: message j of row i at i * width + j
            raws[k::width] = col
            times[k::width] = stamps_ns
        cids = [cid for cid, _ in columns] * n
        lengths = np.fromiter(map(len, raws), dtype=np.int64, count=m)
        ends = np.cumsum(lengths + _HEAD.size)  # end of each record, counted from the first one
        heads = list(map(_HEAD.pack, repeat(5, m), (lengths + 22).tolist(), cids, repeat(0, m), times, times))
        parts: list[bytes | memoryview] = [b''] * (2 * m)
        parts[0::2], parts[1::2] = heads, raws
        bounds = ends.tolist()
        starts = (ends - lengths - _HEAD.size).tolist()
        i = 0
        while i < m:
            chunk = self.chunk
            at = chunk.bio.tell()
            base = bounds[i - 1] if i else 0
            stop = min(bisect_right(bounds, _CHUNK_LIMIT - at + base, i) + 1, m)
            chunk.bio.write(b''.join(parts[2 * i:2 * stop]))
            shift = at - base
            for k in range(min(width, stop - i)):  # first written first, as rosbags' index goes
                j = i + k
                pairs = [0] * (2 * len(range(j, stop, width)))
                pairs[0::2] = times[j:stop:width]
                pairs[1::2] = [shift + x for x in starts[j:stop:width]] if shift else starts[j:stop:width]
                self.index.setdefault(cids[j], []).extend(pairs)
            low, high = min(times[i:stop]), max(times[i:stop])  # rows need not come in time order
            chunk.message_start_time = min(low, chunk.message_start_time)
            chunk.message_end_time = max(high, chunk.message_end_time)
            if shift + bounds[stop - 1] > _CHUNK_LIMIT:
                self.close_chunk()
            i = stop
        low, high = min(stamps_ns), max(stamps_ns)
        self.message_start_time = min(low, self.message_start_time)
        self.message_end_time = max(high, self.message_end_time)
        for cid, _ in columns:
            self.channel_stats[cid] += n

    def close_chunk(self) -> None:
        """Close the open chunk as rosbags' writer does: the chunk record, a message index record per topic (in
        the order first written) and the chunk's index entry for the summary."""
        chunk, bio = self.chunk, self.bio
        data = chunk.bio.getvalue()
        compressed = self.compressor(data)
        name = self.compression.encode()
        record = b''.join((_CHUNK.pack(chunk.message_start_time, chunk.message_end_time, len(data), 0, len(name)),
                           name, _U64.pack(len(compressed)), compressed))
        chunk_start = bio.tell()
        bio.write(_RECORD.pack(0x06, len(record)))
        bio.write(record)
        chunk_end = bio.tell()
        offsets: list[tuple[int, int]] = []
        for cid, pairs in self.index.items():
            offsets.append((cid, bio.tell()))
            bio.write(_RECORD.pack(0x07, 6 + 8 * len(pairs)) + _INDEX.pack(cid, 8 * len(pairs)))
            bio.write(struct.pack(f'<{len(pairs)}Q', *pairs))
        entry = BytesIO()
        entry.write(_QQQQI.pack(chunk.message_start_time, chunk.message_end_time, chunk_start, chunk_end - chunk_start,
                                10 * len(offsets)))
        for cid, offset in offsets:
            entry.write(_OFFSET.pack(cid, offset))
        entry.write(_U64.pack(bio.tell() - chunk_end) + _U32.pack(len(name)) + name
                    + _QQ.pack(len(compressed), len(data)))
        self.chunks.append(entry)
        self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
        self.index = {}


class McapStorage:
    """rosbag2's default storage since Iron: one ``.mcap`` file of chunks, a summary and a footer."""

    storage = Storage.MCAP
    suffix = '.mcap'
    plugin = StoragePlugin.MCAP

    def flush(self, writer: Writer) -> None:
        """Close the open chunk (if it holds messages) and flush the file buffer.

        rosbags' Writer has no flush; this reaches into its mcap storage writer (the open chunk and
        the file object), as ``McapChunkWriter`` does.
        """
        storage = writer.storage
        assert isinstance(storage, McapWriter)
        held = storage.holds_messages() if isinstance(storage, McapChunkWriter) else any(storage.chunk.msgs.values())
        if held:
            storage.close_chunk()
        storage.bio.flush()

    def write_rows(self, writer: Writer, stamps_ns: Sequence[int], columns: Columns) -> None:
        """Through ``McapChunkWriter.write_rows`` (``BagWriter``'s mcap storage), keeping the Writer's counts and
        time range as its ``write`` does; a bag of another storage writer, or whose Writer compresses each message,
        goes through ``writer.write``."""
        storage = writer.storage
        if not isinstance(storage, McapChunkWriter) or writer.compression_mode != CompressionMode.NONE:
            write_one_by_one(writer, stamps_ns, columns)
            return
        for conn, _ in columns:
            if conn not in writer.connections:
                raise BagError(f'{writer.path}: topic {conn.topic} was not added to this bag')
        if not stamps_ns or not columns:
            return
        stamps = [int(t) for t in stamps_ns]
        storage.write_rows(stamps, [(conn.id, raws) for conn, raws in columns])
        low, high = min(stamps), max(stamps)
        writer.min_timestamp = min(low, writer.min_timestamp)
        writer.max_timestamp = max(high, writer.max_timestamp)
        for conn, _ in columns:
            writer.counts[conn.id] += len(stamps)

    def scan(self, file: Path, state: ScanState) -> Iterator[FoundTopic | StoredMessage]:
        """Every complete record, read with the ``mcap`` library's stream reader (no summary needed)."""
        from mcap.records import Channel, Message, Schema
        from mcap.stream_reader import StreamReader

        schemas: dict[int, Schema] = {}
        size = file.stat().st_size
        with file.open('rb') as f:
            records = StreamReader(f, record_size_limit=max(size, 1)).records
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    state.kept_bytes = f.tell()
                    return
                except Exception as exc:  # the stream ends (mid-record, or with no footer), or a record is corrupt
                    if state.kept_bytes < size:
                        state.dropped = (f'{size - state.kept_bytes} bytes after the last complete record: '
                                         f'{one_line(exc)}')
                    return
                state.kept_bytes = f.tell()
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    schema = schemas.get(record.schema_id)
                    if schema is None:
                        continue
                    msgdef = schema.data.decode('utf8', 'replace')
                    yield FoundTopic(record.id, record.topic, schema.name, msgdef,
                                     type_hash(schema.name, msgdef, schema.encoding), record.message_encoding,
                                     parse_offered_qos(record.metadata.get('offered_qos_profiles', '')))
                elif isinstance(record, Message):
                    yield record.channel_id, record.log_time, bytes(record.data)
