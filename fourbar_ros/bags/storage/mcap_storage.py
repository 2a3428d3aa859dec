"""The mcap storage adapter: flush an open rosbags writer, scan a file a killed recording left."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter

from fourbar_ros.bags.storage.common import parse_offered_qos, type_hash
from fourbar_ros.bags.storage.protocol import FoundTopic, ScanState, StoredMessage
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import Storage


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
