"""The budgets of an acceptance test's metrics (issue 35): TE p-p per direction and the
hysteresis metrics, from the data the step runner holds (the whole record of each segment).

* TE p-p of a direction (the largest p-p of one whole output revolution):
  :func:`~rv_te_bench.core.te_uncertainty.te_pp_budget` at the extremes of that
  revolution (near-equal peaks within reach of the encoder errors as candidates), type A
  from the spread of the revolutions' p-p;
* hysteresis metrics of the measuring position that gives the unit's value:
  :func:`~rv_te_bench.core.hysteresis_uncertainty.hysteresis_budgets` on the dwell points
  of its first load cycle (equal-torque-step tests);
* hysteresis metrics of a constant-speed test (the samples read by local fits against
  time): :func:`constant_speed_budgets`, numeric sensitivities through the same reading
  of the whole record, type A from the spread over its cycles.

The bench's error model is the runner's (:class:`~rv_te_bench.core.bench_uncertainty.
BenchUncertainty`: the data-sheet defaults of the BenchInfo encoder models, or what the
caller built from the bench description).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.hysteresis_measured import split_cycles
from rv_te_bench.core.hysteresis_uncertainty import hysteresis_budgets, min_budget
from rv_te_bench.core.te import output_phase_and_te
from rv_te_bench.core.te_uncertainty import extreme_candidates, extreme_reach, te_pp_budget
from rv_te_bench.core.uncertainty import UncertaintyInput, combine, type_a, type_b
from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    from rv_te_bench.core.bench_uncertainty import BenchUncertainty
    from rv_te_bench.core.directional import DirectionTe
    from rv_te_bench.core.hysteresis import HysteresisConfig
    from rv_te_bench.core.hysteresis_measured import HysteresisReading, MeasuredHysteresis
    from rv_te_bench.core.uncertainty import Budget

__all__ = ['constant_speed_budgets', 'hysteresis_point_budgets', 'te_direction_budget']

_TWO_PI = 2.0 * math.pi
#: Central-difference step of the torque sensor's zero and gain, per half-width of the band
#: (the whole band: a reading by local fits over windows chosen by torque is not smooth on
#: a finer scale, a window gaining or losing a sample).
_SENS_STEP = 1.0


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


def _sides(m: MeasuredHysteresis, config: HysteresisConfig) -> dict[str, float]:
    """The reported values, the rigidity as its two sides (means over the cycles)."""
    out = {n: m.values[n] for n in ('lost_motion_rad', 'backlash_rad', 'hysteresis_loss_j')}
    for r in config.rigidity_regions:
        for j, side in enumerate(('pos', 'neg')):
            out[f'torsional_rigidity_{r.name}_{side}'] = float(np.mean(
                [c.rigidity_nm_per_rad[r.name][j] for c in m.cycles]))
    return out


def _per_cycle(m: MeasuredHysteresis, name: str) -> list[float]:
    if name.startswith('torsional_rigidity_'):
        region, _, side = name[len('torsional_rigidity_'):].rpartition('_')
        return [c.rigidity_nm_per_rad[region][0 if side == 'pos' else 1] for c in m.cycles]
    return [float(getattr(c, name)) for c in m.cycles]


def constant_speed_budgets(time_s: np.ndarray, torque_nm: np.ndarray, angle_rad: np.ndarray,
                           theta_out0_rad: float, config: HysteresisConfig,
                           reading: HysteresisReading, measured: MeasuredHysteresis, *,
                           bench: BenchUncertainty) -> dict[str, Budget]:
    """Budgets of a constant-speed test's metrics (the samples read by local fits).

    Every sensitivity is numeric, through the reading itself (``measured_hysteresis`` of
    the whole record again): each output-encoder harmonic (graduation orders, mounting,
    interpolation) added to the samples' angles in sine and cosine quadrature (arcsine
    input, first order: a fit over many samples averages the fast harmonic's second-order
    term), the torque sensor's zero (+-z) and gain (+-e) applied to the torque channel
    (central differences over the band). A record turned until the torque read +-T_R
    ends there: a perturbed torque channel that no longer reaches T_R is read by the last
    fit, extrapolated, so the rigidity's (its region ends at T_R) sensitivities to the
    zero and gain include that end effect (on the Li 2023 unit dK/de = 1.085 K against
    K for the reading alone; the larger side's is taken: conservative). Type A: the
    spread of each metric over the cycles, of their mean (cycles - 1 dof; with one cycle
    there is none and the budget says so). The rigidity is the smaller side:
    :func:`min_budget` over both.
    """
    from rv_te_bench.core.hysteresis_measured import measured_hysteresis

    t, a = np.asarray(torque_nm, np.float64), np.asarray(angle_rad, np.float64)
    base = _sides(measured, config)

    def again(tq: np.ndarray, ang: np.ndarray) -> dict[str, float]:
        try:
            return _sides(measured_hysteresis(time_s, tq, ang, config, reading), config)
        except TeInputError:
            return dict.fromkeys(base, math.nan)

    def fin(x: float) -> float:
        return float(x) if math.isfinite(x) else 0.0

    inputs: dict[str, list[UncertaintyInput | None]] = {n: [] for n in base}
    enc = bench.encoder_out
    th = theta_out0_rad + (a - a[0])
    step = 1e-9
    for cname, order, g in enc.components():
        ds = again(t, a + step * np.sin(order * th))
        dc = again(t, a + step * np.cos(order * th))
        for n in base:
            c = math.hypot(fin((ds[n] - base[n]) / step), fin((dc[n] - base[n]) / step))
            inputs[n].append(type_b(f'output encoder: {cname}', sensitivity=c,
                                    distribution='arcsine', half_width=g, source=enc.source,
                                    note='numeric, through the local fits (first order)'))
    zero = bench.torque_zero_for(config.rated_torque_nm)
    gain = bench.torque_gain_rel
    for label, hw, unit in (('torque sensor: zero and linearity', zero, 'N m'),
                            ('torque sensor: sensitivity (gain)', gain, '1')):
        if not hw > 0:
            continue
        h = _SENS_STEP * hw
        up, dn = ((again(t + h, a), again(t - h, a)) if unit == 'N m' else
                  (again(t * (1 + h), a), again(t * (1 - h), a)))
        for n in base:
            inputs[n].append(type_b(label, sensitivity=fin((up[n] - dn[n]) / (2 * h)),
                                    distribution='rectangular', half_width=hw, unit=unit,
                                    source=bench.source,
                                    note='numeric: central difference over the class band'))
    for n in base:
        unit = 'N m/rad' if n.startswith('torsional') else ('J' if n.endswith('_j') else 'rad')
        inputs[n].append(type_a('repeatability: spread over the cycles',
                                _per_cycle(measured, n), unit=unit,
                                source=f'{len(measured.cycles)} cycles of this record'))
    notes = ['constant-speed test: the metrics read by local fits of the samples against '
             'time; sensitivities numeric through that reading',
             *([] if len(measured.cycles) > 1 else
               ['one cycle: no type A (noise, friction variation) in this budget; run two or '
                'more cycles'])]
    out: dict[str, Budget] = {}
    for n in ('lost_motion_rad', 'backlash_rad', 'hysteresis_loss_j'):
        out[n] = combine(n, base[n], inputs[n], unit='J' if n.endswith('_j') else 'rad',
                         notes=notes)
    for r in config.rigidity_regions:
        name = f'torsional_rigidity_{r.name}_nm_per_rad'
        sides = [combine(f'{name} ({s})', base[f'torsional_rigidity_{r.name}_{s}'],
                         inputs[f'torsional_rigidity_{r.name}_{s}'], unit='N m/rad',
                         notes=notes) for s in ('pos', 'neg')]
        out[name] = min_budget(name, sides[0], sides[1], notes=notes)
    return out
