"""Issue 34: hysteresis metrics of measured-looking records against the closed-form truth.

The records of tests/core/hysteresis_records.py (RV-20E class unit, 0.4 N m torque noise,
RON 886 on the output, loader ramps and ripple; torque steps with a preload and three
cycles, constant speed with two) read by the suite's reading (dwells by time and stability,
local fits against time, cycles averaged) and by the reading before issue 34 (runs of
exactly equal torque, first crossing; on one clean cycle, as the live runner fed it).
Prints the largest relative error over the seeds, per metric (docs/ACCEPTANCE.md).

    python scripts/hysteresis_reading_accuracy.py [--seeds 10]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rv_te_bench.core.hysteresis import (
    HysteresisConfig,
    RigidityRegion,
    dwell_points,
    hysteresis_metrics,
)
from rv_te_bench.core.hysteresis_measured import (
    HysteresisReading,
    measured_hysteresis,
)
from rv_te_bench.errors import TeInputError
from tests.core.hysteresis_records import (
    Unit,
    constant_speed_record,
    step_torques,
    torque_step_record,
)

UNIT = Unit()
REGIONS = {'K': (0.5, 1.0), 'K1': (0.1, 0.35)}
CONFIG = HysteresisConfig(rated_torque_nm=UNIT.rated_nm, rigidity_regions=tuple(
    RigidityRegion(k, *v) for k, v in REGIONS.items()))
TRUTH = {**UNIT.truth(regions=REGIONS), 'hysteresis_loss_j': UNIT.loop_area_j()}


def old(t: np.ndarray, a: np.ndarray) -> dict[str, float]:
    tp, ap, _ = dwell_points(t, a)
    m = hysteresis_metrics(tp, ap, CONFIG)
    return {'backlash_rad': m.backlash_rad, 'lost_motion_rad': m.lost_motion_rad,
            'hysteresis_loss_j': m.hysteresis_loss_j,
            **{f'torsional_rigidity_{k}_nm_per_rad': m.rigidity_min_nm_per_rad(k)
               for k in REGIONS}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seeds', type=int, default=10)
    n = ap.parse_args().seeds
    rows: dict[str, dict[str, list[float]]] = {}

    def add(case: str, values: dict[str, float] | None) -> None:
        d = rows.setdefault(case, {k: [] for k in TRUTH})
        for k in TRUTH:
            d[k].append(math.inf if values is None else values[k] / TRUTH[k] - 1.0)

    steps = HysteresisReading('torque_steps', min_dwell_samples=150,
                              resolution_nm=0.25 * 0.03 * UNIT.rated_nm)
    for seed in range(n):
        rng = np.random.default_rng(seed)
        r = torque_step_record(UNIT, step_torques(UNIT, regions=(0.1, 0.35, 0.5, 1.0),
                                                  cycles=3), rng)
        add('torque steps, 3 cycles: issue 34 reading',
            measured_hysteresis(r.time_s, r.torque_nm, r.angle_rad, CONFIG, steps).values)
        try:
            add('torque steps, 3 cycles: reading before', old(r.torque_nm, r.angle_rad))
        except TeInputError:
            add('torque steps, 3 cycles: reading before', None)
        r1 = torque_step_record(UNIT, step_torques(UNIT, regions=(0.1, 0.35, 0.5, 1.0),
                                                   preload=False), rng)
        add('torque steps, 1 cycle: reading before', old(r1.torque_nm, r1.angle_rad))
        c = constant_speed_record(UNIT, rng, cycles=2)
        add('constant speed, 2 cycles: issue 34 reading',
            measured_hysteresis(c.time_s, c.torque_nm, c.angle_rad, CONFIG,
                                HysteresisReading('constant_speed')).values)
        c1 = constant_speed_record(UNIT, rng, cycles=1, preload=False)
        add('constant speed, 1 cycle: reading before', old(c1.torque_nm, c1.angle_rad))
    names = {'backlash_rad': 'backlash', 'lost_motion_rad': 'lost motion',
             'torsional_rigidity_K_nm_per_rad': 'K (50-100 %)',
             'torsional_rigidity_K1_nm_per_rad': 'K1 (10-35 %)',
             'hysteresis_loss_j': 'loss'}
    print(f'largest |error| over {n} seeds [%] (inf: the record could not be read)')
    print('| record, reading | ' + ' | '.join(names[k] for k in TRUTH) + ' |')
    print('|---|' + '---|' * len(TRUTH))
    for case, d in rows.items():
        cells = [f'{100 * max(abs(x) for x in d[k]):.2f}' for k in TRUTH]
        print(f'| {case} | ' + ' | '.join(cells) + ' |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
