"""Static torsion of a reducer with the input locked: backlash, stiffness, friction hysteresis.

The hysteresis test (GB/T 35089-2018; docs/ACCEPTANCE.md) locks the input and twists the
output with a torque. This module gives each preset's static torsion characteristic at a
locked input position, from the preset's own model:

* **Wang 2020 (2K-V)**: Wang 2020 Eq. 18 (``sim.wang2020.static_te_rad``) with the mesh stiffness k,
  the uneven load sharing of the two planet pairs and the time-varying backlash of
  Wang 2020 Eqs 7-9.
  A torque twisting the output forwards closes the tooth backs (Wang 2020 Eqs 3-4), a reverse torque
  loads the drive flanks; with both pairs in contact the stiffness is 2 k r_p^2.
* **Hu 2020 (RV)**: the load-deformation curve of the tooth contact analysis (Hu 2020 Eqs 28-48):
  the cycloid disc turns by beta = delta_max / r_c' (Hu 2020 Eq. 37) under the torque; the initial
  clearances of the tooth-profile modifications (Hu 2020 Eq. 32) give a free play of
  2 min_i(Delta_i / l_i) before the first pin touches.
* **Li 2023 (RV)**: the lumped-parameter stiffness of the quasi-static model
  (``Li2023DteModel.static_response``, output rotation under the torque, kinematic input
  angle held): linear, so the stiffness is one number.

Every preset has a ``[torsion]`` section (assumptions, with their reasons in the preset):
``rated_torque_nm`` (T_R of the test), ``friction_torque_nm`` (T_f, Coulomb friction in the
output path), ``clearance_rad`` (free play of the parts the model does not carry: crank
bearings, pin holes; added to the model's own) and ``series_stiffness_nm_rad`` (a compliance
in series with the model's, 0 = none).

**Friction hysteresis (stated assumption).** Real curves are loops even without backlash:
friction in the bearings and the pin contacts. Here one Coulomb element acts in parallel
with the elastic characteristic g(phi) (0 inside the free play): quasi-statically the output
sticks while |T - g(phi)| <= T_f and slides with T = g(phi) + T_f sign(dphi/dt). Under a
torque program this is the play operator phi_k = clip(phi_k-1, lo(T_k), hi(T_k)) with
lo(T) = min{phi: g(phi) >= T - T_f}, hi(T) = max{phi: g(phi) <= T + T_f}; under a position
program (constant-speed loading) T = g(phi) + T_f sign(dphi/dt).

The curve's closed-form catalogue values (:func:`expected_metrics`) are the truth the
measured metrics are tested against.

Angles: torsion angle of the output [rad], positive in the positive sense of rotation;
torque: applied to the output [N m], positive in the positive sense (a positive torque
twists the output positively). The bench's load convention is the opposite sign (a positive
load resists forward rotation): applied torque = -load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from sim.errors import ModelInputError, PresetError

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy.typing as npt

    from sim.presets import Preset

__all__ = [
    'ExpectedMetrics',
    'TorsionCurve',
    'TorsionParams',
    'expected_metrics',
    'torsion_curve',
]

#: Torque grid of the tabulated curves, as fractions of the largest torque.
_GRID_POINTS = 64
#: Curves are tabulated to this multiple of the rated torque (beyond: last slope).
_TORQUE_SPAN = 1.5


@dataclass(frozen=True)
class TorsionParams:
    """The ``[torsion]`` section of a preset (SI units).

    Attributes:
        rated_torque_nm: Rated torque T_R of the hysteresis test [N m], > 0.
        friction_torque_nm: Coulomb friction T_f [N m], 0 <= T_f < T_R / 2.
        clearance_rad: Free play added to the model's own [rad], >= 0.
        series_stiffness_nm_rad: Stiffness in series with the model's [N m/rad]; 0 = none.
    """

    rated_torque_nm: float
    friction_torque_nm: float = 0.0
    clearance_rad: float = 0.0
    series_stiffness_nm_rad: float = 0.0

    def __post_init__(self) -> None:
        """Validate (PresetError names the preset key and the rule)."""
        checks: tuple[tuple[str, Callable[[float], bool], str], ...] = (
            ('rated_torque_nm', lambda v: v > 0, '> 0'),
            ('friction_torque_nm', lambda v: 0 <= v < self.rated_torque_nm / 2,
             '>= 0 and < rated_torque_nm / 2'),
            ('clearance_rad', lambda v: v >= 0, '>= 0'),
            ('series_stiffness_nm_rad', lambda v: v >= 0, '>= 0 (0 = none)'))
        for name, ok, rule in checks:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                    or not ok(v):
                msg = f'torsion.{name} = {v!r}: must be a finite number {rule}'
                raise PresetError(msg)

    @classmethod
    def from_preset(cls, preset: Preset) -> TorsionParams:
        """Read ``torsion.*`` (``rated_torque_nm`` required).

        Raises:
            PresetError: The section or a value is missing or invalid.
        """
        sec = preset.section('torsion')
        if 'rated_torque_nm' not in sec:
            msg = (f'preset {preset.name!r} has no torsion.rated_torque_nm: its hysteresis '
                   'test needs a rated torque')
            raise PresetError(msg)
        known = {'rated_torque_nm', 'friction_torque_nm', 'clearance_rad',
                 'series_stiffness_nm_rad'}
        return cls(**{k: v for k, v in sec.items() if k in known})


@dataclass(frozen=True)
class TorsionCurve:
    """Static torsion characteristic at one locked input position.

    The output sits on the positive flank at centre + backlash/2 + d_pos(T_e) for an elastic
    torque T_e > 0, on the negative flank at centre - backlash/2 - d_neg(-T_e) for T_e < 0,
    and anywhere in between at T_e = 0.

    Attributes:
        torque_nm: Torque grid, 0 first, strictly increasing [N m].
        deflection_pos_rad: d_pos at those torques, 0 first, non-decreasing [rad].
        deflection_neg_rad: d_neg likewise (magnitudes) [rad].
        backlash_rad: Free play between the flanks [rad], >= 0.
        friction_torque_nm: T_f [N m], >= 0.
        centre_rad: Angle of the middle of the free play [rad] (the kinematic TE there).
    """

    torque_nm: np.ndarray = field(repr=False)
    deflection_pos_rad: np.ndarray = field(repr=False)
    deflection_neg_rad: np.ndarray = field(repr=False)
    backlash_rad: float
    friction_torque_nm: float
    centre_rad: float = 0.0

    def __post_init__(self) -> None:
        """Validate the tables (ModelInputError names the rule)."""
        t = np.asarray(self.torque_nm, dtype=np.float64)
        dp = np.asarray(self.deflection_pos_rad, dtype=np.float64)
        dn = np.asarray(self.deflection_neg_rad, dtype=np.float64)
        if t.ndim != 1 or t.size < 2 or t.shape != dp.shape or t.shape != dn.shape:
            msg = 'torque and deflection tables must be 1-D, of one length >= 2'
            raise ModelInputError(msg)
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(dp)) and np.all(np.isfinite(dn))):
            msg = 'torsion tables must be finite'
            raise ModelInputError(msg)
        if t[0] != 0 or np.any(np.diff(t) <= 0):
            msg = 'torque grid must start at 0 and increase strictly'
            raise ModelInputError(msg)
        for name, d in (('deflection_pos_rad', dp), ('deflection_neg_rad', dn)):
            if d[0] != 0 or np.any(np.diff(d) <= 0):
                msg = f'{name} must start at 0 and increase strictly with torque'
                raise ModelInputError(msg)
        for name in ('backlash_rad', 'friction_torque_nm', 'centre_rad'):
            v = float(getattr(self, name))
            if not math.isfinite(v) or (name != 'centre_rad' and v < 0):
                msg = f'{name} must be finite{"" if name == "centre_rad" else " and >= 0"}'
                raise ModelInputError(msg)
            object.__setattr__(self, name, v)
        for name, arr in (('torque_nm', t), ('deflection_pos_rad', dp),
                          ('deflection_neg_rad', dn)):
            arr = arr.copy()
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    # -- elastic characteristic -----------------------------------------------------------
    def deflection_rad(self, torque_nm: npt.ArrayLike, *, side: int) -> np.ndarray:
        """d_pos (side +1) or d_neg (side -1) at |torque| [rad]; the last slope beyond."""
        t = np.abs(np.asarray(torque_nm, dtype=np.float64))
        d = self.deflection_pos_rad if side > 0 else self.deflection_neg_rad
        out = np.interp(t, self.torque_nm, d)
        slope = (d[-1] - d[-2]) / (self.torque_nm[-1] - self.torque_nm[-2])
        defl: npt.NDArray[np.float64] = np.where(
            t > self.torque_nm[-1], d[-1] + slope * (t - self.torque_nm[-1]), out)
        return defl

    def elastic_torque_nm(self, angle_rad: npt.ArrayLike) -> np.ndarray:
        """g(phi): the elastic torque at torsion angles ``angle_rad`` [N m] (0 in the play)."""
        x = np.asarray(angle_rad, dtype=np.float64) - self.centre_rad
        h = 0.5 * self.backlash_rad
        t = self.torque_nm
        pos, neg = x - h, -x - h

        def inv(d: np.ndarray, table: np.ndarray) -> np.ndarray:
            out = np.interp(d, table, t)
            slope = (t[-1] - t[-2]) / (table[-1] - table[-2])
            torque: npt.NDArray[np.float64] = np.where(
                d > table[-1], t[-1] + slope * (d - table[-1]), out)
            return torque

        return np.where(pos > 0, inv(np.maximum(pos, 0.0), self.deflection_pos_rad),
                        np.where(neg > 0, -inv(np.maximum(neg, 0.0), self.deflection_neg_rad),
                                 0.0))

    def _lo(self, te: np.ndarray) -> np.ndarray:
        """min{phi: g(phi) >= te}."""
        h = 0.5 * self.backlash_rad
        return self.centre_rad + np.where(
            te > 0, h + self.deflection_rad(te, side=1),
            -h - self.deflection_rad(np.minimum(te, 0.0), side=-1))

    def _hi(self, te: np.ndarray) -> np.ndarray:
        """max{phi: g(phi) <= te}."""
        h = 0.5 * self.backlash_rad
        return self.centre_rad + np.where(
            te >= 0, h + self.deflection_rad(np.maximum(te, 0.0), side=1),
            -h - self.deflection_rad(te, side=-1))

    # -- programs ---------------------------------------------------------------------------
    def angle_under_torque(self, torque_nm: npt.ArrayLike, angle0_rad: float) -> np.ndarray:
        """Torsion angle under a quasi-static torque program (play operator, friction).

        Args:
            torque_nm: Applied torque at consecutive instants [N m], 1-D.
            angle0_rad: Angle before the first instant [rad].

        Returns:
            The angle at each instant [rad]. Vectorised within each monotone run of the
            torque (a test has a handful of runs).
        """
        t = np.asarray(torque_nm, dtype=np.float64).ravel()
        if t.size == 0:
            return np.zeros(0)
        if not np.all(np.isfinite(t)):
            msg = 'torque_nm must be finite'
            raise ModelInputError(msg)
        tf = self.friction_torque_nm
        lo, hi = self._lo(t - tf), self._hi(t + tf)
        d = np.sign(np.diff(np.concatenate((t[:1], t))))
        # a flat stretch continues the run it is in: carry the last non-zero sign forward
        nz = np.flatnonzero(d)
        idx = np.maximum.accumulate(np.where(d != 0, np.arange(t.size), 0))
        d = d[idx] if nz.size else d
        starts = np.flatnonzero(np.concatenate(([True], d[1:] != d[:-1])))
        out = np.empty_like(t)
        phi = float(angle0_rad)
        for s, e in zip(starts, np.append(starts[1:], t.size), strict=True):
            if d[s] >= 0:
                seg = np.minimum(np.maximum(phi, np.maximum.accumulate(lo[s:e])), hi[s:e])
            else:
                seg = np.maximum(np.minimum(phi, np.minimum.accumulate(hi[s:e])), lo[s:e])
            out[s:e] = seg
            phi = float(seg[-1])
        return out

    def torque_under_motion(self, angle_rad: npt.ArrayLike, direction: int) -> np.ndarray:
        """Torque a constant-speed loader measures: g(phi) + T_f * direction [N m]."""
        return self.elastic_torque_nm(angle_rad) + self.friction_torque_nm * float(
            np.sign(direction))

    def angle_at_torque(self, target_nm: float, direction: int) -> float:
        """Angle at which a loader moving in ``direction`` reaches torque ``target_nm`` [rad]."""
        tf = self.friction_torque_nm * float(np.sign(direction))
        te = np.array([target_nm - tf])
        return float((self._lo(te) if direction > 0 else self._hi(te))[0])


@dataclass(frozen=True)
class ExpectedMetrics:
    """Catalogue values of a torsion curve in closed form (the truth of a simulated unit).

    Attributes:
        backlash_rad: Width at zero torque, b + d_pos(T_f) + d_neg(T_f) [rad].
        lost_motion_rad: Mid-point distance at +-t [rad].
        rigidity_nm_per_rad: Region name -> (positive, negative) secant on the loading
            branches [N m/rad].
        hysteresis_loss_j: Loop area for a continuous cycle to +-T_R [J].
    """

    backlash_rad: float
    lost_motion_rad: float
    rigidity_nm_per_rad: dict[str, tuple[float, float]]
    hysteresis_loss_j: float


def expected_metrics(curve: TorsionCurve, *, rated_torque_nm: float,
                     lost_motion_fraction: float = 0.03,
                     regions: tuple[tuple[str, float, float], ...] = (('K', 0.5, 1.0),),
                     ) -> ExpectedMetrics:
    """Closed-form catalogue values of ``curve`` for a cycle 0 -> +T_R -> 0 -> -T_R -> 0.

    With the friction model above: the loading branch sits at d(T - T_f) past the flank,
    the unloading one at d(T + T_f) (T_f < t < T_R / 2 assumed). Computed from the curve's
    tables directly, not by simulating a test.
    """
    tf, b = curve.friction_torque_nm, curve.backlash_rad
    t = lost_motion_fraction * rated_torque_nm
    if not tf < t:
        msg = (f'friction torque {tf} N m must be below the lost-motion torque {t} N m '
               'for the closed form')
        raise ModelInputError(msg)

    def dp(x: float) -> float:
        return float(curve.deflection_rad(x, side=1))

    def dn(x: float) -> float:
        return float(curve.deflection_rad(x, side=-1))

    rig: dict[str, tuple[float, float]] = {}
    for name, lo, hi in regions:
        t1, t2 = lo * rated_torque_nm, hi * rated_torque_nm
        rig[name] = ((t2 - t1) / (dp(t2 - tf) - dp(t1 - tf)),
                     (t2 - t1) / (dn(t2 - tf) - dn(t1 - tf)))
    # loop area: 2 T_f times the angle travelled between the turning points
    phi_max = b / 2 + dp(rated_torque_nm - tf)
    phi_min = -b / 2 - dn(rated_torque_nm - tf)
    return ExpectedMetrics(
        backlash_rad=b + dp(tf) + dn(tf),
        lost_motion_rad=b + 0.5 * (dp(t - tf) + dp(t + tf) + dn(t - tf) + dn(t + tf)),
        rigidity_nm_per_rad=rig,
        hysteresis_loss_j=2.0 * tf * (phi_max - phi_min),
    )


# ------------------------------------------------------------------------- per preset


def _with_series(t: np.ndarray, d: np.ndarray, k_s: float) -> np.ndarray:
    return d + t / k_s if k_s > 0 else d


def _wang_curve(preset: Preset, theta_in_rad: float, grid: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray, float, float]:
    from sim import wang2020

    p = wang2020.Wang2kvParams.from_preset(preset)
    th = theta_in_rad / p.kinematics.gear_ratio
    # applied torque T twists the output forwards: the bench's load is -T (tooth backs)
    # (at exactly zero load static_te_rad picks the drive flanks: the tooth-back branch is
    # taken as the limit from the back side, a load of -1e-300 N m)
    fwd = wang2020.static_te_rad(th, -np.maximum(grid, 1e-300), p)
    rev = wang2020.static_te_rad(th, grid, p)
    up, down = float(fwd[0]), float(rev[0])
    return fwd - up, down - rev, up - down, 0.5 * (up + down)


def _hu_curve(preset: Preset, t_max: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The TCA rotation beta(T) (``sim.hu2020.elastic_te_rad``) past the first pin contact."""
    from sim import hu2020

    params = hu2020.HuRvParams.from_preset(preset)
    # the initial clearances (Hu 2020 Eq. 32) and lever arms (Hu 2020 Eq. 36) are geometry: any
    # torque will do
    tca = hu2020.tooth_contact_analysis(params)
    beta0 = float(np.min(tca.clearance_m / tca.lever_arm_m))
    grid = np.r_[0.0, np.geomspace(2e-3 * t_max, t_max, _GRID_POINTS - 1)]
    beta = -hu2020.elastic_te_rad(params, grid)
    # beta includes closing the play; below the first contact the table falls linearly to 0
    defl = np.maximum.accumulate(np.maximum(beta - beta0, 0.0))
    # strictly increasing for the inverse (the paper's 0.1 % iteration tolerance can leave
    # two neighbours equal): a ramp of 1e-15 rad, far below any angle here
    defl = defl + np.arange(defl.size) * 1e-15
    return grid, defl - defl[0], 2.0 * beta0


def _li_stiffness(preset: Preset, theta_in_rad: float) -> float:
    from sim import li2023

    model = li2023.build_te_model(preset, 'dte')
    i_out = model.state_index('output')
    ref = 1000.0
    q0 = model.static_response(theta_in_rad, 0.0)
    q1 = model.static_response(theta_in_rad, ref)   # load resists: output turns back
    rot = float(q0[i_out] - q1[i_out])
    if not rot > 0:
        msg = f'preset {preset.name!r}: the lumped model gives no output rotation under load'
        raise PresetError(msg)
    return ref / rot


def torsion_curve(preset: Preset, theta_in_rad: float = 0.0) -> TorsionCurve:
    """The static torsion characteristic of ``preset`` with the input locked at an angle.

    Args:
        preset: A loaded preset with a ``[torsion]`` section.
        theta_in_rad: Locked input angle [rad] (the 2K-V curve depends on it through the
            eccentricities; the RV curves here do not).

    Raises:
        PresetError: No ``[torsion]`` section, or a model that has no static torsion.
    """
    tp = TorsionParams.from_preset(preset)
    t_max = _TORQUE_SPAN * tp.rated_torque_nm
    grid = t_max * np.linspace(0.0, 1.0, _GRID_POINTS) ** 2   # finer near zero
    centre = 0.0
    if preset.model == 'wang2020-2kv':
        dp, dn, b, centre = _wang_curve(preset, theta_in_rad, grid)
    elif preset.model == 'hu2020-rv':
        grid, dp, b = _hu_curve(preset, t_max)
        dn = dp
    elif preset.model == 'li2023-rv':
        k = _li_stiffness(preset, theta_in_rad)
        dp = dn = grid / k
        b = 0.0
    else:
        msg = f'preset {preset.name!r}: model {preset.model!r} has no static torsion model'
        raise PresetError(msg)
    return TorsionCurve(
        torque_nm=grid,
        deflection_pos_rad=_with_series(grid, dp, tp.series_stiffness_nm_rad),
        deflection_neg_rad=_with_series(grid, dn, tp.series_stiffness_nm_rad),
        backlash_rad=b + tp.clearance_rad,
        friction_torque_nm=tp.friction_torque_nm,
        centre_rad=centre)
