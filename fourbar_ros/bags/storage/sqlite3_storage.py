"""The sqlite3 storage adapter: flush an open rosbags writer, scan a file a killed recording left."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator, Sequence
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

from fourbar_ros.bags.storage.common import parse_offered_qos, type_hash
from fourbar_ros.bags.storage.protocol import Columns, FoundTopic, ScanState, StoredMessage, write_one_by_one
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import Storage


class Sqlite3Storage:
    """rosbag2's storage before Iron: one ``.db3`` sqlite database (topics, messages, definitions)."""

    storage = Storage.SQLITE3
    suffix = '.db3'
    plugin = StoragePlugin.SQLITE3

    def flush(self, writer: Writer) -> None:
        """Commit the open transaction.

        rosbags' Writer has no flush; this reaches into its sqlite3 storage writer (the connection), the
        one place in the package that does.
        """
        storage = writer.storage
        assert isinstance(storage, Sqlite3Writer)
        storage.conn.commit()

    def write_rows(self, writer: Writer, stamps_ns: Sequence[int], columns: Columns) -> None:
        """Through ``writer.write``, message by message (an insert per message either way)."""
        write_one_by_one(writer, stamps_ns, columns)

    def scan(self, file: Path, state: ScanState) -> Iterator[FoundTopic | StoredMessage]:
        """Every committed row (sqlite rolls an uncommitted transaction back when it opens the file)."""
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
                yield FoundTopic(int(tid), str(name), str(typ), text,
                                 str(digest or def_digest or type_hash(str(typ), text, enc)), str(ser),
                                 parse_offered_qos(str(qos_text)))
            try:
                for tid, stamp, data in con.execute('SELECT topic_id, timestamp, data FROM messages ORDER BY id'):
                    yield int(tid), int(stamp), bytes(data)
            except sqlite3.Error as exc:
                state.dropped = one_line(exc)
            state.kept_bytes = file.stat().st_size
        finally:
            con.close()
