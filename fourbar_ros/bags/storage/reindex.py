"""Turn what a killed recording left into a complete, readable bag, like ``ros2 bag reindex``."""

from __future__ import annotations

import os
import secrets
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from rosbags.interfaces import Connection

from fourbar_ros.bags.storage.adapters import adapter_of_file
from fourbar_ros.bags.storage.common import BagError
from fourbar_ros.bags.storage.protocol import FoundTopic, ScanState, StorageAdapter
from fourbar_ros.bags.storage.read import open_bag
from fourbar_ros.bags.storage.write import AtomicBagWriter, fsync_path
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import Storage


@dataclass
class ReindexResult:
    """What ``reindex`` recovered: the new bag, its messages per topic, and what was dropped.

    ``source``: the storage file read; ``source_bytes``: its size; ``kept_bytes``: the bytes of its
    complete records (mcap) or its size (sqlite3); ``dropped``: why reading stopped before the end of
    the file (an incomplete last chunk, a corrupt page), or None when the whole file was readable.
    """

    path: Path
    storage: Storage
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


def _storage_file(bag: Path) -> tuple[Path, StorageAdapter]:
    files = sorted((p, a) for p in bag.iterdir() if p.is_file() and (a := adapter_of_file(p)) is not None)
    if not files:
        raise BagError(f'{bag}: no storage file (.mcap or .db3) to reindex')
    if len(files) > 1:
        raise BagError(f'{bag}: {len(files)} storage files; reindex handles single-file bags')
    return files[0]


def _copy(file: Path, storage: StorageAdapter, bag: AtomicBagWriter, result: ReindexResult) -> None:
    """Write every recoverable topic and message of ``file`` into ``bag``, in stored order."""
    conns: dict[int, Connection] = {}
    by_name: dict[str, Connection] = {}
    state = ScanState()
    try:
        for item in storage.scan(file, state):
            if isinstance(item, FoundTopic):
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
    finally:
        result.kept_bytes, result.dropped = state.kept_bytes, state.dropped


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
    result = ReindexResult(target, storage.storage, file, file.stat().st_size, 0)
    in_place = target == source
    build = target if not in_place else target.parent / f'.{target.name}.reindexed'
    if build.exists():
        raise BagError(f'{build}: exists already, not overwriting')
    try:
        with AtomicBagWriter(build, storage.storage) as bag:
            _copy(file, storage, bag, result)
            if not result.counts:
                raise BagError(f'{file}: no complete topic to recover ({result.dropped or "empty"})')
        if in_place:
            _replace_dir(target, build)
    except BaseException as exc:
        if in_place:  # a build complete just before the stop landed is not left beside the bag
            shutil.rmtree(build, ignore_errors=True)
        if isinstance(exc, Exception) and not isinstance(exc, BagError):
            raise BagError(f'{file}: cannot recover ({one_line(exc)})') from exc
        raise
    if work is not None and not in_place:
        shutil.rmtree(work, ignore_errors=True)
        result.removed = work
    return result


def _replace_dir(target: Path, new: Path) -> None:
    """Put the directory ``new`` at ``target``'s place. Stopped half-way (a signal between the two renames), the
    state on disk decides: ``target`` is put back as it was, or the swap is finished."""
    old = target.parent / f'.{target.name}.{secrets.token_hex(8)}.original'
    try:
        os.rename(target, old)
        os.rename(new, target)
    except BaseException:
        if not target.exists() and old.exists():
            os.rename(old, target)
        shutil.rmtree(old, ignore_errors=True)
        raise
    fsync_path(target.parent)
    shutil.rmtree(old, ignore_errors=True)
