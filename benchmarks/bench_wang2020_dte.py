"""Real-time factor of the Wang 2020 2K-V DTE (sim.wang2020, Eq. 19) at 10 kHz.

Run: ``.venv/bin/python benchmarks/bench_wang2020_dte.py [--runs 5] [--all]``.
Acceptance case: one output revolution (15.8 s at 300 rpm input) sampled at 10 kHz
(158,000 samples) must be computed at least 10x faster than real time (< 1.6 s).
Cases: constant 30 N m (the preset's drive) in one call and in 1000-sample blocks (the
way the bench calls it), 300 N m, and a 30 N m sinusoidal load at the crank frequency
(Fig. 7a: load reversals, impacts across the backlash). The sinusoidal load at the mesh
frequency (Fig. 7b, rattling at every reversal) is timed with ``--all``. Prints the median
of ``--runs`` runs as markdown table rows; real-time factor = simulated s / wall s.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from collections.abc import Callable

import numpy as np

from sim.presets import load_preset
from sim.wang2020 import Wang2kvDynamics, Wang2kvParams

FS_HZ = 10_000.0


def _case(params: Wang2kvParams, load_fn: Callable[[np.ndarray], np.ndarray], block: int,
          runs: int) -> tuple[float, int]:
    """Median wall time [s] over ``runs`` runs of one output revolution, and switches."""
    f_in = params.input_speed_rpm / 60.0
    n = round(params.kinematics.output_period_s(f_in) * FS_HZ)
    t = np.arange(n) / FS_HZ
    omega = 2.0 * math.pi * f_in
    theta = omega * t
    om = np.full(n, omega)
    load = load_fn(t)
    walls = []
    switches = 0
    for _ in range(runs):
        dyn = Wang2kvDynamics(params)
        t0 = time.perf_counter()
        if block <= 0:
            dyn.te_rad(t, theta, om, load)
        else:
            for s in range(0, n, block):
                sl = slice(s, s + block)
                dyn.te_rad(t[sl], theta[sl], om[sl], load[sl])
        walls.append(time.perf_counter() - t0)
        switches = dyn.state.switches
    return float(np.median(walls)), switches


def main() -> None:
    """Print the markdown table."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--runs', type=int, default=5, help='runs per case (median reported)')
    ap.add_argument('--all', action='store_true', help='also the mesh-frequency load case')
    args = ap.parse_args()
    params = Wang2kvParams.from_preset(load_preset('wang2020-2kv'))
    freqs = params.kinematics.frequencies(params.input_speed_rpm / 60.0)
    fw, fm = freqs['crank_hz'], freqs['mesh_stage2_hz']
    cases = [
        ('30 N m constant, one call', lambda t: np.full(t.size, 30.0), 0),
        ('30 N m constant, 1000-sample blocks', lambda t: np.full(t.size, 30.0), 1000),
        ('300 N m constant, one call', lambda t: np.full(t.size, 300.0), 0),
        ('30 N m sin at f_w (Fig. 7a), one call',
         lambda t: 30.0 * np.sin(2 * math.pi * fw * t), 0),
    ]
    if args.all:
        cases.append(('30 N m sin at 52 f_w (Fig. 7b), one call',
                      lambda t: 30.0 * np.sin(2 * math.pi * fm * t), 0))
    period_s = params.kinematics.output_period_s(params.input_speed_rpm / 60.0)
    print(f'# Wang 2020 DTE, 1 output rev = {period_s:.1f} s at {FS_HZ:.0f} Hz '
          f'({round(period_s * FS_HZ)} samples); {platform.processor() or platform.machine()}, '
          f'{os.cpu_count()} CPUs, load avg {os.getloadavg()[0]:.1f}, median of {args.runs}')
    print('| case | wall s | real-time factor | contact changes | >= 10x |')
    print('|---|---|---|---|---|')
    for name, fn, block in cases:
        wall, sw = _case(params, fn, block, args.runs)
        rtf = period_s / wall
        print(f'| {name} | {wall:.3f} | {rtf:.1f} | {sw} | {"yes" if rtf >= 10 else "no"} |')


if __name__ == '__main__':
    main()
