"""Assembly-phase optimisation of a 2K-V reducer (Wang 2020, Eqs 1-8, 18 and 21).

The no-load TE of the 2K-V second stage (Wang 2020 Eqs 1-8) is the upper envelope of two mesh-line
increments divided by the ring base radius r_p. With the angle laws of DESIGN.md s.4 (the
planet eccentricities theta_p1, theta_p2 and the revolution eccentricity theta_g advance
at the absolute crank rate ``k_c * phi`` with ``k_c = -25`` for Wang's unit, the output
wheel eccentricity theta_ot at the output rate ``phi``; ``phi`` is the output angle, t0 at
``phi = 0``), every term is ``e * [sin(theta0 + k * phi - alpha) - sin(theta0 - alpha)]``
and the identity ``sin(x + c) - sin(x) = sin(x) (cos c - 1) + cos(x) sin c`` makes each
increment *linear* in four basis functions of ``phi``::

    Delta_1(phi) = a1 (cos k_c phi - 1) + b1 sin k_c phi + ao (cos phi - 1) + bo sin phi
    Delta_2(phi) = a2 (cos k_c phi - 1) + b2 sin k_c phi - ao (cos phi - 1) - bo sin phi
    b1 + i a1 = e_p1 exp(i (theta_p1 - alpha)) + e_g exp(i (theta_g - alpha))   ("P1")
    b2 + i a2 = e_p2 exp(i (theta_p2 - alpha)) - e_g exp(i (theta_g - alpha))   ("P2")
    bo + i ao = e_ot exp(i (theta_ot - alpha))                                   ("E")
    NLTE(phi) = max(Delta_1, Delta_2) / r_p                        [rad]

The Wang 2020 Eq. 21 objective S = max_phi |NLTE(phi)| over one output revolution (the "major
cycle": it contains |k_c| whole crank revolutions) is minimised over the four phases on the
paper's grid [-180:10:180] deg (37^4 = 1,874,161 combinations).

Fast grid evaluation. ``max|max(D1, D2)| = max(max D1, max D2, -min max(D1, D2))``. The
first two terms depend on three of the four phases each (37^3 rows) and are computed on a
fine sampling; only the envelope minimum needs all 37^4 combinations, computed from
per-factor tables ``D1 = T_p1[i1] + T_g[i3] + T_ot[i4]``, ``D2 = T_p2[i2] - T_g[i3] -
T_ot[i4]`` on a coarse sampling in float32, chunked over (i3, i4). Sampling errors are
bounded (a sampled maximum of a smooth function is low by at most ``D'' h^2 / 8``; the
envelope is Lipschitz with ``L = |k_c| (e_p + e_g) + e_ot``, so a sampled minimum is high by
at most ``L h / 2``); every combination whose lower bound is not above the best upper
bound is re-evaluated on finer samplings until the winner is certain to the resolution
(the landscape is flat: near the paper's optimum several grid points differ by 1e-4').
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, TypeAlias, TypedDict

import numpy as np
import numpy.typing as npt

from rv_te_bench.core.advice import Advice, Modification
from rv_te_bench.core.te import TeStats, te_statistics
from rv_te_bench.core.units import json_deg
from rv_te_bench.errors import CompensationError
from sim._checks import Rule, real_number
from sim.units import deg_to_rad, rad_to_arcmin, rad_to_deg

if TYPE_CHECKING:
    from sim.wang2020 import Wang2kvParams

__all__ = [
    'PHASE_NAMES',
    'EccentricGeometry',
    'PhaseOptimisation',
    'PhaseOptimisationJson',
    'PhaseTableRow',
    'SteComparison',
    'delta_pair_m',
    'grid_search_phases',
    'nlte_from_phases_rad',
    'optimise_phases',
    'phase_objective_rad',
    'static_te_from_phases_rad',
]

FloatArray = npt.NDArray[np.float64]
ProgressCallback = Callable[[float], None]
#: What the optimiser and the identification take: a geometry, or the Wang 2020 parameters
#: it is read from (:meth:`EccentricGeometry.from_params`).
GeometrySource: TypeAlias = 'EccentricGeometry | Wang2kvParams'

#: Order of the four phases everywhere in this module (Wang 2020 Eq. 21).
PHASE_NAMES: tuple[str, str, str, str] = ('theta_p1', 'theta_p2', 'theta_g', 'theta_ot')
_FACTOR_NAMES = ('eccentricity phase of planet 1', 'eccentricity phase of planet 2',
                 'eccentricity phase of revolution', 'eccentricity phase of output wheel')
#: Memory bound of one 4-D grid chunk. 2 MiB: the temporaries stay in the cache and under
#: glibc's mmap threshold (reused heap, no page faults); 48 MiB chunks cost 1.8-2x the CPU
#: for the same result (0.88 vs 0.45 CPU s per optimise_phases at step 10 with refinement,
#: 13,000 page faults vs 0 per call; issue #23 item 1: four benches' searches at once).
_CHUNK_BYTES = 2 * 2**20
_N_COARSE_PER_CRANK = 24         # samples per crank revolution in the 4-D pass
_N_FINE_PER_CRANK = 144          # samples per crank revolution for the smooth maxima
_N_REPORT = 2**16                # samples per output revolution for reported statistics
_REL_TOL = 1e-5                  # winner certain once bounds are this close (relative)
_N_MAX = 2**20                   # finest sampling of the candidate cascade
_MAX_CASCADE_ELEMENTS = 2**25    # candidates x samples per cascade level
_N_PROBE = 64                    # most promising combinations that set the first upper bound
_TWO_PI = 2.0 * math.pi


def _finite(name: str, value: object, *, positive: bool = False, nonneg: bool = False,
            ) -> float:
    """Return ``value`` as float or raise CompensationError naming ``name``."""
    rule: Rule = '>0' if positive else '>=0' if nonneg else ''
    return real_number(name, value, rule, error=CompensationError, coerce=True)


def wrap_rad(x: npt.ArrayLike) -> np.ndarray:
    """Wrap angles to [-pi, pi) [rad]."""
    return (np.asarray(x, dtype=np.float64) + math.pi) % _TWO_PI - math.pi


@dataclass(frozen=True)
class EccentricGeometry:
    """What Wang 2020 Eqs 1-8 need of a 2K-V unit: eccentricities, phases, alpha, r_p, crank order.

    Attributes:
        e_m: Eccentricity magnitudes (e_p1, e_p2, e_g, e_ot) [m], >= 0.
        phases_rad: Assembly phases (theta_p1, theta_p2, theta_g, theta_ot) at t0 [rad].
        alpha_rad: Working pressure angle of the 2nd stage [rad] (35.266 deg for Wang).
        r_p_m: Ring base radius of Wang 2020 Eq. 5 [m] (> 0; Wang preset 61.08 mm, DESIGN.md s.4).
        crank_order: Signed absolute crank revolutions per output revolution (-25 for
            Wang's unit); an integer, so one output revolution holds whole crank turns.
        mesh_stiffness_n_m: Mesh stiffness k of Wang 2020 Eqs 10-18 [N/m] (NaN: STE not available).
    """

    e_m: tuple[float, ...]           # 4 values (checked on construction)
    phases_rad: tuple[float, ...]    # 4 values (checked on construction)
    alpha_rad: float
    r_p_m: float
    crank_order: float = -25.0
    mesh_stiffness_n_m: float = math.nan

    def __post_init__(self) -> None:
        """Validate and normalise to float tuples.

        Raises:
            CompensationError: A value is non-finite, negative where it must not be, or the
                crank order is not a non-zero integer.
        """
        if len(self.e_m) != 4 or len(self.phases_rad) != 4:
            msg = f'e_m and phases_rad need 4 values, got {self.e_m!r}, {self.phases_rad!r}'
            raise CompensationError(msg)
        e = tuple(_finite(f'e_m[{n}]', v, nonneg=True) for n, v in zip(
            ('e_p1', 'e_p2', 'e_g', 'e_ot'), self.e_m, strict=True))
        ph = tuple(_finite(f'phases_rad[{n}]', v) for n, v in zip(
            PHASE_NAMES, self.phases_rad, strict=True))
        object.__setattr__(self, 'e_m', e)
        object.__setattr__(self, 'phases_rad', ph)
        object.__setattr__(self, 'alpha_rad', _finite('alpha_rad', self.alpha_rad))
        object.__setattr__(self, 'r_p_m', _finite('r_p_m', self.r_p_m, positive=True))
        k = _finite('crank_order', self.crank_order)
        if k == 0 or k != round(k):
            msg = f'crank_order must be a non-zero integer, got {self.crank_order!r}'
            raise CompensationError(msg)
        object.__setattr__(self, 'crank_order', k)
        ks = float(self.mesh_stiffness_n_m)
        if not (math.isnan(ks) or (math.isfinite(ks) and ks > 0)):
            msg = f'mesh_stiffness_n_m must be > 0 or NaN, got {self.mesh_stiffness_n_m!r}'
            raise CompensationError(msg)
        object.__setattr__(self, 'mesh_stiffness_n_m', ks)

    @classmethod
    def from_params(cls, params: Wang2kvParams) -> EccentricGeometry:
        """Geometry of a ``sim.wang2020.Wang2kvParams`` (or anything with its fields)."""
        return _geometry_from_params(params)

    def with_phases(self, phases_rad: Sequence[float]) -> EccentricGeometry:
        """Copy with other assembly phases [rad]."""
        return replace(self, phases_rad=tuple(float(p) for p in phases_rad))

    def with_eccentricities(self, e_m: Sequence[float]) -> EccentricGeometry:
        """Copy with other eccentricity magnitudes [m]."""
        return replace(self, e_m=tuple(float(v) for v in e_m))

    @property
    def lipschitz_m_per_rad(self) -> float:
        """Bound of |dDelta_i/dphi| over both pairs [m/rad]."""
        e1, e2, eg, eo = self.e_m
        return abs(self.crank_order) * (max(e1, e2) + eg) + eo

    @property
    def curvature_m_per_rad2(self) -> float:
        """Bound of |d^2 Delta_i/dphi^2| over both pairs [m/rad^2]."""
        e1, e2, eg, eo = self.e_m
        return self.crank_order**2 * (max(e1, e2) + eg) + eo


def _geometry_from_params(params: Wang2kvParams) -> EccentricGeometry:
    """Read the fields of ``sim.wang2020.Wang2kvParams`` into a geometry."""
    try:
        kin = params.kinematics
        return EccentricGeometry(
            e_m=(params.e_p1_m, params.e_p2_m, params.e_g_m, params.e_ot_m),
            phases_rad=(params.theta_p1_0_rad, params.theta_p2_0_rad, params.theta_g_0_rad,
                        params.theta_ot_0_rad),
            alpha_rad=params.pressure_angle_rad, r_p_m=params.r_p_m,
            crank_order=round(kin.crank_per_input * kin.gear_ratio, 9),
            mesh_stiffness_n_m=params.mesh_stiffness_n_m)
    except AttributeError as exc:
        msg = f'params {type(params).__name__} is not a Wang2kvParams: {exc}'
        raise CompensationError(msg) from None


# --------------------------------------------------------------------------- model


def _coefficients(phases_rad: FloatArray, geom: EccentricGeometry) -> tuple[FloatArray, ...]:
    """Basis coefficients (a1, b1, a2, b2, ao, bo) [m] for phases of shape (..., 4)."""
    e1, e2, eg, eo = geom.e_m
    x = np.asarray(phases_rad, dtype=np.float64) - geom.alpha_rad
    s, c = np.sin(x), np.cos(x)
    a1 = e1 * s[..., 0] + eg * s[..., 2]
    b1 = e1 * c[..., 0] + eg * c[..., 2]
    a2 = e2 * s[..., 1] - eg * s[..., 2]
    b2 = e2 * c[..., 1] - eg * c[..., 2]
    return a1, b1, a2, b2, eo * s[..., 3], eo * c[..., 3]


def _basis(phi_rad: FloatArray, crank_order: float) -> FloatArray:
    """Rows (cos k_c phi - 1, sin k_c phi, cos phi - 1, sin phi), shape (4, n)."""
    c = crank_order * phi_rad
    return np.stack([np.cos(c) - 1.0, np.sin(c), np.cos(phi_rad) - 1.0, np.sin(phi_rad)])


def delta_pair_m(phi_out_rad: npt.ArrayLike, geom: EccentricGeometry, *,
                 phases_rad: npt.ArrayLike | None = None) -> tuple[FloatArray, FloatArray]:
    """Mesh-line increments Delta_1, Delta_2 of Wang 2020 Eqs 1-2 [m].

    Args:
        phi_out_rad: Output angle since t0 [rad], shape (n,).
        geom: Unit geometry; its phases are used unless ``phases_rad`` is given.
        phases_rad: Phase sets (..., 4) [rad] in :data:`PHASE_NAMES` order.

    Returns:
        Delta_1 and Delta_2, shape (..., n) [m].
    """
    phi = np.asarray(phi_out_rad, dtype=np.float64)
    ph = np.asarray(geom.phases_rad if phases_rad is None else phases_rad, dtype=np.float64)
    a1, b1, a2, b2, ao, bo = _coefficients(ph, geom)
    bas = _basis(phi, geom.crank_order)
    c1 = np.stack([a1, b1, ao, bo], axis=-1)
    c2 = np.stack([a2, b2, -ao, -bo], axis=-1)
    return c1 @ bas, c2 @ bas


def nlte_from_phases_rad(phi_out_rad: npt.ArrayLike, geom: EccentricGeometry, *,
                         phases_rad: npt.ArrayLike | None = None) -> FloatArray:
    """No-load TE of Wang 2020 Eq. 8, max(Delta_1, Delta_2) / r_p [rad], shape (..., n).

    Examples:
        >>> g = EccentricGeometry((1e-5, 2e-5, 1e-5, 1e-5), (0.0, 0.0, 0.0, 0.0),
        ...                       alpha_rad=0.6, r_p_m=0.06)
        >>> float(nlte_from_phases_rad([0.0], g)[0])
        0.0
    """
    d1, d2 = delta_pair_m(phi_out_rad, geom, phases_rad=phases_rad)
    return np.maximum(d1, d2) / geom.r_p_m


def static_te_from_phases_rad(phi_out_rad: npt.ArrayLike, load_nm: float,
                              geom: EccentricGeometry, *,
                              phases_rad: npt.ArrayLike | None = None) -> FloatArray:
    """Static TE of Wang 2020 Eq. 18 under a constant load torque [rad].

    Args:
        phi_out_rad: Output angle since t0 [rad].
        load_nm: Output load torque T [N m] (>= 0).
        geom: Unit geometry with ``mesh_stiffness_n_m`` set.
        phases_rad: Optional phase sets (..., 4) [rad].

    Raises:
        CompensationError: No mesh stiffness, or a negative/non-finite load.
    """
    load = _finite('load_nm', load_nm, nonneg=True)
    k = geom.mesh_stiffness_n_m
    if math.isnan(k):
        msg = ('mesh_stiffness_n_m is not set: static TE (Wang 2020 Eq. 18) needs the mesh '
               'stiffness k')
        raise CompensationError(msg)
    d1, d2 = delta_pair_m(phi_out_rad, geom, phases_rad=phases_rad)
    defl = load / (geom.r_p_m * k)
    one = np.maximum(d1, d2) - defl
    both = 0.5 * (d1 + d2) - 0.5 * defl
    return np.where(np.abs(d1 - d2) >= defl, one, both) / geom.r_p_m


def _cycle(n: int) -> FloatArray:
    """``n`` equally spaced output angles over one revolution [rad]."""
    return np.arange(n, dtype=np.float64) * (_TWO_PI / n)


def _bounds_for_sets(phases_rad: FloatArray, geom: EccentricGeometry, n: int,
                     ) -> tuple[FloatArray, FloatArray]:
    """Lower/upper bounds of S [m] for phase sets (m, 4) from ``n`` samples (chunked)."""
    phi = _cycle(n)
    bas = _basis(phi, geom.crank_order)
    h = _TWO_PI / n
    eps_max = geom.curvature_m_per_rad2 * h * h / 8.0
    eps_min = geom.lipschitz_m_per_rad * h / 2.0
    m = phases_rad.shape[0]
    lo = np.empty(m)
    hi = np.empty(m)
    step = max(1, _CHUNK_BYTES // (8 * 3 * n))
    for s in range(0, m, step):
        a1, b1, a2, b2, ao, bo = _coefficients(phases_rad[s:s + step], geom)
        d1 = np.stack([a1, b1, ao, bo], axis=-1) @ bas
        d2 = np.stack([a2, b2, -ao, -bo], axis=-1) @ bas
        np.maximum(d1, d2, out=d1)   # NLTE * r_p; its max is the larger of the two maxima
        mx = d1.max(-1)
        mn = d1.min(-1)
        lo[s:s + step] = np.maximum(mx, -mn)
        hi[s:s + step] = np.maximum(mx + eps_max, -mn + eps_min)
    return lo, hi


def phase_objective_rad(phases_rad: npt.ArrayLike, geom: EccentricGeometry, *,
                        n_samples: int = _N_REPORT) -> FloatArray:
    """Wang 2020 Eq. 21 objective S = max |NLTE| over one output revolution [rad].

    Args:
        phases_rad: Phase sets (..., 4) [rad] in :data:`PHASE_NAMES` order.
        geom: Unit geometry (magnitudes, alpha, r_p).
        n_samples: Samples per output revolution (the result is within
            ``L * pi / n_samples / r_p`` below the continuous maximum).

    Returns:
        S per phase set [rad], shape (...).
    """
    ph = np.asarray(phases_rad, dtype=np.float64)
    lo, _ = _bounds_for_sets(ph.reshape(-1, 4), geom, int(n_samples))
    return lo.reshape(ph.shape[:-1]) / geom.r_p_m


def _certain_best(cands: FloatArray, geom: EccentricGeometry, n_start: int,
                  prior_lo: FloatArray | None = None) -> tuple[int, float, int]:
    """Refine the sampling until one candidate is best for certain; (index, S_m, n).

    ``prior_lo`` (lower bounds from a coarser pass) orders the candidates when there are
    too many to refine (exact ties), so that the cap keeps the most promising ones.
    """
    idx = np.arange(cands.shape[0])
    n = n_start
    cap = max(1, _MAX_CASCADE_ELEMENTS // (4 * n))
    if prior_lo is not None and idx.size > cap:
        idx = np.argsort(prior_lo, kind='stable')[:cap]
    while True:
        lo, hi = _bounds_for_sets(cands[idx], geom, n)
        keep = lo <= hi.min()
        idx, lo, hi = idx[keep], lo[keep], hi[keep]
        best = int(np.argmin(lo))
        spread = hi.min() - lo.min()
        if idx.size == 1 or spread <= _REL_TOL * hi.min() or n >= _N_MAX:
            return int(idx[best]), float(lo[best]), n
        if idx.size * n * 4 > _MAX_CASCADE_ELEMENTS:
            # Many exact or near ties (e.g. a factor with zero eccentricity makes its phase
            # irrelevant): any of them is optimal within the spread; keep the lowest.
            order = np.argsort(lo, kind='stable')[:max(1, _MAX_CASCADE_ELEMENTS // (4 * n))]
            idx = idx[order]
        n *= 4


def _combos(ax: Sequence[FloatArray], flat: np.ndarray, shape: tuple[int, int, int],
            shape34: tuple[int, int]) -> FloatArray:
    """Phase sets (m, 4) [rad] of flat indices into the (i3*i4, i1, i2) grid."""
    i34, i1, i2 = np.unravel_index(flat, shape)
    i3, i4 = np.unravel_index(i34, shape34)
    return np.stack([ax[0][i1], ax[1][i2], ax[2][i3], ax[3][i4]], axis=-1)


def grid_search_phases(geom: EccentricGeometry, axes_rad: Sequence[npt.ArrayLike], *,
                       progress: ProgressCallback | None = None,
                       ) -> tuple[tuple[float, ...], float, int]:
    """Minimise the Wang 2020 Eq. 21 objective over the Cartesian product of four phase axes.

    Args:
        geom: Unit geometry (magnitudes; its phases are ignored).
        axes_rad: Four 1-D arrays of candidate phases [rad] for theta_p1, theta_p2,
            theta_g, theta_ot.
        progress: Called with the fraction done (0..1) after each chunk.

    Returns:
        (best phases [rad], S at the best phases [rad], number of combinations).

    Raises:
        CompensationError: Not four non-empty finite axes.
    """
    if len(axes_rad) != 4:
        msg = f'axes_rad needs 4 axes, got {len(axes_rad)}'
        raise CompensationError(msg)
    ax = [np.asarray(a, dtype=np.float64).ravel() for a in axes_rad]
    for name, a in zip(PHASE_NAMES, ax, strict=True):
        if a.size == 0 or not np.all(np.isfinite(a)):
            msg = f'phase axis {name} must be non-empty and finite, got {a!r}'
            raise CompensationError(msg)
    n1, n2, n3, n4 = (a.size for a in ax)
    kc = abs(geom.crank_order)
    nc = int(_N_COARSE_PER_CRANK * kc)
    nf = int(_N_FINE_PER_CRANK * kc)

    def tables(n: int, dtype: type) -> list[np.ndarray]:
        bas = _basis(_cycle(n), geom.crank_order)
        out = []
        for f, a in enumerate(ax):
            x = a - geom.alpha_rad
            rows = (bas[0 if f < 3 else 2], bas[1 if f < 3 else 3])
            t = geom.e_m[f] * (np.sin(x)[:, None] * rows[0] + np.cos(x)[:, None] * rows[1])
            out.append(t.astype(dtype))
        return out

    # Lower bounds of S for every combination, in two passes. S >= max over the samples of
    # each pair's Delta (U1[i3, i4, i1], U2[i3, i4, i2]: separable, cheap), and S >= -min
    # over the samples of max(Delta_1, Delta_2) (V: joint in i1 and i2, the costly part).
    # The positive side alone rules out almost the whole grid (for the wang2020-2kv preset
    # all but ~300 of 1.87 M combinations), so V is computed only where U leaves a chance.
    tc = tables(nc, np.float32)
    go_c = (tc[2][:, None, :] + tc[3][None, :, :]).reshape(n3 * n4, nc)
    total = n3 * n4
    k_u = max(1, _CHUNK_BYTES // ((n1 + n2) * nc * 4))
    u1 = np.empty((total, n1), dtype=np.float32)
    u2 = np.empty((total, n2), dtype=np.float32)
    for s in range(0, total, k_u):
        gc = go_c[s:s + k_u]
        u1[s:s + k_u] = (tc[0][None] + gc[:, None, :]).max(-1)
        u2[s:s + k_u] = (tc[1][None] - gc[:, None, :]).max(-1)
        if progress is not None:
            progress(0.5 * min(s + k_u, total) / total)
    f32_tol = 1e-6 * float(max(np.abs(u1).max(), np.abs(u2).max(), np.abs(go_c).max()))
    umax = np.maximum(u1[:, :, None], u2[:, None, :]).ravel()
    # An upper bound of the optimum from the most promising combinations.
    top = np.argpartition(umax, min(_N_PROBE, umax.size) - 1)[:_N_PROBE]
    _, hi_top = _bounds_for_sets(_combos(ax, top, (total, n1, n2), (n3, n4)), geom, nf)
    best_hi = float(hi_top.min())
    flat = np.flatnonzero(umax <= best_hi + f32_tol)
    # The negative side for the combinations still in the running (chunked by i3, i4).
    lo = umax[flat].astype(np.float64) - f32_tol
    i34, i1, i2 = np.unravel_index(flat, (total, n1, n2))
    k_v = max(1, _CHUNK_BYTES // (nc * 4 * 3))
    for s in range(0, flat.size, k_v):
        sl = slice(s, s + k_v)
        b1 = tc[0][i1[sl]] + go_c[i34[sl]]
        b2 = tc[1][i2[sl]] - go_c[i34[sl]]
        v = np.maximum(b1, b2).min(-1).astype(np.float64)
        lo[sl] = np.maximum(lo[sl], -v - f32_tol)
        if progress is not None:
            progress(0.5 + 0.5 * min(s + k_v, flat.size) / max(flat.size, 1))
    keep = lo <= best_hi
    flat, lo = flat[keep], lo[keep]
    cands = _combos(ax, flat, (total, n1, n2), (n3, n4))
    j, s_m, _ = _certain_best(cands, geom, nf, prior_lo=lo)
    best = tuple(float(x) for x in cands[j])
    return best, s_m / geom.r_p_m, n1 * n2 * n3 * n4


# --------------------------------------------------------------------------- result


@dataclass(frozen=True)
class SteComparison:
    """Static TE (Wang 2020 Eq. 18) statistics at one load before and after re-assembly.

    Attributes:
        load_nm: Constant output load torque [N m].
        before: Statistics at the original phases.
        after: Statistics at the optimised phases.
    """

    load_nm: float
    before: TeStats
    after: TeStats


class PhaseTableRow(TypedDict):
    """A row of :meth:`PhaseOptimisation.table_rows` (Table 4 style, arcmin)."""

    case: str
    when: str
    te_pp_arcmin: float
    te_amplitude_arcmin: float
    te_std_arcmin: float
    te_mean_arcmin: float


class PhaseOptimisationJson(TypedDict):
    """The JSON of :class:`PhaseOptimisation` (unit suffixes; None: not finite)."""

    phases_before_rad: list[float]
    phases_after_rad: list[float]
    phases_before_deg: list[float | None]
    phases_after_deg: list[float | None]
    objective_before_arcmin: float
    objective_after_arcmin: float
    objective_before_rad: float
    objective_after_rad: float
    grid_step_deg: float | None
    refined: bool
    n_combinations: int
    elapsed_s: float
    e_m: list[float]
    table: list[PhaseTableRow]


@dataclass(frozen=True)
class PhaseOptimisation:
    """Result of the Wang 2020 Eq. 21 phase optimisation (Table 4 rows before/after).

    Attributes:
        phases_before_rad: Phases as assembled (theta_p1, theta_p2, theta_g, theta_ot).
        phases_after_rad: Optimised phases, wrapped to [-pi, pi) [rad].
        objective_before_rad: S = max |NLTE| at the original phases [rad].
        objective_after_rad: S at the optimised phases [rad].
        nlte_before: NLTE statistics over one output revolution, original phases.
        nlte_after: The same at the optimised phases.
        ste: STE statistics per load (empty when the geometry has no mesh stiffness).
        grid_step_rad: Step of the coarse grid [rad].
        refined: Whether a local refinement below the grid step was run.
        n_combinations: Phase combinations evaluated (grid plus refinement).
        elapsed_s: Wall time of the search [s].
        e_m: Eccentricity magnitudes used (e_p1, e_p2, e_g, e_ot) [m].
    """

    phases_before_rad: tuple[float, float, float, float]
    phases_after_rad: tuple[float, float, float, float]
    objective_before_rad: float
    objective_after_rad: float
    nlte_before: TeStats
    nlte_after: TeStats
    ste: tuple[SteComparison, ...] = ()
    grid_step_rad: float = math.nan
    refined: bool = False
    n_combinations: int = 0
    elapsed_s: float = math.nan
    e_m: tuple[float, ...] = (math.nan,) * 4
    details: dict[str, Any] = field(default_factory=dict, compare=False)

    @property
    def reduction(self) -> float:
        """Relative reduction of S, 1 - after / before (0..1)."""
        if self.objective_before_rad == 0:
            return 0.0
        return 1.0 - self.objective_after_rad / self.objective_before_rad

    def table_rows(self) -> list[PhaseTableRow]:
        """Table 4 style rows in arcmin (pp, amplitude, std, mean) for people and JSON."""
        rows: list[PhaseTableRow] = []
        pairs = [('NLTE', self.nlte_before, self.nlte_after)]
        pairs += [(f'{c.load_nm:g} Nm STE', c.before, c.after) for c in self.ste]
        for name, b, a in pairs:
            for when, st in (('before', b), ('after', a)):
                rows.append({
                    'case': name, 'when': when,
                    'te_pp_arcmin': float(rad_to_arcmin(st.pp_rad)),
                    'te_amplitude_arcmin': float(rad_to_arcmin(st.amplitude_rad)),
                    'te_std_arcmin': float(rad_to_arcmin(st.std_rad)),
                    'te_mean_arcmin': float(rad_to_arcmin(st.mean_rad)),
                })
        return rows

    def to_advice(self, preset_name: str, *, method: str = 'assembly-phases') -> Advice:
        """The recommendation as :class:`Advice` (one Modification per phase, unit rad)."""
        mods = tuple(
            Modification(factor=f, symbol=s, unit='rad', current_value=float(b),
                         recommended_value=float(a))
            for f, s, b, a in zip(_FACTOR_NAMES, PHASE_NAMES, self.phases_before_rad,
                                  self.phases_after_rad, strict=True))
        deg = ', '.join(f'{float(rad_to_deg(p)):.1f}' for p in self.phases_after_rad)
        summary = (f'Re-assemble at phases [{deg}] deg (theta_p1, theta_p2, theta_g, '
                   f'theta_ot): max|NLTE| {float(rad_to_arcmin(self.objective_before_rad)):.3f}'
                   f"' -> {float(rad_to_arcmin(self.objective_after_rad)):.3f}'")
        if method == 'assembly-phases':
            summary += (f' (a unit built to the nominal eccentricities and phases of preset '
                        f'{preset_name})')
        return Advice(method=method, preset=preset_name, summary=summary,
                      te_metric='amplitude', te_before_rad=self.objective_before_rad,
                      te_after_rad=self.objective_after_rad, modifications=mods,
                      details={'table': self.table_rows(), 'refined': self.refined,
                               'grid_step_deg': json_deg(self.grid_step_rad),
                               'n_combinations': self.n_combinations,
                               'e_m': list(self.e_m), **self.details})

    def to_json_dict(self) -> PhaseOptimisationJson:
        """JSON-friendly dict with unit suffixes."""
        return {
            'phases_before_rad': list(self.phases_before_rad),
            'phases_after_rad': list(self.phases_after_rad),
            'phases_before_deg': [json_deg(p) for p in self.phases_before_rad],
            'phases_after_deg': [json_deg(p) for p in self.phases_after_rad],
            'objective_before_arcmin': float(rad_to_arcmin(self.objective_before_rad)),
            'objective_after_arcmin': float(rad_to_arcmin(self.objective_after_rad)),
            'objective_before_rad': self.objective_before_rad,
            'objective_after_rad': self.objective_after_rad,
            'grid_step_deg': json_deg(self.grid_step_rad),
            'refined': self.refined, 'n_combinations': self.n_combinations,
            'elapsed_s': self.elapsed_s, 'e_m': list(self.e_m),
            'table': self.table_rows(),
        }


def _grid_axis(step_rad: float) -> FloatArray:
    """The paper's axis [-180:step:180] deg in radians (both ends kept, as in Wang 2020 Eq. 21)."""
    n = math.floor(_TWO_PI / step_rad + 1e-9)
    return -math.pi + step_rad * np.arange(n + 1, dtype=np.float64)


def _stats(te_rad: FloatArray) -> TeStats:
    return te_statistics(te_rad, revolutions=1.0)


def optimise_phases(geom_or_params: GeometrySource, *, step_deg: float = 10.0,
                    refine: bool = False, refine_tol_deg: float = 0.5,
                    loads_nm: Sequence[float] = (30.0, 100.0, 300.0),
                    progress: ProgressCallback | None = None) -> PhaseOptimisation:
    """Wang 2020 Eq. 21: minimise max |NLTE| over the four assembly phases.

    Args:
        geom_or_params: :class:`EccentricGeometry` or ``sim.wang2020.Wang2kvParams``.
        step_deg: Grid step [deg] of the axis [-180:step:180] for every phase (> 0, <= 180).
        refine: Refine the best grid point with successively finer local grids
            (+-1 step at step/5) until the step is below ``refine_tol_deg``.
        refine_tol_deg: Final local grid step [deg] (> 0).
        loads_nm: Loads [N m] for the STE rows (skipped without mesh stiffness).
        progress: Called with the fraction done (0..1).

    Returns:
        The optimum, the objective and Table 4 style statistics before and after.

    Raises:
        CompensationError: Bad step, tolerance or load (message names the value).

    Examples:
        >>> g = EccentricGeometry((0.0, 0.0, 0.0, 1e-5), (0.0, 0.0, 0.0, 0.0),
        ...                       alpha_rad=0.6, r_p_m=0.06)
        >>> r = optimise_phases(g, step_deg=90.0)
        >>> r.objective_after_rad > 0.0   # e_ot alone: |NLTE| = |e_ot sin(.)| changes
        True
    """
    geom = (geom_or_params if isinstance(geom_or_params, EccentricGeometry)
            else EccentricGeometry.from_params(geom_or_params))
    step = _finite('step_deg', step_deg, positive=True)
    if step > 180.0:
        msg = f'step_deg must be <= 180, got {step_deg!r}'
        raise CompensationError(msg)
    tol = _finite('refine_tol_deg', refine_tol_deg, positive=True)
    loads = tuple(_finite('loads_nm', x, nonneg=True) for x in loads_nm)
    t0 = time.perf_counter()
    step_rad = float(deg_to_rad(step))
    axis = _grid_axis(step_rad)
    n_levels = 0
    if refine:
        s = step
        while s > tol:
            s /= 5.0
            n_levels += 1
    share = 1.0 / (1 + 0.1 * n_levels)

    grid_prog = None if progress is None else (lambda f: progress(share * f))
    best, s_best, n_comb = grid_search_phases(geom, [axis] * 4, progress=grid_prog)
    local_step = step_rad
    for level in range(n_levels):
        # Local grid +-1 step at step/5: small (11^4), so evaluated directly on the fine
        # sampling (the coarse 4-D pass would not prune at this scale).
        local_step /= 5.0
        offs = local_step * np.arange(-5, 6, dtype=np.float64)
        mesh = np.meshgrid(*[b + offs for b in best], indexing='ij')
        cands = np.stack([m.ravel() for m in mesh], axis=-1)
        j, s_m, _ = _certain_best(cands, geom, int(_N_FINE_PER_CRANK * abs(geom.crank_order)))
        n_comb += cands.shape[0]
        if s_m / geom.r_p_m <= s_best:
            best, s_best = tuple(float(x) for x in cands[j]), s_m / geom.r_p_m
        if progress is not None:
            progress(share + (level + 1) * (1.0 - share) / n_levels)
    if progress is not None:
        progress(1.0)
    after = tuple(float(x) for x in wrap_rad(best))
    phi = _cycle(_N_REPORT)
    before_te = nlte_from_phases_rad(phi, geom)
    after_te = nlte_from_phases_rad(phi, geom, phases_rad=after)
    ste: list[SteComparison] = []
    if not math.isnan(geom.mesh_stiffness_n_m):
        for load in loads:
            ste.append(SteComparison(
                load, _stats(static_te_from_phases_rad(phi, load, geom)),
                _stats(static_te_from_phases_rad(phi, load, geom, phases_rad=after))))
    # Both objectives on the same fine sampling (the search certified the winner; its
    # value may come from a coarser level of the cascade).
    s_before = float(phase_objective_rad(np.asarray(geom.phases_rad), geom))
    s_after = float(phase_objective_rad(np.asarray(after), geom))
    return PhaseOptimisation(
        phases_before_rad=geom.phases_rad, phases_after_rad=after,  # type: ignore[arg-type]
        objective_before_rad=s_before, objective_after_rad=s_after,
        nlte_before=_stats(before_te), nlte_after=_stats(after_te), ste=tuple(ste),
        grid_step_rad=step_rad, refined=bool(refine), n_combinations=int(n_comb),
        elapsed_s=time.perf_counter() - t0, e_m=geom.e_m)
