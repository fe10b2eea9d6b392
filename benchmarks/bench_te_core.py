"""Benchmark of the TE core: StreamingTeAnalyzer throughput and push() latency.

Run from the project root::

    .venv/bin/python benchmarks/bench_te_core.py [--revolutions 10] [--repeats 5]
        [--baseline REV] [--quick]

Realistic settings: the Wang 2020 2K-V (i = 79, f_w = 25 f_out, mesh order 1300) at
300 rpm input (15.8 s per output revolution), one-revolution windows with their order
spectrum (K = 10 crank harmonics, sidebands, mesh line), input speed varying +-50 %
(Hu 2020 style) so the angle-domain resampling does real work.

- Throughput: 10 kHz sampling (158,000 samples per window) in 1000-sample blocks, pushed
  as fast as possible; samples/s per CPU second (target >= 15e6 per core, issue #23). The
  headline is the TE node's path: ``cumulative`` read after every push, as
  ``te_node._publish_samples`` does for every TransmissionError message; push() alone is
  the second row. Also the time of push() alone relative to
  two floors over the same window lengths: a bare ``numpy.fft.rfft``, and the bare numpy
  arithmetic of the window analysis (Eq. 22, min/max/mean/std, linear ``np.interp`` onto
  the angle grid, rfft, abs). ``--baseline REV`` runs the TE core (core/te.py,
  core/spectrum.py, core/stream.py) as of that git revision interleaved with the current
  one (``--repeats`` times each; medians, and the median of the per-repeat ratios).
- Latency: ``push()`` at 1 kHz sampling with blocks of 100 and 1000 samples, median and
  p99 over every push, window closes included (target median < 10 ms).

Prints a markdown table.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.stream import StreamingTeAnalyzer
from rv_te_bench.core.stream_records import EncoderBlockData, TeAnalysisConfig
from rv_te_bench.core.units import arcmin_to_rad

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


def _push_all(stream_mod: ModuleType, blocks: list[EncoderBlockData], *,
              read_cumulative: bool = False) -> tuple[float, float, list]:
    """Push every block through a fresh analyzer of ``stream_mod``: (wall s, CPU s, windows).

    ``read_cumulative``: read ``analyzer.cumulative`` after every push, as the TE node does
    for its te/samples message.
    """
    analyzer = stream_mod.StreamingTeAnalyzer(stream_mod.TeAnalysisConfig(orders=ORDERS))
    windows: list = []
    t0, c0 = time.perf_counter(), time.process_time()
    for b in blocks:
        windows += analyzer.push(b).windows
        if read_cumulative:
            _ = analyzer.cumulative
    return time.perf_counter() - t0, time.process_time() - c0, windows


def _floor(te_all: np.ndarray, phi_all: np.ndarray,
           cuts: list[tuple[int, int]]) -> tuple[float, float]:
    """CPU s of the bare numpy floors over the same windows: (rfft only, arithmetic).

    ``arithmetic``: what any implementation of the window analysis has to do, in numpy's
    cheapest form: Eq. 22 (divide, subtract) over the samples, min / max / mean / std,
    linear ``np.interp`` onto the angle grid, ``np.fft.rfft``, ``abs``.
    """
    c0 = time.process_time()
    start = 0
    for m, n_fft in cuts:
        np.fft.rfft(te_all[start:start + m], n=n_fft)
        start += m
    fft_cpu = time.process_time() - c0
    theta_in = phi_all * RATIO
    theta_out = phi_all + te_all
    c0 = time.process_time()
    start = 0
    for m, n_fft in cuts:
        phi = theta_in[start:start + m] / RATIO
        te = theta_out[start:start + m] - phi
        te.min(), te.max(), te.mean(), te.std()
        grid = np.arange(n_fft) * (2.0 * math.pi / n_fft) + phi[0]
        np.abs(np.fft.rfft(np.interp(grid, phi, te)))
        start += m
    return fft_cpu, time.process_time() - c0


def throughput(revolutions: float, rng: np.random.Generator, *, repeats: int = 1,
               baseline: ModuleType | None = None) -> dict[str, Any]:
    """Samples/s of push() over 1000-sample blocks at 10 kHz, and the numpy floors.

    Both wall-clock and process CPU time are measured: on a shared machine the CPU time is
    the better estimate of what one core does. With ``baseline`` (the stream module of an
    older revision) both run interleaved, ``repeats`` times each; medians are reported.
    """
    import rv_te_bench.core.stream as current

    rate_hz, block = 10_000.0, 1000
    n_blocks = math.ceil(revolutions * OUTPUT_PERIOD_S * rate_hz / block)
    blocks = make_blocks(rate_hz, block, n_blocks, rng)
    variants = {'now': (current, False), 'now+cum': (current, True)}
    if baseline is not None:
        variants = {'base': (baseline, False), **variants, 'base+cum': (baseline, True)}
    cpu: dict[str, list[float]] = {k: [] for k in variants}
    wall: dict[str, list[float]] = {k: [] for k in variants}
    floors: dict[str, list[float]] = {'fft': [], 'arith': []}
    windows: list = []
    n = n_blocks * block
    te_all = np.concatenate([b.theta_out_rad - b.theta_in_rad / RATIO for b in blocks])
    phi_all = np.concatenate([b.theta_in_rad / RATIO for b in blocks])
    for _ in range(repeats):   # interleaved: machine noise hits every variant alike
        for name, (mod, read_cum) in variants.items():
            w_s, c_s, ws = _push_all(mod, blocks, read_cumulative=read_cum)
            wall[name].append(w_s)
            cpu[name].append(c_s)
            if name == 'now':
                windows = ws
        cuts = [(w.stats.n_samples, int(w.spectrum.samples_per_rev * w.spectrum.revolutions))
                for w in windows if w.complete and w.spectrum is not None]
        fft_s, arith_s = _floor(te_all, phi_all, cuts)
        floors['fft'].append(fft_s)
        floors['arith'].append(arith_s)
    med = statistics.median
    return {'samples': n, 'windows': len(cuts), 'repeats': repeats,
            'cpu_s': {k: med(v) for k, v in cpu.items()},
            'wall_s': {k: med(v) for k, v in wall.items()},
            'ratio': (statistics.median(b / a for a, b in zip(cpu['now'], cpu['base'],
                                                              strict=True))
                      if 'base' in cpu else math.nan),
            'ratio_cum': (statistics.median(b / a for a, b in zip(cpu['now+cum'],
                                                                  cpu['base+cum'], strict=True))
                          if 'base+cum' in cpu else math.nan),
            'fft_cpu_s': med(floors['fft']), 'arith_cpu_s': med(floors['arith']),
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
    parser.add_argument('--repeats', type=int, default=5,
                        help='interleaved repeats of the throughput run (medians reported)')
    parser.add_argument('--baseline', default=None, metavar='REV',
                        help='also run the TE core (te, spectrum, stream) as of this git '
                             'revision, side by side (e.g. 48604b2)')
    parser.add_argument('--quick', action='store_true', help='smaller runs (smoke test)')
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    revs = 2.0 if args.quick else args.revolutions
    base = None
    if args.baseline:
        from _baseline import load_core_at
        base = load_core_at(args.baseline)['rv_te_bench.core.stream']
    load0 = os.getloadavg()[0]
    tp = throughput(revs, rng, repeats=1 if args.quick else args.repeats, baseline=base)
    lat_blocks = {100: 400 if args.quick else 4000, 1000: 60 if args.quick else 600}
    lats = {bs: latency(bs, nb, rng) for bs, nb in lat_blocks.items()}
    print(f'machine: {platform.machine()}, {os.cpu_count()} cores, python '
          f'{platform.python_version()}, numpy {np.__version__}, '
          f'{time.strftime("%Y-%m-%d %H:%M")}; '
          f'load average {load0:.2f} -> {os.getloadavg()[0]:.2f}; median of {tp["repeats"]} '
          'interleaved repeats\n')
    n = tp['samples']
    cpu = tp['cpu_s']
    print('| measurement | value | target |')
    print('|---|---|---|')
    # headline: the TE node's path (push, then `cumulative` for the te/samples message)
    print(f"| throughput on the TE node's path (push + `cumulative` read after every push), "
          f"1000-sample blocks @ 10 kHz, {tp['windows']} one-rev windows ({n:,} samples), "
          f"per CPU second | **{n / cpu['now+cum'] / 1e6:.2f} M samples/s**"
          + (f" (before ({args.baseline}) {n / cpu['base+cum'] / 1e6:.2f} M: "
             f"**{tp['ratio_cum']:.2f}x**, median of per-repeat ratios)"
             if 'base+cum' in cpu else '') + ' | >= 15 M samples/s (#23) |')
    print(f"| same, push() alone (no `cumulative` read), per CPU second; per wall-clock second "
          f"| {n / cpu['now'] / 1e6:.2f} M samples/s"
          + (f" (before {n / cpu['base'] / 1e6:.2f} M: {tp['ratio']:.2f}x)"
             if 'base' in cpu else '')
          + f"; {n / tp['wall_s']['now'] / 1e6:.2f} M samples/s | - |")
    print(f"| analyzer time / bare numpy floors of the same windows: rfft only (n_fft "
          f"{tp['n_fft']:,}); arithmetic (Eq. 22, min/max/mean/std, np.interp to the grid, rfft, "
          f"abs: {n / tp['arith_cpu_s'] / 1e6:.1f} M samples/s) | "
          f"{cpu['now'] / tp['fft_cpu_s']:.1f} x ({cpu['now'] * 1e3:.0f} ms vs "
          f"{tp['fft_cpu_s'] * 1e3:.0f} ms); {cpu['now'] / tp['arith_cpu_s']:.2f} x "
          f"({tp['arith_cpu_s'] * 1e3:.0f} ms) CPU | - |")
    for bs, lat in lats.items():
        print(f"| push() latency, {bs}-sample blocks @ 1 kHz ({lat['pushes']} pushes, "
              f"{lat['windows']} windows closed) | median {lat['median_ms']:.3f} ms, "
              f"p99 {lat['p99_ms']:.3f} ms, max {lat['max_ms']:.1f} ms | median < 10 ms |")
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
