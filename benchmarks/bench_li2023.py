"""Real-time factor of the Li 2023 RV dynamic model (sim.li2023) at 1 kHz output sampling.

Run: ``.venv/bin/python benchmarks/bench_li2023.py [--seconds 5] [--block 100]``. Prints a
markdown table row per case. The model is fed blocks of ``--block`` samples at 1 kHz
(1500 rpm input, 450 N m, the paper's case) the way the bench node calls ``te_rad``;
real-time factor = simulated seconds / wall seconds (>= 1: fast enough to run live); the
CPU real-time factor divides by the process CPU time (all threads) instead, which depends
far less on what else runs on the machine.
The first block (LTCA, matrix assembly, caches) is not timed.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from sim.li2023 import build_te_model
from sim.presets import load_preset
from sim.units import rpm_to_rad_s


def _time_case(errors: bool, seconds: float, block: int,
               fs_hz: float) -> tuple[float, float, float]:
    """Wall real-time factor, wall ms per block and CPU real-time factor (load-independent)."""
    preset = load_preset('li2023-rv', {'errors.enabled': str(errors).lower()})
    model = build_te_model(preset, 'dte')
    w = float(rpm_to_rad_s(1500.0))
    k = 0

    def next_block() -> None:
        nonlocal k
        t = (k * block + np.arange(block)) / fs_hz
        model.te_rad(t, w * t, np.full(block, w), np.full(block, 450.0))
        k += 1

    next_block()                                     # warm-up, not timed
    n_blocks = max(1, round(seconds * fs_hz / block))
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(n_blocks):
        next_block()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    sim_s = n_blocks * block / fs_hz
    return sim_s / wall, 1e3 * wall / n_blocks, sim_s / cpu


def main(argv: list[str] | None = None) -> int:
    """Time both cases (without / with the Table 3 errors) and print the table."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--seconds', type=float, default=5.0, help='simulated seconds per case')
    ap.add_argument('--block', type=int, default=100, help='samples per te_rad call')
    ap.add_argument('--fs', default='1000,10000',
                    help='output sampling rates [Hz], comma separated; 1 kHz decides')
    args = ap.parse_args(argv)
    preset = load_preset('li2023-rv')
    rates = [float(x) for x in args.fs.split(',')]
    print(f'sim.li2023 te_rad, blocks of {args.block}, 1500 rpm, 450 N m, '
          f'max step {preset["solver.max_step_s"]:g} s; Python {platform.python_version()}, '
          f'numpy {np.__version__}, {os.cpu_count()} CPUs, load average '
          f'{os.getloadavg()[0]:.1f}\n')
    print('| model | errors | fs [Hz] | block | simulated [s] | ms/block | real-time factor '
          '| CPU real-time factor |')
    print('|---|---|---|---|---|---|---|---|')
    worst = float('inf')
    for fs in rates:
        for errors in (False, True):
            rtf, ms, rtf_cpu = _time_case(errors, args.seconds, args.block, fs)
            if fs == rates[0]:
                worst = min(worst, rtf)
            print(f'| li2023-rv dte | {"Table 3 + E_cr" if errors else "none"} | {fs:g} | '
                  f'{args.block} | {args.seconds:g} | {ms:.1f} | {rtf:.2f} | {rtf_cpu:.2f} |')
    print(f'\nworst real-time factor at {rates[0]:g} Hz: {worst:.2f} '
          f'({"ok" if worst >= 1 else "TOO SLOW"})')
    return 0 if worst >= 1 else 1


if __name__ == '__main__':
    raise SystemExit(main())
