"""The mcap storage adapter: flush an open rosbags writer, scan a file a killed recording left.

Also the package's mcap storage writer (``McapChunkWriter``): rosbags' file, written faster."""

from __future__ import annotations

import struct
from bisect import bisect_right
from collections import defaultdict
from collections.abc import Iterator, Sequence
from io import BytesIO
from itertools import accumulate, chain
from pathlib import Path

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
    """rosbags' mcap storage writer, writing the same file byte for byte, faster for many messages.

    rosbags' writer costs a few microseconds per message in Python calls (a BytesIO per record and per-field
    writes, again for each message's index entry when a chunk closes). ``write_rows`` builds each record's head
    with one struct call and joins a chunk's records into one write; ``close_chunk`` packs a chunk's message
    index with one struct call per topic. Both keep the writer's state as its ``write`` and ``close_chunk`` do
    (the open chunk's records, message index and time range; the file's time range, counts and chunk indexes),
    so either way of writing, and any mix, gives the file rosbags' writer gives. Installed by ``BagWriter``.
    """

    def write_rows(self, stamps_ns: Sequence[int], columns: Sequence[tuple[int, Sequence[bytes | memoryview]]]) -> None:
        """Write row i's message of every (channel id, messages) column at ``stamps_ns[i]`` (ns), row by row and
        in column order: what ``write`` called in that order writes, closing a chunk after the same message (the
        first that takes it past 1 MiB)."""
        n, width = len(stamps_ns), len(columns)
        raws = [raw for row in zip(*(col for _, col in columns), strict=True) for raw in row]
        if len(raws) != n * width:
            raise ValueError(f'{n} stamps for {len(raws) // max(width, 1)} messages per topic')
        if not raws:
            return
        cids = [cid for cid, _ in columns] * n
        times = [t for t in stamps_ns for _ in range(width)]
        sizes = [_HEAD.size + len(raw) for raw in raws]
        ends = list(accumulate(sizes))  # end of each record, counted from the first one
        pack = _HEAD.pack
        i = 0
        while i < len(raws):
            chunk = self.chunk
            at = chunk.bio.tell()
            base = ends[i - 1] if i else 0
            stop = min(bisect_right(ends, _CHUNK_LIMIT - at + base, i) + 1, len(raws))
            chunk.bio.write(b''.join([part for c, t, raw in zip(cids[i:stop], times[i:stop], raws[i:stop], strict=True)
                                      for part in (pack(5, len(raw) + 22, c, 0, t, t), raw)]))
            starts = [at - base + e - s for e, s in zip(ends[i:stop], sizes[i:stop], strict=True)]
            for k in range(min(width, stop - i)):  # first seen first, as the chunk's message index goes
                chunk.msgs[cids[i + k]].extend(zip(times[i + k:stop:width], starts[k::width], strict=True))
            low, high = min(times[i:stop]), max(times[i:stop])  # rows need not come in time order
            chunk.message_start_time = min(low, chunk.message_start_time)
            chunk.message_end_time = max(high, chunk.message_end_time)
            if at - base + ends[stop - 1] > _CHUNK_LIMIT:
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
        for cid, msgs in chunk.msgs.items():
            offsets.append((cid, bio.tell()))
            bio.write(_RECORD.pack(0x07, 6 + 16 * len(msgs)) + _INDEX.pack(cid, 16 * len(msgs)))
            bio.write(struct.pack(f'<{2 * len(msgs)}Q', *chain.from_iterable(msgs)))
        entry = BytesIO()
        entry.write(_QQQQI.pack(chunk.message_start_time, chunk.message_end_time, chunk_start, chunk_end - chunk_start,
                                10 * len(offsets)))
        for cid, offset in offsets:
            entry.write(_OFFSET.pack(cid, offset))
        entry.write(_U64.pack(bio.tell() - chunk_end) + _U32.pack(len(name)) + name
                    + _QQ.pack(len(compressed), len(data)))
        self.chunks.append(entry)
        self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))


class McapStorage:
    """rosbag2's default storage since Iron: one ``.mcap`` file of chunks, a summary and a footer."""

    storage = Storage.MCAP
    suffix = '.mcap'
    plugin = StoragePlugin.MCAP

    def flush(self, writer: Writer) -> None:
        """Close the open chunk (if it holds messages) and flush the file buffer.

        rosbags' Writer has no flush; this reaches into its mcap storage writer (the open chunk and
        the file object), the one place in the package that does.
        """
        storage = writer.storage
        assert isinstance(storage, McapWriter)
        if any(storage.chunk.msgs.values()):
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
