"""Block guarding for the offline analysis: stop cleanly at a read error, keep a TE trace."""

from __future__ import annotations

import itertools
import time
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.errors import BagError
from rv_te_bench.report.results import TeTrace

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Iterator

    import numpy.typing as npt

    from rv_te_bench.core.angle_fold import AngleFold
    from rv_te_bench.core.head_combine import WindowBreak
    from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData

    FloatArray = npt.NDArray[np.float64]
    ProgressFn = Callable[[int, int, float], None]


class _GuardedBlocks:
    """Iterator over encoder blocks/batches that stops cleanly at a read error, keeps a trace.

    The reader (``strict=False``) stops quietly at a truncated or corrupt part and lists
    the problem; a ``BagError`` raised in the middle of the iteration (e.g. the topic
    carries another type further on) would make the TE core lose every window already
    closed, so this wrapper ends the iteration instead and remembers the error. It also
    counts blocks for the progress callback and keeps a thinned TE trace for the plot (at
    most ``max_points`` points: the trace is thinned by 2 when exceeded).
    """

    def __init__(self, blocks: Iterable[EncoderBlockData | EncoderBatch | WindowBreak],
                 gear_ratio: float,
                 *, progress: ProgressFn | None, t_start: float,
                 fold: AngleFold | None = None, max_points: int) -> None:
        self._it = iter(blocks)
        self._max_points = max_points
        self._fold = fold
        self._ratio = gear_ratio
        self._progress = progress
        self._t0 = t_start
        self.blocks = 0
        self.samples = 0
        self.error: str | None = None
        self._stride = 1
        self._last_seq: int | None = None
        self._parts: list[tuple[npt.NDArray[np.int64], FloatArray, FloatArray]] = []
        self._kept = 0
        #: (input, output) angle of the first and of the last sample read [rad]
        self.first_angles: tuple[float, float] | None = None
        self.last_angles: tuple[float, float] | None = None

    def advance(self) -> tuple[float, float]:
        """How far the input and the output angle advanced from the first to the last
        sample read [rad] (multi-turn angles: gaps do not matter)."""
        if self.first_angles is None or self.last_angles is None:
            return 0.0, 0.0
        return (self.last_angles[0] - self.first_angles[0],
                self.last_angles[1] - self.first_angles[1])

    def _ends(self, th_in: npt.ArrayLike, th_out: npt.ArrayLike) -> None:
        a, b = np.asarray(th_in), np.asarray(th_out)
        if a.size and a.shape == b.shape:
            if self.first_angles is None:
                self.first_angles = (float(a.flat[0]), float(b.flat[0]))
            self.last_angles = (float(a.flat[-1]), float(b.flat[-1]))

    def __iter__(self) -> Iterator[EncoderBlockData | EncoderBatch | WindowBreak]:
        return self

    def __next__(self) -> EncoderBlockData | EncoderBatch | WindowBreak:
        from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData

        try:
            item = next(self._it)
        except BagError as exc:
            self.error = str(exc)
            raise StopIteration from None
        if not isinstance(item, EncoderBlockData | EncoderBatch):   # a WindowBreak: passed on
            return item
        self._ends(item.theta_in_rad, item.theta_out_rad)
        if isinstance(item, EncoderBatch):
            self.blocks += item.n_blocks
            self.samples += item.n_samples
            self._keep_batch(item)
        else:
            self.blocks += 1
            self.samples += int(np.size(item.theta_out_rad))
            self._keep(item)
        if self._progress is not None:
            self._progress(self.blocks, self.samples, time.monotonic() - self._t0)
        return item

    def _keep(self, block: EncoderBlockData) -> None:
        """Keep every ``stride``-th sample (by global sample index) and a NaN row at gaps."""
        th_out = np.asarray(block.theta_out_rad, dtype=np.float64)
        th_in = np.asarray(block.theta_in_rad, dtype=np.float64)
        n = th_out.size
        if th_out.shape != th_in.shape or n == 0:
            return  # the core reports malformed blocks; the plot just skips them
        self._keep_run(int(block.seq), int(block.seq), th_in, th_out, self.samples - n)

    def _keep_batch(self, batch: EncoderBatch) -> None:
        """As ``_keep`` for each block of a batch, one run of continuous blocks at a time."""
        seq = np.asarray(batch.seq, dtype=np.int64)
        starts = np.asarray(batch.starts, dtype=np.intp)
        g0 = self.samples - batch.n_samples
        cuts = [0, *(np.flatnonzero(seq[1:] != seq[:-1] + 1) + 1).tolist(), seq.size]
        if batch.parts:   # the chunks of a merged batch, as the fold was given them
            cuts = sorted({*cuts, *batch.parts})
        for k0, k1 in itertools.pairwise(cuts):
            a, b = int(starts[k0]), int(starts[k1])
            self._keep_run(int(seq[k0]), int(seq[k1 - 1]), batch.theta_in_rad[a:b],
                           batch.theta_out_rad[a:b], g0 + a)

    def _keep_run(self, seq_first: int, seq_last: int, th_in: FloatArray,
                  th_out: FloatArray, g0: int) -> None:
        """Samples of consecutive blocks seq_first..seq_last, the first at global index g0."""
        from rv_te_bench.core.te import transmission_error_rad

        if self._last_seq is not None and seq_first != self._last_seq + 1:
            self._parts.append((np.array([-1]), np.array([np.nan]), np.array([np.nan])))
        self._last_seq = seq_last
        if self._fold is not None:
            self._fold.add_encoders(th_in, th_out, gear_ratio=self._ratio)
        start = (-g0) % self._stride
        th = th_out[start::self._stride]
        te = transmission_error_rad(th_in[start::self._stride], th, gear_ratio=self._ratio)
        g = g0 + np.arange(start, th_out.size, self._stride, dtype=np.int64)
        self._parts.append((g, np.array(th, dtype=np.float64), np.asarray(te, dtype=np.float64)))
        self._kept += th.size
        while self._kept > self._max_points:
            g_all, th_all, te_all = self._joined()
            self._stride *= 2
            keep = (g_all < 0) | (g_all % self._stride == 0)
            self._parts = [(g_all[keep], th_all[keep], te_all[keep])]
            self._kept = int(np.count_nonzero(keep))

    def _joined(self) -> tuple[npt.NDArray[np.int64], FloatArray, FloatArray]:
        if not self._parts:
            return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
        g, th, te = (np.concatenate(a) for a in zip(*self._parts, strict=True))
        return g, th, te

    def trace(self) -> TeTrace:
        """The thinned trace collected so far (read-only arrays)."""
        _, th, te = self._joined()
        th.setflags(write=False)
        te.setflags(write=False)
        return TeTrace(theta_out_rad=th, te_rad=te, stride=self._stride)
