"""Split of the identified pair sums into part phases, and how well posed that split is.

One TE record identifies Q1 = e_p1 e^{i theta_p1} + g, Q2 = e_p2 e^{i theta_p2} - g (g =
e_g e^{i theta_g}) and E (see :mod:`rv_te_bench.core.identify`). With the part magnitudes
e_p1, e_p2, e_g known, theta_g solves |Q1 - g| = e_p1 and |Q2 + g| = e_p2 on the circle
|g| = e_g (least squares when the magnitudes do not fit exactly), and theta_p1 =
arg(Q1 - g), theta_p2 = arg(Q2 + g).

Conditioning: where the circles meet at a grazing angle, or a planet magnitude is small, a
small error of Q1, Q2 (or of the magnitudes) turns the split phases a lot, and not linearly
(near a tangency the intersection moves with the square root of the error). So the
sensitivity is measured by re-solving with finite errors: the largest phase change over
errors of 1 % of the larger of |Q1|, |Q2| added to Q1 and Q2 in 8 x 8 directions, and over
+-1 um on each magnitude. The 1-sigma phase errors from the fit's covariance use the local
derivatives (central differences), since that noise is tiny.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

__all__ = ['SplitResult', 'split_pairs']

_GRID = np.linspace(-math.pi, math.pi, 7201)


def _solve(q1: complex, q2: complex, e_p1: float, e_p2: float, e_g: float,
           ) -> tuple[float, float, float, float]:
    """theta_p1, theta_p2, theta_g [rad] and RMS misfit [m]."""
    th = _GRID
    for _ in range(3):   # dense grid, then two zooms around the best
        g = e_g * np.exp(1j * th)
        cost = (np.abs(q1 - g) - e_p1) ** 2 + (np.abs(q2 + g) - e_p2) ** 2
        j = int(np.argmin(cost))
        width = 2 * (th[1] - th[0])
        th = np.linspace(th[j] - width, th[j] + width, 401)
    tg = float(th[200])
    g = e_g * complex(math.cos(tg), math.sin(tg))
    res = math.sqrt(((abs(q1 - g) - e_p1) ** 2 + (abs(q2 + g) - e_p2) ** 2) / 2.0)
    p1 = q1 - g if e_p1 > 0 else complex(1.0, 0.0)
    p2 = q2 + g if e_p2 > 0 else complex(1.0, 0.0)
    wrapped = (tg + math.pi) % (2 * math.pi) - math.pi
    return float(np.angle(p1)), float(np.angle(p2)), wrapped, res


def _wrap(x: FloatArray) -> FloatArray:
    return (x + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class SplitResult:
    """Part phases from the pair sums and the magnitudes, with their conditioning.

    Attributes:
        phases_rad: theta_p1, theta_p2, theta_g [rad].
        misfit_m: RMS misfit of the magnitudes to the sums [m] (0: they fit exactly).
        deg_per_pct: Largest change of a split phase [deg] for a vector error of 1 % (of the
            larger of |Q1|, |Q2|) on Q1 and Q2.
        deg_per_um: Largest change of a split phase [deg] for 1 um error of one magnitude.
        sigma_rad: 1-sigma error of each split phase from the sums' covariance [rad].
    """

    phases_rad: tuple[float, float, float]
    misfit_m: float
    deg_per_pct: float
    deg_per_um: float
    sigma_rad: tuple[float, float, float]


def split_pairs(q1: complex, q2: complex, e_m: tuple[float, float, float], *,
                cov_m2: FloatArray | None = None) -> SplitResult:
    """Split Q1, Q2 with the part magnitudes (e_p1, e_p2, e_g) [m].

    Args:
        q1: Pair-1 sum [m].
        q2: Pair-2 sum [m].
        e_m: Part magnitudes e_p1, e_p2, e_g [m].
        cov_m2: Covariance (4, 4) of (Re Q1, Im Q1, Re Q2, Im Q2) [m^2] (None: no sigma).
    """
    e_p1, e_p2, e_g = e_m
    base = _solve(q1, q2, e_p1, e_p2, e_g)
    ph0 = np.array(base[:3])
    scale = max(abs(q1), abs(q2), 1e-12)

    def moved(dq1: complex, dq2: complex, mags: tuple[float, float, float]) -> float:
        ph = np.array(_solve(q1 + dq1, q2 + dq2, *mags)[:3])
        return float(np.abs(_wrap(ph - ph0)).max())

    ring = 0.01 * scale * np.exp(1j * np.linspace(0.0, 2 * math.pi, 8, endpoint=False))
    per_pct = max(moved(complex(a), complex(b), e_m) for a in ring for b in ring)
    per_um = 0.0
    for k in range(3):
        for du in (-1e-6, 1e-6):
            mags = list(e_m)
            mags[k] = max(mags[k] + du, 0.0)
            per_um = max(per_um, moved(0j, 0j, (mags[0], mags[1], mags[2])))
    sigma: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    if cov_m2 is not None and np.all(np.isfinite(cov_m2)):
        h = 1e-6 * scale
        jac = np.empty((3, 4))
        for k, d in enumerate((complex(h), complex(0, h))):
            jac[:, k] = _wrap(np.array(_solve(q1 + d, q2, *e_m)[:3])
                              - np.array(_solve(q1 - d, q2, *e_m)[:3])) / (2 * h)
            jac[:, k + 2] = _wrap(np.array(_solve(q1, q2 + d, *e_m)[:3])
                                  - np.array(_solve(q1, q2 - d, *e_m)[:3])) / (2 * h)
        var = np.einsum('ij,jk,ik->i', jac, cov_m2, jac)
        sigma = tuple(float(math.sqrt(max(v, 0.0))) for v in var)  # type: ignore[assignment]
    return SplitResult(phases_rad=(float(ph0[0]), float(ph0[1]), float(ph0[2])),
                       misfit_m=base[3], deg_per_pct=math.degrees(per_pct),
                       deg_per_um=math.degrees(per_um), sigma_rad=sigma)
