"""Read the next chunk of a file while the import writes the last one (a second core only).

Parsing a CSV block (pyarrow), reading TDMS / MDF channels and compressing the bag's
chunks (zstd) release the GIL, so a helper thread that reads one chunk ahead lets both
cores work: the import then takes about as long as the slower of reading and writing
rather than their sum (issue 41). Where one core is allowed (``taskset``, a cgroup quota,
``RV_TE_READ_AHEAD=0`` as fleet workers run) no thread is started: it would only add
hand-overs (:mod:`rv_te_bench.io._cores`).

Memory stays flat: at most one chunk waits in the queue beside the one being read and the
one being written. An error in the reader (a bad cell, named by line) is raised in the
caller at the point the chunk would have been, after every chunk before it.
"""

from __future__ import annotations

import queue
import threading
from typing import TYPE_CHECKING, TypeVar

from rv_te_bench.io._cores import helper_threads_allowed

if TYPE_CHECKING:
    from collections.abc import Generator, Iterator

__all__ = ['read_ahead']

T = TypeVar('T')
_POLL_S = 0.1


def read_ahead(chunks: Iterator[T], *, threads: bool | None = None) -> Generator[T, None, None]:
    """``chunks`` as they come, read one ahead by a helper thread where two cores are allowed.

    Close the returned generator (``close()``) when done early: the helper is stopped and
    joined (after at most the chunk it is reading), so the file can be closed safely.

    Args:
        chunks: The reader's chunk iterator (only the helper thread advances it).
        threads: Force the helper on / off (None: :func:`helper_threads_allowed`).
    """
    if not (helper_threads_allowed() if threads is None else threads):
        yield from chunks
        return
    q: queue.Queue[tuple[str, object]] = queue.Queue(maxsize=1)
    stop = threading.Event()

    def put(item: tuple[str, object]) -> bool:
        while not stop.is_set():
            try:
                q.put(item, timeout=_POLL_S)
            except queue.Full:
                continue
            return True
        return False

    def run() -> None:
        try:
            for c in chunks:
                if not put(('chunk', c)):
                    return
            put(('end', None))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller, raised there
            put(('error', exc))
        finally:
            close = getattr(chunks, 'close', None)
            if close is not None:
                close()

    helper = threading.Thread(target=run, name='import-read-ahead', daemon=True)
    helper.start()
    try:
        while True:
            kind, value = q.get()
            if kind == 'chunk':
                yield value  # type: ignore[misc]
            elif kind == 'end':
                return
            else:
                raise value  # type: ignore[misc]
    finally:
        stop.set()
        helper.join()
