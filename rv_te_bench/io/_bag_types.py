"""The record types of the bag readers: the lowest floor of :mod:`rv_te_bench.io`'s reading side.

As rosbags keeps ``Connection`` / ``TopicInfo`` apart from the storages and the readers,
these types import nothing of the package: the storages (:mod:`._storage_mcap`,
:mod:`._storage_sqlite3`) build them, the opener (:mod:`._bag_open`) chooses a storage, and
the readers on top (:mod:`.bag_reader`, :mod:`.bench_record`) hand them to callers.

* :class:`Bag`: a validated bag layout (files, metadata.yaml, topic types, notes);
* :class:`MessageStream`: an iterator that records whether the result is partial;
* :data:`RawMessage` and :data:`Unit`: one stored message, and one storage unit (an MCAP
  chunk, or a buffer of sqlite3 rows) with the offsets of the messages wanted in it;
  :class:`UnitColumns`: the same unit with its messages as arrays (no per-message Python
  work: the offline reader's path);
* :func:`summarize_problems`: the problems of a read as one line.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import numpy as np

from rv_te_bench.errors import BagError

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator
    from pathlib import Path

__all__ = ['PROBLEMS_SHOWN', 'Bag', 'MessageStream', 'RawMessage', 'Unit', 'UnitColumns',
           'summarize_problems']

T = TypeVar('T')
RawMessage = tuple[str, str, int, memoryview]
"""(topic, msgtype, timestamp_ns, cdr_bytes): one message as stored."""

Unit = tuple[memoryview, list[tuple[str, str, int, int, int]]]
"""(buffer, [(topic, msgtype, log_time_ns, start, end), ...]): the messages wanted from one
storage unit (an MCAP chunk, or ~1 MiB of sqlite3 rows), as offsets into its buffer."""


@dataclass(frozen=True, slots=True)
class UnitColumns:
    """The wanted messages of one storage unit as arrays (a :data:`Unit` by columns).

    Attributes:
        buf: The unit's buffer (a decompressed MCAP chunk, or sqlite3 rows).
        targets: ``(topic, msgtype)`` of each kind of message in the unit.
        kind: Per message, its index into ``targets``.
        log_time: Per message, its log time [ns] (uint64).
        start: Per message, where its data starts in ``buf``.
        end: Per message, where its data ends in ``buf``.
    """

    buf: memoryview
    targets: tuple[tuple[str, str], ...]
    kind: np.ndarray
    log_time: np.ndarray
    start: np.ndarray
    end: np.ndarray

    @classmethod
    def from_rows(cls, buf: memoryview,
                  rows: list[tuple[str, str, int, int, int]]) -> UnitColumns:
        """The columns of a :data:`Unit`'s rows."""
        index: dict[tuple[str, str], int] = {}
        kind = [index.setdefault((r[0], r[1]), len(index)) for r in rows]
        return cls(buf, tuple(index), np.array(kind, np.intp),
                   np.array([r[2] for r in rows], np.uint64),
                   np.array([r[3] for r in rows], np.int64),
                   np.array([r[4] for r in rows], np.int64))

    def rows(self) -> list[tuple[str, str, int, int, int]]:
        """The messages as a :data:`Unit`'s rows ``(topic, msgtype, log_time, start, end)``."""
        targets = self.targets
        return [(*targets[k], t, a, b) for k, t, a, b in zip(
            self.kind.tolist(), self.log_time.tolist(), self.start.tolist(), self.end.tolist(),
            strict=True)]

#: Problems named one by one in a one-line message; the rest are counted.
PROBLEMS_SHOWN = 3


def summarize_problems(problems: list[str] | tuple[str, ...]) -> str:
    """The problems as one line: the first few, then how many more (a bag damaged all
    through has one problem per chunk, hundreds of them).

    Examples:
        >>> summarize_problems(['a', 'b'])
        'a; b'
        >>> summarize_problems([f'chunk {i} bad' for i in range(10)])
        'chunk 0 bad; chunk 1 bad; chunk 2 bad; ... and 7 more problems'
    """
    shown = '; '.join(problems[:PROBLEMS_SHOWN])
    if len(problems) > PROBLEMS_SHOWN:
        shown += f'; ... and {len(problems) - PROBLEMS_SHOWN} more problems'
    return shown


@dataclass(frozen=True, slots=True)
class Bag:
    """A validated bag layout.

    Attributes:
        path: The bag folder (or the lone ``.mcap`` file).
        files: The storage files (``.mcap`` or ``.db3``) in recording order.
        info: ``rosbag2_bagfile_information`` from metadata.yaml (empty for a lone file).
        topic_types: Topic name -> type from metadata.yaml (empty for a lone file).
        notes: What a reader should know but that does not stop reading: unlisted .mcap
            files (ignored), messages the recorder could not write (a full disk).
    """

    path: Path
    files: tuple[Path, ...]
    info: dict[str, Any]
    topic_types: dict[str, str]
    notes: tuple[str, ...] = ()

    @property
    def finalized(self) -> bool | None:
        """True when the writer closed the bag, False when it did not, None if unknown."""
        state = (self.info.get('custom_data') or {}).get('rv_te_bench.writer_state')
        return None if state is None else state == 'closed'

    @property
    def storage(self) -> str:
        """The storage of the files: ``'mcap'`` or ``'sqlite3'`` (a lone file is MCAP)."""
        return str(self.info.get('storage_identifier') or 'mcap') if self.info else 'mcap'


class MessageStream(Generic[T]):
    """Iterator over a bag's messages that records whether the result is partial.

    Attributes:
        partial: True once a problem made part of the bag unreadable.
        problems: One message per problem, each naming the file.
    """

    def __init__(self, producer: Callable[[MessageStream[T]], Iterator[T]], *,
                 strict: bool) -> None:
        self.partial = False
        self.problems: list[str] = []
        self._strict = strict
        self._it = producer(self)
        self._done = False

    def __iter__(self) -> MessageStream[T]:
        return self

    def __next__(self) -> T:
        if self._done:
            raise StopIteration
        try:
            return next(self._it)
        except StopIteration:
            self._done = True
            if self._strict and self.problems:
                msg = (summarize_problems(self.problems)
                       + ' (the messages before were read: partial)')
                raise BagError(msg) from None
            raise

    def report_problem(self, text: str) -> None:
        """Mark the result partial and record why (used by the producers)."""
        self.partial = True
        self.problems.append(text)
