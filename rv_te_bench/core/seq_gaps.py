"""Gaps in a stream of encoder blocks without the TE analysis: what ``identify`` reports.

:class:`SeqGapWatch` follows the block sequence numbers and times as they are read and
lists the breaks exactly as :class:`~rv_te_bench.core.stream.StreamingTeAnalyzer` reports
them (a seq jump with its time and length: lost blocks of a live session, or a drop-out of
an imported DAQ file; a block starting before the previous one ended).
"""

from __future__ import annotations

import numpy as np

from rv_te_bench.core.stream_records import GapEvent, seq_jump_event

__all__ = ['SeqGapWatch']


class SeqGapWatch:
    """Collects the gaps of a block stream, batch by batch (no Python loop over blocks
    except at the gaps themselves).

    Attributes:
        gaps: The gaps found, in order.
    """

    def __init__(self) -> None:
        self.gaps: list[GapEvent] = []
        self._last_seq: int | None = None
        self._last_t: float | None = None
        self._t_first: float | None = None

    def add(self, seq: np.ndarray, t_first: np.ndarray, t_last: np.ndarray,
            rate_hz: np.ndarray) -> None:
        """Blocks in stream order: their seqs, first and last sample times [s], rates [Hz]."""
        seq = np.asarray(seq, dtype=np.int64)
        if seq.size == 0:
            return
        t_first = np.asarray(t_first, dtype=np.float64)
        t_last = np.asarray(t_last, dtype=np.float64)
        if self._t_first is None:
            self._t_first = float(t_first[0])
        prev_seq = np.concatenate([[seq[0] - 1 if self._last_seq is None else self._last_seq],
                                   seq[:-1]])
        prev_t = np.concatenate([[-np.inf if self._last_t is None else self._last_t],
                                 t_last[:-1]])
        jumps = np.flatnonzero((seq != prev_seq + 1) | ~(t_first > prev_t))
        for k in jumps.tolist():
            before = float(prev_t[k]) if np.isfinite(prev_t[k]) else None
            if seq[k] != prev_seq[k] + 1:
                self.gaps.append(seq_jump_event(int(prev_seq[k]) + 1, int(seq[k]), before,
                                                float(t_first[k]), float(rate_hz[k]),
                                                self._t_first))
            else:
                self.gaps.append(GapEvent(
                    'time_backwards', int(seq[k]),
                    f'block seq {int(seq[k])} starts at {float(t_first[k])!r} s, not after '
                    f'{before!r} s'))
        self._last_seq = int(seq[-1])
        self._last_t = float(t_last[-1])
