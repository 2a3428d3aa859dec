"""The storage adapters by storage and by file suffix."""

from __future__ import annotations

from pathlib import Path

from fourbar_ros.bags.storage.mcap_storage import McapStorage
from fourbar_ros.bags.storage.protocol import StorageAdapter
from fourbar_ros.bags.storage.sqlite3_storage import Sqlite3Storage
from fourbar_ros.interface.topics import Storage

ADAPTERS: dict[Storage, StorageAdapter] = {a.storage: a for a in (McapStorage(), Sqlite3Storage())}


def adapter(storage: Storage) -> StorageAdapter:
    """The adapter of ``storage``."""
    return ADAPTERS[storage]


def adapter_of_file(file: Path) -> StorageAdapter | None:
    """The adapter whose storage files end like ``file`` (None for another suffix)."""
    return next((a for a in ADAPTERS.values() if file.suffix == a.suffix), None)
