"""File operations of ``BagWriter``, in one place so that a test can inject faults.

``Storage`` is the real thing (``os`` calls). A test passes a subclass to
``BagWriter(..., storage=...)`` that fails the way a full disk does (a short write, then
``ENOSPC``) without mounting anything; ``tests/io/faults.py`` has one.

The writer keeps a **reserve file** in the bag folder: space allocated in advance so that,
when the disk fills, the open ``.mcap`` file can still be closed with its summary and
``metadata.yaml`` rewritten (the reserve is given back first). ``reserve`` allocates with
``posix_fallocate`` where the file system supports it and writes zeros otherwise (file
systems that compress or deduplicate zeros, e.g. ZFS with compression, may not really
reserve them; the writer then falls back to a footer-only trailer, which every reader still
opens).
"""

from __future__ import annotations

import errno
import os
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Sequence
    from pathlib import Path

__all__ = ['SPACE_ERRNOS', 'Storage']

#: errno values that mean "no space (for now)": recording stalls and retries.
SPACE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})
_ZEROS = bytes(1 << 16)


class Storage:
    """The file system calls ``BagWriter`` makes (override to inject faults)."""

    def create(self, path: Path) -> int:
        """Create ``path`` exclusively for writing; return its descriptor."""
        return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, 'O_CLOEXEC', 0),
                       0o644)

    def pwritev(self, fd: int, parts: Sequence[bytes | bytearray | memoryview],
                offset: int) -> int:
        """Write ``parts`` at ``offset``; return the bytes written (may be short)."""
        return os.pwritev(fd, parts, offset)

    def truncate(self, fd: int, size: int) -> None:
        """Cut (or extend) the file to ``size`` bytes."""
        os.ftruncate(fd, size)

    def close(self, fd: int) -> None:
        """Close a descriptor from ``create``."""
        os.close(fd)

    def write_file(self, path: Path, data: bytes) -> None:
        """Write a whole small file (created or truncated)."""
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)

    def replace(self, src: Path, dst: Path) -> None:
        """Rename ``src`` over ``dst`` atomically."""
        os.replace(src, dst)

    def unlink(self, path: Path) -> None:
        """Remove a file; a missing file is not an error."""
        try:
            os.unlink(path)
        except FileNotFoundError:
            pass

    def reserve(self, path: Path, size: int) -> None:
        """Make ``path`` hold ``size`` allocated bytes (grow or shrink it).

        Raises:
            OSError: The space is not there (``ENOSPC``) or the file cannot be written.
        """
        fd = os.open(path, os.O_WRONLY | os.O_CREAT, 0o644)
        try:
            have = os.fstat(fd).st_size
            if size <= have:
                os.ftruncate(fd, size)
                return
            try:
                os.posix_fallocate(fd, have, size - have)
            except OSError as exc:
                if exc.errno not in {errno.EOPNOTSUPP, errno.EINVAL, errno.ENOSYS}:
                    os.ftruncate(fd, have)   # give back what a partial allocation took
                    raise
                self._write_zeros(fd, have, size)
        finally:
            os.close(fd)

    @staticmethod
    def _write_zeros(fd: int, start: int, end: int) -> None:
        pos = start
        try:
            while pos < end:
                pos += os.pwrite(fd, _ZEROS[:min(len(_ZEROS), end - pos)], pos)
        except OSError:
            os.ftruncate(fd, start)
            raise

    def free_bytes(self, folder: Path) -> int | None:
        """Bytes an unprivileged writer may still use in ``folder`` (None: unknown)."""
        try:
            st = os.statvfs(folder)
        except (OSError, AttributeError):
            return None
        return st.f_bavail * st.f_frsize
