"""Uncertainty budgets of the identified eccentricities (issue 35; :mod:`.identify`).

What one TE record identifies is the output-wheel eccentricity E = e_ot e^{i theta_ot} and
the two pair sums Q1, Q2 (:data:`~rv_te_bench.core.identify.OBSERVABILITY`). Each of the
six results (three magnitudes [m], three phases [rad]) gets a budget:

* **encoder harmonic errors.** A TE error d(phi) moves the least-squares solution x by
  ``pinv(J) (r_p w d)`` to first order (J the weighted design matrix at the solution, the
  touching pair fixed: Gauss-Newton), and a result q by grad_q . dx. An encoder harmonic
  g sin(k theta + rho) of unknown phase is an arcsine input of amplitude g with the
  closed-form sensitivity hypot(q's response to sin(k phi), to cos(k phi)) (output
  encoder: order k of the output revolution; input encoder: order k i, divided by i). The
  output encoder's order-1 errors (graduation order 1, mounting eccentricity) sit on the
  order of E itself and dominate its budget: a TE bench cannot tell an output-wheel
  eccentricity from an eccentric output scale (DESIGN.md s.7: 5 um on a 100 mm ring is
  +-20.6"); the mounting eccentricity of the scale, stated in the bench description with
  its uncertainty, is the input that says how far.
* **fit residual** (type A): the covariance of the least squares, the residual taken as
  white noise (dof n - 7).
* the position error within one signal period (order N per revolution, far above the
  fold's resolution) averages out in the bins and is orthogonal to the model's orders; the
  DAQ skew adds a constant to the TE that the offset c absorbs; the temperature's scale
  drift over a record is far below both. Stated in the notes, not entered.

The model's own parameters (alpha, r_p, the crank order) are design values, not
measured here: e = TE x r_p scales with r_p; an r_p known to 0.1 % adds 0.1 % of e (a
note, not an input).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core._eccentric_fit import deltas, design
from rv_te_bench.core.phases import _basis
from rv_te_bench.core.uncertainty import Budget, UncertaintyInput, combine, type_b

if TYPE_CHECKING:
    from rv_te_bench.core.angle_fold import FoldedTe
    from rv_te_bench.core.bench_uncertainty import BenchUncertainty
    from rv_te_bench.core.identification import Identification

__all__ = ['IDENTIFIED', 'identification_budgets', 'long_range_terms', 'solution']

#: The identified results that get a budget: (name, unit).
IDENTIFIED = (('e_ot_m', 'm'), ('pair1_m', 'm'), ('pair2_m', 'm'),
              ('theta_ot_rad', 'rad'), ('pair1_phase_rad', 'rad'),
              ('pair2_phase_rad', 'rad'))
#: Harmonic orders above this part of the fold's bins are averaged out in the bins.
_MAX_ORDER_PER_BIN = 0.25


def solution(ident: Identification) -> np.ndarray:
    """x = (a1, b1, a2, b2, ao, bo, c) [m] of the identification (labels as reported:
    the label swap is an exact symmetry of the model, either set fits)."""
    geom = ident.geometry
    assert geom is not None
    rot = complex(math.cos(-geom.alpha_rad), math.sin(-geom.alpha_rad))
    q1, q2, ee = (z * rot for z in ident.pair_phasors_m)      # b + i a = Q e^{-i alpha}
    return np.array([q1.imag, q1.real, q2.imag, q2.real, ee.imag, ee.real,
                     ident.offset_rad * geom.r_p_m])


def long_range_terms(bench: BenchUncertainty, gear_ratio: float, n_bins: int,
                     ) -> list[tuple[str, float, float, float]]:
    """(input name, TE scale, order per output revolution, amplitude) of the encoders'
    harmonic errors a fold of ``n_bins`` resolves (orders up to a quarter of the bins)."""
    out = []
    for enc, who, per_out, scale in ((bench.encoder_out, 'output encoder', 1.0, 1.0),
                                     (bench.encoder_in, 'input encoder', gear_ratio,
                                      -1.0 / gear_ratio)):
        for cname, k, g in enc.components():
            order = k * per_out
            if order <= _MAX_ORDER_PER_BIN * n_bins:
                out.append((f'{who}: {cname}', scale, order, g))
    return out


def _gradients(x: np.ndarray, alpha: float) -> dict[str, np.ndarray]:
    """d(result)/dx of each identified result."""
    rot = complex(math.cos(alpha), math.sin(alpha))
    out = {}
    for name, (ia, ib) in (('pair1', (0, 1)), ('pair2', (2, 3)), ('e_ot', (4, 5))):
        z = complex(x[ib], x[ia]) * rot          # Q = (b + i a) e^{i alpha}
        mag = abs(z)
        g_mag = np.zeros(7)
        g_ph = np.zeros(7)
        if mag > 0:
            # dQ = (db + i da) rot: d|Q| = Re(conj(Q) dQ) / |Q|, d arg Q = Im(conj(Q) dQ) / |Q|^2
            for idx, dz in ((ib, rot), (ia, 1j * rot)):
                w = z.conjugate() * dz
                g_mag[idx] = w.real / mag
                g_ph[idx] = w.imag / (mag * mag)
        key = 'theta_ot' if name == 'e_ot' else f'{name}_phase'
        out[f'{name}_m'] = g_mag
        out[f'{key}_rad'] = g_ph
    return out


def identification_budgets(ident: Identification, folded: FoldedTe, *,
                           gear_ratio: float, bench: BenchUncertainty) -> dict[str, Budget]:
    """Budgets of the identified |E|, |Q1|, |Q2| [m] and their phases [rad].

    Args:
        ident: From :func:`~rv_te_bench.core.identify.identify_folded`.
        folded: The folded record it was identified from.
        gear_ratio: i (the input encoder turns i times per output revolution).
        bench: The bench's type B inputs.

    Returns:
        One budget per :data:`IDENTIFIED` name.
    """
    geom = ident.geometry
    assert geom is not None
    x = solution(ident)
    phi = np.asarray(folded.phi_rad, dtype=np.float64)
    w = np.sqrt(np.asarray(folded.counts, dtype=np.float64))
    bas = _basis(phi, geom.crank_order) * w
    d1, d2 = deltas(x, bas)
    jw = design(bas, d1 >= d2, w)
    pinv = np.linalg.pinv(jw)                      # (7, n_bins)
    grads = _gradients(x, geom.alpha_rad)
    r_p = geom.r_p_m

    def response(te_error: np.ndarray) -> np.ndarray:
        return pinv @ (te_error * r_p * w)        # dx [m] per TE error [rad]

    inputs: dict[str, list[UncertaintyInput | None]] = {n: [] for n, _ in IDENTIFIED}
    for name, scale, order, g in long_range_terms(bench, gear_ratio, folded.n_bins):
        ds = response(np.sin(order * phi))
        dc = response(np.cos(order * phi))
        enc = bench.encoder_out if name.startswith('output') else bench.encoder_in
        for n, _ in IDENTIFIED:
            c = abs(scale) * math.hypot(float(grads[n] @ ds), float(grads[n] @ dc))
            inputs[n].append(type_b(
                name, sensitivity=c, distribution='arcsine', half_width=g, source=enc.source,
                note=f'closed form (Gauss-Newton): response to order {order:g} of the '
                     'output revolution, sine and cosine quadrature'))
    # the fit residual as white noise: the covariance of the weighted least squares
    n_samples = folded.n_samples
    fit = ident.fit
    rss = (fit.residual_rms_rad ** 2) * n_samples if fit is not None else 0.0
    dof = max(n_samples - 7, 1)
    cov = (rss * r_p * r_p / dof) * (pinv @ pinv.T)
    for name, _ in IDENTIFIED:
        u = math.sqrt(max(float(grads[name] @ cov @ grads[name]), 0.0))
        inputs[name].append(UncertaintyInput(
            name='fit residual (least-squares covariance)', kind='A', u=u, sensitivity=1.0,
            distribution='t', dof=float(dof), unit='m' if name.endswith('_m') else 'rad',
            source=f'this record ({n_samples} samples)',
            note='residual taken as white noise: rss / (n - 7) (J^T J)^-1'))
    values = {'e_ot_m': ident.e_m['e_ot'], 'pair1_m': ident.e_m['pair1'],
              'pair2_m': ident.e_m['pair2'], 'theta_ot_rad': ident.phases_rad['theta_ot'],
              'pair1_phase_rad': ident.phases_rad['pair1'],
              'pair2_phase_rad': ident.phases_rad['pair2']}
    notes = ['the output encoder\'s order-1 errors (graduation order 1, mounting eccentricity '
             'of the scale) lie on the order of e_ot: a TE record cannot tell them apart',
             'not entered: the interpolation error (averaged out in the fold, orthogonal to '
             'the model), DAQ skew (a TE offset, absorbed by c), temperature drift',
             f'design values not measured here: r_p = {r_p * 1e3:.6g} mm (e scales with it), '
             f'alpha, crank order {geom.crank_order:g}']
    notes += [f'{who} model {e.model!r} is not known: its errors are not in the budget'
              for who, e in (('input encoder', bench.encoder_in),
                             ('output encoder', bench.encoder_out)) if not e.known]
    return {name: combine(name, values[name], inputs[name], unit=unit, notes=notes)
            for name, unit in IDENTIFIED}
