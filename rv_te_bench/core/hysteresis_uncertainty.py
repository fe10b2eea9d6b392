"""Uncertainty budgets of the hysteresis metrics: lost motion, backlash, loss, rigidity.

The metrics (:func:`~rv_te_bench.core.hysteresis.hysteresis_metrics`) are functions of the
points of one load cycle (dwell means of a torque-step test, or the samples of a
constant-speed one). Their inputs:

* **output encoder, harmonic errors** (graduation orders, mounting eccentricity, the
  position error within one signal period): an error g sin(k theta + rho) of unknown phase
  added to every point's angle. The sensitivity is numeric: the metric recomputed with
  the error function added in sine and in cosine quadrature, |change| per unit amplitude
  (an arcsine input of amplitude g). The input shaft is locked: its encoder's error is a
  constant and cancels.
* **second order of a fast harmonic.** The points' angles are themselves read with the
  error, so the error function is evaluated at positions off by e(theta): to second order
  g sin(k (theta_m - e) + rho) = g s - (k g^2 / 2) sin(2 (k theta_m + rho)). For the
  position error within one signal period of a RON 886 (k = 36,000, g = 0.4") k g / 2 is
  3.5 % of the first-order term, enough to move an arcsine-dominated budget's coverage by
  a per cent or two. The two terms share the phase rho (at the phase where the first is
  largest the second has one fixed value: they are not independent), so the input is the
  harmonic with the distribution of first + second over a uniform rho, tabulated on a
  grid of rho (``'tabulated'``: its coverage factor and Monte Carlo draws use that
  distribution itself); its sensitivity is the largest change per unit amplitude.
* **noise** of the points (type A: the pooled within-dwell standard deviation, its dof;
  else the data sheet's) and **quantisation** (+-q/2 per point, not reduced by averaging
  a dwell at one position), through the numeric weight of each point.
* **torque sensor** zero and gain: a point held at the reading t sits at the true torque
  (t - z) / (1 + e), its angle off by phi'(t) (z + e t), with phi' the local compliance
  of its branch (:func:`local_compliance`).
* **test resolution** of a constant-speed test (angle between samples).

The torsional rigidity is reported as the smaller of the two sides (positive and negative
torque). A minimum of two uncertain values is not a smooth function at the crossing, and
it reads low: E[min(Y+, Y-)] falls short of the smaller true value by up to
sigma_d / sqrt(2 pi) (Clark 1961, sigma_d the standard uncertainty of the difference),
at equal sides. Its budget (:func:`min_budget`) is therefore taken over both sides: every
input at the larger of its two sides' sensitivities, and the low-side bias bound (Clark's
bias at the smallest separation of the sides the data support at about 95 %), not
corrected and added to U above the value.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.hysteresis import PointCycle, hysteresis_metrics
from rv_te_bench.core.uncertainty import Budget, UncertaintyInput, combine, type_b

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    import numpy.typing as npt

    from rv_te_bench.core.bench_uncertainty import BenchUncertainty
    from rv_te_bench.core.hysteresis import HysteresisConfig

__all__ = ['hysteresis_budgets', 'local_compliance', 'min_budget', 'second_order_amplitude']

#: A harmonic's second-order term enters when k g / 2 exceeds this part of its amplitude.
_SECOND_ORDER_MIN = 1e-3
#: Phases on which a harmonic's first- and second-order terms are evaluated together.
_PHASE_GRID = 3600
_SIDES = ('pos', 'neg')


def second_order_amplitude(order: int, amplitude_rad: float) -> float:
    """Amplitude of the second-order term of a harmonic read at shifted positions,
    k g^2 / 2 [rad] (see the module docstring).

    Examples:
        >>> a = 0.4 / 206264.806 * 1.0                   # 0.4" at 36,000 periods per rev
        >>> round(second_order_amplitude(36_000, a) / a, 4)
        0.0349
    """
    return 0.5 * order * amplitude_rad * amplitude_rad


def _names(config: HysteresisConfig) -> list[str]:
    out = ['lost_motion_rad', 'backlash_rad', 'hysteresis_loss_j']
    for r in config.rigidity_regions:
        out += [f'torsional_rigidity_{r.name}_{s}' for s in _SIDES]
    return out


def _metrics(cyc: PointCycle, a: np.ndarray) -> dict[str, float]:
    """The metrics of the cycle's points at angles ``a`` (those of hysteresis_metrics)."""
    r = cyc.cycle(cyc.readings(a))
    return _named(r.backlash_rad, r.lost_motion_rad, cyc.loss(a), r.rigidity_nm_per_rad)


def _named(backlash_rad: float, lost_motion_rad: float, loss_j: float,
           rigidity: dict[str, tuple[float, float]]) -> dict[str, float]:
    out = {'lost_motion_rad': lost_motion_rad, 'backlash_rad': backlash_rad,
           'hysteresis_loss_j': loss_j}
    for name, (pos, neg) in rigidity.items():
        out[f'torsional_rigidity_{name}_pos'] = pos
        out[f'torsional_rigidity_{name}_neg'] = neg
    return out


def _point_weights(cyc: PointCycle, a: np.ndarray, base: dict[str, float],
                   step: float) -> dict[str, np.ndarray]:
    """Each metric's change per unit change of each point's angle: the point moved by
    ``step`` alone and the metrics taken again (:func:`_delta`), where a point changes
    only the readings it enters (one or two points each) and the loop's area (every
    point of the loop): a point in neither changes nothing."""
    base_read = cyc.readings(a)
    entered: dict[int, list[tuple[int, float]]] = {}
    for key in base_read:
        for i in cyc.points(key):
            entered.setdefault(i, []).append(key)
    in_loop = set(cyc.loop_index.tolist())
    weights = {n: np.zeros(a.size) for n in base}
    for j in sorted(entered.keys() | in_loop):
        bump = np.zeros(a.size)
        bump[j] = step
        moved = a + bump
        new = dict(base)
        if j in entered:
            read = dict(base_read)
            for key in entered[j]:
                read[key] = cyc.read(key, moved)
            r = cyc.cycle(read)
            new.update(_named(r.backlash_rad, r.lost_motion_rad, new['hysteresis_loss_j'],
                              r.rigidity_nm_per_rad))
        if j in in_loop:
            new['hysteresis_loss_j'] = cyc.loss(moved)
        for n, v in new.items():
            weights[n][j] = _finite((v - base[n]) / step)
    return weights


def _finite(x: float) -> float:
    return float(x) if math.isfinite(x) else 0.0


def _delta(f: Callable[[np.ndarray, np.ndarray], dict[str, float]], base: dict[str, float],
           t: np.ndarray, a: np.ndarray, step: float) -> dict[str, float]:
    new = f(t, a)
    return {n: _finite((new[n] - base[n]) / step) for n in base}


def hysteresis_budgets(torque_nm: npt.ArrayLike, angle_rad: npt.ArrayLike,
                       config: HysteresisConfig, *, bench: BenchUncertainty,
                       theta_out_rad: float, counts: npt.ArrayLike | None = None,
                       dwell_sigma_rad: tuple[float, int] | None = None,
                       sample_step_rad: float = 0.0) -> dict[str, Budget]:
    """Budgets of lost motion, backlash, hysteresis loss and each rigidity region.

    Args:
        torque_nm, angle_rad: The points the metrics were computed from (dwell means of a
            torque-step test, or the samples of a constant-speed one).
        config: As for :func:`~rv_te_bench.core.hysteresis.hysteresis_metrics`.
        bench: The bench's type B inputs.
        theta_out_rad: Output encoder angle at the first point [rad] (only differences
            between the points matter).
        counts: Samples averaged in each point (None: one each).
        dwell_sigma_rad: (pooled within-dwell standard deviation [rad], its dof): type A
            noise of the points; None: the data sheet's noise.
        sample_step_rad: Angle between samples of a constant-speed test (test resolution).

    Returns:
        ``lost_motion_rad``, ``backlash_rad``, ``hysteresis_loss_j`` and
        ``torsional_rigidity_<region>_nm_per_rad`` (the smaller side, as reported, with
        its budget over both sides: :func:`min_budget`).
    """
    t = np.asarray(torque_nm, dtype=np.float64)
    a = np.asarray(angle_rad, dtype=np.float64)
    n_pts = np.ones(t.size) if counts is None else np.asarray(counts, dtype=np.float64)

    m = hysteresis_metrics(t, a, config)
    base = _named(m.backlash_rad, m.lost_motion_rad, m.hysteresis_loss_j,
                  m.rigidity_nm_per_rad)
    cyc = PointCycle(t, config)

    def metrics(_tt: np.ndarray, aa: np.ndarray) -> dict[str, float]:
        return _metrics(cyc, aa)

    names = _names(config)
    inputs: dict[str, list[UncertaintyInput | None]] = {n: [] for n in names}
    step = 1e-9
    # output encoder error functions: the metric change per unit amplitude, sin and cos
    th = theta_out_rad + (a - a[0])
    enc = bench.encoder_out
    rho = np.linspace(0.0, 2.0 * math.pi, _PHASE_GRID, endpoint=False)
    for cname, order, g in enc.components():
        ds = _delta(metrics, base, t, a + step * np.sin(order * th), step)
        dc = _delta(metrics, base, t, a + step * np.cos(order * th), step)
        g2 = second_order_amplitude(order, g)
        second = g2 > _SECOND_ORDER_MIN * g
        if second:
            ds2 = _delta(metrics, base, t, a + step * np.sin(2 * order * th), step)
            dc2 = _delta(metrics, base, t, a + step * np.cos(2 * order * th), step)
        for n in names:
            f = None
            if second:
                # one phase rho for both orders: the metric's change on a grid of rho
                f = (g * (ds[n] * np.cos(rho) + dc[n] * np.sin(rho))
                     - g2 * (ds2[n] * np.cos(2 * rho) + dc2[n] * np.sin(2 * rho)))
            if f is None or not float(np.max(np.abs(f))) > 0:
                inputs[n].append(type_b(
                    f'output encoder: {cname}', sensitivity=math.hypot(ds[n], dc[n]),
                    distribution='arcsine', half_width=g, source=enc.source,
                    note='numeric: metric change per unit error, sine and cosine quadrature'))
                continue
            peak = float(np.max(np.abs(f)))
            inputs[n].append(type_b(
                f'output encoder: {cname}', sensitivity=peak / g, distribution='tabulated',
                half_width=g, shape=f / peak, source=enc.source,
                note=(f'numeric, to second order (the points read at positions the error '
                      f'moved: k g^2 / 2 = {g2:.3g} rad at order 2 k, the same phase): the '
                      'distribution of the change over the phase, tabulated; sensitivity: '
                      'its largest value per unit amplitude')))
    # per-point weights (numeric): the metric change per unit angle change of each point
    weights = _point_weights(cyc, a, base, step)
    comp = local_compliance(t, a)
    zero = bench.torque_zero_for(config.rated_torque_nm)
    for n in names:
        cw = weights[n]
        inputs[n] += _point_inputs(cw, n_pts, enc.noise_sigma_rad, enc.resolution_rad,
                                   enc.source, dwell_sigma_rad, sample_step_rad)
        # torque sensor: a point held at the reading t_j sits at the true torque
        # (t_j - z) / (1 + e): the unit's angle at t_j is phi_j - phi'_j (z + e t_j)
        inputs[n].append(type_b(
            'torque sensor: zero and linearity', sensitivity=_finite(float(np.sum(cw * comp))),
            distribution='rectangular', half_width=zero, unit='N m', source=bench.source,
            note='numeric: sum of point weights x local compliance'))
        inputs[n].append(type_b(
            'torque sensor: sensitivity (gain)',
            sensitivity=_finite(float(np.sum(cw * comp * t))), distribution='rectangular',
            half_width=bench.torque_gain_rel, unit='1', source=bench.source,
            note='numeric: sum of point weights x local compliance x torque'))
    notes = ['input shaft locked: the input encoder error is constant and cancels',
             *_unknown_notes(bench)]
    out = {}
    for n in ('lost_motion_rad', 'backlash_rad', 'hysteresis_loss_j'):
        out[n] = combine(n, base[n], inputs[n], unit='J' if n.endswith('_j') else 'rad',
                         notes=notes)
    for r in config.rigidity_regions:
        name = f'torsional_rigidity_{r.name}_nm_per_rad'
        sides = [combine(f'{name} ({s})', base[f'torsional_rigidity_{r.name}_{s}'],
                         inputs[f'torsional_rigidity_{r.name}_{s}'], unit='N m/rad',
                         notes=notes) for s in _SIDES]
        out[name] = min_budget(name, sides[0], sides[1], notes=notes)
    return out


def _point_inputs(cw: np.ndarray, n_pts: np.ndarray, noise_rad: float, q_rad: float,
                  source: str, dwell_sigma_rad: tuple[float, int] | None,
                  sample_step_rad: float) -> list[UncertaintyInput]:
    """Noise, quantisation and test resolution of the points, through their weights."""
    out = []
    if dwell_sigma_rad is not None and dwell_sigma_rad[1] >= 1:
        s, dof = dwell_sigma_rad
        out.append(UncertaintyInput(
            name='output encoder: noise of the dwell means (pooled within-dwell s)',
            kind='A', u=s, sensitivity=float(np.sqrt(np.sum(cw * cw / n_pts))),
            distribution='t', dof=float(dof), source='this record',
            note='numeric weights of the points, / sqrt(n per dwell)'))
    elif noise_rad > 0:
        out.append(type_b('output encoder: read-head noise',
                          sensitivity=float(np.sqrt(np.sum(cw * cw / n_pts))),
                          distribution='normal', u=noise_rad, source=source))
    if q_rad > 0:
        out.append(type_b('output encoder: quantisation',
                          sensitivity=float(np.sqrt(np.sum(cw * cw))),
                          distribution='rectangular', half_width=q_rad / 2.0, source=source,
                          note='+-q/2 per point, not reduced by averaging'))
    if sample_step_rad > 0:
        out.append(type_b('test resolution: angle between samples',
                          sensitivity=float(np.sqrt(np.sum(cw * cw))),
                          distribution='rectangular', half_width=sample_step_rad / 2.0,
                          source='this record'))
    return out


def _unknown_notes(bench: BenchUncertainty) -> list[str]:
    e = bench.encoder_out
    return [] if e.known else [
        f'output encoder model {e.model!r} is not known: its graduation and interpolation '
        'errors are not in the budget (state them in the bench description)']


def _phi(x: float) -> float:
    return math.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi)


def _cdf(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def min_budget(measurand: str, a: Budget, b: Budget, *, notes: Sequence[str] = (),
               separation_k: float = 2.0) -> Budget:
    """The budget of min(a, b), a result reported as the smaller of two.

    Every input of either side enters at the larger of its two sensitivities (within its
    uncertainty either side may be the smaller). The minimum of two uncertain values reads
    low (Clark 1961): with d the true separation and sigma_d the standard uncertainty of
    the measured difference, E[min] = min - (sigma_d phi(d / sigma_d) - d Phi(-d /
    sigma_d)). The bias is largest (sigma_d / sqrt(2 pi)) at d = 0; it is bounded at the
    smallest separation the data support, max(|a - b| - ``separation_k`` sigma_d, 0), and
    added to U above the value (``bias_low_bound``). sigma_d is taken as
    sqrt(u_c(a)^2 + u_c(b)^2) (the inputs' signs are not kept: the correlation of the two
    sides is not credited).

    Examples:
        Two equal sides, each with one normal input of u = 1: the bias bound is
        sqrt(2) / sqrt(2 pi) = 0.564.

        >>> x = combine('a', 10.0, [type_b('n', sensitivity=1.0, distribution='normal', u=1.0)])
        >>> m = min_budget('m', x, x)
        >>> m.value, round(m.u_c, 3), round(m.bias_low_bound, 3)
        (10.0, 1.0, 0.564)
    """
    if not (math.isfinite(a.value) and math.isfinite(b.value)):
        # one side missing: the reported minimum is NaN (hysteresis_metrics' rule)
        return combine(measurand, math.nan, list(a.inputs if math.isfinite(a.value)
                                                 else b.inputs), unit=a.unit,
                       notes=[*notes, 'one side missing'])
    pick: dict[str, UncertaintyInput] = {}
    for x in (*a.inputs, *b.inputs):
        if x.name not in pick or x.contribution > pick[x.name].contribution:
            pick[x.name] = x
    sd = math.hypot(a.u_c, b.u_c)
    gap = max(abs(a.value - b.value) - separation_k * sd, 0.0)
    bias = sd * _phi(gap / sd) - gap * _cdf(-gap / sd) if sd > 0 else 0.0
    side = 'positive' if a.value <= b.value else 'negative'
    extra = [f'the smaller of two sides ({a.value:.6g} and {b.value:.6g} {a.unit}; reported: '
             f'the {side} torque side); every input at the larger of its two sides\' '
             'sensitivities; the minimum reads low by up to '
             f'{bias:.3g} {a.unit} (Clark 1961), added to U above the value']
    return combine(measurand, min(a.value, b.value), list(pick.values()), unit=a.unit,
                   notes=[*notes, *extra], bias_low_bound=bias, parts=(a, b))


def _quadratic_slope(x: np.ndarray, y: np.ndarray, x0: float) -> float:
    """d/dx at x0 of the parabola through three points (Lagrange form)."""
    (xa, xb, xc), (ya, yb, yc) = x, y
    return float(ya * (2 * x0 - xb - xc) / ((xa - xb) * (xa - xc))
                 + yb * (2 * x0 - xa - xc) / ((xb - xa) * (xb - xc))
                 + yc * (2 * x0 - xa - xb) / ((xc - xa) * (xc - xb)))


def local_compliance(torque_nm: npt.ArrayLike, angle_rad: npt.ArrayLike) -> np.ndarray:
    """d angle / d torque at each point of a load cycle [rad/(N m)].

    A point at a torque t != 0 takes the derivative of the parabola through it and two
    neighbours on its own branch (torque monotone through the three, all of its sign):
    preferably the two towards larger |torque| (the flank, away from the backlash and the
    friction stick after a turning point), else one on each side. A curve that stiffens
    with load is followed (a secant would understate the compliance at low torque). Where
    no such neighbours exist (zero torque, the turning points, the ends), of the secants
    to its two neighbours in time order the one of smaller magnitude (the other may span
    the jump through the backlash).
    """
    t = np.asarray(torque_nm, dtype=np.float64)
    a = np.asarray(angle_rad, dtype=np.float64)
    with np.errstate(divide='ignore', invalid='ignore'):
        sec = np.diff(a) / np.diff(t)
    sec = np.where(np.isfinite(sec), sec, np.inf)
    left: npt.NDArray[np.float64] = np.r_[np.inf, sec]
    right: npt.NDArray[np.float64] = np.r_[sec, np.inf]
    out = np.where(np.abs(left) <= np.abs(right), left, right)
    out = np.where(np.isfinite(out), out, 0.0)
    n = t.size
    for j in range(n):
        s = np.sign(t[j])
        if s == 0:
            continue
        for idx in ((j, j + 1, j + 2), (j, j - 1, j - 2), (j - 1, j, j + 1)):
            if min(idx) < 0 or max(idx) >= n:
                continue
            x = t[list(idx)] * s
            if idx[1] == j:                   # central: monotone through the point
                ok = bool(np.all(x > 0) and (x[0] - x[1]) * (x[1] - x[2]) > 0)
            else:                              # one-sided: away from zero torque
                ok = bool(x[0] > 0 and x[0] < x[1] < x[2])
            if ok:
                d = _quadratic_slope(t[list(idx)], a[list(idx)], float(t[j]))
                if math.isfinite(d):
                    out[j] = d
                break
    return out
