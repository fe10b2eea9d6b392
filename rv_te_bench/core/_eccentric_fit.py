"""The least-squares machinery of :mod:`rv_te_bench.core.identify` (private).

Parameters x = (a1, b1, a2, b2, ao, bo, c) [m] along the mesh line, with the basis rows of
:func:`rv_te_bench.core.phases._basis`; the data are the bins of an
:class:`~rv_te_bench.core.angle_fold.FoldedTe`, each row weighted by the square root of its
count (so that the bin means carry the information of their samples).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from rv_te_bench.core.phases import _basis

if TYPE_CHECKING:
    from rv_te_bench.core.angle_fold import FoldedTe
    from rv_te_bench.core.phases import EccentricGeometry

FloatArray = npt.NDArray[np.float64]
_MAX_ALTERNATIONS = 60
_SEARCH_BINS = 2048           # bins per output revolution of the multi-start search


def design(bas: FloatArray, mask1: npt.NDArray[np.bool_], w: FloatArray) -> FloatArray:
    """Design matrix (n, 7) for x = (a1, b1, a2, b2, ao, bo, c) given the touching pair.

    ``bas`` rows are already multiplied by the weights ``w``; the offset column is ``w``.
    """
    n = bas.shape[1]
    d = np.zeros((n, 7))
    m1 = mask1.astype(np.float64)
    m2 = 1.0 - m1
    d[:, 0] = bas[0] * m1
    d[:, 1] = bas[1] * m1
    d[:, 2] = bas[0] * m2
    d[:, 3] = bas[1] * m2
    sign = m1 - m2
    d[:, 4] = bas[2] * sign
    d[:, 5] = bas[3] * sign
    d[:, 6] = w
    return d


def deltas(x: FloatArray, bas: FloatArray) -> tuple[FloatArray, FloatArray]:
    d1 = x[0] * bas[0] + x[1] * bas[1] + x[4] * bas[2] + x[5] * bas[3]
    d2 = x[2] * bas[0] + x[3] * bas[1] - x[4] * bas[2] - x[5] * bas[3]
    return d1, d2


def _solve_normal(a: FloatArray, b: FloatArray) -> FloatArray:
    """Least-squares solution from the normal equations (min-norm if a pair is empty)."""
    try:
        return np.asarray(np.linalg.solve(a, b), dtype=np.float64)
    except np.linalg.LinAlgError:
        return np.asarray(np.linalg.lstsq(a, b, rcond=None)[0], dtype=np.float64)


def alternate(x: FloatArray, bas: FloatArray, w: FloatArray, y: FloatArray,
              ) -> tuple[FloatArray, float]:
    """Assign-and-solve iterations from ``x``; returns (x, weighted sum of squares).

    Weights are positive, so the touching pair of the weighted increments is that of the
    plain ones.
    """
    prev = None
    for _ in range(_MAX_ALTERNATIONS):
        d1, d2 = deltas(x, bas)
        mask = d1 >= d2
        if prev is not None and np.array_equal(mask, prev):
            break
        prev = mask
        d = design(bas, mask, w)
        x = _solve_normal(d.T @ d, d.T @ y)
    d1, d2 = deltas(x, bas)
    r = np.maximum(d1, d2) + x[6] * w - y
    return x, float(r @ r)


def _starts(bas: FloatArray, w: FloatArray, y: FloatArray, scale: float,
            rng: np.random.Generator, n_random: int) -> list[FloatArray]:
    """Initial parameter vectors: a linear sinusoid fit, its variants, and random ones."""
    lin = np.linalg.lstsq(np.column_stack([bas.T, w]), y, rcond=None)[0]
    a, b, ao, bo, c = lin
    out = [np.array([a, b, a, b, ao, bo, c]), np.array([a, b, -a, -b, ao, bo, c]),
           np.array([2 * a, 2 * b, 0.0, 0.0, ao, bo, c]),
           np.array([0.0, 0.0, 2 * a, 2 * b, ao, bo, c])]
    for _ in range(n_random):
        mag = scale * rng.uniform(0.2, 2.5, size=3)
        ph = rng.uniform(-math.pi, math.pi, size=3)
        out.append(np.array([mag[0] * math.sin(ph[0]), mag[0] * math.cos(ph[0]),
                             mag[1] * math.sin(ph[1]), mag[1] * math.cos(ph[1]),
                             mag[2] * math.sin(ph[2]), mag[2] * math.cos(ph[2]), c]))
    return out


def search(folded: FoldedTe, geom: EccentricGeometry, rng: np.random.Generator,
           n_starts: int) -> FloatArray:
    """Best of the alternating fits from every start, on a coarser fold (speed) [m]."""
    factor = max(1, folded.n_bins // _SEARCH_BINS)
    counts, phi, te = folded.coarse(factor)
    w = np.sqrt(counts)
    bas = _basis(phi, geom.crank_order) * w
    y = te * geom.r_p_m * w
    best_x, best_cost = None, math.inf
    scale = max(folded.te_std_rad * geom.r_p_m, 1e-12)
    for x0 in _starts(bas, w, y, scale, rng, n_starts):
        x, cost = alternate(x0, bas, w, y)
        if cost < best_cost:
            best_x, best_cost = x, cost
    assert best_x is not None
    return best_x


def polish(x0: FloatArray, bas: FloatArray, w: FloatArray, y: FloatArray) -> FloatArray:
    """Alternate from ``x0`` on the full fold, then least_squares; the better of the two."""
    from scipy.optimize import least_squares

    best_x, best_cost = alternate(x0, bas, w, y)

    def resid(x: FloatArray) -> FloatArray:
        d1, d2 = deltas(x, bas)
        r: FloatArray = np.maximum(d1, d2) + x[6] * w - y
        return r

    def jac(x: FloatArray) -> FloatArray:
        d1, d2 = deltas(x, bas)
        return design(bas, d1 >= d2, w)

    s = max(float(np.abs(best_x).max()), 1e-12)
    def resid_scaled(u: FloatArray) -> FloatArray:
        return resid(u * s)

    def jac_scaled(u: FloatArray) -> FloatArray:
        return jac(u * s) * s

    sol = least_squares(resid_scaled, best_x / s, jac=jac_scaled,
                        method='trf', xtol=1e-12, ftol=1e-12)
    x = sol.x * s if 2 * sol.cost <= best_cost else best_x
    return alternate(x, bas, w, y)[0]


def slope_basis(phi: FloatArray, crank_order: float) -> FloatArray:
    """d/dphi of the rows of ``_basis``, shape (4, n)."""
    c = crank_order * phi
    return np.stack([-crank_order * np.sin(c), crank_order * np.cos(c), -np.sin(phi),
                     np.cos(phi)])


def q_covariance(cov: FloatArray, alpha: float) -> FloatArray:
    """Covariance of (Re Q1, Im Q1, Re Q2, Im Q2) from that of x [m^2]."""
    c, s = math.cos(alpha), math.sin(alpha)
    # Q = (b + i a)(c + i s): Re = b c - a s, Im = b s + a c
    t = np.zeros((4, 7))
    for k, (ia, ib) in enumerate(((0, 1), (2, 3))):
        t[2 * k, ia], t[2 * k, ib] = -s, c
        t[2 * k + 1, ia], t[2 * k + 1, ib] = c, s
    return t @ cov @ t.T
