"""Real-time factor of the Li 2023 RV dynamic model (sim.li2023), fed block by block.

Run: ``.venv/bin/python benchmarks/bench_li2023.py [--seconds 5] [--block 100]
[--fs 1000,10000] [--baseline REV [--runs 5] [--check-rev]]``. Prints a markdown table row
per case. The model is fed blocks of ``--block`` samples (comma separated: several block
sizes) at each ``--fs`` (1500 rpm input, 450 N m, the paper's case) the way the bench node
calls ``te_rad``; real-time factor = simulated seconds / wall seconds (>= 1: fast enough
to run live); the CPU real-time factor divides by the process CPU time (all threads)
instead, which depends far less on what else runs on the machine.
The first block (LTCA, matrix assembly, caches) is not timed.

With ``--baseline REV`` (e.g. ``48604b2``) sim/li2023.py as of that git revision runs side
by side (interleaved, median of ``--runs``; benchmarks/_baseline.py) and the table shows
both real-time factors, their ratio and the largest difference of the two TE records
[arcsec] over the timed blocks. ``--check-rev`` first compares the two TE records over one
output revolution (4.84 s at 1500 rpm) at every rate and block size, with and without the
errors.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from types import ModuleType

import numpy as np

import sim.li2023 as current
from sim.presets import load_preset
from sim.units import rpm_to_rad_s

ARCSEC_PER_RAD = 180.0 * 3600.0 / np.pi


def _model(module: ModuleType, errors: bool) -> object:
    preset = load_preset('li2023-rv', {'errors.enabled': str(errors).lower()})
    return module.build_te_model(preset, 'dte')


def _blocks(model: object, fs_hz: float, block: int, k0: int, n_blocks: int) -> np.ndarray:
    w = float(rpm_to_rad_s(1500.0))
    out = []
    for k in range(k0, k0 + n_blocks):
        t = (k * block + np.arange(block)) / fs_hz
        out.append(model.te_rad(t, w * t, np.full(block, w), np.full(block, 450.0)))  # type: ignore[attr-defined]
    return np.concatenate(out)


def _time_case(module: ModuleType, errors: bool, seconds: float, block: int,
               fs_hz: float) -> tuple[float, float, float, np.ndarray]:
    """Wall real-time factor, wall ms per block, CPU real-time factor, TE record [rad]."""
    model = _model(module, errors)
    _blocks(model, fs_hz, block, 0, 1)               # warm-up, not timed
    n_blocks = max(1, round(seconds * fs_hz / block))
    t0, c0 = time.perf_counter(), time.process_time()
    te = _blocks(model, fs_hz, block, 1, n_blocks)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    sim_s = n_blocks * block / fs_hz
    return sim_s / wall, 1e3 * wall / n_blocks, sim_s / cpu, te


def _check_rev(base: ModuleType, rates: list[float], blocks: list[int]) -> None:
    """Largest TE difference new vs baseline over one output revolution."""
    period = 60.0 / 1500.0 * 121.0
    print('\nTE record, this tree vs baseline, one output revolution '
          f'({period:g} s from t = 0):\n')
    print('| errors | fs [Hz] | block | samples | max difference [arcsec] | TE p-p [arcsec] |')
    print('|---|---|---|---|---|---|')
    for fs in rates:
        for block in blocks:
            for errors in (False, True):
                n_blocks = int(np.ceil(period * fs / block))
                te_new = _blocks(_model(current, errors), fs, block, 0, n_blocks)
                te_old = _blocks(_model(base, errors), fs, block, 0, n_blocks)
                diff = float(np.max(np.abs(te_new - te_old))) * ARCSEC_PER_RAD
                print(f'| {"Table 3 + E_cr" if errors else "none"} | {fs:g} | {block} | '
                      f'{te_new.size} | {diff:.1e} | {np.ptp(te_old) * ARCSEC_PER_RAD:.3f} |')


def main(argv: list[str] | None = None) -> int:
    """Time both cases (without / with the Table 3 errors) and print the table."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--seconds', type=float, default=5.0, help='simulated seconds per case')
    ap.add_argument('--block', default='100', help='samples per te_rad call, comma separated')
    ap.add_argument('--fs', default='1000,10000',
                    help='output sampling rates [Hz], comma separated; the first decides')
    ap.add_argument('--baseline', default=None, metavar='REV',
                    help='git revision whose sim/li2023.py runs side by side')
    ap.add_argument('--runs', type=int, default=3, help='runs per case with --baseline (median)')
    ap.add_argument('--check-rev', action='store_true',
                    help='with --baseline: compare the TE records over one output revolution')
    args = ap.parse_args(argv)
    base = None
    if args.baseline:
        from _baseline import load_at
        base = load_at(args.baseline, 'sim/li2023.py', 'sim.li2023')
    preset = load_preset('li2023-rv')
    rates = [float(x) for x in args.fs.split(',')]
    blocks = [int(x) for x in args.block.split(',')]
    print(f'sim.li2023 te_rad, 1500 rpm, 450 N m, max step {preset["solver.max_step_s"]:g} s; '
          f'Python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} CPUs, '
          f'load average {os.getloadavg()[0]:.1f}'
          + (f', baseline {args.baseline}, median of {args.runs} interleaved runs'
             if base else '') + '\n')
    if base:
        if args.check_rev:
            _check_rev(base, rates, blocks)
            print()
        print('| errors | fs [Hz] | block | simulated [s] | ms/block (baseline / now) '
              '| real-time factor (baseline / now) | CPU real-time factor (baseline / now) '
              '| speed-up | max difference [arcsec] |')
        print('|---|---|---|---|---|---|---|---|---|')
    else:
        print('| model | errors | fs [Hz] | block | simulated [s] | ms/block | real-time factor '
              '| CPU real-time factor |')
        print('|---|---|---|---|---|---|---|---|')
    worst = float('inf')
    for fs in rates:
        for block in blocks:
            for errors in (False, True):
                name = 'Table 3 + E_cr' if errors else 'none'
                if base is None:
                    rtf, ms, rtf_cpu, _ = _time_case(current, errors, args.seconds, block, fs)
                    print(f'| li2023-rv dte | {name} | {fs:g} | {block} | {args.seconds:g} | '
                          f'{ms:.1f} | {rtf:.2f} | {rtf_cpu:.2f} |')
                else:
                    now, old = [], []
                    for _ in range(args.runs):          # interleaved: same machine state
                        old.append(_time_case(base, errors, args.seconds, block, fs))
                        now.append(_time_case(current, errors, args.seconds, block, fs))
                    med = [[float(np.median([r[i] for r in runs])) for i in range(3)]
                           for runs in (old, now)]
                    (rtf_b, ms_b, cpu_b), (rtf, ms, rtf_cpu) = med
                    diff = float(np.max(np.abs(now[-1][3] - old[-1][3]))) * ARCSEC_PER_RAD
                    print(f'| {name} | {fs:g} | {block} | {args.seconds:g} | {ms_b:.2f} / '
                          f'{ms:.2f} | {rtf_b:.2f} / {rtf:.2f} | {cpu_b:.2f} / {rtf_cpu:.2f} '
                          f'| {rtf / rtf_b:.2f}x | {diff:.1e} |')
                if fs == rates[0]:
                    worst = min(worst, rtf)
    print(f'\nworst real-time factor at {rates[0]:g} Hz: {worst:.2f} '
          f'({"ok" if worst >= 1 else "TOO SLOW"})')
    return 0 if worst >= 1 else 1


if __name__ == '__main__':
    raise SystemExit(main())
