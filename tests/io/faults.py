"""Fault-injecting file operations for ``BagWriter`` (no mount needed), and a real tmpfs.

``SmallDisk`` behaves like a small tmpfs holding only the bag folder: every byte of every
file the writer creates (``.mcap`` files, the reserve, metadata.yaml and its temporary copy)
counts against ``capacity_bytes``. A write that does not fit writes what fits and returns a
short count; the next write raises ``ENOSPC``, as Linux does. Raising ``capacity_bytes``
later is "space returns". The files are real (under the test's tmp_path), so independent
readers open them afterwards.
"""

from __future__ import annotations

import contextlib
import errno
import os
import subprocess
from typing import TYPE_CHECKING

import pytest

from rv_te_bench.io._storage import Storage

if TYPE_CHECKING:
    from collections.abc import Iterator, Sequence
    from pathlib import Path


def _enospc() -> OSError:
    return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


class SmallDisk(Storage):
    """A disk of ``capacity_bytes`` for one bag folder (see the module docstring).

    Attributes:
        capacity_bytes: Size of the disk; raise it to give space back.
        failed_writes: Writes that raised ``ENOSPC`` so far.
        short_writes: Writes that wrote only part of their bytes.
    """

    def __init__(self, capacity_bytes: int) -> None:
        self.capacity_bytes = capacity_bytes
        self.sizes: dict[str, int] = {}
        self._paths: dict[int, str] = {}
        self.failed_writes = 0
        self.short_writes = 0

    @property
    def used_bytes(self) -> int:
        """Bytes held by the files on this disk."""
        return sum(self.sizes.values())

    def _free(self) -> int:
        return max(0, self.capacity_bytes - self.used_bytes)

    def create(self, path: Path) -> int:
        fd = super().create(path)
        self._paths[fd] = str(path)
        self.sizes[str(path)] = 0
        return fd

    def pwritev(self, fd: int, parts: Sequence[bytes | bytearray | memoryview],
                offset: int) -> int:
        path = self._paths[fd]
        data = b''.join(parts)
        size = self.sizes[path]
        room = size + self._free() - offset   # bytes that fit from offset on
        if len(data) <= room:
            n = super().pwritev(fd, [data], offset)
        elif room <= 0:
            self.failed_writes += 1
            raise _enospc()
        else:
            self.short_writes += 1
            n = super().pwritev(fd, [data[:room]], offset)
        self.sizes[path] = max(size, offset + n)
        return n

    def truncate(self, fd: int, size: int) -> None:
        path = self._paths[fd]
        if size > self.sizes[path] + self._free():
            raise _enospc()
        super().truncate(fd, size)
        self.sizes[path] = size

    def close(self, fd: int) -> None:
        super().close(fd)
        del self._paths[fd]

    def write_file(self, path: Path, data: bytes) -> None:
        room = self._free() + self.sizes.get(str(path), 0)
        if len(data) > room:   # a real disk leaves the part that fitted
            super().write_file(path, data[:room])
            self.sizes[str(path)] = room
            self.failed_writes += 1
            raise _enospc()
        super().write_file(path, data)
        self.sizes[str(path)] = len(data)

    def replace(self, src: Path, dst: Path) -> None:
        super().replace(src, dst)
        self.sizes[str(dst)] = self.sizes.pop(str(src), 0)

    def unlink(self, path: Path) -> None:
        super().unlink(path)
        self.sizes.pop(str(path), None)

    def reserve(self, path: Path, size: int) -> None:
        have = self.sizes.get(str(path), 0)
        if size > have + self._free():
            self.failed_writes += 1
            raise _enospc()
        super().reserve(path, size)
        self.sizes[str(path)] = size

    def free_bytes(self, folder: Path) -> int | None:
        return self._free()


@contextlib.contextmanager
def tmpfs(where: Path, size_bytes: int) -> Iterator[Path]:
    """A real tmpfs of ``size_bytes`` mounted at ``where`` (skips the test unless root)."""
    if os.geteuid() != 0:
        pytest.skip('mounting a tmpfs needs root (CI runs as root)')
    where.mkdir()
    done = subprocess.run(['mount', '-t', 'tmpfs', '-o', f'size={size_bytes}', 'tmpfs',
                           str(where)], capture_output=True, text=True, timeout=10,
                          check=False)
    if done.returncode != 0:
        pytest.skip(f'cannot mount a tmpfs: {done.stderr.strip()}')
    try:
        yield where
    finally:
        subprocess.run(['umount', '-l', str(where)], capture_output=True, timeout=10,
                       check=False)
