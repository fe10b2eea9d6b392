"""Tooth-profile TE compensation of an RV reducer (Hu 2020, Eqs 24-27, Table 6).

The measured total TE is assigned to the three error factors whose sensitivity index is
negative (Table 2): the pin radius (``delta_b``), the shifting tooth-profile modification
(``delta_g``) and the cumulative circumference error of the cycloid (``delta_h``). Hu 2020 Eq. 27
turns the TE shares into error values::

    delta = (pi a z_c / (180 * 60)) A^-1 dtheta        (dtheta in arcmin)
          = a z_c A^-1 dtheta                           (dtheta in rad)

with ``A`` the diagonal matrix of Hu 2020 Eq. 24 (twice the Table 2 coefficients). The paper says
the TE is divided among the three factors "in inverse proportion"; its Table 6 changes
(-0.0279, +0.0171, -0.011 mm) are in the ratio of the sensitivity indices
(-1.6308 : -1 : -0.6441, DESIGN.md s.4). Shares ``dtheta_j = TE A_jj^2 / sum_k A_kk^2``
are the ones that give exactly that ratio through Hu 2020 Eq. 27, so they are used here.

Ambiguities of the paper, stated rather than hidden:

* **Absolute scale.** Hu 2020 Eq. 27 with the paper's total TE (1.4559 arcmin) gives changes of
  0.0081 / 0.0050 / 0.0032 mm; Table 6 has 0.0279 / 0.0171 / 0.011 mm, about 3.45 times
  more. No reading of Hu 2020 Eq. 27 found reproduces the Table 6 scale. The recommendation follows
  Hu 2020 Eq. 27 as written (``scale='eq27'``); ``scale='table6'`` scales it to Table 6 instead.
  ``Advice.details`` carries Table 6, what Hu 2020 Eq. 27 gives for the paper's TE, and their ratio.
* **Direction of the shifting modification.** Hu 2020 Eq. 27 gives all three errors negative
  (``A_jj < 0``, TE shares positive). Table 6 applies the pin radius and cumulative errors
  as signed changes (3 -> 2.9721 mm, 0 -> -0.011 mm) but moves the shifting modification
  towards zero (-0.0437 -> -0.0266 mm), i.e. it reduces the magnitude of the shift. That is
  what the paper built and tested (more pins in mesh, lower F_max, -47 % TE on the bench), so
  the recommendation does the same: ``delta_r_p_new = delta_r_p - delta_g``.
* **Predicted TE (issue #18).** The linear model (Hu 2020 Eq. 23) cancels the assigned TE
  completely, which no one should believe: part of a measured TE is elastic, the cycloid disc
  turning by ``beta = delta_max / r_c'`` against the pins under the torque (TCA, Hu 2020 Eqs 35-48,
  :func:`sim.hu2020.elastic_te_rad`). A geometric modification does not cancel it; it only
  changes it through the TCA of the new geometry (more pins in mesh, smaller delta_max). The
  prediction is therefore ``TE_after = (1 - fraction) * G + E_after`` with ``E`` the elastic
  part of the peak-to-peak (``load_case='reversing'``: 2 beta, the load changes sign within
  the period as in the paper's Adams run with its reversing input) at the preset's TCA
  torque, and
  ``G = max(TE - E_before, 0)`` the geometric part. The recommendation itself assigns the
  whole TE as the paper does. The paper measured -41 % (Adams) and -47 % (bench); the
  elastic part alone falls only as delta_max does (-21 % here, -24 % in the paper).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from rv_te_bench.core.advice import Advice, Modification
from rv_te_bench.errors import CompensationError
from sim.errors import ModelInputError, PresetError
from sim.hu2020 import HuRvParams, elastic_te_rad, sensitivity_table, tooth_contact_analysis
from sim.units import ARCMIN_PER_RAD

if TYPE_CHECKING:
    from sim.presets import Preset

__all__ = [
    'LOAD_CASES',
    'NEGATIVE_FACTORS',
    'PAPER_TABLE6',
    'compensate_preset',
    'eq27_errors_m',
    'te_shares_rad',
    'tooth_profile_advice',
    'tooth_profile_compensation',
]

#: Factors with negative sensitivity that receive the TE (Table 2 / s.3.2).
NEGATIVE_FACTORS: tuple[str, ...] = ('pin_radius', 'shifting_mod_error', 'cumulative_pitch')

_SCALES = ('eq27', 'table6')
LOAD_CASES = ('reversing',)

#: Hu 2020 Table 6 (and the TE it was computed from), SI.
PAPER_TABLE6: dict[str, Any] = {
    'te_total_arcmin': 1.4559,          # s.5.1, Adams, initial prototype
    'r_rp_m': 2.9721e-3,                # was 3 mm
    'delta_r_p_m': -0.0266e-3,          # was -0.0437 mm
    'cumulative_mod_m': -0.011e-3,      # was 0
    'change_m': {'pin_radius': -0.0279e-3, 'shifting_mod_error': 0.0171e-3,
                 'cumulative_pitch': -0.011e-3},
    'k1_prime': 0.7898,
}


def _diag_a(params: HuRvParams) -> dict[str, float]:
    """Diagonal of Hu 2020 Eq. 24's A for the three negative factors."""
    coef = {r.key: r.coefficient for r in sensitivity_table(params)}
    return {k: 2.0 * coef[k] for k in NEGATIVE_FACTORS}


def te_shares_rad(params: HuRvParams, te_rad: float) -> dict[str, float]:
    """Split a TE among the negative factors, share_j = TE A_jj^2 / sum A_kk^2 [rad]."""
    a = _diag_a(params)
    total = sum(v * v for v in a.values())
    return {k: te_rad * a[k] ** 2 / total for k in NEGATIVE_FACTORS}


def eq27_errors_m(params: HuRvParams, shares_rad: dict[str, float]) -> dict[str, float]:
    """Hu 2020 Eq. 27: error values from TE shares, ``delta_j = a z_c dtheta_j / A_jj`` [m].

    ``A`` is diagonal, so ``A^-1`` acts per factor; only the factors given are solved (the
    full 9 x 9 ``A`` is singular without modification, where ``k_n = 0``).
    """
    a = _diag_a(params)
    az = params.a_m * params.z_c
    return {k: az * v / a[k] for k, v in shares_rad.items()}


def _check_te(te_rad: float, fraction: float) -> None:
    if not isinstance(te_rad, int | float) or not math.isfinite(te_rad) or te_rad <= 0:
        msg = f'measured TE must be a finite value > 0, got te_rad={te_rad!r}'
        raise CompensationError(msg)
    if not (math.isfinite(fraction) and 0.0 < fraction <= 1.0):
        msg = f'fraction must be in (0, 1], got {fraction!r}'
        raise CompensationError(msg)


def tooth_profile_compensation(params: HuRvParams, te_rad: float, *, preset: str = '',
                               fraction: float = 1.0, scale: str = 'eq27',
                               te_metric: str = 'pp', with_tca: bool = True,
                               load_case: str = 'reversing') -> Advice:
    """Recommend pin radius, shifting modification and cumulative-error modification.

    Args:
        params: The reducer's cycloid stage as it is now (e.g. Table 3).
        te_rad: Measured (or simulated) total TE [rad]; the paper's "value for a period"
            (peak-to-peak) unless ``te_metric`` says otherwise.
        preset: Preset name recorded in the advice.
        fraction: Part of the TE to compensate, in (0, 1].
        scale: ``'eq27'`` (default): Hu 2020 Eq. 27 as written. ``'table6'``: the same directions
            and ratios, scaled to the paper's Table 6, i.e. 0.0171 mm per unit sensitivity
            index for 1.4559 arcmin, proportional to the TE (an empirical calibration on
            the paper's one example, about 3.45 x Hu 2020 Eq. 27).
        te_metric: Which statistic ``te_rad`` is, ``'pp'`` or ``'amplitude'`` (recorded).
        with_tca: Also run the tooth contact analysis before/after (into ``details``).
        load_case: How the load acts over the measured period, for the elastic part of the
            prediction: ``'reversing'`` (the elastic TE spans 2 beta; the only case: under a
            one-way constant load this model's elastic TE is a constant offset and the
            linear model would again claim a TE of zero).

    Returns:
        Advice with method ``'tooth-profile'``, three Modification items in Table 6 order
        (values in m) and ``details`` holding the Hu 2020 Eq. 27 numbers, the paper's Table 6 and,
        with ``with_tca``, the TCA summaries before and after.

    Raises:
        CompensationError: TE not finite or <= 0, bad fraction, or a recommended geometry
            that is invalid (e.g. K1' >= 1 or a pin radius <= 0).

    Examples:
        >>> p = HuRvParams(z_c=39, z_p=40, r_p_m=0.076, r_rp_m=0.003, a_m=0.0015,
        ...                delta_r_rp_m=-0.022e-3, delta_r_p_m=-0.0437e-3)
        >>> adv = tooth_profile_compensation(p, 1.4559 / 10800 * math.pi, with_tca=False)
        >>> [round(m.recommended_value * 1e3, 4) for m in adv.modifications]
        [2.9919, -0.0387, -0.0032]
        >>> adv = tooth_profile_compensation(p, 1.4559 / 10800 * math.pi, scale='table6',
        ...                                  with_tca=False)
        >>> [round(m.recommended_value * 1e3, 4) for m in adv.modifications]   # Table 6
        [2.9721, -0.0266, -0.011]
    """
    _check_te(te_rad, fraction)
    if te_metric not in ('pp', 'amplitude'):
        msg = f'te_metric must be "pp" or "amplitude", got {te_metric!r}'
        raise CompensationError(msg)
    if scale not in _SCALES:
        msg = f'scale must be one of {_SCALES}, got {scale!r}'
        raise CompensationError(msg)
    if load_case not in LOAD_CASES:
        msg = f'load_case must be one of {LOAD_CASES}, got {load_case!r}'
        raise CompensationError(msg)
    shares = te_shares_rad(params, fraction * te_rad)
    errors = eq27_errors_m(params, shares)
    index = {r.key: r.sensitivity_index for r in sensitivity_table(params)}
    per_index_eq27 = errors['shifting_mod_error'] / index['shifting_mod_error']
    if scale == 'table6':
        per_index = (PAPER_TABLE6['change_m']['shifting_mod_error'] * fraction * te_rad
                     * ARCMIN_PER_RAD / PAPER_TABLE6['te_total_arcmin'])
        errors = {k: v * per_index / per_index_eq27 for k, v in errors.items()}
    new_r_rp = params.r_rp_m + errors['pin_radius']
    new_shift = params.delta_r_p_m - errors['shifting_mod_error']   # Table 6 direction
    new_cum = params.cumulative_mod_m + errors['cumulative_pitch']
    try:
        after = params.replace(r_rp_m=new_r_rp, delta_r_p_m=new_shift, cumulative_mod_m=new_cum)
    except PresetError as exc:
        msg = f'TE {te_rad!r} rad leads to an invalid geometry: {exc}'
        raise CompensationError(msg) from None
    mods = (
        Modification('pin radius', 'r_rp', 'm', params.r_rp_m, new_r_rp, index['pin_radius']),
        Modification('shifting tooth profile modification', 'delta_r_p', 'm',
                     params.delta_r_p_m, new_shift, index['shifting_mod_error']),
        Modification('modification of cumulative error of circumference', 'delta_delta_8',
                     'm', params.cumulative_mod_m, new_cum, index['cumulative_pitch']),
    )
    paper_shares = te_shares_rad(params, PAPER_TABLE6['te_total_arcmin'] / ARCMIN_PER_RAD)
    paper_eq27 = eq27_errors_m(params, paper_shares)
    details: dict[str, Any] = {
        'te_shares_rad': shares,
        'eq27_errors_m': errors,
        'scale': scale,
        'eq27_change_per_unit_index_m': per_index_eq27,
        'paper_table6': {k: v for k, v in PAPER_TABLE6.items() if k != 'change_m'}
        | {'change_m': dict(PAPER_TABLE6['change_m'])},
        'eq27_for_paper_te_m': paper_eq27,
        'table6_over_eq27': abs(PAPER_TABLE6['change_m']['pin_radius'] / paper_eq27['pin_radius']),
        'k1_prime_before': params.k1_prime,
        'k1_prime_after': after.k1_prime,
        'ambiguity': ('Hu 2020 Eq. 27 as written gives ~1/3.45 of the Table 6 changes for the '
                      'same TE; '
                      'the shifting modification is moved towards zero as in Table 6, the '
                      'opposite sign of the Hu 2020 Eq. 27 error. See module docstring.'),
    }
    if with_tca:
        try:
            details['tca_before'] = tooth_contact_analysis(params).summary()
            details['tca_after'] = tooth_contact_analysis(after).summary()
        except ModelInputError as exc:
            raise CompensationError(f'tooth contact analysis failed: {exc}') from None
    try:
        beta_before = -float(elastic_te_rad(params, params.torque_nm))
        beta_after = -float(elastic_te_rad(after, after.torque_nm))
    except ModelInputError as exc:
        raise CompensationError(f'tooth contact analysis failed: {exc}') from None
    elastic_before, elastic_after = 2.0 * beta_before, 2.0 * beta_after
    geometric = max(te_rad - elastic_before, 0.0)
    te_after = (1.0 - fraction) * geometric + elastic_after
    details |= {
        'load_case': load_case, 'torque_nm': params.torque_nm,
        'elastic_beta_before_rad': beta_before, 'elastic_beta_after_rad': beta_after,
        'elastic_pp_before_rad': elastic_before, 'elastic_pp_after_rad': elastic_after,
        'geometric_part_rad': geometric,
        'te_after_linear_model_rad': (1.0 - fraction) * te_rad,
        'prediction': ('TE_after = (1 - fraction) * G + E_after: the linear model (Hu 2020 Eq. 23) '
                       'removes the geometric part G = TE - E_before; the elastic part E '
                       '(disc rotation delta_max / r_c\' of the TCA, x2 for a reversing '
                       'load) follows the TCA of the new geometry'),
    }
    summary = (f'[{scale}] assign {fraction:.0%} of the TE to r_rp, delta_r_p, delta_delta_8 '
               '(Hu 2020 Eq. 27): '
               f'r_rp {params.r_rp_m * 1e3:.4f} -> {new_r_rp * 1e3:.4f} mm, delta_r_p '
               f'{params.delta_r_p_m * 1e3:.4f} -> {new_shift * 1e3:.4f} mm, '
               f'delta_delta_8 {params.cumulative_mod_m * 1e3:.4f} -> {new_cum * 1e3:.4f} mm')
    return Advice(method='tooth-profile', preset=preset, summary=summary, te_metric=te_metric,
                  te_before_rad=float(te_rad), te_after_rad=float(te_after),
                  modifications=mods, details=details)


def compensate_preset(preset: Preset, te_rad: float, *, fraction: float = 1.0,
                      scale: str = 'eq27', te_metric: str = 'pp',
                      with_tca: bool = True, load_case: str = 'reversing') -> Advice:
    """:func:`tooth_profile_compensation` for a hu2020-rv preset (overrides applied).

    Raises:
        CompensationError: The preset is not a valid Hu 2020 RV stage (the message names
            the key and value, e.g. K1' >= 1), or any error of the compensation itself.
    """
    _check_te(te_rad, fraction)
    try:
        params = HuRvParams.from_preset(preset)
    except PresetError as exc:
        msg = f'preset {preset.name!r}: {exc}'
        raise CompensationError(msg) from None
    return tooth_profile_compensation(params, te_rad, preset=preset.name, fraction=fraction,
                                      scale=scale, te_metric=te_metric, with_tca=with_tca,
                                      load_case=load_case)


#: Name used by the compensation node and the offline report.
tooth_profile_advice = compensate_preset
