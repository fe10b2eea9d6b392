"""Monte Carlo propagation of the TE budgets (GUM Supplement 1): the check of the linearisation.

Each draw takes every input of a budget from its stated distribution and computes the
result again *through the measurement model itself*, not through the sensitivity
coefficients:

* TE p-p: the encoders' long-range harmonic errors are drawn as error *functions* (a new
  phase per harmonic) and removed from the recorded TE sample by sample; the p-p of each
  revolution is taken again (max - min: the non-linear part, the envelope theorem's
  extremes may move); the other inputs (quantisation, type A, skew, temperature,
  sampling) are scalars added with their sensitivity;
* a spectrum line: the drawn error functions' Fourier coefficient at the line's order,
  evaluated on the recorded output angles (theta_out = phi + TE, not phi), is removed
  from the line's phasor, and amplitude |.| and phase arg(.) are taken again;
* hysteresis metrics: the output encoder's error functions are removed from the angles,
  the torque readings corrected for a drawn zero and gain error, noise drawn per point,
  and :func:`~rv_te_bench.core.hysteresis.hysteresis_metrics` run again.

The coverage interval is the probabilistically symmetric 95.45 % interval of the draws
(Supplement 1, 7.7). Its half-width is compared with U = k u_c of the law of propagation;
the one-sided bias bound of a p-p is applied the same way in both (it is a bound, not a
distribution).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.uncertainty import COVERAGE_PROBABILITY, monte_carlo_interval, sample_input

if TYPE_CHECKING:
    import numpy.typing as npt

    from rv_te_bench.core.angle_fold import FoldedTe
    from rv_te_bench.core.bench_uncertainty import BenchUncertainty
    from rv_te_bench.core.hysteresis import HysteresisConfig
    from rv_te_bench.core.identification import Identification
    from rv_te_bench.core.uncertainty import Budget

__all__ = ['McResult', 'mc_hysteresis', 'mc_identification', 'mc_line', 'mc_te_pp']

_TWO_PI = 2.0 * math.pi
_BATCH = 64
#: Relative tolerance (of U) on the ends of an interval compared with the Monte Carlo's.
CONTAINMENT_TOLERANCE = 0.05


@dataclass(frozen=True)
class McResult:
    """A Monte Carlo propagation beside the budget it checks (SI).

    Attributes:
        measurand: The budget's measurand.
        draws: Number of draws.
        u_gum: U = k u_c of the law of propagation.
        u_mc: Half-width of the 95.45 % probabilistically symmetric interval of the draws.
        std_mc: Standard deviation of the draws (compare with u_c).
        u_c: u_c of the budget.
        low, high: The Monte Carlo interval.
        interval_gum: The budget's interval [y - U - b_high, y + U + b_low].
    """

    measurand: str
    draws: int
    u_gum: float
    u_mc: float
    std_mc: float
    u_c: float
    low: float
    high: float

    interval_gum: tuple[float, float] = (math.nan, math.nan)

    @property
    def contained(self) -> bool:
        """The budget's interval contains the Monte Carlo interval, each end to within
        ``CONTAINMENT_TOLERANCE`` x U: the Monte Carlo's ends are themselves estimates of
        the 2.3 % and 97.7 % quantiles, with a standard error of about 3 % of U at 2000
        draws (sqrt(p (1 - p) / n) / f(q) for a normal), so a strict comparison fails on
        sampling noise where an end of the budget's interval is reached (the rigidity's
        smaller side); the same numerical tolerance as the width check (GUM S1, 8.1)."""
        lo, hi = self.interval_gum
        tol = CONTAINMENT_TOLERANCE * self.u_gum
        return lo - tol <= self.low and self.high <= hi + tol

    @property
    def difference(self) -> float:
        """(U_mc - U_gum) / U_gum."""
        return (self.u_mc - self.u_gum) / self.u_gum if self.u_gum > 0 else math.nan


def _result(budget: Budget, y: np.ndarray) -> McResult:
    u_mc, lo, hi = monte_carlo_interval(y, budget.value, COVERAGE_PROBABILITY)
    return McResult(measurand=budget.measurand, draws=int(y.size), u_gum=budget.expanded,
                    u_mc=u_mc, std_mc=float(np.std(y, ddof=1)), u_c=budget.u_c, low=lo, high=hi,
                    interval_gum=budget.interval)


def _scalar_draws(budget: Budget, skip: set[str], n: int, rng: np.random.Generator,
                  ) -> np.ndarray:
    """Sum of c_i X_i over the inputs not propagated through the model (signed
    sensitivities: the sign of a symmetric input does not matter)."""
    out = np.zeros(n)
    for x in budget.inputs:
        if x.name not in skip and x.contribution > 0:
            out += x.sensitivity * sample_input(x, n, rng)
    return out


def _signal_components(bench: BenchUncertainty, gear_ratio: float, *, long_range: bool = True,
                       ) -> list[tuple[str, float, int, float, bool]]:
    """(input name, TE scale, order, amplitude, on the input shaft) of the error functions."""
    out = []
    for enc, who, sc, inp in ((bench.encoder_out, 'output encoder', 1.0, False),
                              (bench.encoder_in, 'input encoder', -1.0 / gear_ratio, True)):
        comps = enc.long_range_components() if long_range else enc.components()
        out += [(f'{who}: {name}', sc, k, g, inp) for name, k, g in comps]
    return out


def mc_te_pp(budget: Budget, phi_rad: npt.ArrayLike, te_rad: npt.ArrayLike, *,
             gear_ratio: float, bench: BenchUncertainty, draws: int,
             rng: np.random.Generator, theta_out_offset_rad: float = 0.0) -> McResult:
    """Monte Carlo of a TE p-p budget (the direction value: the largest p-p of a whole
    revolution of ``phi``, as :func:`~rv_te_bench.core.directional.direction_te`).

    Args:
        budget: From :func:`~rv_te_bench.core.te_uncertainty.te_pp_budget`.
        phi_rad, te_rad: The record (one direction, whole revolutions from its start).
        gear_ratio, bench: As for the budget.
        draws: Number of draws (>= 100).
        rng: Generator.
        theta_out_offset_rad: Output encoder angle at phi = 0.
    """
    phi = np.asarray(phi_rad, dtype=np.float64)
    te = np.asarray(te_rad, dtype=np.float64)
    travel = np.abs(phi - phi[0])
    rev = np.floor(travel / _TWO_PI + 1e-12).astype(np.int64)
    revs = max(int(rev.max()), 1)
    keep = rev < revs
    phi, te, rev = phi[keep], te[keep], rev[keep]
    starts = np.flatnonzero(np.r_[True, rev[1:] != rev[:-1]])
    comps = _signal_components(bench, gear_ratio)
    theta_out = phi + te + theta_out_offset_rad
    theta_in = gear_ratio * phi
    # the error function of a draw with phases rho_j: sum_j s_j(theta) cos(rho_j) +
    # c_j(theta) sin(rho_j), i.e. one matrix product of the (2 components, samples) basis
    # with the (draws, 2 components) weights; rows are draws, so that each revolution's
    # max and min run along contiguous memory
    basis = np.empty((2 * len(comps), te.size))
    for j, (_, sc, k, g, inp) in enumerate(comps):
        th = theta_in if inp else theta_out
        basis[2 * j] = sc * g * np.sin(k * th)
        basis[2 * j + 1] = sc * g * np.cos(k * th)
    skip = {c[0] for c in comps}
    y = np.empty(draws)
    for b0 in range(0, draws, _BATCH):
        m = min(_BATCH, draws - b0)
        weights = np.empty((m, 2 * len(comps)))
        for j in range(len(comps)):
            rho = rng.uniform(0.0, _TWO_PI, m)
            weights[:, 2 * j] = np.cos(rho)
            weights[:, 2 * j + 1] = np.sin(rho)
        corr = weights @ basis
        np.subtract(te, corr, out=corr)
        pp = np.maximum.reduceat(corr, starts, axis=1)
        pp -= np.minimum.reduceat(corr, starts, axis=1)
        y[b0:b0 + m] = pp.max(axis=1)
    y += _scalar_draws(budget, skip, draws, rng)
    return _result(budget, y)


def mc_line(amplitude_budget: Budget, phase_budget: Budget, phi_rad: npt.ArrayLike,
            te_rad: npt.ArrayLike, output_order: float, *, gear_ratio: float,
            bench: BenchUncertainty, draws: int, rng: np.random.Generator,
            theta_out_offset_rad: float = 0.0) -> tuple[McResult, McResult]:
    """Monte Carlo of a line's amplitude and phase budgets.

    The line's phasor is that of the budgets (amplitude, phase); the drawn error
    functions' Fourier coefficient at ``output_order`` over the record's whole revolutions
    (samples weighted by their spacing in phi) is removed from it.
    """
    phi = np.asarray(phi_rad, dtype=np.float64)
    te = np.asarray(te_rad, dtype=np.float64)
    dphi = np.gradient(phi)
    span = float(np.sum(dphi))
    ker = 2.0 * dphi * np.exp(-1j * output_order * phi) / span
    amp0, ph0 = amplitude_budget.value, phase_budget.value
    c0 = amp0 * np.exp(1j * ph0)
    # TE(phi) ~ a cos(o phi + p): coefficient 2/span int TE e^{-i o phi} = a e^{i p}
    comps = [c for c in _signal_components(bench, gear_ratio, long_range=False)
             if abs(c[2] * (gear_ratio if c[4] else 1.0) - output_order)
             <= 1e-9 * max(1.0, output_order)]
    theta_out = phi + te + theta_out_offset_rad
    theta_in = gear_ratio * phi
    coef = []
    for _, sc, k, g, inp in comps:
        th = theta_in if inp else theta_out
        coef.append((sc * g * np.sum(ker * np.sin(k * th)), sc * g * np.sum(ker * np.cos(k * th))))
    c = np.full(draws, c0, dtype=np.complex128)
    for cs, cc in coef:
        rho = rng.uniform(0.0, _TWO_PI, draws)
        c -= cs * np.cos(rho) + cc * np.sin(rho)
    skip = {x[0] for x in comps}
    amp = np.abs(c) + _scalar_draws(amplitude_budget, skip, draws, rng)
    dev = np.angle(c * np.exp(-1j * ph0)) + _scalar_draws(phase_budget, skip, draws, rng)
    return _result(amplitude_budget, amp), _result(phase_budget, ph0 + dev)


def mc_hysteresis(budgets: dict[str, Budget], torque_nm: npt.ArrayLike, angle_rad: npt.ArrayLike,
                  config: HysteresisConfig, *, bench: BenchUncertainty, theta_out_rad: float,
                  draws: int, rng: np.random.Generator,
                  counts: npt.ArrayLike | None = None) -> dict[str, McResult]:
    """Monte Carlo of the hysteresis budgets (every metric recomputed per draw).

    The output encoder's error function e (its harmonics at drawn phases) is removed from
    the points at their true positions, found from the read ones by the fixed point
    theta = theta_m - e(theta) (two steps): the second-order term of a fast harmonic is
    propagated, not assumed. A rigidity is the smaller side of each draw, as reported;
    each side is propagated too (``'<name> (pos)'``, ``'<name> (neg)'``: the budgets the
    minimum's budget is taken over, :func:`~.hysteresis_uncertainty.min_budget`). The law
    of propagation holds for each side; the minimum is not smooth where the sides cross,
    so its budget is an envelope of the two and is checked by containing the Monte Carlo
    interval (:attr:`McResult.contained`).
    """
    from rv_te_bench.core.hysteresis import hysteresis_metrics
    from rv_te_bench.core.hysteresis_uncertainty import local_compliance

    t = np.asarray(torque_nm, dtype=np.float64)
    a = np.asarray(angle_rad, dtype=np.float64)
    n_pts = np.ones(t.size) if counts is None else np.asarray(counts, dtype=np.float64)
    th = theta_out_rad + (a - a[0])
    enc = bench.encoder_out
    comps = enc.components()
    names = list(budgets)
    any_b = next(iter(budgets.values()))
    noise = next((x for x in any_b.inputs if 'noise' in x.name), None)
    zero = next(x for x in any_b.inputs if x.name == 'torque sensor: zero and linearity')
    gain = next(x for x in any_b.inputs if x.name == 'torque sensor: sensitivity (gain)')
    q = enc.resolution_rad
    comp = local_compliance(t, a)
    side_budgets = dict(budgets)
    for n in names:
        for part in budgets[n].parts:
            side_budgets[part.measurand] = part
    out = {n: np.empty(draws) for n in side_budgets}
    for d in range(draws):
        rho = rng.uniform(0.0, _TWO_PI, len(comps))

        def err(x: np.ndarray, rho: np.ndarray = rho) -> np.ndarray:
            e = np.zeros(x.size)
            for (_, k, g), r in zip(comps, rho, strict=True):
                e += g * np.sin(k * x + r)
            return e

        th_true = th - err(th - err(th))
        aa = a - err(th_true)
        if noise is not None and noise.u > 0:
            aa = aa + sample_input(noise, t.size, rng) / np.sqrt(n_pts)
        if q > 0:
            aa = aa + rng.uniform(-q / 2, q / 2, t.size)
        z = float(sample_input(zero, 1, rng)[0])
        e = float(sample_input(gain, 1, rng)[0])
        # the point held at reading t sat at (t - z) / (1 + e): the unit's angle at t is
        # phi + phi' (t - (t - z) / (1 + e))
        aa = aa + comp * (t - (t - z) / (1.0 + e))
        m = hysteresis_metrics(t, aa, config)
        vals = {'lost_motion_rad': m.lost_motion_rad, 'backlash_rad': m.backlash_rad,
                'hysteresis_loss_j': m.hysteresis_loss_j}
        for r in config.rigidity_regions:
            pos, neg = m.rigidity_nm_per_rad[r.name]
            name = f'torsional_rigidity_{r.name}_nm_per_rad'
            vals[name] = min(pos, neg)
            vals[f'{name} (pos)'] = pos
            vals[f'{name} (neg)'] = neg
        for n in out:
            out[n][d] = vals[n]
    return {n: _result(side_budgets[n], out[n]) for n in out}


def mc_identification(budgets: dict[str, Budget], folded: FoldedTe, ident: Identification, *,
                      gear_ratio: float, bench: BenchUncertainty, draws: int,
                      rng: np.random.Generator) -> dict[str, McResult]:
    """Monte Carlo of the identified eccentricities' budgets: the folded record with the
    encoders' drawn error functions removed (and the fit residual drawn as white noise per
    bin) is fitted again by the non-linear least squares itself (from the identified
    solution: :func:`~rv_te_bench.core._eccentric_fit.polish`, the touching pair free)."""
    from rv_te_bench.core._eccentric_fit import polish
    from rv_te_bench.core.identify_uncertainty import IDENTIFIED, long_range_terms, solution
    from rv_te_bench.core.phases import _basis

    geom = ident.geometry
    assert geom is not None
    phi = np.asarray(folded.phi_rad, dtype=np.float64)
    counts = np.asarray(folded.counts, dtype=np.float64)
    w = np.sqrt(counts)
    bas = _basis(phi, geom.crank_order) * w
    te = np.asarray(folded.te_rad, dtype=np.float64)
    r_p = geom.r_p_m
    x0 = solution(ident)
    terms = long_range_terms(bench, gear_ratio, folded.n_bins)
    sigma = ident.fit.residual_rms_rad if ident.fit is not None else 0.0
    out = {n: np.empty(draws) for n, _ in IDENTIFIED}
    rot = complex(math.cos(geom.alpha_rad), math.sin(geom.alpha_rad))
    for d in range(draws):
        err = np.zeros(phi.size)
        for _, scale, order, g in terms:
            err += scale * g * np.sin(order * phi + rng.uniform(0.0, _TWO_PI))
        noise = sigma * rng.standard_normal(phi.size) / w
        y = (te - err + noise) * r_p * w
        x = polish(x0, bas, w, y)
        for name, (ia, ib) in (('pair1', (0, 1)), ('pair2', (2, 3)), ('e_ot', (4, 5))):
            z = complex(x[ib], x[ia]) * rot
            key = 'theta_ot' if name == 'e_ot' else f'{name}_phase'
            out[f'{name}_m'][d] = abs(z)
            ref = budgets[f'{key}_rad'].value
            out[f'{key}_rad'][d] = ref + math.remainder(math.atan2(z.imag, z.real) - ref, _TWO_PI)
    return {n: _result(budgets[n], out[n]) for n, _ in IDENTIFIED}
