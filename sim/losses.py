"""Power losses of a reducer: the input torque a bench needs, efficiency, starting and
back-driving torque (vectorised over samples, SI units).

Every torque of this module is referred to the **input shaft** unless its name says
otherwise; the load is the bench's output torque in the bench convention (``load_nm > 0``
resists positive rotation). With the input speed ``w`` (sign ``s``), the ratio ``i`` and
``T_res = s * load_nm`` (> 0: the load absorbs power, forward power flow; < 0: the load
drives the gear, reverse power flow) the steady input torque is

    T_in = s * ( T_res / i  +  f_z |T_res| / i  +  T_b1  +  T_drag )  +  J_in dw/dt

where each term is one loss with its own law and source:

* **Tooth contact** (load dependent): the mesh loses the fraction ``f_z`` of the power it
  carries, in either direction (ISO/TR 14179-2: P_VZP = P mu_mz H_V). The mean friction
  coefficient follows Schlenk's correlation quoted there,
  mu_mz ~ F_bt^0.2 v^-0.2 eta_oil^-0.05, hence
  ``f_z = f_ref (|T|/T_ref)^0.2 (|w|/w_ref)^-0.2 (nu/nu_ref)^-0.05``, capped at the
  boundary-friction value ``f_s`` (reached at low speed; also the static value). Forward
  efficiency of the mesh 1/(1 + f_z), backward 1 - f_z: the classical pair of a mechanism
  with a friction loss factor (self-locking when f >= 1).
* **Bearings** (Palmgren 1959, as in Harris & Kotzalas, *Rolling Bearing Analysis*):
  M = M0 + M1 on the crank bearings (``bearing_count`` of them), which turn at
  ``r_b = |crank_rel_per_input|`` times the input speed.
  M0 = 1e-7 f0 (nu n)^(2/3) dm^3 [N mm; nu mm^2/s, n rpm, dm mm] above
  nu n = 2000, 160e-7 f0 dm^3 below; the two branches are joined where they cross
  (nu n = 160^1.5 = 2024) so M0 is continuous. M1 = f1 P dm with the total bearing load
  P = k_P |T_load| (load dependent). Referred to the input: T_b = r_b M.
* **Churning** of the lubricant (speed and viscosity dependent): Changenet & Velex (2007,
  J. Mech. Des. 129:128) give C_m ~ Fr^-0.6 Re^-0.21 at low Reynolds number, i.e. a drag
  torque ~ w^0.59 nu^0.21: ``T_ch = T_ch_ref (|w|/w_ref)^0.59 (nu/nu_ref)^0.21``.
* **Seals**: a constant drag torque ``T_seal``.

``T_drag = T_b0 + T_ch + T_seal`` is the no-load running torque. The viscosity ``nu`` comes
from the case temperature through :class:`sim.lubricant.Lubricant` (ASTM D341).

At rest: the **starting torque** (quasi-static input torque at which rotation begins) is
``k_s (T_b0(0) + T_seal) + (1 + f_s) |T_load| / i + T_b1`` with the static-to-kinetic
ratio ``k_s`` and the boundary mesh loss ``f_s``; the **back-driving torque** (output
torque at which the output turns with the input free and unloaded) is the output torque
``T_bd`` that balances ``(1 - f_s) T_bd / i = k_s T_d0 + r_b f1 k_P dm T_bd``, infinite
when the gear self-locks. Churning vanishes at rest.

Energy balance (what :func:`loss_powers` returns and the tests check):
``T_in w - load w / i = P_mesh + P_b1 + P_b0 + P_churn + P_seal (+ J w dw/dt)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from sim._checks import Rule, real_number
from sim.errors import ModelInputError, PresetError
from sim.kinematics import kinematics_from_preset
from sim.lubricant import Lubricant
from sim.units import RAD_S_PER_RPM

if TYPE_CHECKING:
    import numpy.typing as npt

    from sim.presets import Preset

__all__ = [
    'LossModel',
    'LossParams',
    'LossPowers',
    'palmgren_m0_nm',
]

#: nu * n where Palmgren's two M0 branches cross [mm^2/s * rpm].
_PALMGREN_KNEE = 160.0 ** 1.5


def palmgren_m0_nm(nu_mm2_s: npt.ArrayLike, n_rpm: npt.ArrayLike, f0: float,
                   dm_m: float) -> np.ndarray:
    """Palmgren's load-independent bearing friction torque M0 [N m] (vectorised).

    ``1e-7 f0 (nu n)^(2/3) dm^3`` [N mm] with dm in mm, the low-speed branch
    ``160e-7 f0 dm^3`` where nu n is below 2024 (the branches' crossing).
    """
    x = np.maximum(np.asarray(nu_mm2_s, dtype=np.float64) * np.abs(n_rpm), _PALMGREN_KNEE)
    return 1e-7 * f0 * x ** (2.0 / 3.0) * (dm_m * 1e3) ** 3 * 1e-3


_RULES: dict[str, Rule] = {
    'gear_ratio': '>0', 'bearing_speed_ratio': '>=0', 'reference_speed_rpm': '>0',
    'reference_temp_degc': '', 'reference_torque_nm': '>0', 'mesh_loss_ref': '>=0',
    'mesh_load_exp': '', 'mesh_speed_exp': '', 'mesh_visc_exp': '', 'mesh_loss_static': '>=0',
    'bearing_f0': '>=0', 'bearing_count': '>0', 'bearing_dm_m': '>0', 'bearing_f1': '>=0',
    'bearing_load_n_per_nm': '>=0', 'churn_torque_ref_nm': '>=0', 'churn_speed_exp': '',
    'churn_visc_exp': '', 'seal_torque_nm': '>=0', 'static_to_kinetic': '>0',
    'inertia_in_kgm2': '>=0',
}


@dataclass(frozen=True)
class LossParams:
    """The ``[losses]`` section of a preset plus the ratio and crank speed (SI units).

    Attributes:
        gear_ratio: i (> 0), from the preset's kinematics.
        bearing_speed_ratio: r_b, crank-bearing speed per input speed (>= 0), from the
            kinematics (|crank_rel_per_input|).
        reference_speed_rpm: Input speed of the reference point w_ref [rpm], > 0.
        reference_temp_degc: Case temperature of the reference point [degC].
        reference_torque_nm: Output torque of the reference point T_ref [N m], > 0.
        mesh_loss_ref: f_ref, mesh loss factor at the reference point, >= 0.
        mesh_load_exp, mesh_speed_exp, mesh_visc_exp: Exponents of |T|, |w|, nu in f_z.
        mesh_loss_static: f_s, boundary/static mesh loss factor (cap of f_z), >= 0.
        bearing_f0: Palmgren f0, >= 0.
        bearing_count: Number of bearings of that size turning at r_b w (M0 each), > 0.
        bearing_dm_m: Bearing pitch diameter dm [m], > 0.
        bearing_f1: Palmgren f1, >= 0.
        bearing_load_n_per_nm: k_P, bearing load per output torque [N/(N m)], >= 0.
        churn_torque_ref_nm: T_ch_ref, churning torque at the reference point [N m], >= 0.
        churn_speed_exp, churn_visc_exp: Exponents of |w| and nu in the churning torque.
        seal_torque_nm: T_seal [N m], >= 0.
        static_to_kinetic: k_s, breakaway over running drag at zero speed, >= 1.
        inertia_in_kgm2: J_in, inertia referred to the input [kg m^2], >= 0.
    """

    gear_ratio: float
    bearing_speed_ratio: float
    reference_speed_rpm: float
    reference_temp_degc: float
    reference_torque_nm: float
    mesh_loss_ref: float
    mesh_load_exp: float
    mesh_speed_exp: float
    mesh_visc_exp: float
    mesh_loss_static: float
    bearing_f0: float
    bearing_count: float
    bearing_dm_m: float
    bearing_f1: float
    bearing_load_n_per_nm: float
    churn_torque_ref_nm: float
    churn_speed_exp: float
    churn_visc_exp: float
    seal_torque_nm: float
    static_to_kinetic: float
    inertia_in_kgm2: float = 0.0

    def __post_init__(self) -> None:
        """Validate every field (ModelInputError names it and the rule)."""
        for f in fields(self):
            rule = _RULES[f.name]
            object.__setattr__(self, f.name, real_number(f'losses.{f.name}',
                                                         getattr(self, f.name), rule))
        if self.static_to_kinetic < 1.0:
            msg = f'losses.static_to_kinetic must be >= 1, got {self.static_to_kinetic!r}'
            raise ModelInputError(msg)
        if self.mesh_loss_static < self.mesh_loss_ref:
            msg = (f'losses.mesh_loss_static ({self.mesh_loss_static}) must be >= '
                   f'mesh_loss_ref ({self.mesh_loss_ref}): boundary friction caps the mesh')
            raise ModelInputError(msg)

    @classmethod
    def from_preset(cls, preset: Preset) -> LossParams:
        """Read ``losses.*`` and the kinematics of a preset.

        Raises:
            PresetError: The section is missing, a key is missing or unknown, or a value
                breaks its rule (the message names the key).
        """
        sec = preset.section('losses')
        if not sec:
            msg = f'preset {preset.name!r} has no [losses] section: it has no loss model'
            raise PresetError(msg)
        names = [f.name for f in fields(cls)]
        derived = {'gear_ratio', 'bearing_speed_ratio'}
        unknown = sorted(set(sec) - (set(names) - derived))
        if unknown:
            msg = (f'preset {preset.name!r}: unknown key losses.{unknown[0]}; expected '
                   f'{", ".join(n for n in names if n not in derived)}')
            raise PresetError(msg)
        missing = [n for n in names if n not in derived | {'inertia_in_kgm2'} and n not in sec]
        if missing:
            msg = f'preset {preset.name!r} has no losses.{missing[0]}'
            raise PresetError(msg)
        kin = kinematics_from_preset(preset)
        try:
            return cls(gear_ratio=float(kin.gear_ratio),
                       bearing_speed_ratio=abs(float(kin.crank_rel_per_input)),
                       **{k: sec[k] for k in names if k in sec})
        except ModelInputError as exc:
            msg = f'preset {preset.name!r}: {exc}'
            raise PresetError(msg) from None




class LossPowers(NamedTuple):
    """Power of each loss [W] (>= 0), same shape as the samples."""

    mesh_w: np.ndarray
    bearing_load_w: np.ndarray
    bearing_drag_w: np.ndarray
    churn_w: np.ndarray
    seal_w: np.ndarray

    @property
    def total_w(self) -> np.ndarray:
        """Sum of the losses [W]."""
        total: npt.NDArray[np.float64] = self.mesh_w + self.bearing_load_w + self.bearing_drag_w \
            + self.churn_w + self.seal_w
        return total


def _arr(name: str, x: npt.ArrayLike) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if not np.isfinite(a).all():   # (the method: np.all's wrapper costs more, per block)
        msg = f'{name} must be finite (NaN or inf found)'
        raise ModelInputError(msg)
    return a


class LossModel:
    """The losses of one reducer with one lubricant (see the module docstring).

    Args:
        params: The loss parameters.
        lubricant: The lubricant whose viscosity follows the case temperature.
    """

    def __init__(self, params: LossParams, lubricant: Lubricant) -> None:
        """Store the parameters and the reference viscosity."""
        if not isinstance(params, LossParams) or not isinstance(lubricant, Lubricant):
            msg = (f'LossModel needs LossParams and Lubricant, got {type(params).__name__}, '
                   f'{type(lubricant).__name__}')
            raise ModelInputError(msg)
        self.params = params
        self.lubricant = lubricant
        self.nu_ref_mm2_s = float(lubricant.viscosity_mm2_s(params.reference_temp_degc))
        self.w_ref_rad_s = params.reference_speed_rpm * RAD_S_PER_RPM
        p = params
        #: input-referred load-dependent bearing torque per N m of output torque
        self.bearing_load_coef = p.bearing_speed_ratio * p.bearing_f1 * p.bearing_load_n_per_nm \
            * p.bearing_dm_m

    @classmethod
    def from_preset(cls, preset: Preset) -> LossModel:
        """Build from ``[losses]``, ``[lubricant]`` and the kinematics of a preset."""
        return cls(LossParams.from_preset(preset), Lubricant.from_preset(preset))

    # -- the laws ---------------------------------------------------------------------------
    def viscosity_mm2_s(self, temp_case_degc: npt.ArrayLike) -> np.ndarray:
        """Lubricant viscosity at the case temperature [mm^2/s]."""
        return self.lubricant.viscosity_mm2_s(temp_case_degc)

    def mesh_loss_factor(self, omega_in_rad_s: npt.ArrayLike, load_nm: npt.ArrayLike,
                         nu_mm2_s: npt.ArrayLike) -> np.ndarray:
        """f_z, fraction of the mesh power lost (Schlenk exponents, capped at f_s)."""
        p = self.params
        w = np.abs(_arr('omega_in_rad_s', omega_in_rad_s))
        t = np.abs(_arr('load_nm', load_nm))
        nu = _arr('nu_mm2_s', nu_mm2_s)
        with np.errstate(divide='ignore', invalid='ignore'):   # 0 load at w = 0: 0 * inf
            f = p.mesh_loss_ref * (t / p.reference_torque_nm) ** p.mesh_load_exp \
                * (w / self.w_ref_rad_s) ** p.mesh_speed_exp \
                * (nu / self.nu_ref_mm2_s) ** p.mesh_visc_exp
        f_mesh: npt.NDArray[np.float64] = np.minimum(
            np.nan_to_num(f, nan=p.mesh_loss_static, posinf=p.mesh_loss_static),
            p.mesh_loss_static)
        return f_mesh

    def bearing_drag_nm(self, omega_in_rad_s: npt.ArrayLike,
                        nu_mm2_s: npt.ArrayLike) -> np.ndarray:
        """Palmgren M0 of the crank bearings, referred to the input [N m]."""
        p = self.params
        n_b = np.abs(_arr('omega_in_rad_s', omega_in_rad_s)) / RAD_S_PER_RPM \
            * p.bearing_speed_ratio
        return p.bearing_speed_ratio * p.bearing_count * palmgren_m0_nm(
            nu_mm2_s, n_b, p.bearing_f0, p.bearing_dm_m)

    def churn_nm(self, omega_in_rad_s: npt.ArrayLike, nu_mm2_s: npt.ArrayLike) -> np.ndarray:
        """Churning drag at the input [N m] (Changenet-Velex exponents)."""
        p = self.params
        w = np.abs(_arr('omega_in_rad_s', omega_in_rad_s))
        churn: npt.NDArray[np.float64] = p.churn_torque_ref_nm \
            * (w / self.w_ref_rad_s) ** p.churn_speed_exp \
            * (_arr('nu_mm2_s', nu_mm2_s) / self.nu_ref_mm2_s) ** p.churn_visc_exp
        return churn

    def no_load_torque_nm(self, omega_in_rad_s: npt.ArrayLike,
                          temp_case_degc: npt.ArrayLike) -> np.ndarray:
        """No-load running torque T_drag at the input [N m] (>= 0, for |w| > 0)."""
        nu = self.viscosity_mm2_s(temp_case_degc)
        drag: npt.NDArray[np.float64] = self.bearing_drag_nm(omega_in_rad_s, nu) \
            + self.churn_nm(omega_in_rad_s, nu) \
            + self.params.seal_torque_nm
        return drag

    # -- running ----------------------------------------------------------------------------
    def _terms(self, w: np.ndarray, load: np.ndarray, temp: npt.ArrayLike
               ) -> tuple[np.ndarray, ...]:
        nu = self.viscosity_mm2_s(temp)
        f = self.mesh_loss_factor(w, load, nu)
        b1 = self.bearing_load_coef * np.abs(load)
        b0 = self.bearing_drag_nm(w, nu)
        ch = self.churn_nm(w, nu)
        return f, b1, b0, ch

    def input_torque_nm(self, omega_in_rad_s: npt.ArrayLike, load_nm: npt.ArrayLike,
                        temp_case_degc: npt.ArrayLike, *,
                        alpha_in_rad_s2: npt.ArrayLike = 0.0) -> np.ndarray:
        """Input torque the drive must give [N m] (signed like the motion; vectorised).

        Samples at w == 0 carry no loss (a held shaft): T_in = load / i there (see
        :meth:`starting_torque_nm` for the breakaway).

        Args:
            omega_in_rad_s: Input speed [rad/s].
            load_nm: Output load torque, bench convention [N m].
            temp_case_degc: Case temperature [degC] (scalar or per sample).
            alpha_in_rad_s2: Input acceleration [rad/s^2] (inertia term J_in alpha).
        """
        w = _arr('omega_in_rad_s', omega_in_rad_s)
        load = _arr('load_nm', load_nm)
        w, load = np.broadcast_arrays(w, load)
        return self._input_torque(w, load, self._terms(w, load, temp_case_degc),
                                  alpha_in_rad_s2)

    def _input_torque(self, w: np.ndarray, load: np.ndarray, terms: tuple[np.ndarray, ...],
                      alpha_in_rad_s2: npt.ArrayLike) -> np.ndarray:
        i = self.params.gear_ratio
        s = np.sign(w)
        t_res = s * load
        f, b1, b0, ch = terms
        mag = t_res / i + f * np.abs(t_res) / i + b1 + b0 + ch + self.params.seal_torque_nm
        t_in = np.where(s == 0.0, load / i, s * mag)
        return t_in + self.params.inertia_in_kgm2 * _arr('alpha_in_rad_s2', alpha_in_rad_s2)

    def loss_powers(self, omega_in_rad_s: npt.ArrayLike, load_nm: npt.ArrayLike,
                    temp_case_degc: npt.ArrayLike) -> LossPowers:
        """Power of each loss [W] at the samples (0 where w == 0)."""
        w = _arr('omega_in_rad_s', omega_in_rad_s)
        load = _arr('load_nm', load_nm)
        w, load = np.broadcast_arrays(w, load)
        return self._powers(w, self._terms(w, load, temp_case_degc), load)

    def running(self, omega_in_rad_s: npt.ArrayLike, load_nm: npt.ArrayLike,
                temp_case_degc: npt.ArrayLike, *, alpha_in_rad_s2: npt.ArrayLike = 0.0,
                ) -> tuple[np.ndarray, LossPowers]:
        """(:meth:`input_torque_nm`, :meth:`loss_powers`) of the same samples, the loss
        terms computed once (a bench block needs both)."""
        w = _arr('omega_in_rad_s', omega_in_rad_s)
        load = _arr('load_nm', load_nm)
        w, load = np.broadcast_arrays(w, load)
        terms = self._terms(w, load, temp_case_degc)
        return (self._input_torque(w, load, terms, alpha_in_rad_s2),
                self._powers(w, terms, load))

    def _powers(self, w: np.ndarray, terms: tuple[np.ndarray, ...],
                load: np.ndarray) -> LossPowers:
        f, b1, b0, ch = terms
        aw = np.abs(w)
        return LossPowers(
            mesh_w=f * np.abs(load) / self.params.gear_ratio * aw,
            bearing_load_w=b1 * aw, bearing_drag_w=b0 * aw, churn_w=ch * aw,
            seal_w=self.params.seal_torque_nm * aw * (aw > 0))

    def efficiency(self, omega_in_rad_s: npt.ArrayLike, load_nm: npt.ArrayLike,
                   temp_case_degc: npt.ArrayLike) -> np.ndarray:
        """Steady forward efficiency P_out / P_in (load resisting the motion, w != 0)."""
        w = _arr('omega_in_rad_s', omega_in_rad_s)
        load = _arr('load_nm', load_nm)
        t_in = self.input_torque_nm(w, load, temp_case_degc)
        with np.errstate(divide='ignore', invalid='ignore'):
            eff: npt.NDArray[np.float64] = (load * w / self.params.gear_ratio) / (t_in * w)
            return eff

    # -- at rest ----------------------------------------------------------------------------
    def _static_drag_nm(self) -> float:
        """Running drag at zero speed without churning: Palmgren low branch + seals."""
        p = self.params
        m0 = float(palmgren_m0_nm(0.0, 0.0, p.bearing_f0, p.bearing_dm_m))
        return p.bearing_speed_ratio * p.bearing_count * m0 + p.seal_torque_nm

    def starting_torque_nm(self, load_nm: npt.ArrayLike = 0.0) -> np.ndarray:
        """Input torque at which rotation begins, against a resisting output load [N m]."""
        p = self.params
        t = np.abs(_arr('load_nm', load_nm))
        breakaway: npt.NDArray[np.float64] = p.static_to_kinetic * self._static_drag_nm() \
            + (1.0 + p.mesh_loss_static) * t / p.gear_ratio + self.bearing_load_coef * t
        return breakaway

    def back_driving_torque_nm(self) -> float:
        """Output torque at which the output turns, input free and unloaded [N m]
        (``inf`` when the gear self-locks)."""
        p = self.params
        denom = (1.0 - p.mesh_loss_static) / p.gear_ratio - self.bearing_load_coef
        if denom <= 0.0:
            return math.inf
        return p.static_to_kinetic * self._static_drag_nm() / denom
