"""The storage adapters by name and by file suffix."""

from __future__ import annotations

from pathlib import Path

from fourbar_ros.bags.storage.common import BagError
from fourbar_ros.bags.storage.mcap_storage import McapStorage
from fourbar_ros.bags.storage.protocol import StorageAdapter
from fourbar_ros.bags.storage.sqlite3_storage import Sqlite3Storage

ADAPTERS: dict[str, StorageAdapter] = {a.name: a for a in (McapStorage(), Sqlite3Storage())}
#: The storage identifiers, the default first.
STORAGES: tuple[str, ...] = tuple(ADAPTERS)


def adapter(storage: str, path: Path) -> StorageAdapter:
    """The adapter of ``storage`` ('mcap' or 'sqlite3'); BagError naming ``path`` for any other name."""
    found = ADAPTERS.get(storage)
    if found is None:
        raise BagError(f'{path}: unknown storage {storage!r} (choose from {", ".join(STORAGES)})')
    return found


def adapter_of_file(file: Path) -> StorageAdapter | None:
    """The adapter whose storage files end like ``file`` (None for another suffix)."""
    return next((a for a in ADAPTERS.values() if file.suffix == a.suffix), None)
