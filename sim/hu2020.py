"""Hu 2020 RV reducer: cycloid geometry, geometric TE factors, error sensitivity, TCA.

Hu, Li, Zhu, Cui, "An elastic transmission error compensation method for rotary vector
speed reducers based on error sensitivity analysis", Appl. Sci. 10 (2020) 481.

* Cycloid tooth profile with isometric (``delta_r_rp``) and shifting (``delta_r_p``)
  modification, Hu 2020 Eqs 1-4; ``K1' = a z_p / (r_p + delta_r_p)`` (0.78993 for Table 3).
* The nine geometric error factors of s.2.2 (Hu 2020 Eqs 5-14): TE per unit error
  ``g_j = A_jj / (a z_c)`` with ``A`` the matrix of Hu 2020 Eq. 24 (= 2 x the Table 2 coefficients),
  except the eccentricity (Hu 2020 Eq. 13: ``-2 k_n``). Sensitivity index
  ``S_j = coefficient_j / sqrt(1 - K1'^2)`` reproduces Table 2 (DESIGN.md s.4).
* A geometric TE model for the bench: each factor is a sinusoidal error of given amplitude
  and phase that excites one order of the output rotation (see :data:`FACTOR_ORDER`):
  the mesh zone follows the eccentric direction, i.e. the absolute crank angle (``z_c``
  turns per output turn, ``crank``), so once-around errors of the fixed pin ring appear at
  the crank order; relative to the cycloid disc the mesh zone turns ``z_p`` times per output
  turn (``crank_rel``), so once-around errors of the disc appear there; errors that repeat
  at every pin appear at the pin-mesh order ``z_p z_c``. The crank eccentricity error is
  put at the crank order. No factor of the paper excites the output order itself (the pin
  ring is fixed).
* Tooth contact analysis (Hu 2020 Eqs 28-48): paper's fixed-point iteration for the maximum contact
  force, the pins in mesh and the normal deformation per pin.
* Elastic TE (issue #18): under the torque T_c the loaded cycloid disc turns by
  ``beta = delta_max / r_c'`` against the pins (Hu 2020 Eqs 35-37), and the output with it:
  TE_el = -sign(T) delta_max(|T|) / r_c' (:func:`elastic_te_rad`; mode ``'elastic'`` of the
  TE model adds it to the geometric TE at the live load). It is a load-dependent offset:
  it enters a TE peak-to-peak only where the load changes (2 beta for a full reversal).

Readings of the printed equations (the paper has OCR noise and typos), chosen so that the
paper's own numbers follow:

* Hu 2020 Eqs 1-2: ``a / (r_p + r_rp)`` is read ``a / (r_p + delta_r_p)`` (the standard modified
  cycloid; only then is the profile a closed tooth of the right root/tip radii).
* Hu 2020 Eq. 32: the second term carries ``delta_r_p`` (printed ``delta_r_rp``); it then
  vanishes at ``cos(phi) = K1`` (Hu 2020 Eq. 33). Section 4 uses ``K1 = a z_p / r_p`` (no prime) and
  ``r_c' = a z_c``. Pins sit at ``phi_i = 2 pi i / z_p`` from the line of centres; a pin is in
  mesh when ``delta_i = (l_i / r_c') delta_max > Delta_i`` and ``l_i > 0``. With these, the
  initial prototype meshes on the 9 pins at 18..90 deg, as Table 5 (whose ``delta_i`` are
  exactly ``(l_i / r_c') delta_max`` at those angles).
* Hu 2020 Eq. 45 is ``|F_1 - F_2| / 2`` (as printed it is negative) with ``F_1 = 2.2 T / (z_c r_p)``
  and ``F_2 = 0.55 T / r_p`` (``r_p' = r_p``).
* E, Poisson ratio, torque and face width are not given; the presets state the values used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
import numpy.typing as npt

from sim.errors import ModelInputError, PresetError
from sim.kinematics import kinematics_from_preset

if TYPE_CHECKING:
    from sim.kinematics import ReducerKinematics
    from sim.presets import Preset

__all__ = [
    'FACTOR_KEYS',
    'FACTOR_ORDER',
    'HuGeometricTeModel',
    'HuRvParams',
    'SensitivityRow',
    'TcaResult',
    'TcaSummary',
    'build_te_model',
    'cycloid_profile_m',
    'elastic_te_rad',
    'error_gains_rad_per_m',
    'factor_orders',
    'max_contact_force_n',
    'max_deformation_m',
    'modification_te_rad',
    'sensitivity_table',
    'tooth_contact_analysis',
]

# Preset keys of the parameters (messages name them).
_KEYS = {
    'r_p_m': 'geometry.r_p_m', 'r_rp_m': 'geometry.r_rp_m', 'a_m': 'geometry.a_m',
    'delta_r_rp_m': 'geometry.delta_r_rp_m', 'delta_r_p_m': 'geometry.delta_r_p_m',
    'cumulative_mod_m': 'geometry.cumulative_mod_m', 'e_pa': 'material.e_pa',
    'poisson': 'material.poisson', 'face_width_m': 'tca.face_width_m',
    'torque_nm': 'tca.torque_nm', 'load_share': 'tca.load_share',
    'z_c': 'kinematics.z_gear', 'z_p': 'kinematics.z_ring',
}


@dataclass(frozen=True)
class HuRvParams:
    """Cycloid-pin stage of an RV reducer (SI units), validated on construction.

    Attributes:
        z_c: Cycloid teeth.
        z_p: Number of pins (``z_c + 1``).
        r_p_m: Pin-circle (pinwheel centre circle) radius [m].
        r_rp_m: Pin radius [m].
        a_m: Eccentricity [m].
        delta_r_rp_m: Isometric tooth-profile modification [m] (Table 3: -0.022 mm).
        delta_r_p_m: Shifting tooth-profile modification [m] (Table 3: -0.0437 mm).
        cumulative_mod_m: Modification of the cumulative circumference error [m] (Table 6).
        e_pa: Elastic modulus of cycloid and pins [Pa].
        poisson: Poisson ratio [1].
        face_width_m: Cycloid face width b [m].
        torque_nm: Output torque T used by the TCA [N m].
        load_share: Share of T on the more loaded cycloid disc (Hu 2020 Eq. 31: 0.55).
    """

    z_c: int
    z_p: int
    r_p_m: float
    r_rp_m: float
    a_m: float
    delta_r_rp_m: float = 0.0
    delta_r_p_m: float = 0.0
    cumulative_mod_m: float = 0.0
    e_pa: float = 2.06e11
    poisson: float = 0.3
    face_width_m: float = 0.011
    torque_nm: float = 1094.0
    load_share: float = 0.55

    def __post_init__(self) -> None:
        """Check every value; the message names the preset key and the rule.

        Raises:
            PresetError: Non-finite value, non-positive size, z_p != z_c + 1, K1' >= 1 ...
        """
        for name in ('z_c', 'z_p'):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v <= 0:
                msg = f'{_KEYS[name]} must be a positive integer, got {v!r}'
                raise PresetError(msg)
        if self.z_p != self.z_c + 1:
            msg = (f'{_KEYS["z_p"]} ({self.z_p}) must be {_KEYS["z_c"]} + 1 ({self.z_c + 1}) '
                   'for a cycloid-pin stage')
            raise PresetError(msg)
        for name in _KEYS:
            if name in ('z_c', 'z_p'):
                continue
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v):
                msg = f'{_KEYS[name]} must be a finite number, got {v!r}'
                raise PresetError(msg)
        for name in ('r_p_m', 'r_rp_m', 'a_m', 'e_pa', 'face_width_m', 'torque_nm'):
            if getattr(self, name) <= 0:
                msg = f'{_KEYS[name]} must be > 0, got {getattr(self, name)!r}'
                raise PresetError(msg)
        if not 0.0 <= self.poisson < 0.5:
            msg = f'{_KEYS["poisson"]} must be in [0, 0.5), got {self.poisson!r}'
            raise PresetError(msg)
        if not 0.0 < self.load_share <= 1.0:
            msg = f'{_KEYS["load_share"]} must be in (0, 1], got {self.load_share!r}'
            raise PresetError(msg)
        if self.r_rp_m + self.delta_r_rp_m <= 0 or self.r_p_m + self.delta_r_p_m <= 0:
            msg = (f'modified radii must stay > 0: r_rp + delta_r_rp = '
                   f'{self.r_rp_m + self.delta_r_rp_m!r} m, r_p + delta_r_p = '
                   f'{self.r_p_m + self.delta_r_p_m!r} m')
            raise PresetError(msg)
        k1p = self.k1_prime
        if not k1p < 1.0:
            msg = (f"K1' = a z_p / (r_p + delta_r_p) = {self.a_m!r} * {self.z_p} / "
                   f'({self.r_p_m!r} + {self.delta_r_p_m!r}) = {k1p:.6g} must be < 1 '
                   f'(check {_KEYS["a_m"]}, {_KEYS["r_p_m"]}, {_KEYS["delta_r_p_m"]})')
            raise PresetError(msg)

    @property
    def k1_prime(self) -> float:
        """Short-amplitude coefficient after shifting modification, Hu 2020 Eq. 3 [1]."""
        return self.a_m * self.z_p / (self.r_p_m + self.delta_r_p_m)

    @property
    def k1(self) -> float:
        """Short-amplitude coefficient without modification, ``a z_p / r_p`` [1]."""
        return self.a_m * self.z_p / self.r_p_m

    @property
    def r_c_m(self) -> float:
        """Cycloid pitch radius ``r_c' = a z_c`` [m] (the maximum force arm, Hu 2020 Eq. 29)."""
        return self.a_m * self.z_c

    @classmethod
    def from_preset(cls, preset: Preset) -> HuRvParams:
        """Build from a preset with ``[kinematics]``, ``[geometry]``, ``[material]``, ``[tca]``.

        Raises:
            PresetError: A key is missing or a value breaks a rule (named in the message).
        """
        kin = kinematics_from_preset(preset)
        if kin.kind != 'rv':
            msg = f'preset {preset.name!r}: kinematics.kind must be "rv", got {kin.kind!r}'
            raise PresetError(msg)
        kw: dict[str, Any] = {'z_c': kin.z_gear, 'z_p': kin.z_ring}
        optional = {'cumulative_mod_m', 'e_pa', 'poisson', 'face_width_m', 'torque_nm',
                    'load_share'}
        for name, key in _KEYS.items():
            if name in kw:
                continue
            if key in preset.values:
                kw[name] = preset[key]
            elif name not in optional:
                msg = f'preset {preset.name!r} has no key {key!r}'
                raise PresetError(msg)
        return cls(**kw)

    def replace(self, **changes: Any) -> HuRvParams:
        """Copy with some fields changed (validated again)."""
        kw = {f: getattr(self, f) for f in self.__dataclass_fields__}
        kw.update(changes)
        return HuRvParams(**kw)


# ----------------------------------------------------------------------------- geometry


def cycloid_profile_m(params: HuRvParams, phi_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Modified cycloid tooth profile, Hu 2020 Eqs 1-4, in the cycloid frame O_c-x_c y_c.

    Args:
        params: Stage parameters.
        phi_rad: Meshing phase angle(s) phi [rad]; 0..2 pi traces one tooth.

    Returns:
        ``(x_m, y_m)`` profile coordinates [m], same shape as ``phi_rad``.

    Examples:
        >>> p = HuRvParams(z_c=39, z_p=40, r_p_m=0.076, r_rp_m=0.003, a_m=0.0015)
        >>> x, y = cycloid_profile_m(p, np.array([0.0]))
        >>> round(float(x[0]) * 1e3, 6)   # root radius r_p - a - r_rp [mm]
        71.5
    """
    phi = np.asarray(phi_rad, dtype=np.float64)
    k = params.k1_prime
    i_h = params.z_p / params.z_c
    r_rp = params.r_rp_m + params.delta_r_rp_m
    inv_s = (1.0 + k * k - 2.0 * k * np.cos(phi)) ** -0.5                       # Hu 2020 Eq. 4
    outer = params.r_p_m + params.delta_r_p_m - r_rp * inv_s
    inner = params.a_m - k * r_rp * inv_s        # a/(r_p+dr_p) * [r_p+dr_p - z_p r_rp Phi]
    x = outer * np.cos((1.0 - i_h) * phi) - inner * np.cos(i_h * phi)
    y = outer * np.sin((1.0 - i_h) * phi) + inner * np.sin(i_h * phi)
    return x, y


def modification_te_rad(params: HuRvParams) -> float:
    """Mean geometric TE of the tooth-profile modifications, Hu 2020 Eqs 5 + 6 [rad]."""
    s = math.sqrt(1.0 - params.k1_prime**2)
    az = params.a_m * params.z_c
    return 2.0 * params.delta_r_rp_m / az - 2.0 * params.delta_r_p_m * s / az


# -------------------------------------------------------------------- error sensitivity

#: The nine factors of Table 1/2 in the paper's order (keys of the ``[errors]`` section).
FACTOR_KEYS: tuple[str, ...] = (
    'pin_circle_radius', 'pin_radius', 'groove_clearance', 'cycloid_runout',
    'pin_housing_position', 'isometric_mod_error', 'shifting_mod_error', 'cumulative_pitch',
    'eccentricity')

_FACTOR_INFO = {  # key: (Table 2 name, symbol, equation)
    'pin_circle_radius': ('Pinwheel center circle radius error', 'delta_a', 'Hu 2020 Eq. 7'),
    'pin_radius': ('Pinwheel housing radius error (pin radius)', 'delta_b', 'Hu 2020 Eq. 8'),
    'groove_clearance': ('Pinwheel groove matching clearance', 'delta_c', 'Hu 2020 Eq. 9'),
    'cycloid_runout': ('Cycloidal gear ring radial runout', 'delta_d', 'Hu 2020 Eq. 10'),
    'pin_housing_position': ('Pinwheel housing circumferential position error', 'delta_e',
                             'Hu 2020 Eq. 11'),
    'isometric_mod_error': ('Isometric tooth profile modification error', 'delta_f',
                            'Hu 2020 Eq. 13'),
    'shifting_mod_error': ('Shifting tooth profile modification error', 'delta_g',
                           'Hu 2020 Eq. 13'),
    'cumulative_pitch': ('Cumulative error of circumference', 'delta_h', 'Hu 2020 Eq. 12'),
    'eccentricity': ('Eccentricity error', 'delta_i', 'Hu 2020 Eqs 13-14'),
}

#: Which order of the output rotation each factor excites in the geometric TE model:
#: ``'crank'`` absolute crank order (z_c per output turn), ``'crank_rel'`` crank order
#: relative to the carrier (z_p), ``'pin_mesh'`` pin-mesh order (z_p z_c).
FACTOR_ORDER: dict[str, str] = {
    'pin_circle_radius': 'crank',       # once-around out-of-roundness of the fixed pin ring
    'pin_radius': 'pin_mesh',           # repeats at every pin
    'groove_clearance': 'pin_mesh',     # repeats at every pin
    'cycloid_runout': 'crank_rel',      # once around the cycloid disc
    'pin_housing_position': 'crank',    # cumulative position error around the fixed ring
    'isometric_mod_error': 'pin_mesh',  # tooth profile error, every tooth
    'shifting_mod_error': 'pin_mesh',   # tooth profile error, every tooth
    'cumulative_pitch': 'crank_rel',    # cumulative pitch error around the disc
    'eccentricity': 'crank',            # crank eccentric
}


@dataclass(frozen=True)
class SensitivityRow:
    """One row of Table 2.

    Attributes:
        key: Factor key (``[errors]`` section).
        factor: Name as in Table 2.
        symbol: Table 2 symbol (``delta_a`` .. ``delta_i``).
        coefficient: Error coefficient of Table 2 [1]; the eccentricity row is ``k_n``
            of Hu 2020 Eq. 14 evaluated in mm, as the paper does [1/mm].
        sensitivity_index: ``coefficient / sqrt(1 - K1'^2)`` (eccentricity row [1/mm]).
            Hu 2020 Eq. 14 as printed gives +6.1e-4 for Table 3 where Table 2 prints -0.00024;
            both are negligible (< 0.1 % of the reference), the paper's conclusion.
        gain_rad_per_m: TE per unit error of the factor [rad/m] (Hu 2020 Eqs 5-13).
    """

    key: str
    factor: str
    symbol: str
    coefficient: float
    sensitivity_index: float
    gain_rad_per_m: float


def _k_n_per_mm(params: HuRvParams) -> float:
    """Hu 2020 Eq. 14 as printed, evaluated with lengths in mm (the paper's units) [1/mm].

    Hu 2020 Eq. 14 is not dimensionally consistent (its second term is in 1/length^2), so its value
    depends on the length unit; the paper works in mm, and so does this function.
    """
    a, rp = params.a_m * 1e3, params.r_p_m * 1e3
    d_rrp, d_rp = params.delta_r_rp_m * 1e3, params.delta_r_p_m * 1e3
    zc = params.z_c
    s = math.sqrt(1.0 - params.k1_prime**2)
    return d_rrp / (a * a * zc) - (zc * d_rp / (a * rp * rp * s) + d_rp * s / (a * a * zc))


def _coefficients(params: HuRvParams) -> dict[str, float]:
    k = params.k1_prime
    s = math.sqrt(1.0 - k * k)
    return {
        'pin_circle_radius': s, 'pin_radius': -1.0, 'groove_clearance': 0.5,
        'cycloid_runout': 0.25, 'pin_housing_position': k, 'isometric_mod_error': 1.0,
        'shifting_mod_error': -s, 'cumulative_pitch': -k / 2.0,
        'eccentricity': _k_n_per_mm(params),
    }


def error_gains_rad_per_m(params: HuRvParams) -> dict[str, float]:
    """TE per unit error of each factor, ``d(TE)/d(delta_j)`` [rad/m] (Hu 2020 Eqs 5-13).

    ``A_jj / (a z_c)`` with ``A`` of Hu 2020 Eq. 24; eccentricity ``-2 k_n`` (Hu 2020 Eq. 13).
    """
    az = params.a_m * params.z_c
    gains = {key: 2.0 * c / az for key, c in _coefficients(params).items()}
    gains['eccentricity'] = -2.0 * _k_n_per_mm(params) * 1e3  # [1/mm] -> [rad/m]
    return gains


def sensitivity_table(params: HuRvParams) -> list[SensitivityRow]:
    """Table 2: error coefficients and sensitivity indices of the nine factors.

    The reference (index 1) is the pin-circle radius error, whose coefficient is
    ``sqrt(1 - K1'^2)``.

    Examples:
        >>> p = HuRvParams(z_c=39, z_p=40, r_p_m=0.076, r_rp_m=0.003, a_m=0.0015,
        ...                delta_r_rp_m=-0.022e-3, delta_r_p_m=-0.0437e-3)
        >>> [round(r.sensitivity_index, 4) for r in sensitivity_table(p)][:3]
        [1.0, -1.6308, 0.8154]
    """
    coef = _coefficients(params)
    gains = error_gains_rad_per_m(params)
    ref = coef['pin_circle_radius']
    rows = []
    for key in FACTOR_KEYS:
        name, sym, _eq = _FACTOR_INFO[key]
        rows.append(SensitivityRow(key, name, sym, coef[key], coef[key] / ref, gains[key]))
    return rows


def factor_orders(kinematics: ReducerKinematics) -> dict[str, float]:
    """Order (per output revolution) excited by each factor, per :data:`FACTOR_ORDER`."""
    named = {
        'crank': kinematics.crank_per_output,
        'crank_rel': kinematics.crank_rel_per_output,
        'pin_mesh': kinematics.mesh_orders_out[-1],
    }
    return {key: named[FACTOR_ORDER[key]] for key in FACTOR_KEYS}


# ------------------------------------------------------------------- geometric TE model


class HuGeometricTeModel:
    """Geometric (+ elastic) TE of an RV reducer with manufacturing errors (TeModel protocol).

    ``TE(theta) = sum_j g_j delta_j cos(n_j theta_in / i + phase_j)`` with ``g_j`` from
    :func:`error_gains_rad_per_m`, ``n_j`` from :func:`factor_orders` (output orders) and the
    amplitudes ``delta_j`` [m] / phases [rad] of the ``[errors]`` preset section. Zero mean
    (the constant TE of the modifications is :func:`modification_te_rad`); load and speed do
    not enter (geometric model), unless ``elastic``: then the elastic TE of the TCA at the
    sample's load is added. Stateless, so blocks can come in any size.
    """

    def __init__(self, params: HuRvParams, kinematics: ReducerKinematics,
                 amplitudes_m: dict[str, float], phases_rad: dict[str, float], *,
                 elastic: bool = False) -> None:
        """Store the factor lines.

        Args:
            params: Stage parameters (for the gains and the TCA).
            kinematics: Reducer kinematics (ratio and orders).
            amplitudes_m: Error amplitude per factor key [m]; missing keys are 0.
            phases_rad: Phase per factor key [rad]; missing keys are 0.
            elastic: Add the elastic TE of the TCA at the live load (:func:`elastic_te_rad`).

        Raises:
            ModelInputError: Unknown factor key or non-finite value.
        """
        unknown = (set(amplitudes_m) | set(phases_rad)) - set(FACTOR_KEYS)
        if unknown:
            msg = f'unknown error factor(s) {sorted(unknown)}; known: {", ".join(FACTOR_KEYS)}'
            raise ModelInputError(msg)
        for key, v in [*amplitudes_m.items(), *phases_rad.items()]:
            if not math.isfinite(v):
                msg = f'error factor {key!r}: value must be finite, got {v!r}'
                raise ModelInputError(msg)
        self.params = params
        self.kinematics = kinematics
        self.elastic = elastic
        gains = error_gains_rad_per_m(params)
        orders = factor_orders(kinematics)
        self.orders: dict[str, float] = orders
        self.line_amplitude_rad: dict[str, float] = {
            k: gains[k] * float(amplitudes_m.get(k, 0.0)) for k in FACTOR_KEYS}
        self.phases_rad: dict[str, float] = {k: float(phases_rad.get(k, 0.0)) for k in FACTOR_KEYS}

    def components_rad(self, theta_in_rad: np.ndarray) -> dict[str, np.ndarray]:
        """TE contribution of each factor at the input angles [rad]."""
        th_out = np.asarray(theta_in_rad, dtype=np.float64) / self.kinematics.gear_ratio
        return {k: self.line_amplitude_rad[k] * np.cos(self.orders[k] * th_out
                                                       + self.phases_rad[k])
                for k in FACTOR_KEYS}

    def te_rad(self, t_s: np.ndarray, theta_in_rad: np.ndarray, omega_in_rad_s: np.ndarray,
               load_nm: np.ndarray) -> np.ndarray:
        """TE = theta_out - theta_in / i at the samples [rad].

        Args:
            t_s: Sample times [s], 1-D.
            theta_in_rad: Unwrapped input angle [rad], same shape.
            omega_in_rad_s: Input speed [rad/s] (unused by the geometric model).
            load_nm: Output load [N m] (unused by the geometric model).

        Raises:
            ModelInputError: Arrays not 1-D of one length, or non-finite input angle.
        """
        arrays = [np.asarray(x, dtype=np.float64)
                  for x in (t_s, theta_in_rad, omega_in_rad_s, load_nm)]
        if any(a.ndim != 1 for a in arrays) or len({a.shape for a in arrays}) != 1:
            shapes = [a.shape for a in arrays]
            msg = f'te_rad needs 1-D arrays of one length, got shapes {shapes}'
            raise ModelInputError(msg)
        th = arrays[1]
        if not np.all(np.isfinite(th)):
            msg = 'te_rad: theta_in_rad contains non-finite values'
            raise ModelInputError(msg)
        th_out = th / self.kinematics.gear_ratio
        amp = np.array([self.line_amplitude_rad[k] for k in FACTOR_KEYS])
        n = np.array([self.orders[k] for k in FACTOR_KEYS])
        ph = np.array([self.phases_rad[k] for k in FACTOR_KEYS])
        te: npt.NDArray[np.float64] = amp @ np.cos(np.outer(n, th_out) + ph[:, None])
        if self.elastic:
            te = te + elastic_te_rad(self.params, arrays[3])
        return te

    def reset(self) -> None:
        """Nothing to reset (stateless)."""


def build_te_model(preset: Preset, mode: str) -> HuGeometricTeModel:
    """Factory registered for ``model = "hu2020-rv"`` (see :mod:`sim.models`).

    Args:
        preset: A hu2020-rv preset; ``errors.<factor>_m`` amplitudes [m] and
            ``errors.<factor>_phase_deg`` phases [deg] (missing factors are 0).
        mode: ``'geometric'`` (load-free) or ``'elastic'`` (geometric + the TCA's elastic TE
            at the live load).

    Raises:
        PresetError: Unsupported mode, unknown ``errors.*`` key, or an invalid value.
    """
    if mode not in ('geometric', 'elastic'):
        msg = (f'preset {preset.name!r}: model hu2020-rv supports modes "geometric" and '
               f'"elastic", got {mode!r}')
        raise PresetError(msg)
    params = HuRvParams.from_preset(preset)
    kin = kinematics_from_preset(preset)
    amps: dict[str, float] = {}
    phases: dict[str, float] = {}
    for key, value in preset.section('errors').items():
        if key.endswith('_phase_deg') and key[:-len('_phase_deg')] in FACTOR_KEYS:
            phases[key[:-len('_phase_deg')]] = math.radians(float(value))
        elif key.endswith('_m') and key[:-2] in FACTOR_KEYS:
            amps[key[:-2]] = float(value)
        else:
            msg = (f'preset {preset.name!r}: unknown key errors.{key}; expected '
                   f'errors.<factor>_m / errors.<factor>_phase_deg with factor in '
                   f'{", ".join(FACTOR_KEYS)}')
            raise PresetError(msg)
    try:
        return HuGeometricTeModel(params, kin, amps, phases, elastic=mode == 'elastic')
    except ModelInputError as exc:
        raise PresetError(f'preset {preset.name!r}: {exc}') from None


# ----------------------------------------------------------------- tooth contact analysis


class TcaSummary(TypedDict):
    """:meth:`TcaResult.summary` (SI; the mesh arc None when no pin is in mesh)."""

    pins_in_mesh: int
    f_max_n: float
    delta_max_m: float
    iterations: int
    mesh_from_deg: float | None
    mesh_to_deg: float | None


@dataclass(frozen=True)
class TcaResult:
    """Result of the tooth contact analysis (Hu 2020 Eqs 28-48) for one cycloid disc.

    Per-pin arrays cover the pins on the loaded side (``0 < phi_i < pi``), ordered by angle.

    Attributes:
        f_max_n: Maximum contact force F_max (Hu 2020 Eq. 48) [N].
        delta_max_m: Maximum normal deformation delta_max at F_max (Hu 2020 Eq. 38) [m].
        pins_in_mesh: Number of pins in mesh.
        pin_angle_rad: Angle phi_i of each pin from the line of centres [rad].
        lever_arm_m: Normal distance l_i from the contact normal to O_c (Hu 2020 Eq. 36) [m].
        clearance_m: Initial normal clearance Delta(phi)_i of the modification (Hu 2020 Eq. 32) [m].
        deformation_m: Normal deformation delta_i = (l_i / r_c') delta_max (Hu 2020 Eq. 37) [m].
        force_n: Contact force F_i (Hu 2020 Eq. 41), 0 for pins not in mesh [N].
        in_mesh: Pin in mesh (delta_i > Delta_i).
        iterations: Iterations k of the paper's scheme until |F_k - F_k-1| <= 0.1 % F_k.
        history_n: F_max_0, F_max_1, ..., F_max_k [N].
        torque_cycloid_nm: Torque on the disc, T_c = load_share * T [N m].
        rho_m: Tooth curvature radius at phi_0 (Hu 2020 Eq. 40) [m].
    """

    f_max_n: float
    delta_max_m: float
    pins_in_mesh: int
    pin_angle_rad: np.ndarray
    lever_arm_m: np.ndarray
    clearance_m: np.ndarray
    deformation_m: np.ndarray
    force_n: np.ndarray
    in_mesh: np.ndarray
    iterations: int
    history_n: tuple[float, ...]
    torque_cycloid_nm: float
    rho_m: float

    def summary(self) -> TcaSummary:
        """JSON-friendly summary (SI, unit-suffixed keys)."""
        ang = np.degrees(self.pin_angle_rad[self.in_mesh])
        return {'pins_in_mesh': self.pins_in_mesh, 'f_max_n': self.f_max_n,
                'delta_max_m': self.delta_max_m, 'iterations': self.iterations,
                'mesh_from_deg': float(ang.min()) if ang.size else None,
                'mesh_to_deg': float(ang.max()) if ang.size else None}


def _delta_max_m(params: HuRvParams, f_n: float, rho_abs_m: float) -> float:
    """Hu 2020 Eqs 38-39: maximum normal deformation at contact force ``f_n`` [m]."""
    e, nu, b, r = params.e_pa, params.poisson, params.face_width_m, params.r_rp_m
    c = 4.99e-3 * math.sqrt(4.0 * (1 - nu * nu) * f_n * rho_abs_m * r
                            / (e * b * (rho_abs_m + r)))
    return 2.0 * f_n * (1 - nu * nu) / (math.pi * e * b) * (
        2.0 / 3.0 + math.log(16.0 * r * rho_abs_m / (c * c)))


@dataclass(frozen=True)
class _Pins:
    """Pins of the loaded side: angle, lever arm (Eq. 36), initial clearance (Eq. 32), and the
    tooth curvature radius at phi_0 (Eq. 40, signed)."""

    phi: np.ndarray
    lever: np.ndarray
    clearance: np.ndarray
    rho: float


def _pins(params: HuRvParams) -> _Pins:
    k = params.k1
    s = math.sqrt(1.0 - k * k)
    rc = params.r_c_m
    zp = params.z_p
    phi = 2.0 * np.pi * np.arange(1, (zp + 1) // 2) / zp
    phi = phi[np.sin(phi) > 1e-12]
    root = np.sqrt(1.0 + k * k - 2.0 * k * np.cos(phi))
    lever = rc * np.sin(phi) / root                                              # Hu 2020 Eq. 36
    clearance = (params.delta_r_rp_m * (1.0 - np.sin(phi) / root)
                 - params.delta_r_p_m * (1.0 - k * np.cos(phi) - s * np.sin(phi)) / root)  # 32
    cos0 = k                                                                     # Hu 2020 Eq. 33
    rho = (params.r_p_m * (1.0 + k * k - 2.0 * k * cos0) ** 1.5
           / (k * (zp + 1) * cos0 - (1.0 + zp * k * k)) + params.r_rp_m)           # Hu 2020 Eq. 40
    return _Pins(phi, lever, clearance, float(rho))


def max_deformation_m(params: HuRvParams, f_max_n: float) -> float:
    """Hu 2020 Eqs 38-40: maximum normal deformation delta_max at contact force F_max [m].

    Raises:
        ModelInputError: Force not finite and > 0.
    """
    f = float(f_max_n)
    if not (math.isfinite(f) and f > 0):
        msg = f'f_max_n must be finite and > 0, got {f_max_n!r}'
        raise ModelInputError(msg)
    return _delta_max_m(params, f, abs(_pins(params).rho))


def max_contact_force_n(params: HuRvParams, delta_max_m: float,
                        torque_nm: float | None = None) -> tuple[float, int]:
    """Hu 2020 Eq. 44 at a given delta_max: F_max and the number of pins in mesh.

    The pins in mesh are those with ``(l_i / r_c') delta_max > Delta_i`` (Hu 2020 Eqs 32, 37).

    Args:
        params: Stage parameters.
        delta_max_m: Maximum normal deformation [m] (> 0).
        torque_nm: Output torque T [N m] (T_c = load_share T); ``params.torque_nm`` if None.

    Raises:
        ModelInputError: Values not finite and > 0, or no pin closes its clearance.
    """
    t = params.torque_nm if torque_nm is None else float(torque_nm)
    d = float(delta_max_m)
    if not (math.isfinite(t) and t > 0 and math.isfinite(d) and d > 0):
        msg = f'torque_nm and delta_max_m must be finite and > 0, got {t!r}, {delta_max_m!r}'
        raise ModelInputError(msg)
    pins = _pins(params)
    rc = params.r_c_m
    mesh = pins.lever / rc * d > pins.clearance
    if not mesh.any():
        msg = (f'tooth contact analysis: at torque {t!r} N m no pin closes its initial '
               f'clearance (smallest {float(np.min(pins.clearance)):.3g} m); raise tca.torque_nm')
        raise ModelInputError(msg)
    lever, cl = pins.lever[mesh], pins.clearance[mesh]
    denom = float(np.sum((lever / rc - cl / d) * lever))
    return params.load_share * t / denom, int(mesh.sum())                         # Eq. 44


def tooth_contact_analysis(params: HuRvParams, torque_nm: float | None = None, *,
                           max_iter: int = 200) -> TcaResult:
    """Maximum contact force, pins in mesh and normal deformation (Hu 2020 s.4, Hu 2020 Eqs 28-48).

    The paper's iteration: start from F_max_0 (Hu 2020 Eqs 45-47), compute delta_max
    (Hu 2020 Eqs 38-40), the pins in mesh (delta_i > Delta_i, Hu 2020 Eqs 32, 37) and F_max_k
    (Hu 2020 Eq. 44) until ``|F_k - F_k-1| <= 0.1 % F_k``; F_max = (F_k + F_k-1) / 2
    (Hu 2020 Eq. 48). If the plain iteration oscillates, it is continued with averaging
    (damping 1/2).

    Args:
        params: Stage parameters (E, Poisson ratio, face width, load share used).
        torque_nm: Output torque T [N m]; ``params.torque_nm`` when None.
        max_iter: Iteration limit.

    Returns:
        The converged :class:`TcaResult`.

    Raises:
        ModelInputError: Torque not finite and > 0, or no convergence.
    """
    t = params.torque_nm if torque_nm is None else float(torque_nm)
    if not (math.isfinite(t) and t > 0):
        msg = f'torque_nm must be finite and > 0, got {torque_nm!r}'
        raise ModelInputError(msg)
    pins = _pins(params)
    phi, lever, clearance, rho = pins.phi, pins.lever, pins.clearance, pins.rho
    rho_abs = abs(rho)
    rc = params.r_c_m
    t_c = params.load_share * t

    def step(f_n: float) -> tuple[float, float, np.ndarray]:
        d_max = _delta_max_m(params, f_n, rho_abs)
        mesh = lever / rc * d_max > clearance
        if not mesh.any():
            msg = (f'tooth contact analysis: at torque {t!r} N m no pin closes its initial '
                   f'clearance (smallest {float(np.min(clearance)):.3g} m); raise tca.torque_nm')
            raise ModelInputError(msg)
        denom = float(np.sum((lever[mesh] / rc - clearance[mesh] / d_max) * lever[mesh]))
        return t_c / denom, d_max, mesh                                          # Hu 2020 Eq. 44

    f1 = 2.2 * t / (params.z_c * params.r_p_m)                                   # Hu 2020 Eq. 46
    f2 = params.load_share * t / params.r_p_m                                    # Hu 2020 Eq. 47
    f_prev = abs(f1 - f2) / 2.0                                                  # Hu 2020 Eq. 45
    history = [f_prev]
    damping = 1.0
    for it in range(1, max_iter + 1):
        f_new, _, _ = step(f_prev)
        f_new = f_prev + damping * (f_new - f_prev)
        history.append(f_new)
        if abs(f_new - f_prev) <= 1e-3 * f_new:
            f_max = 0.5 * (f_new + f_prev)                                       # Hu 2020 Eq. 48
            break
        if it == 50:
            damping = 0.5
        f_prev = f_new
    else:
        msg = f'tooth contact analysis did not converge in {max_iter} iterations (T={t} N m)'
        raise ModelInputError(msg)
    d_max = _delta_max_m(params, f_max, rho_abs)
    deformation = lever / rc * d_max                                             # Hu 2020 Eq. 37
    mesh = deformation > clearance
    force = np.where(mesh, (deformation - clearance) / d_max * f_max, 0.0)       # Hu 2020 Eq. 41
    for arr in (phi, lever, clearance, deformation, force, mesh):
        arr.setflags(write=False)
    return TcaResult(f_max_n=float(f_max), delta_max_m=float(d_max),
                     pins_in_mesh=int(mesh.sum()), pin_angle_rad=phi, lever_arm_m=lever,
                     clearance_m=clearance, deformation_m=deformation, force_n=force,
                     in_mesh=mesh, iterations=it, history_n=tuple(history),
                     torque_cycloid_nm=t_c, rho_m=float(rho))


_ELASTIC_POINTS = 40          # torques of the elastic-TE table, log-spaced


def _elastic_table(params: HuRvParams) -> tuple[np.ndarray, np.ndarray]:
    """beta = delta_max / r_c' [rad] of the TCA at torques from 0.1 % to 300 % of the preset's.

    Below the smallest torque where a TCA converges, beta falls linearly to 0 at T = 0.
    """
    torques = params.torque_nm * np.geomspace(1e-3, 3.0, _ELASTIC_POINTS)
    t_ok, beta = [0.0], [0.0]
    for t in torques:
        try:
            res = tooth_contact_analysis(params, float(t))
        except ModelInputError:
            continue
        t_ok.append(float(t))
        beta.append(res.delta_max_m / params.r_c_m)
    return np.array(t_ok), np.array(beta)


_ELASTIC_CACHE: dict[HuRvParams, tuple[np.ndarray, np.ndarray]] = {}


def elastic_te_rad(params: HuRvParams, torque_nm: np.ndarray | float) -> np.ndarray:
    """Elastic TE of the cycloid-pin stage under an output torque [rad] (Hu 2020 Eqs 35-44).

    The more loaded disc (T_c = load_share T) turns by ``beta = delta_max / r_c'`` against
    the pins (Hu 2020 Eq. 37: delta_i = l_i beta, delta_max = r_c' beta) with delta_max from the
    converged TCA (Hu 2020 Eqs 38-48); the output follows it: TE = -sign(T) beta(|T|) (a positive
    torque resists the motion, the output lags). Interpolated in a table of TCAs from 0.1 %
    to 300 % of the preset torque (linear above it); beyond 3x the preset torque it is
    extrapolated linearly.

    Args:
        params: Stage parameters (geometry, modifications, material, face width).
        torque_nm: Output torque(s) T [N m].

    Returns:
        TE [rad], shape of ``torque_nm``.

    Raises:
        ModelInputError: Non-finite torque.
    """
    t = np.asarray(torque_nm, dtype=np.float64)
    if not np.all(np.isfinite(t)):
        msg = 'torque_nm must be finite'
        raise ModelInputError(msg)
    table = _ELASTIC_CACHE.get(params)
    if table is None:
        if len(_ELASTIC_CACHE) > 16:
            _ELASTIC_CACHE.clear()
        table = _ELASTIC_CACHE[params] = _elastic_table(params)
    tt, bb = table
    mag = np.abs(t)
    beta = np.interp(mag, tt, bb)
    over = mag > tt[-1]
    if np.any(over):
        slope = (bb[-1] - bb[-2]) / (tt[-1] - tt[-2])
        beta = np.where(over, bb[-1] + slope * (mag - tt[-1]), beta)
    te: npt.NDArray[np.float64] = -np.sign(t) * beta
    return te
