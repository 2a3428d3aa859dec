"""The node's parameter file rewritten with new values, and a command's outputs written all or none."""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

from fourbar_ros.commands import CommandError

_NUMBER_LINE = r'^(?P<head>[ \t]*{key}[ \t]*:[ \t]*)(?P<value>[^#\n]*?)(?P<tail>[ \t]*(?:#[^\n]*)?)$'


def param_file_with(params: Path, bag: Path, values: dict[str, float], by: str) -> str:
    """The parameter file's text with ``values`` (node parameters) replacing the file's (comments kept), stamped as
    set by the command ``by`` from the recording ``bag``, checked by reading it back with the node's own reader and
    validation."""
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.config.rcl_yaml import read_text
    from fourbar_ros.core.calibration import CalibrationError

    text = read_text(params)
    for name, value in values.items():
        pattern = re.compile(_NUMBER_LINE.format(key=re.escape(name)), re.MULTILINE)
        found = pattern.findall(text)
        if len(found) > 1:
            raise CommandError(f'{params}: {name} is set {len(found)} times; edit the file by hand with the report')
        if found:
            text = pattern.sub(_replacer(value), text)
            continue
        sections = list(re.finditer(r'^(?P<indent>[ \t]*)ros__parameters[ \t]*:[ \t]*(?:#[^\n]*)?$', text,
                                    re.MULTILINE))
        if len(sections) != 1:
            raise CommandError(f'{params}: {name} is not set and the file has {len(sections)} ros__parameters '
                               'sections; set it by hand from the report')
        indent = sections[0]['indent'] + '  '
        at = sections[0].end()
        text = f'{text[:at]}\n{indent}{name}: {value!r}  # calibrated{text[at:]}'
    stamp = f'# {", ".join(values)}: set by `{by}` from the recording {bag.name}.\n'
    text = stamp + text
    with tempfile.TemporaryDirectory() as tmp:
        check = Path(tmp) / 'calibrated.yaml'
        check.write_text(text, encoding='utf-8')
        try:
            cfg = load_config(check)
        except ValueError as exc:
            raise CalibrationError(f'the calibrated values do not make a valid parameter file: {exc}') from None
    read_back = {name: getattr(cfg, name) for name in values}
    if read_back != values:
        raise CommandError(f'{params}: could not set the values in this file (read back {read_back}); set them by '
                           'hand from the report')
    return text


def _replacer(value: float) -> Callable[[re.Match[str]], str]:
    """The substitution of one ``key: value  # comment`` line: the new value (repr: it reads back exactly)."""
    def replace(m: re.Match[str]) -> str:
        return f'{m["head"]}{value!r}{m["tail"]}'
    return replace

def check_outputs(outputs: Sequence[tuple[str, Path | None]], inputs: Sequence[Path] = ()) -> None:
    """Refuse, before any work, outputs (what names each, e.g. ``-o``, and its path; None: not asked for) that
    cannot be written as given: in a directory that does not exist, an existing directory or other file that is not
    a regular one, one file for two outputs, or one of ``inputs``. CommandError (status 2, one line)."""
    seen: dict[Path, str] = {path.resolve(): f'the input {path}' for path in inputs}
    for what, path in outputs:
        if path is None:
            continue
        if path.is_dir():
            raise CommandError(f'{what} {path}: is a directory')
        if path.exists() and not path.is_file():
            raise CommandError(f'{what} {path}: not a regular file')
        if not path.parent.is_dir():
            raise CommandError(f'{path}: directory {path.parent} does not exist')
        key = path.resolve()
        if key in seen:
            raise CommandError(f'{what} {path}: the same file as {seen[key]}; give each output a path of its own')
        seen[key] = f'{what} {path}'


def write_atomically(files: dict[Path, bytes]) -> None:
    """Write every file or none: each to a hidden temporary file beside it (fsynced), then all renamed into place;
    on any failure the temporaries are removed and no target is touched (a rename failing midway removes the ones
    already made). An error names the target, not its temporary; a target that is a directory is refused before
    anything is written."""
    for path in files:
        if path.is_dir():
            raise CommandError(f'cannot write {path}: it is a directory')
    temps: list[tuple[Path, Path]] = []
    done: list[Path] = []
    at: Path | None = None  # the target being written or renamed into place
    try:
        for at, content in files.items():
            fd, name = tempfile.mkstemp(prefix=f'.{at.name}.', suffix='.partial', dir=at.parent)
            temps.append((Path(name), at))
            os.fchmod(fd, 0o666 & ~_umask())  # as open() would make it, not mkstemp's 0600
            with os.fdopen(fd, 'wb') as f:
                f.write(content)
                f.flush()
                os.fsync(f.fileno())
        for tmp, at in temps:
            os.replace(tmp, at)
            done.append(at)
    except BaseException as exc:
        for tmp, _ in temps:
            with contextlib.suppress(OSError):
                tmp.unlink()
        for path in done:
            with contextlib.suppress(OSError):
                path.unlink()
        if isinstance(exc, OSError):
            raise CommandError(f'cannot write {at or "the outputs"}: {exc.strerror}') from None
        raise


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
