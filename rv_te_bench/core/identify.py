"""Eccentricity identification of a 2K-V unit from a measured TE record (Wang 2020 Eqs 1-8).

Model (see :mod:`rv_te_bench.core.phases`): with the output angle ``phi`` measured from the
assembly reference (t0) and ``k_c`` the signed crank order (-25 for Wang's unit),

    TE(phi) = max(Delta_1, Delta_2) / r_p + c + noise                          [rad]
    Delta_1 = Im[Q1 e^{-i a} (e^{i k_c phi} - 1)] + Im[E e^{-i a} (e^{i phi} - 1)]
    Delta_2 = Im[Q2 e^{-i a} (e^{i k_c phi} - 1)] - Im[E e^{-i a} (e^{i phi} - 1)]
    Q1 = e_p1 e^{i theta_p1} + e_g e^{i theta_g},   Q2 = e_p2 e^{i theta_p2} - e_g e^{i theta_g}
    E  = e_ot e^{i theta_ot}

``c`` is the unknown zero of the encoders (Eq. 22 TE has an arbitrary offset).

What one TE record can tell (observability):

* The output-wheel eccentricity acts at the output order: ``E`` (e_ot, theta_ot) is
  identified, up to the label swap below.
* e_p1, e_p2 and e_g all turn at the crank rate (DESIGN.md s.4), so the record only holds
  the two *pair phasors* Q1 and Q2 (4 numbers for 6 unknowns): adding any phasor z to
  e_g e^{i theta_g} and compensating in the planets leaves the TE unchanged. The split
  between planet and revolution eccentricity is **not observable** from one record of one
  assembly. It becomes so with the magnitudes of the parts (runout inspection, or the
  preset's tolerance-class values): then theta_g solves |Q1 - g| = e_p1, |Q2 + g| = e_p2,
  |g| = e_g, and theta_p1 = arg(Q1 - g), theta_p2 = arg(Q2 + g). (A second record after
  turning one part by a known angle would identify it too; not implemented.)
* Label swap: (Q1, Q2, E) -> (Q2, Q1, -E) gives the same TE exactly (pair 1 and pair 2 are
  told apart only by convention). With unequal planet magnitudes the split above picks the
  labelling that fits them; with equal ones both labellings are the same physical unit
  and recommend the same re-assembly.
* A pair that never touches (its increment always below the other's) leaves its phasor
  unobservable; ``contact_fraction`` reports how much of the record each pair carried.

Noise model: white read-head noise and quantisation of both encoders (RON 886: 36,000 lines
x interpolation, q = 0.036", sigma ~0.01-0.3") enter the TE as independent, zero-mean (after
the offset c takes the -q/2 bias of truncating counts) noise of a few 0.1", small against
the eccentricity TE (~30"); least squares is then the maximum-likelihood estimate. The
encoders' graduation errors (harmonics 2-4 of the output, <= 1") are not modelled: the
order-2..4 content does not alias onto orders 1 and 25, but leaks a few per cent into E.

Fit: the model is linear in (Q1, Q2, E, c) once it is known which pair touches at each
sample, so an alternating scheme (assign samples to the touching pair, solve the linear
least squares, repeat) converges to a local optimum in a few steps; it is run from several
starts (a linear sinusoid fit and random phasors drawn from ``rng``), the best is polished
with ``scipy.optimize.least_squares`` (Jacobian = the design matrix of the active pieces).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from rv_te_bench.core.advice import Advice
from rv_te_bench.core.phases import (
    PHASE_NAMES,
    EccentricGeometry,
    PhaseOptimisation,
    ProgressCallback,
    _basis,
    optimise_phases,
    wrap_rad,
)
from rv_te_bench.errors import CompensationError
from sim.units import rad_to_arcmin, rad_to_arcsec, rad_to_deg

__all__ = ['LABEL_RATIO_RESOLVED', 'Identification', 'identified_advice',
           'identify_eccentricities', 'recommend_reassembly']

FloatArray = npt.NDArray[np.float64]
_MIN_SAMPLES = 64
_MIN_CRANK_REVS = 2.0
_MAX_ALTERNATIONS = 60
#: label_ratio above which pair 1 and pair 2 count as told apart.
LABEL_RATIO_RESOLVED = 2.0


@dataclass(frozen=True)
class Identification:
    """Eccentricities of one 2K-V unit identified from a TE record.

    Attributes:
        e_m: Identified magnitudes [m]: ``e_ot`` and the pair eccentricities ``pair1``
            (|Q1|) and ``pair2`` (|Q2|).
        phases_rad: Identified phases [rad]: ``theta_ot``, ``pair1`` (arg Q1), ``pair2``
            (arg Q2), and ``theta_p1``, ``theta_p2``, ``theta_g`` when the part magnitudes
            resolve the split (see ``assumed_e_m``).
        residual_rms_rad: RMS of measured minus fitted TE [rad].
        offset_rad: Fitted TE offset c (encoder zeros) [rad].
        contact_fraction: Share of samples where pair 1 / pair 2 carries the TE.
        output_revolutions: Output revolutions the record spans.
        n_samples: Samples used.
        assumed_e_m: Part magnitudes (e_p1, e_p2, e_g) used to split Q1, Q2 [m] (empty:
            no split).
        split_residual_m: RMS misfit of that split [m] (large: magnitudes inconsistent).
        labels_swapped: The fit's pair labels were swapped to match the part magnitudes.
        label_ratio: Split misfit of the other labelling over that of the chosen one
            (>= 1; below :data:`LABEL_RATIO_RESOLVED` the labels are ambiguous: planets of
            nearly equal eccentricity; the advice is then nearly the same either way).
        geometry: Geometry (alpha, r_p, crank order) used for the fit.
    """

    e_m: dict[str, float]
    phases_rad: dict[str, float]
    residual_rms_rad: float
    offset_rad: float
    contact_fraction: tuple[float, float]
    output_revolutions: float
    n_samples: int
    assumed_e_m: dict[str, float] = field(default_factory=dict)
    split_residual_m: float = math.nan
    labels_swapped: bool = False
    label_ratio: float = math.nan
    geometry: EccentricGeometry | None = field(default=None, repr=False)

    @property
    def pair_phasors_m(self) -> tuple[complex, complex, complex]:
        """(Q1, Q2, E) as complex eccentricity vectors [m]."""
        def z(mag: str, ph: str) -> complex:
            return self.e_m[mag] * complex(math.cos(self.phases_rad[ph]),
                                           math.sin(self.phases_rad[ph]))
        return z('pair1', 'pair1'), z('pair2', 'pair2'), z('e_ot', 'theta_ot')

    @property
    def labels_resolved(self) -> bool:
        """Whether the part magnitudes told pair 1 from pair 2 (label_ratio large)."""
        return self.label_ratio >= LABEL_RATIO_RESOLVED

    @property
    def split_resolved(self) -> bool:
        """Whether theta_p1, theta_p2 and theta_g are available."""
        return all(n in self.phases_rad for n in PHASE_NAMES)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict with unit suffixes (um, deg, arcsec for people)."""
        return {
            'e_um': {k: v * 1e6 for k, v in self.e_m.items()},
            'e_m': dict(self.e_m),
            'phases_deg': {k: float(rad_to_deg(v)) for k, v in self.phases_rad.items()},
            'phases_rad': dict(self.phases_rad),
            'residual_rms_arcsec': float(rad_to_arcsec(self.residual_rms_rad)),
            'offset_arcmin': float(rad_to_arcmin(self.offset_rad)),
            'contact_fraction': list(self.contact_fraction),
            'output_revolutions': self.output_revolutions,
            'n_samples': self.n_samples,
            'assumed_e_um': {k: v * 1e6 for k, v in self.assumed_e_m.items()},
            'split_residual_um': (self.split_residual_m * 1e6
                                  if math.isfinite(self.split_residual_m) else None),
            'labels_swapped': self.labels_swapped,
            'label_ratio': self.label_ratio if math.isfinite(self.label_ratio) else None,
        }


def _geometry(params: Any) -> EccentricGeometry:  # noqa: ANN401
    if isinstance(params, EccentricGeometry):
        return params
    return EccentricGeometry.from_params(params)


def _check_record(phase_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike,
                  crank_order: float) -> tuple[FloatArray, FloatArray]:
    phi = np.asarray(phase_out_rad, dtype=np.float64)
    te = np.asarray(te_rad, dtype=np.float64)
    if phi.ndim != 1 or phi.shape != te.shape:
        msg = f'phase_out_rad and te_rad must be 1-D of equal length, got {phi.shape} and {te.shape}'
        raise CompensationError(msg)
    for name, arr in (('phase_out_rad', phi), ('te_rad', te)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            msg = f'{name}[{int(bad[0])}] is not finite ({arr[bad[0]]!r})'
            raise CompensationError(msg)
    if phi.size < _MIN_SAMPLES:
        msg = f'need at least {_MIN_SAMPLES} samples, got {phi.size}'
        raise CompensationError(msg)
    span = float(phi.max() - phi.min())
    crank_revs = span * abs(crank_order) / (2 * math.pi)
    if crank_revs < _MIN_CRANK_REVS:
        msg = (f'the record spans {crank_revs:.2f} crank revolutions; identification needs '
               f'at least {_MIN_CRANK_REVS:g} (better: one output revolution)')
        raise CompensationError(msg)
    return phi, te


def _design(bas: FloatArray, mask1: npt.NDArray[np.bool_]) -> FloatArray:
    """Design matrix (n, 7) for x = (a1, b1, a2, b2, ao, bo, c) given the touching pair."""
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
    d[:, 6] = 1.0
    return d


def _deltas(x: FloatArray, bas: FloatArray) -> tuple[FloatArray, FloatArray]:
    d1 = x[0] * bas[0] + x[1] * bas[1] + x[4] * bas[2] + x[5] * bas[3]
    d2 = x[2] * bas[0] + x[3] * bas[1] - x[4] * bas[2] - x[5] * bas[3]
    return d1, d2


def _solve_normal(a: FloatArray, b: FloatArray) -> FloatArray:
    """Least-squares solution from the normal equations (min-norm if a pair is empty)."""
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(a, b, rcond=None)[0]


def _alternate(x: FloatArray, bas: FloatArray, y: FloatArray) -> tuple[FloatArray, float]:
    """Assign-and-solve iterations from ``x``; returns (x, sum of squares)."""
    prev = None
    for _ in range(_MAX_ALTERNATIONS):
        d1, d2 = _deltas(x, bas)
        mask = d1 >= d2
        if prev is not None and np.array_equal(mask, prev):
            break
        prev = mask
        d = _design(bas, mask)
        x = _solve_normal(d.T @ d, d.T @ y)
    d1, d2 = _deltas(x, bas)
    r = np.maximum(d1, d2) + x[6] - y
    return x, float(r @ r)


def _starts(bas: FloatArray, y: FloatArray, rng: np.random.Generator, n_random: int,
            ) -> list[FloatArray]:
    """Initial parameter vectors: a linear sinusoid fit, its variants, and random ones."""
    lin = np.linalg.lstsq(np.column_stack([bas.T, np.ones(bas.shape[1])]), y, rcond=None)[0]
    a, b, ao, bo, c = lin
    out = [np.array([a, b, a, b, ao, bo, c]), np.array([a, b, -a, -b, ao, bo, c]),
           np.array([2 * a, 2 * b, 0.0, 0.0, ao, bo, c]),
           np.array([0.0, 0.0, 2 * a, 2 * b, ao, bo, c])]
    scale = max(float(np.std(y)), 1e-12)
    for _ in range(n_random):
        mag = scale * rng.uniform(0.2, 2.5, size=3)
        ph = rng.uniform(-math.pi, math.pi, size=3)
        out.append(np.array([mag[0] * math.sin(ph[0]), mag[0] * math.cos(ph[0]),
                             mag[1] * math.sin(ph[1]), mag[1] * math.cos(ph[1]),
                             mag[2] * math.sin(ph[2]), mag[2] * math.cos(ph[2]),
                             float(np.mean(y))]))
    return out


def _split(q1: complex, q2: complex, e_p1: float, e_p2: float, e_g: float,
           ) -> tuple[float, float, float, float]:
    """theta_p1, theta_p2, theta_g [rad] and RMS misfit [m] from Q1, Q2 and magnitudes."""
    th = np.linspace(-math.pi, math.pi, 7201)
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
    return (float(np.angle(p1)), float(np.angle(p2)), float(wrap_rad(tg)), res)


def identify_eccentricities(phase_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike,
                            params: Any, *, rng: np.random.Generator | None = None,  # noqa: ANN401
                            n_starts: int = 16, split: bool = True) -> Identification:
    """Fit the Eqs 1-8 model to a TE record and identify the unit's eccentricities.

    Args:
        phase_out_rad: Output angle of each sample, measured from the assembly reference
            (t0) [rad], 1-D, unwrapped; ideally one whole output revolution or more.
        te_rad: Measured TE (Eq. 22, any constant offset) [rad], same shape.
        params: ``sim.wang2020.Wang2kvParams`` or :class:`EccentricGeometry`: alpha, r_p
            and the crank order are used; its e_p1, e_p2 and e_g are taken as the *known
            part magnitudes* that split the pair phasors (see module docstring). Its phases
            and e_ot are not used.
        rng: Generator for the random starts (default: ``np.random.default_rng(0)``).
        n_starts: Random starts in addition to four deterministic ones (>= 0).
        split: Resolve theta_p1, theta_p2, theta_g with the part magnitudes.

    Returns:
        The identification (observable quantities, and the split when requested).

    Raises:
        CompensationError: Arrays of different shape, non-finite values, too few samples,
            a record shorter than two crank revolutions, or ``n_starts < 0``.
    """
    geom = _geometry(params)
    phi, te = _check_record(phase_out_rad, te_rad, geom.crank_order)
    if isinstance(n_starts, bool) or not isinstance(n_starts, int) or n_starts < 0:
        msg = f'n_starts must be an integer >= 0, got {n_starts!r}'
        raise CompensationError(msg)
    gen = np.random.default_rng(0) if rng is None else rng
    r_p = geom.r_p_m
    bas = _basis(phi, geom.crank_order)
    y = te * r_p                                       # work along the mesh line [m]
    best_x, best_cost = None, math.inf
    for x0 in _starts(bas, y, gen, n_starts):
        x, cost = _alternate(x0, bas, y)
        if cost < best_cost:
            best_x, best_cost = x, cost
    assert best_x is not None  # noqa: S101 - at least the four deterministic starts ran

    def resid(x: FloatArray) -> FloatArray:
        d1, d2 = _deltas(x, bas)
        return np.maximum(d1, d2) + x[6] - y

    def jac(x: FloatArray) -> FloatArray:
        d1, d2 = _deltas(x, bas)
        return _design(bas, d1 >= d2)

    scale = max(float(np.abs(best_x).max()), 1e-12)
    sol = least_squares(lambda u: resid(u * scale), best_x / scale,
                        jac=lambda u: jac(u * scale) * scale, method='trf',
                        xtol=1e-12, ftol=1e-12)
    x = sol.x * scale if 2 * sol.cost <= best_cost else best_x
    x, _ = _alternate(x, bas, y)
    r = resid(x)
    d1, d2 = _deltas(x, bas)
    frac1 = float(np.mean(d1 >= d2))
    rot = complex(math.cos(geom.alpha_rad), math.sin(geom.alpha_rad))
    q1 = complex(x[1], x[0]) * rot            # b + i a = Q e^{-i alpha}
    q2 = complex(x[3], x[2]) * rot
    ee = complex(x[5], x[4]) * rot
    swapped = False
    assumed: dict[str, float] = {}
    split_res = math.nan
    ratio = math.nan
    extra: dict[str, float] = {}
    if split:
        e_p1, e_p2, e_g, _ = geom.e_m
        assumed = {'e_p1': e_p1, 'e_p2': e_p2, 'e_g': e_g}
        a = _split(q1, q2, e_p1, e_p2, e_g)
        b = _split(q2, q1, e_p1, e_p2, e_g)
        if b[3] < a[3]:
            swapped = True
            q1, q2, ee = q2, q1, -ee
            frac1 = 1.0 - frac1
            a, b = b, a
        ratio = b[3] / a[3] if a[3] > 0 else math.inf
        extra = {'theta_p1': a[0], 'theta_p2': a[1], 'theta_g': a[2]}
        split_res = a[3]
    e_m = {'e_ot': abs(ee), 'pair1': abs(q1), 'pair2': abs(q2)}
    phases = {'theta_ot': float(np.angle(ee)), 'pair1': float(np.angle(q1)),
              'pair2': float(np.angle(q2)), **extra}
    span = float(phi.max() - phi.min())
    return Identification(
        e_m=e_m, phases_rad=phases, residual_rms_rad=float(np.sqrt(np.mean(r * r))) / r_p,
        offset_rad=float(x[6]) / r_p, contact_fraction=(frac1, 1.0 - frac1),
        output_revolutions=span / (2 * math.pi), n_samples=int(phi.size),
        assumed_e_m=assumed, split_residual_m=split_res, labels_swapped=swapped,
        label_ratio=ratio, geometry=geom)


def recommend_reassembly(identification: Identification, params: Any, *,  # noqa: ANN401
                         step_deg: float = 10.0, refine: bool = False,
                         refine_tol_deg: float = 0.5,
                         progress: ProgressCallback | None = None) -> PhaseOptimisation:
    """Re-assembly phases for an identified unit (Eq. 21 with its eccentricities).

    The magnitudes are e_p1, e_p2, e_g as assumed in the identification (part
    magnitudes) and the identified e_ot; the current phases are the identified ones, so
    the advice's ``current_value`` -> ``recommended_value`` is how far to turn each part.

    Args:
        identification: Result of :func:`identify_eccentricities` with the split resolved.
        params: Wang2kvParams or EccentricGeometry (alpha, r_p, crank order, stiffness).
        step_deg: Grid step [deg] (see :func:`optimise_phases`).
        refine: Refine below the grid step.
        refine_tol_deg: Final local grid step of the refinement [deg].
        progress: Fraction-done callback.

    Raises:
        CompensationError: The identification has no split (part magnitudes unknown).
    """
    if not identification.split_resolved:
        msg = ('the identification did not resolve theta_p1/theta_p2/theta_g (part '
               'magnitudes unknown): re-assembly needs e_p1, e_p2, e_g')
        raise CompensationError(msg)
    geom = _geometry(params)
    a = identification.assumed_e_m
    unit = geom.with_eccentricities(
        (a['e_p1'], a['e_p2'], a['e_g'], identification.e_m['e_ot'])).with_phases(
        [identification.phases_rad[n] for n in PHASE_NAMES])
    return optimise_phases(unit, step_deg=step_deg, refine=refine,
                           refine_tol_deg=refine_tol_deg, progress=progress)


def identified_advice(phase_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike, params: Any, *,  # noqa: ANN401
                      preset_name: str, step_deg: float = 10.0,
                      progress: ProgressCallback | None = None) -> Advice:
    """Identify this unit from its TE record and recommend re-assembly phases, as Advice.

    The one call the compensation node and the offline report make: identification
    (:func:`identify_eccentricities`), then :func:`recommend_reassembly`, then the advice
    with method ``'identified-assembly-phases'`` (current = identified phases).

    Raises:
        CompensationError: The record cannot be identified (see the two functions).
    """
    ident = identify_eccentricities(phase_out_rad, te_rad, params)
    result = recommend_reassembly(ident, params, step_deg=step_deg, progress=progress)
    advice = result.to_advice(preset_name, method='identified-assembly-phases')
    details = dict(advice.details)
    details['identification'] = ident.to_json_dict()
    return replace(advice, details=details)
