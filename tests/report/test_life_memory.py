"""The analysis keeps what a life test's report needs in memory that does not grow with it.

Issue 41 s.5: a 10-hour session (360 million samples) is analysed in <= 500 MB. Run here
as ``analyze_bag`` runs it (:class:`~rv_te_bench.report._guarded._GuardedBlocks` keeping the
thinned TE trace, the min/max envelope for the plot, the windows kept without their per-bin
spectra), on a synthetic stream of 1 and of 8 units of length: the memory held at the end
and the peak grow by no more than the per-window results (about 6 kB a window with its labelled
lines, 15 MB for a 10-hour session; measured here with tracemalloc, which numpy reports its
arrays to), and the plotted data
(envelope buckets, trace points) is bounded whatever the length. The same run with the
trace not thinned (the planted defect: every sample kept for the plot) grows by its
samples.
"""

from __future__ import annotations

import math
import tracemalloc
from dataclasses import replace

import numpy as np

from rv_te_bench.core.envelope import MinMaxEnvelope
from rv_te_bench.core.offline import analyze_blocks
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.spectrum import SpectrumAverager
from rv_te_bench.core.stream_records import EncoderBatch, TeAnalysisConfig, WindowResult
from rv_te_bench.report._guarded import _GuardedBlocks

FS_HZ = 10_000.0
BLOCK = 1000
PER_BATCH = 100          # blocks per batch (an MCAP chunk's worth)
F_OUT_HZ = 2.0           # output revolutions per second: many windows per second of record
RATIO = 81.0
UNIT = 500_000           # samples of the short record


def _batches(n_samples: int):
    k0 = 0
    for b0 in range(0, n_samples // BLOCK, PER_BATCH):
        nb = min(PER_BATCH, n_samples // BLOCK - b0)
        n = nb * BLOCK
        t = (k0 + np.arange(n)) / FS_HZ
        th_out = 2 * math.pi * F_OUT_HZ * t
        te = 1e-4 * np.sin(36 * th_out) + 3e-5 * np.sin(th_out)
        yield EncoderBatch(
            seq=np.arange(b0, b0 + nb, dtype=np.int64),
            stamp_s=(k0 + np.arange(nb) * BLOCK) / FS_HZ,
            sample_rate_hz=np.full(nb, FS_HZ),
            starts=np.arange(nb + 1, dtype=np.int64) * BLOCK,
            time_offset_s=np.tile(np.arange(BLOCK) / FS_HZ, nb),
            theta_in_rad=RATIO * (th_out - te), theta_out_rad=th_out)
        k0 += n


def _run(n_samples: int, max_points: int) -> tuple[int, int, int, int, int]:
    """(held at the end, peak, windows, envelope buckets, trace points) [bytes, counts]."""
    config = TeAnalysisConfig(orders=OrderSet(gear_ratio=RATIO, crank_per_output=RATIO - 1))
    tracemalloc.start()
    try:
        reader = _GuardedBlocks(_batches(n_samples), RATIO, progress=None, t_start=0.0,
                                max_points=max_points)
        averager = SpectrumAverager()
        kept: list[WindowResult] = []

        def on_window(w: WindowResult) -> None:
            if w.spectrum is not None:
                if w.complete:
                    averager.add(w.spectrum)
                w = replace(w, spectrum=w.spectrum.lines_only())
            kept.append(w)

        envelope = MinMaxEnvelope()
        analyze_blocks(reader, config, on_window=on_window, envelope=envelope)
        trace = reader.trace()
        data = envelope.data()
        held, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return held, peak, len(kept), data.size, trace.te_rad.size


def test_memory_does_not_grow_with_the_record_but_for_its_windows() -> None:
    held1, peak1, win1, env1, pts1 = _run(UNIT, 40_000)
    held8, peak8, win8, env8, pts8 = _run(8 * UNIT, 40_000)
    assert win8 > 7 * win1 > 100      # (400 and 3200 windows of one output revolution)
    per_window = 10_000               # bytes a kept window may cost, at most (6 kB)
    extra = (win8 - win1) * per_window
    assert held8 - held1 < extra, (held1, held8, win1, win8)
    assert peak8 - peak1 < extra + 2 * 2**20, (peak1, peak8)
    assert env8 <= 20_000 and pts8 <= 40_000 and env1 <= 20_000 and pts1 <= 40_000
    # the planted defect: every sample kept for the plot (16 B a sample, two arrays)
    held_bad, *_ = _run(8 * UNIT, 10**9)
    assert held_bad - held8 > 8 * UNIT * 16, (held8, held_bad)
