"""The budgets of an acceptance test's metrics (issue 35): TE p-p per direction and the
hysteresis metrics, from the data the step runner holds (the whole record of each segment).

* TE p-p of a direction (the largest p-p of one whole output revolution):
  :func:`~rv_te_bench.core.te_uncertainty.te_pp_budget` at the extremes of that
  revolution (near-equal peaks within reach of the encoder errors as candidates), type A
  from the spread of the revolutions' p-p;
* hysteresis metrics of the measuring position that gives the unit's value:
  :func:`~rv_te_bench.core.hysteresis_uncertainty.hysteresis_budgets` on the dwell points
  of its first load cycle (equal-torque-step tests; a constant-speed test reads the
  samples by local fits and has no budget here: its metrics are reported without U).

The bench's error model is the runner's (:class:`~rv_te_bench.core.bench_uncertainty.
BenchUncertainty`: the data-sheet defaults of the BenchInfo encoder models, or what the
caller built from the bench description).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.hysteresis_measured import split_cycles
from rv_te_bench.core.hysteresis_uncertainty import hysteresis_budgets
from rv_te_bench.core.te import output_phase_and_te
from rv_te_bench.core.te_uncertainty import extreme_candidates, extreme_reach, te_pp_budget

if TYPE_CHECKING:
    from rv_te_bench.core.bench_uncertainty import BenchUncertainty
    from rv_te_bench.core.directional import DirectionTe
    from rv_te_bench.core.hysteresis import HysteresisConfig
    from rv_te_bench.core.uncertainty import Budget

__all__ = ['hysteresis_point_budgets', 'te_direction_budget']

_TWO_PI = 2.0 * math.pi


def te_direction_budget(name: str, th_in: np.ndarray, th_out: np.ndarray, d: DirectionTe, *,
                        gear_ratio: float, bench: BenchUncertainty) -> Budget | None:
    """The budget of a direction's TE p-p (the largest of one revolution of ``d``)."""
    if not d.pp_per_rev_rad:
        return None
    phi, te = output_phase_and_te(th_in, th_out, gear_ratio=gear_ratio, check=False)
    travel = np.abs(phi - phi[0])
    j = int(np.argmax(d.pp_per_rev_rad))
    m = (travel >= j * _TWO_PI) & (travel < (j + 1) * _TWO_PI)
    if np.count_nonzero(m) < 8:
        return None
    found = extreme_candidates(phi[m], te[m], extreme_reach(bench, gear_ratio))
    if found is None:
        return None
    (p_max, p_min), others = found
    spectrum = d.spectrum
    dominant = None
    if spectrum is not None and spectrum.lines:
        big = max(spectrum.lines, key=lambda ln: ln.amplitude_rad)
        dominant = (big.amplitude_rad, big.output_order)
    pps = np.asarray(d.pp_per_rev_rad, dtype=np.float64)
    return te_pp_budget(name, float(np.max(pps)), phi_max_rad=p_max, phi_min_rad=p_min,
                        gear_ratio=gear_ratio, bench=bench,
                        per_revolution_rad=pps if pps.size >= 2 else None,
                        samples_per_rev=float(np.count_nonzero(m)), dominant=dominant,
                        other_extremes=others)


def hysteresis_point_budgets(points: tuple[np.ndarray, np.ndarray], theta_out0_rad: float,
                             config: HysteresisConfig, *, bench: BenchUncertainty,
                             ) -> dict[str, Budget]:
    """The budgets of one measuring position's hysteresis metrics, from the dwell points
    the measurement read (:class:`~rv_te_bench.core.hysteresis_measured.MeasuredHysteresis`
    ``points``), on their first complete load cycle: the encoder's errors sit at the same
    positions in every cycle (averaging cycles does not reduce them); the noise is taken as
    that of single samples (the dwell lengths are not kept: conservative).

    Returns:
        Metric name -> budget; empty when no complete cycle is found.
    """
    t, a = (np.asarray(x, dtype=np.float64) for x in points)
    bounds = split_cycles(t, config.rated_torque_nm)
    if not bounds:
        return {}
    c = bounds[0]
    # hysteresis_metrics reads one cycle 0 -> +T_R -> 0 -> -T_R -> 0: the loading branch
    # from its last point at or below zero torque (a preload leaves it at -T_R)
    up = np.flatnonzero(t[c.up_start:c.peak + 1] <= 0.0)
    start = c.up_start + (int(up[-1]) if up.size else 0)
    sl = slice(start, c.back_end + 1)
    return hysteresis_budgets(t[sl], a[sl], config, bench=bench, theta_out_rad=theta_out0_rad)
