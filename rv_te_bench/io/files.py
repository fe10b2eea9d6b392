"""Writing output files so that a full disk or a crash never leaves a half-written one.

``write_atomic`` writes a temporary file beside the target, flushes it to the disk
(``fsync``: some file systems report a full disk only then) and renames it over the target:
readers see the old file or the new one, never a 0-byte or truncated one. ``write_all``
does that for several files (a report: images, JSON, HTML) all or nothing: every file is
staged first, and only when all are on disk are they renamed into place.

``check_folder_name`` is the rule for a name that must stay inside its output folder
(``--name``, ``--session``, the recorder's ``bag_name``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Mapping

__all__ = ['claim_folder', 'folder_name_problem', 'write_all', 'write_atomic']


def _stage(path: Path, data: bytes) -> Path:
    """Write ``data`` to a temporary file beside ``path``; return it (removed on failure)."""
    tmp = path.with_name(f'.{path.name}.{os.getpid()}.tmp')
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    return tmp


def write_atomic(path: str | os.PathLike[str], data: bytes | str) -> None:
    """Replace ``path`` with ``data`` (str: UTF-8) atomically.

    Raises:
        OSError: It could not be written; ``path`` is unchanged and no temporary is left.
    """
    write_all({Path(path): data})


def write_all(files: Mapping[Path, bytes | str]) -> None:
    """Write several files all or nothing: stage each, then rename them into place.

    Raises:
        OSError: One could not be staged (``filename``: that target); none of the
            targets was touched and no temporary is left.
    """
    staged: list[tuple[Path, Path]] = []
    try:
        for path, data in files.items():
            raw = data.encode('utf-8') if isinstance(data, str) else data
            staged.append((_stage(Path(path), raw), Path(path)))
    except OSError:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        raise
    for tmp, path in staged:
        os.replace(tmp, path)


def folder_name_problem(name: str) -> str | None:
    """None when ``name`` is one folder name (it stays inside its output folder), else why.

    Refused: empty, ``.``, ``..``, a path separator, NUL, more than 255 bytes.
    """
    shown = repr(name) if len(name) <= 60 else f'{name[:50]!r}... ({len(name)} characters)'
    if name in {'', '.', '..'} or '/' in name or '\0' in name or (os.sep != '/' and os.sep in name):
        return (f'must be a plain folder name inside the output folder (no "/", not "." '
                f'or ".."), got {shown}')
    if len(name.encode('utf-8', 'surrogateescape')) > 255:
        return f'must be at most 255 bytes long, got {shown}'
    return None


def claim_folder(parent: Path, name: str, *, numbered: bool) -> Path:
    """Create ``parent/name`` (and ``parent``); with ``numbered``, ``name-2``, ``name-3``...
    when it is taken (atomic: two processes never get the same folder).

    Raises:
        FileExistsError: ``parent/name`` exists and ``numbered`` is False.
        OSError: The folder cannot be created.
    """
    parent.mkdir(parents=True, exist_ok=True)
    for n in range(1, 10_000):
        path = parent / (name if n == 1 else f'{name}-{n}')
        try:
            path.mkdir()
        except FileExistsError:
            if not numbered:
                raise
            continue
        return path
    msg = f'no free folder name {name}-<n> in {parent}'
    raise FileExistsError(msg)
