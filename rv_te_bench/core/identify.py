"""Eccentricity identification of a 2K-V unit from a measured TE record (Wang 2020 Eqs 1-8).

Model (see :mod:`rv_te_bench.core.phases`): with ``phi`` the *kinematic* output angle
``theta_in / i`` measured from the assembly reference (t0) and ``k_c`` the signed crank
order (-25 for Wang's unit),

    TE(phi) = max(Delta_1, Delta_2) / r_p + c + noise                          [rad]
    Delta_1 = Im[Q1 e^{-i a} (e^{i k_c phi} - 1)] + Im[E e^{-i a} (e^{i phi} - 1)]
    Delta_2 = Im[Q2 e^{-i a} (e^{i k_c phi} - 1)] - Im[E e^{-i a} (e^{i phi} - 1)]
    Q1 = e_p1 e^{i theta_p1} + e_g e^{i theta_g},   Q2 = e_p2 e^{i theta_p2} - e_g e^{i theta_g}
    E  = e_ot e^{i theta_ot}

``c`` is the unknown zero of the encoders (Wang 2020 Eq. 22 TE has an arbitrary offset). The angle
must be ``theta_in / i``, not the measured ``theta_out = theta_in / i + TE``: the latter
shifts the crank phase by ``|k_c| TE`` (1.3 deg for 3' of TE) and biases the result by
per cents (issue #15).

What one TE record can tell (observability, :data:`OBSERVABILITY`):

* The output-wheel eccentricity acts at the output order: ``E`` (e_ot, theta_ot) is
  identified, up to the label swap below.
* e_p1, e_p2 and e_g all turn at the crank rate (DESIGN.md s.4), so the record only holds
  the two *pair sums* Q1 and Q2 (4 numbers for 6 unknowns): adding any phasor z to
  e_g e^{i theta_g} and compensating in the planets leaves the TE unchanged. The split
  between planet and revolution eccentricity is **not observable** from one record of one
  assembly. It becomes so with the magnitudes of the parts (runout inspection, or the
  preset's tolerance-class values): then theta_g solves |Q1 - g| = e_p1, |Q2 + g| = e_p2,
  |g| = e_g, and theta_p1 = arg(Q1 - g), theta_p2 = arg(Q2 + g) (:mod:`._split`, with its
  conditioning). (A second record after turning one part by a known angle would identify
  it too; not implemented.)
* Label swap: (Q1, Q2, E) -> (Q2, Q1, -E) gives the same TE exactly (pair 1 and pair 2 are
  told apart only by convention). With unequal planet magnitudes the split above picks the
  labelling that fits them; with equal ones both labellings are the same physical unit
  and recommend the same re-assembly.
* A pair that never touches (its increment always below the other's) leaves its phasor
  unobservable; ``contact_fraction`` reports how much of the record each pair carried.

Data reduction: the model is periodic in phi with one output revolution, so the record is
folded onto 2^15 bins of one revolution (:class:`~rv_te_bench.core.angle_fold.AngleFold`,
streamed, memory independent of the length); the fit uses the bin means weighted by their
counts, and the residual is evaluated at the sample level from the per-bin sums.

Noise model: white read-head noise and quantisation of both encoders (RON 886: 36,000 lines
x interpolation, q = 0.036", sigma ~0.01-0.3") enter the TE as independent, zero-mean noise
of a few 0.1", small against the eccentricity TE (~30"); least squares is then the
maximum-likelihood estimate, and the 1-sigma errors reported come from its covariance.
The encoders' graduation errors (harmonics 2-4 of the output, <= 1") are not modelled:
they stay in the residual and leak a few per cent into E.

Fit quality: every result carries the sample-level residual, the TE standard deviation, the
explained fraction ``1 - RSS / TSS`` and a model-free noise estimate
(:class:`FitQuality`). Re-assembly advice is withheld (:class:`PoorFitError`) when the model
explains less than :data:`MIN_EXPLAINED_FRACTION` of the TE variance: the TE is then not
dominated by the eccentricities this model knows (load sharing under torque, other
errors), and phases turned by the advice would not do what it predicts.

Fit: the model is linear in (Q1, Q2, E, c) once it is known which pair touches at each
sample, so an alternating scheme (assign samples to the touching pair, solve the linear
least squares, repeat) converges to a local optimum in a few steps; it is run from several
starts (a linear sinusoid fit and random phasors drawn from ``rng``), the best is polished
with ``scipy.optimize.least_squares`` (Jacobian = the design matrix of the active pieces).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from rv_te_bench.core._eccentric_fit import (
    deltas,
    design,
    polish,
    q_covariance,
    search,
    slope_basis,
)
from rv_te_bench.core._split import split_pairs
from rv_te_bench.core.advice import Advice
from rv_te_bench.core.angle_fold import DEFAULT_BINS, AngleFold, FoldedTe
from rv_te_bench.core.identification import (
    LABEL_MISFIT_FLOOR,
    LABEL_RATIO_RESOLVED,
    MIN_EXPLAINED_FRACTION,
    OBSERVABILITY,
    SPLIT_WELL_POSED_DEG_PER_PCT,
    FitQuality,
    Identification,
    PoorFitError,
    json_rounded,
)
from rv_te_bench.core.phases import (
    PHASE_NAMES,
    EccentricGeometry,
    GeometrySource,
    PhaseOptimisation,
    ProgressCallback,
    _basis,
    optimise_phases,
)
from rv_te_bench.errors import CompensationError, TeInputError

if TYPE_CHECKING:
    from rv_te_bench.core.bench_uncertainty import BenchUncertainty
    from rv_te_bench.core.identification import IdentificationU95Json

__all__ = ['LABEL_MISFIT_FLOOR', 'LABEL_RATIO_RESOLVED', 'MIN_EXPLAINED_FRACTION', 'OBSERVABILITY',
           'SPLIT_WELL_POSED_DEG_PER_PCT', 'FitQuality', 'Identification', 'PoorFitError',
           'check_fit',
           'identification_u95_json', 'identified_advice', 'identify_eccentricities',
           'identify_folded',
           'recommend_reassembly']

FloatArray = npt.NDArray[np.float64]
_MIN_SAMPLES = 64
_MIN_CRANK_REVS = 2.0
def _geometry(params: GeometrySource) -> EccentricGeometry:
    if isinstance(params, EccentricGeometry):
        return params
    return EccentricGeometry.from_params(params)


def _fold_record(phase_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike,
                 n_bins: int) -> FoldedTe:
    phi = np.asarray(phase_out_rad, dtype=np.float64)
    te = np.asarray(te_rad, dtype=np.float64)
    if phi.ndim != 1 or phi.shape != te.shape:
        msg = (f'phase_out_rad and te_rad must be 1-D of equal length, got {phi.shape} and '
               f'{te.shape}')
        raise CompensationError(msg)
    for name, arr in (('phase_out_rad', phi), ('te_rad', te)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            msg = f'{name}[{int(bad[0])}] is not finite ({arr[bad[0]]!r})'
            raise CompensationError(msg)
    fold = AngleFold(n_bins=n_bins)
    fold.add(phi, te)
    return fold.result()


def _check_folded(folded: FoldedTe, crank_order: float) -> None:
    if folded.n_samples < _MIN_SAMPLES:
        msg = f'need at least {_MIN_SAMPLES} samples, got {folded.n_samples}'
        raise CompensationError(msg)
    crank_revs = folded.span_rad * abs(crank_order) / (2 * math.pi)
    if crank_revs < _MIN_CRANK_REVS:
        msg = (f'the record spans {crank_revs:.2f} crank revolutions; identification needs '
               f'at least {_MIN_CRANK_REVS:g} (better: one output revolution)')
        raise CompensationError(msg)


def identify_eccentricities(phase_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike,
                            params: GeometrySource, *, rng: np.random.Generator | None = None,
                            n_starts: int = 16, split: bool = True,
                            n_bins: int = DEFAULT_BINS) -> Identification:
    """Fit the Wang 2020 Eqs 1-8 model to a TE record and identify the unit's eccentricities.

    Args:
        phase_out_rad: Kinematic output angle ``theta_in / i`` of each sample, measured from
            the assembly reference (t0) [rad], 1-D; ideally one whole output revolution or
            more. Not the measured output angle (see the module docstring).
        te_rad: Measured TE (Wang 2020 Eq. 22, any constant offset) [rad], same shape.
        params: ``sim.wang2020.Wang2kvParams`` or :class:`EccentricGeometry`: alpha, r_p
            and the crank order are used; its e_p1, e_p2 and e_g are taken as the *known
            part magnitudes* that split the pair sums (see module docstring). Its phases
            and e_ot are not used.
        rng: Generator for the random starts (default: ``np.random.default_rng(0)``).
        n_starts: Random starts in addition to four deterministic ones (>= 0).
        split: Resolve theta_p1, theta_p2, theta_g with the part magnitudes.
        n_bins: Bins per output revolution of the fold.

    Returns:
        The identification (observable quantities, fit quality, and the split when
        requested).

    Raises:
        CompensationError: Arrays of different shape, non-finite values, too few samples,
            a record shorter than two crank revolutions, or ``n_starts < 0``.
    """
    try:
        folded = _fold_record(phase_out_rad, te_rad, n_bins)
    except TeInputError as exc:
        raise CompensationError(str(exc)) from None
    return identify_folded(folded, params, rng=rng, n_starts=n_starts, split=split)


def identify_folded(folded: FoldedTe, params: GeometrySource, *,
                    rng: np.random.Generator | None = None, n_starts: int = 16,
                    split: bool = True) -> Identification:
    """As :func:`identify_eccentricities`, for a record folded by an ``AngleFold``.

    The way to identify a long record (a bag) without holding it: feed its samples to
    :meth:`AngleFold.add_encoders` as they are read, then call this.
    """
    geom = _geometry(params)
    _check_folded(folded, geom.crank_order)
    if isinstance(n_starts, bool) or not isinstance(n_starts, int) or n_starts < 0:
        msg = f'n_starts must be an integer >= 0, got {n_starts!r}'
        raise CompensationError(msg)
    gen = np.random.default_rng(0) if rng is None else rng
    r_p = geom.r_p_m
    w = np.sqrt(folded.counts.astype(np.float64))
    bas0 = _basis(np.asarray(folded.phi_rad), geom.crank_order)
    bas = bas0 * w
    y = np.asarray(folded.te_rad) * r_p * w               # along the mesh line [m]
    x = polish(search(folded, geom, gen, n_starts), bas, w, y)

    # sample-level fit quality from the fold
    d1, d2 = deltas(x, bas0)
    mask = d1 >= d2
    model = (np.maximum(d1, d2) + x[6]) / r_p
    dbas = slope_basis(np.asarray(folded.phi_rad), geom.crank_order)
    s1, s2 = deltas(x, dbas)
    rss = folded.rss_rad2(model, np.where(mask, s1, s2) / r_p)
    n = folded.n_samples
    frac1 = float(np.sum(folded.counts[mask]) / n)
    rot = complex(math.cos(geom.alpha_rad), math.sin(geom.alpha_rad))
    q1 = complex(x[1], x[0]) * rot            # b + i a = Q e^{-i alpha}
    q2 = complex(x[3], x[2]) * rot
    ee = complex(x[5], x[4]) * rot
    curvature = (geom.crank_order ** 2 * max(abs(q1), abs(q2)) + abs(ee)) / r_p
    fit = FitQuality(
        residual_rms_rad=math.sqrt(rss / n), te_std_rad=folded.te_std_rad,
        explained_fraction=(1.0 - rss / folded.te_ss_rad2 if folded.te_ss_rad2 > 0
                            else math.nan),
        noise_rms_rad=folded.noise_rms_rad(curvature))

    # noise covariance of x (sample-level information J^T J of the weighted bins)
    jw = design(bas, mask, w)
    dof = max(n - 7, 1)
    cov = (rss * r_p * r_p / dof) * np.linalg.pinv(jw.T @ jw)
    # (a, b) -> Q e^{-i alpha} = b + i a; the rotation keeps vector errors
    sig = {k: math.sqrt(max(cov[i, i] + cov[j, j], 0.0))
           for k, (i, j) in (('pair1', (0, 1)), ('pair2', (2, 3)), ('e_ot', (4, 5)))}
    cov_q = q_covariance(np.asarray(cov, dtype=np.float64), geom.alpha_rad)
    return _finish(geom, folded, x, q1, q2, ee, frac1, fit, sig, cov_q, split=split)


def _finish(geom: EccentricGeometry, folded: FoldedTe, x: FloatArray,
            q1: complex, q2: complex, ee: complex, frac1: float, fit: FitQuality,
            sig: dict[str, float], cov_q: FloatArray, *, split: bool) -> Identification:
    """Labels, split and the result object."""
    swapped = False
    assumed: dict[str, float] = {}
    split_res = ratio = other = per_pct = per_um = math.nan
    extra: dict[str, float] = {}
    sig_ph: dict[str, float] = {}
    if split:
        e_p1, e_p2, e_g, _ = geom.e_m
        assumed = {'e_p1': e_p1, 'e_p2': e_p2, 'e_g': e_g}
        swap = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [1, 0, 0, 0], [0, 1, 0, 0]], dtype=float)
        a = split_pairs(q1, q2, (e_p1, e_p2, e_g), cov_m2=cov_q)
        b = split_pairs(q2, q1, (e_p1, e_p2, e_g), cov_m2=swap @ cov_q @ swap.T)
        if b.misfit_m < a.misfit_m:
            swapped = True
            q1, q2, ee = q2, q1, -ee
            frac1 = 1.0 - frac1
            sig = {'pair1': sig['pair2'], 'pair2': sig['pair1'], 'e_ot': sig['e_ot']}
            a, b = b, a
        ratio = b.misfit_m / a.misfit_m if a.misfit_m > 0 else math.inf
        other = b.misfit_m
        extra = dict(zip(('theta_p1', 'theta_p2', 'theta_g'), a.phases_rad, strict=True))
        sig_ph = dict(zip(('theta_p1', 'theta_p2', 'theta_g'), a.sigma_rad, strict=True))
        split_res, per_pct, per_um = a.misfit_m, a.deg_per_pct, a.deg_per_um
    sig_ph['theta_ot'] = sig['e_ot'] / abs(ee) / math.sqrt(2) if abs(ee) > 0 else math.nan
    e_m = {'e_ot': abs(ee), 'pair1': abs(q1), 'pair2': abs(q2)}
    phases = {'theta_ot': float(np.angle(ee)), 'pair1': float(np.angle(q1)),
              'pair2': float(np.angle(q2)), **extra}
    return Identification(
        e_m=e_m, phases_rad=phases, residual_rms_rad=fit.residual_rms_rad,
        offset_rad=float(x[6]) / geom.r_p_m, contact_fraction=(frac1, 1.0 - frac1),
        output_revolutions=folded.output_revolutions, n_samples=folded.n_samples,
        assumed_e_m=assumed, split_residual_m=split_res, labels_swapped=swapped,
        label_ratio=ratio, label_misfit_m=other, geometry=geom, fit=fit, sigma_m=sig,
        sigma_rad=sig_ph,
        split_deg_per_pct=per_pct, split_deg_per_um=per_um)


def recommend_reassembly(identification: Identification, params: GeometrySource, *,
                         step_deg: float = 10.0, refine: bool = False,
                         refine_tol_deg: float = 0.5,
                         progress: ProgressCallback | None = None) -> PhaseOptimisation:
    """Re-assembly phases for an identified unit (Wang 2020 Eq. 21 with its eccentricities).

    The magnitudes are e_p1, e_p2, e_g as assumed in the identification (part
    magnitudes) and the identified e_ot; the current phases are the identified ones, so
    the advice's ``current_value`` -> ``recommended_value`` is how far to turn each part.
    This does not judge the fit: :func:`identified_advice` withholds advice on a poor one.

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


def check_fit(identification: Identification) -> None:
    """Raise :class:`PoorFitError` when the fit is too poor for re-assembly advice."""
    fit = identification.fit
    if fit is not None and not fit.acceptable:
        msg = (f're-assembly advice withheld: {fit.describe()}, below the '
               f'{100 * fit.min_explained_fraction:g} % the advice needs (the TE is not '
               'dominated by the eccentricities of Wang 2020 Eqs 1-8: load sharing under '
               'torque, or other errors)')
        raise PoorFitError(msg, identification)


def identified_advice(phase_out_rad: npt.ArrayLike | FoldedTe, te_rad: npt.ArrayLike | None,
                      params: GeometrySource, *, preset_name: str, step_deg: float = 10.0,
                      refine: bool = False,
                      progress: ProgressCallback | None = None,
                      uncertainty: BenchUncertainty | None = None,
                      gear_ratio: float = math.nan) -> Advice:
    """Identify this unit from its TE record and recommend re-assembly phases, as Advice.

    The one call the compensation node and the offline report make: identification
    (:func:`identify_eccentricities`, or :func:`identify_folded` when given a
    :class:`FoldedTe` and ``te_rad=None``), the fit-quality check, then
    :func:`recommend_reassembly`, then the advice with method
    ``'identified-assembly-phases'`` (current = identified phases; details hold the
    identification with its fit quality). ``step_deg`` and ``refine`` as in
    :func:`recommend_reassembly` (use the same as for the preset's optimum, so that the two
    recommendations differ only in the unit they are for). With ``uncertainty`` (the
    bench's error model) and ``gear_ratio``, a folded record's identification carries the
    budgets of e_ot, |Q1|, |Q2| and their phases (:mod:`.identify_uncertainty`): ``u95_m``,
    ``u95_rad`` (and ``u95_um``, ``u95_deg``) and ``uncertainty`` in its JSON.

    Raises:
        PoorFitError: The model explains less than :data:`MIN_EXPLAINED_FRACTION` of the TE.
        CompensationError: The record cannot be identified (see the two functions).
    """
    if isinstance(phase_out_rad, FoldedTe):
        ident = identify_folded(phase_out_rad, params)
    else:
        ident = identify_eccentricities(phase_out_rad, np.asarray(te_rad), params)
    check_fit(ident)
    result = recommend_reassembly(ident, params, step_deg=step_deg, refine=refine,
                                  progress=progress)
    advice = result.to_advice(preset_name, method='identified-assembly-phases')
    assert ident.fit is not None
    details = dict(advice.details)
    details['identification'] = ident.to_json_dict()
    if uncertainty is not None and isinstance(phase_out_rad, FoldedTe) and math.isfinite(
            gear_ratio):
        details['identification'].update(identification_u95_json(
            ident, phase_out_rad, gear_ratio=gear_ratio, bench=uncertainty))
    details['fit'] = ident.fit.to_json_dict()
    summary = (f'{advice.summary} (this unit, identified from its TE; '
               f'{ident.fit.describe()})')
    return replace(advice, details=details, summary=summary)


def identification_u95_json(ident: Identification, folded: FoldedTe, *, gear_ratio: float,
                            bench: BenchUncertainty) -> IdentificationU95Json:
    """The identification's U (``u95_m``, ``u95_rad``, ``u95_um``, ``u95_deg``) and its
    budgets (``uncertainty``), for its JSON."""
    from rv_te_bench.core.identify_uncertainty import identification_budgets

    buds = identification_budgets(ident, folded, gear_ratio=gear_ratio, bench=bench)
    mags = {'e_ot': 'e_ot_m', 'pair1': 'pair1_m', 'pair2': 'pair2_m'}
    phs = {'theta_ot': 'theta_ot_rad', 'pair1': 'pair1_phase_rad', 'pair2': 'pair2_phase_rad'}
    return {
        'u95_m': {k: json_rounded(buds[v].u95) for k, v in mags.items()},
        'u95_rad': {k: json_rounded(buds[v].u95) for k, v in phs.items()},
        'u95_um': {k: json_rounded(buds[v].u95 * 1e6, 6) for k, v in mags.items()},
        'u95_deg': {k: json_rounded(math.degrees(buds[v].u95), 4) for k, v in phs.items()},
        'uncertainty': {v: b.to_json_dict() for v, b in buds.items()},
    }
