"""What a ``BagWriter`` holds and loses while its disk is full: the bookkeeping of a stall.

While writing fails, :class:`WriteStall` keeps the current :class:`~._write_loss.WriteGap`,
the chunks held in memory (the oldest messages, up to ``buffer_bytes``) and what is lost:
once a message is lost every later one is too until writing resumes, so that each gap loses
one contiguous range of log times. The writer (:mod:`.bag_writer`) decides when a write has
failed and when space has returned; this class only counts.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rv_te_bench.io._mcap_file import MSG_HEADER, Chunk
from rv_te_bench.io._storage import SPACE_ERRNOS
from rv_te_bench.io._write_loss import WriteGap, utc_now

if TYPE_CHECKING:
    from collections.abc import Mapping, Sequence

    from rv_te_bench.io._mcap_file import TopicInfo

__all__ = ['WriteStall']


class WriteStall:
    """The held chunks, the losses and the gaps of one writer.

    Args:
        buffer_bytes: Messages held in memory while the disk is full [bytes], at most.

    Attributes:
        gap: The gap in progress (None: writing works).
        gaps: Every gap so far, in order.
        held: Full chunks waiting for space, oldest first.
        held_bytes: Their size [bytes].
        next_retry_mono: When to look for space again (``time.monotonic``).
    """

    def __init__(self, buffer_bytes: int) -> None:
        self.buffer_bytes = buffer_bytes
        self.gap: WriteGap | None = None
        self.gaps: list[WriteGap] = []
        self.held: list[Chunk] = []
        self.held_bytes = 0
        self.next_retry_mono = 0.0
        self._errno = 0

    @property
    def retrying(self) -> bool:
        """True when the failure means "no space (for now)": writing may resume."""
        return self._errno in SPACE_ERRNOS

    def begin(self, exc: OSError, file_before: str, chunks: Sequence[Chunk],
              open_chunk: Chunk, by_cid: Mapping[int, TopicInfo]) -> bool:
        """A write failed: start a gap; hold the oldest of ``chunks``, lose the rest.

        Returns:
            True when ``open_chunk`` (newer than what was lost) was lost too: the caller
            starts a new one.
        """
        gap = WriteGap(error=exc.strerror or str(exc), started_utc=utc_now(),
                       file_before=file_before)
        self.gap = gap
        self._errno = exc.errno or 0
        self.gaps.append(gap)
        for chunk in chunks:   # the oldest messages are held, one contiguous range is lost
            room = self.buffer_bytes - self.held_bytes
            if not gap.lost_messages and len(chunk.data) <= room:
                self.hold(chunk)
                continue
            if not gap.lost_messages and room > 0:
                head, chunk = chunk.split(room)
                if head.data:
                    self.hold(head)
            self.lose(chunk, by_cid)
        if gap.lost_messages and open_chunk.data:
            self.lose(open_chunk, by_cid)
            return True
        return False

    def admits(self, info: TopicInfo, t_ns: int, size: int, open_bytes: int) -> bool:
        """Whether a message of ``size`` bytes can still be held; if not it is lost.

        Once something is lost, all is until writing resumes (the loss is one range).
        """
        gap = self.gap
        assert gap is not None
        if not gap.lost_messages and (self.held_bytes + open_bytes + MSG_HEADER.size + size
                                      <= self.buffer_bytes):
            return True
        gap.lose(info.name, t_ns)
        info.lost += 1
        return False

    def hold(self, chunk: Chunk) -> None:
        """Keep a full chunk in memory until space returns."""
        self.held.append(chunk)
        self.held_bytes += len(chunk.data)

    def lose(self, chunk: Chunk, by_cid: Mapping[int, TopicInfo]) -> None:
        """Count every message of ``chunk`` lost (per topic, with its log times)."""
        gap = self.gap
        assert gap is not None
        for cid, flat in chunk.index.items():
            if flat:
                times = flat[0::2]
                topic = by_cid[cid]
                topic.lost += len(times)
                gap.lose(topic.name, min(times), len(times), last_ns=max(times))

    def lose_all(self, open_chunk: Chunk, by_cid: Mapping[int, TopicInfo]) -> None:
        """The bag closes while the disk is full: the held chunks and the open one are lost."""
        for chunk in (*self.held, open_chunk):
            self.lose(chunk, by_cid)
        self.held, self.held_bytes = [], 0

    def take_held(self) -> list[Chunk]:
        """Writing resumed: the held chunks, to be written first (no longer held here)."""
        held, self.held, self.held_bytes = self.held, [], 0
        return held
