"""Bookkeeping of what a ``BagWriter`` could not write (a full disk), and how it is stated.

Each period in which the bag could not be written is one ``WriteGap``: when it started,
why, which messages were lost (per topic, with the range of their log times), and whether
and where recording resumed. ``BagWriter`` stores the list in ``metadata.yaml``
(``custom_data``: ``rv_te_bench.lost_messages`` and ``rv_te_bench.write_gaps``, the latter
YAML, as rosbag2's custom_data holds strings) and as an MCAP metadata record
``rv_te_write_gap`` at the start of the file that follows the gap.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any

__all__ = ['WRITE_GAP_RECORD', 'WriteGap', 'describe_gaps', 'utc_now']

WRITE_GAP_RECORD = 'rv_te_write_gap'


def utc_now() -> str:
    """The current UTC time, ISO 8601 to the millisecond."""
    return dt.datetime.now(dt.UTC).isoformat(timespec='milliseconds')


def _utc(t_ns: int) -> str:
    return dt.datetime.fromtimestamp(t_ns * 1e-9, dt.UTC).isoformat(timespec='milliseconds')


@dataclass(slots=True)
class WriteGap:
    """One period in which the bag could not be written (the disk was full).

    Attributes:
        error: The operating system's reason (``No space left on device``).
        started_utc: When the first write failed (wall clock).
        file_before: The ``.mcap`` file that was cut back to its last complete chunk and
            closed when the write failed.
        lost: Messages lost per topic (neither on disk nor held any more).
        lost_first_ns: Log time of the earliest lost message [ns]; None: nothing lost.
        lost_last_ns: Log time of the latest lost message [ns]; None: nothing lost.
        resumed_utc: When writing resumed; None: it had not when the bag was closed.
        file_after: The ``.mcap`` file recording resumed into.
        held: Messages kept in memory during the gap and written after it.
    """

    error: str
    started_utc: str
    file_before: str
    lost: dict[str, int] = field(default_factory=dict)
    lost_first_ns: int | None = None
    lost_last_ns: int | None = None
    resumed_utc: str | None = None
    file_after: str | None = None
    held: int = 0

    def lose(self, topic: str, log_time_ns: int, n: int = 1, *,
             last_ns: int | None = None) -> None:
        """Count ``n`` messages of ``topic`` lost, logged from ``log_time_ns`` to ``last_ns``."""
        self.lost[topic] = self.lost.get(topic, 0) + n
        last = log_time_ns if last_ns is None else last_ns
        if self.lost_first_ns is None or log_time_ns < self.lost_first_ns:
            self.lost_first_ns = log_time_ns
        if self.lost_last_ns is None or last > self.lost_last_ns:
            self.lost_last_ns = last

    @property
    def lost_messages(self) -> int:
        """Messages lost in this gap, all topics."""
        return sum(self.lost.values())

    def as_dict(self) -> dict[str, Any]:
        """The gap as plain data (stored in metadata.yaml and the MCAP record)."""
        return {
            'error': self.error,
            'started_utc': self.started_utc,
            'resumed_utc': self.resumed_utc,
            'file_before': self.file_before,
            'file_after': self.file_after,
            'lost_messages': self.lost_messages,
            'lost': dict(self.lost),
            'lost_log_time_ns': ([self.lost_first_ns, self.lost_last_ns]
                                 if self.lost_first_ns is not None else []),
            'held_and_written': self.held,
        }

    def describe(self) -> str:
        """One line: when, why, how much was lost, whether recording resumed."""
        if self.lost_messages:
            per_topic = ', '.join(f'{t}: {n}' for t, n in sorted(self.lost.items()))
            assert self.lost_first_ns is not None and self.lost_last_ns is not None
            span_s = (self.lost_last_ns - self.lost_first_ns) * 1e-9
            what = (f'{self.lost_messages} messages lost ({per_topic}), logged '
                    f'{_utc(self.lost_first_ns)} .. {_utc(self.lost_last_ns)} ({span_s:.2f} s)')
        else:
            what = 'no message lost'
        end = (f'resumed {self.resumed_utc} in {self.file_after}' if self.resumed_utc
               else 'not resumed before the bag was closed')
        return f'write failed ({self.error}) at {self.started_utc}: {what}; {end}'


def describe_gaps(gaps: list[WriteGap]) -> str:
    """One sentence over all gaps: total lost and how many times the disk was full."""
    lost = sum(g.lost_messages for g in gaps)
    times = 'once' if len(gaps) == 1 else f'{len(gaps)} times'
    return f'the bag could not be written {times}; {lost} messages lost'
