"""Real-time factor of the Wang 2020 2K-V DTE (sim.wang2020, Eq. 19) at 10 kHz.

Run: ``.venv/bin/python benchmarks/bench_wang2020_dte.py [--runs 5] [--all]
[--baseline REV]``. Acceptance case (issue #23): one output revolution (15.8 s at 300 rpm
input) sampled at 10 kHz (158,000 samples), constant 30 N m, in one call: >= 50x real time.
Cases: constant 30 N m in one call and in 1000-sample blocks (the way the bench calls it),
300 N m, and a 30 N m sinusoidal load at the crank frequency (Fig. 7a: load reversals, impacts
across the backlash); ``--all`` adds the sinusoidal load at the mesh frequency (Fig. 7b,
rattling at every reversal). The cases run with the 10 % mesh-stiffness ripple the preset had
before issue #18 (the harder case: Picard passes), and the 30 N m case also with the preset as
it is (no ripple).

With ``--baseline REV`` (e.g. ``main``) the module as of that git revision runs side by side
(interleaved, median of ``--runs``), and the table shows both real-time factors, their ratio
and the largest difference of the two DTE records [arcmin].
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from collections.abc import Callable
from types import ModuleType

import numpy as np

import sim.wang2020 as current
from sim.presets import load_preset
from sim.units import ARCMIN_PER_RAD

FS_HZ = 10_000.0
RIPPLE = ['mesh.stiffness_harmonic_ratio=0.1']


def _inputs(params: object, load_fn: Callable[[np.ndarray], np.ndarray]) -> tuple:
    f_in = params.input_speed_rpm / 60.0  # type: ignore[attr-defined]
    n = round(params.kinematics.output_period_s(f_in) * FS_HZ)  # type: ignore[attr-defined]
    t = np.arange(n) / FS_HZ
    omega = 2.0 * math.pi * f_in
    return t, omega * t, np.full(n, omega), load_fn(t)


def _run(module: ModuleType, overrides: list[str], load_fn: Callable, block: int,
         ) -> tuple[float, np.ndarray, int]:
    """One run: wall time [s], the DTE record [rad] and the contact changes."""
    params = module.Wang2kvParams.from_preset(load_preset('wang2020-2kv', overrides))
    t, th, om, load = _inputs(params, load_fn)
    dyn = module.Wang2kvDynamics(params)
    t0 = time.perf_counter()
    if block <= 0:
        te = dyn.te_rad(t, th, om, load)
    else:
        te = np.concatenate([dyn.te_rad(t[s:s + block], th[s:s + block], om[s:s + block],
                                        load[s:s + block]) for s in range(0, t.size, block)])
    return time.perf_counter() - t0, te, dyn.state.switches


def main() -> None:
    """Print the markdown table."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--runs', type=int, default=5, help='runs per case (median reported)')
    ap.add_argument('--all', action='store_true', help='also the mesh-frequency load case')
    ap.add_argument('--baseline', default=None, metavar='REV',
                    help='git revision whose sim/wang2020.py runs side by side')
    args = ap.parse_args()
    base = None
    if args.baseline:
        from _baseline import load_at
        base = load_at(args.baseline, 'sim/wang2020.py', 'sim.wang2020')
    params = current.Wang2kvParams.from_preset(load_preset('wang2020-2kv'))
    freqs = params.kinematics.frequencies(params.input_speed_rpm / 60.0)
    fw, fm = freqs['crank_hz'], freqs['mesh_stage2_hz']
    cases = [
        ('30 N m constant, one call', RIPPLE, lambda t: np.full(t.size, 30.0), 0),
        ('30 N m constant, 1000-sample blocks', RIPPLE, lambda t: np.full(t.size, 30.0), 1000),
        ('300 N m constant, one call', RIPPLE, lambda t: np.full(t.size, 300.0), 0),
        ('30 N m sin at f_w (Fig. 7a), one call', RIPPLE,
         lambda t: 30.0 * np.sin(2 * math.pi * fw * t), 0),
        ('30 N m constant, one call, preset (no ripple)', [],
         lambda t: np.full(t.size, 30.0), 0),
    ]
    if args.all:
        cases.append(('30 N m sin at 52 f_w (Fig. 7b), one call', RIPPLE,
                      lambda t: 30.0 * np.sin(2 * math.pi * fm * t), 0))
    period_s = params.kinematics.output_period_s(params.input_speed_rpm / 60.0)
    print(f'# Wang 2020 DTE, 1 output rev = {period_s:.1f} s at {FS_HZ:.0f} Hz '
          f'({round(period_s * FS_HZ)} samples); {platform.processor() or platform.machine()}, '
          f'{os.cpu_count()} CPUs, load avg {os.getloadavg()[0]:.1f}, median of {args.runs}'
          + (f', baseline {args.baseline}' if base else ''))
    if base:
        print('| case | wall s (baseline / now) | real-time factor (baseline / now) | speed-up '
              '| contact changes (baseline / now) | max difference [arcmin] |')
        print('|---|---|---|---|---|---|')
    else:
        print('| case | wall s | real-time factor | contact changes | >= 50x |')
        print('|---|---|---|---|---|')
    for name, over, fn, block in cases:
        walls, walls_b = [], []
        for _ in range(args.runs):                   # interleaved: same machine state
            wall, te, sw = _run(current, over, fn, block)
            walls.append(wall)
            if base:
                wall_b, te_b, sw_b = _run(base, over, fn, block)
                walls_b.append(wall_b)
        wall = float(np.median(walls))
        rtf = period_s / wall
        if base:
            wall_b = float(np.median(walls_b))
            diff = float(np.max(np.abs(te - te_b))) * ARCMIN_PER_RAD
            print(f'| {name} | {wall_b:.3f} / {wall:.3f} | {period_s / wall_b:.1f} / {rtf:.1f} '
                  f'| {wall_b / wall:.2f}x | {sw_b} / {sw} | {diff:.2e} |')
        else:
            print(f'| {name} | {wall:.3f} | {rtf:.1f} | {sw} | {"yes" if rtf >= 50 else "no"} |')


if __name__ == '__main__':
    main()
