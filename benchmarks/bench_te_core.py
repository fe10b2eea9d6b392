"""Benchmark of the TE core: StreamingTeAnalyzer throughput and push() latency.

Run from the project root::

    .venv/bin/python benchmarks/bench_te_core.py [--revolutions 10] [--quick]

Realistic settings: the Wang 2020 2K-V (i = 79, f_w = 25 f_out, mesh order 1300) at
300 rpm input (15.8 s per output revolution), one-revolution windows with their order
spectrum (K = 10 crank harmonics, sidebands, mesh line), input speed varying +-50 %
(Hu 2020 style) so the angle-domain resampling does real work.

- Throughput: 10 kHz sampling (158,000 samples per window) in 1000-sample blocks, pushed
  as fast as possible; samples/s, and the time relative to a bare ``numpy.fft.rfft`` of
  the same samples cut into the same window lengths (target >= 5e6 samples/s per core).
- Latency: ``push()`` at 1 kHz sampling with blocks of 100 and 1000 samples, median and
  p99 over every push, window closes included (target median < 10 ms).

Prints a markdown table.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rv_te_bench.core.orders import OrderSet  # noqa: E402
from rv_te_bench.core.stream import (  # noqa: E402
    EncoderBlockData,
    StreamingTeAnalyzer,
    TeAnalysisConfig,
)
from rv_te_bench.core.units import arcmin_to_rad  # noqa: E402

RATIO = 79.0
CRANK_PER_OUTPUT = 25.0
OMEGA_IN_RAD_S = 300.0 * 2.0 * math.pi / 60.0
OUTPUT_PERIOD_S = 2.0 * math.pi * RATIO / OMEGA_IN_RAD_S  # 15.8 s
ORDERS = OrderSet(gear_ratio=RATIO, crank_per_output=CRANK_PER_OUTPUT, n_crank_harmonics=10,
                  mesh_orders_out=(52.0 * CRANK_PER_OUTPUT,), mesh_labels=('52 f_w',))


def make_blocks(sample_rate_hz: float, block_size: int, n_blocks: int,
                rng: np.random.Generator) -> list[EncoderBlockData]:
    """Encoder blocks of a 2K-V with crank/mesh TE lines, input speed varying +-50 %."""
    n = block_size * n_blocks
    t = np.arange(n) / sample_rate_hz
    b_rad_s = 2.0 * math.pi / 3.7
    theta_in = OMEGA_IN_RAD_S * (t + 0.5 * (1.0 - np.cos(b_rad_s * t)) / b_rad_s)
    phi = theta_in / RATIO
    te = np.zeros(n)
    for order, _label in ORDERS.lines():
        te += float(arcmin_to_rad(rng.uniform(0.05, 2.0))) * np.cos(
            order * phi + rng.uniform(-math.pi, math.pi))
    theta_out = phi + te
    offsets = np.arange(block_size) / sample_rate_hz
    return [EncoderBlockData(seq=k, stamp_s=float(t[k * block_size]),
                             sample_rate_hz=sample_rate_hz, time_offset_s=offsets,
                             theta_in_rad=theta_in[k * block_size:(k + 1) * block_size],
                             theta_out_rad=theta_out[k * block_size:(k + 1) * block_size])
            for k in range(n_blocks)]


def throughput(revolutions: float, rng: np.random.Generator) -> dict[str, float]:
    """Samples/s of push() over 1000-sample blocks at 10 kHz, and the rfft baseline.

    Both wall-clock and process CPU time are measured: on a shared machine the CPU time is
    the better estimate of what one core does.
    """
    rate_hz, block = 10_000.0, 1000
    n_blocks = math.ceil(revolutions * OUTPUT_PERIOD_S * rate_hz / block)
    blocks = make_blocks(rate_hz, block, n_blocks, rng)
    analyzer = StreamingTeAnalyzer(TeAnalysisConfig(orders=ORDERS))
    windows = []
    t0, c0 = time.perf_counter(), time.process_time()
    for b in blocks:
        windows += analyzer.push(b).windows
    wall_s, cpu_s = time.perf_counter() - t0, time.process_time() - c0
    n = n_blocks * block
    # baseline: a bare numpy rfft of the same samples, window by window, at the FFT length
    # the analyzer used (a fast length), i.e. the least any spectrum per window costs
    te_all = np.concatenate([b.theta_out_rad - b.theta_in_rad / RATIO for b in blocks])
    cuts = [(w.stats.n_samples, int(w.spectrum.samples_per_rev * w.spectrum.revolutions))
            for w in windows if w.complete and w.spectrum is not None]
    t0, c0 = time.perf_counter(), time.process_time()
    start = 0
    for m, n_fft in cuts:
        np.fft.rfft(te_all[start:start + m], n=n_fft)
        start += m
    fft_wall_s, fft_cpu_s = time.perf_counter() - t0, time.process_time() - c0
    return {'samples': n, 'windows': len(cuts), 'wall_s': wall_s, 'cpu_s': cpu_s,
            'fft_wall_s': fft_wall_s, 'fft_cpu_s': fft_cpu_s,
            'n_fft': cuts[0][1] if cuts else 0}


def latency(block_size: int, n_blocks: int, rng: np.random.Generator) -> dict[str, float]:
    """Median and p99 of push() [ms] for 1 kHz blocks."""
    blocks = make_blocks(1000.0, block_size, n_blocks, rng)
    analyzer = StreamingTeAnalyzer(TeAnalysisConfig(orders=ORDERS))
    times = np.empty(n_blocks)
    closes = 0
    for k, b in enumerate(blocks):
        t0 = time.perf_counter()
        up = analyzer.push(b)
        times[k] = time.perf_counter() - t0
        closes += len(up.windows)
    return {'median_ms': 1e3 * float(np.median(times)),
            'p99_ms': 1e3 * float(np.percentile(times, 99)),
            'max_ms': 1e3 * float(times.max()), 'pushes': n_blocks, 'windows': closes}


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print a markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--revolutions', type=float, default=10.0,
                        help='output revolutions for the throughput run')
    parser.add_argument('--quick', action='store_true', help='smaller runs (smoke test)')
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    revs = 2.0 if args.quick else args.revolutions
    tp = throughput(revs, rng)
    lat_blocks = {100: 400 if args.quick else 4000, 1000: 60 if args.quick else 600}
    lats = {bs: latency(bs, nb, rng) for bs, nb in lat_blocks.items()}
    print('| measurement | value | target |')
    print('|---|---|---|')
    print(f"| throughput, 1000-sample blocks @ 10 kHz, {tp['windows']} one-rev windows "
          f"({tp['samples']:,} samples), per CPU second | "
          f"{tp['samples'] / tp['cpu_s'] / 1e6:.2f} M samples/s | >= 5 M samples/s |")
    print(f"| same, per wall-clock second | {tp['samples'] / tp['wall_s'] / 1e6:.2f} M samples/s "
          f"| - |")
    print(f"| analyzer time / bare numpy rfft of the same windows (n_fft {tp['n_fft']:,}) | "
          f"{tp['cpu_s'] / tp['fft_cpu_s']:.1f} x CPU ({tp['cpu_s'] * 1e3:.0f} ms vs "
          f"{tp['fft_cpu_s'] * 1e3:.0f} ms) | - |")
    for bs, lat in lats.items():
        print(f"| push() latency, {bs}-sample blocks @ 1 kHz ({lat['pushes']} pushes, "
              f"{lat['windows']} windows closed) | median {lat['median_ms']:.3f} ms, "
              f"p99 {lat['p99_ms']:.3f} ms, max {lat['max_ms']:.1f} ms | median < 10 ms |")
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
