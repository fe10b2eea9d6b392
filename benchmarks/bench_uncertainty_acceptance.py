"""Coverage of the hysteresis budgets on the path ``rv-te test`` takes (issue 35).

``bench_uncertainty.py`` checks the hysteresis budgets on the dwell points of one
simulated load cycle read by :func:`~rv_te_bench.core.hysteresis.hysteresis_metrics`.
An acceptance test reads its record differently: the step runner
(:class:`~rv_te_bench.acceptance.StepRunner`) builds the plan's bench program (preload,
equal torque steps, the +-3 % and rigidity points), the record's held torques are found by
time and stability, every cycle's metrics are averaged
(:func:`~rv_te_bench.core.hysteresis_measured.measured_hysteresis`) and the budgets are taken
on the dwell points of the first cycle
(:func:`~rv_te_bench.acceptance._uncertainty.hysteresis_point_budgets`). This script runs
that path end to end on ``--units`` simulated units (rv-80e-101, free play drawn in
0..4e-4 rad, the output at a random position) on benches whose RON 886 graduation and
interpolation phases, DAQ skew and torque-sensor zero and gain are drawn from the stated
distributions, and counts how often the true value (the same runner on the simulator's
true angles and exact torque) lies in [value - U_below, value + U_above], per metric.

Run: ``.venv/bin/python benchmarks/bench_uncertainty_acceptance.py --units 1000``
(about 10 minutes on a busy 2-core VM); the table is kept in benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_uncertainty import ENCODER, sim_spec

from rv_te_bench.acceptance import StepRunner, parse_plan
from rv_te_bench.core.bench_uncertainty import BenchUncertainty
from sim.program import DriveSegment, ProgramSimulator, program_from_plain

PRESET = 'rv-80e-101'
RATED_NM = 784.0
STEP = {'name': 'hysteresis', 'kind': 'hysteresis', 'rated_torque_nm': RATED_NM,
        'method': 'torque_steps', 'step_fraction': 0.1, 'dwell_s': 0.2,
        'lost_motion_fraction': 0.03, 'rigidity': {'K': [0.5, 1.0]}, 'preload': True,
        'positions': 1}


def run_step(sim: ProgramSimulator, position_s: float, bench: BenchUncertainty) -> dict:
    """The hysteresis step on ``sim`` after turning its output for ``position_s``; metric
    name -> (value, U below, U above) in SI."""
    sim.load((DriveSegment(speed_rpm=300.0, duration_s=position_s),))
    while sim.running:
        sim.next_block()
    plan = parse_plan({'plan': 'coverage', 'steps': [STEP]})
    runner = StepRunner(plan.steps[0], sim.info, uncertainty=bench)
    sim.load(program_from_plain(runner.program()))
    runner.expect(sim.segment_blocks)
    while sim.running:
        b, seg = sim.next_block()
        runner.feed(seg, b.theta_in_rad, b.theta_out_rad, b.torque_out_nm)
    measured, _ = runner.result()
    out = {}
    for m in measured:
        lo = m.u_below if math.isfinite(m.u_below) else m.u95
        hi = m.u_above if math.isfinite(m.u_above) else m.u95
        out[m.name] = (m.value, lo, hi, m.u95)
    return out


def one_unit(rng: np.random.Generator, bench: BenchUncertainty) -> tuple[dict, dict]:
    clearance = float(rng.uniform(0.0, 4e-4))
    kw = {'preset': PRESET, 'overrides': (f'torsion.clearance_rad={clearance:.6g}',),
          'sample_rate_hz': 1000.0, 'block_size': 100, 'te_mode': 'geometric'}
    zero = bench.torque_zero_for(RATED_NM)
    sim = ProgramSimulator(**kw, encoder_in=sim_spec(bench, 'in', rng),
                           encoder_out=sim_spec(bench, 'out', rng),
                           seed=int(rng.integers(2**31)),
                           torque_zero_nm=float(rng.uniform(-zero, zero)),
                           torque_gain_error=float(rng.uniform(-bench.torque_gain_rel,
                                                               bench.torque_gain_rel)))
    pos_s = float(rng.uniform(0.05, 1.0)) * sim.gear_ratio * 60.0 / 300.0
    meas = run_step(sim, pos_s, bench)
    ideal = ProgramSimulator(**kw, encoder_in='ideal', encoder_out='ideal')
    true = run_step(ideal, pos_s, bench)
    return meas, {k: v[0] for k, v in true.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--units', type=int, default=1000, help='simulated units')
    ap.add_argument('--seed', type=int, default=3535)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    bench = BenchUncertainty.defaults(ENCODER, ENCODER)
    t0 = time.monotonic()
    hits: dict[str, list[bool]] = {}
    ratio: dict[str, list[float]] = {}
    for u in range(args.units):
        meas, true = one_unit(rng, bench)
        for name, (y, lo, hi, u95) in meas.items():
            if not (math.isfinite(y) and math.isfinite(u95)):
                hits.setdefault(name, []).append(False)
                continue
            t = true[name]
            hits.setdefault(name, []).append(y - lo <= t <= y + hi)
            ratio.setdefault(name, []).append(abs(t - y) / u95 if u95 > 0 else math.inf)
        if (u + 1) % 100 == 0:
            print(f'  {u + 1} units, {time.monotonic() - t0:.0f} s', file=sys.stderr)
    print(f'## Coverage on the acceptance path over {args.units} simulated units\n')
    print('| result | covered | |y - true| / U: median | 95th percentile |')
    print('|---|---:|---:|---:|')
    for name, hs in hits.items():
        rr = np.array(ratio.get(name, [math.inf]))
        print(f'| {name} | {100 * np.mean(hs):.1f} % | {np.median(rr):.2f} | '
              f'{np.quantile(rr, 0.95):.2f} |')
    print(f'\n{time.monotonic() - t0:.0f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
