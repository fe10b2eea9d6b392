"""Torque and efficiency metrics of a reducer test (GB/T 35089-2018 s.7, catalogue practice).

Pure functions of sampled channels (SI units, numpy, no loops over samples):

* :func:`efficiency_point`: eta = T_out w_out / (T_in w_in) of one steady operating point,
  the speeds from the encoder angles over the window (their ratio is d theta_out /
  d theta_in, so the time base cancels), with its standard uncertainty from the torque
  transducers' accuracy classes, the scatter of the means and the angle error;
* :func:`no_load_torque`: the mean input torque at zero load (no-load running torque) with
  the mean case temperature;
* :func:`breakaway_torque`: the torque at which a shaft starts to turn under a
  quasi-static torque ramp (starting torque on the input, back-driving torque on the
  output), detected when the shaft has moved by a stated angle threshold.

Uncertainty of a mean torque (GUM, type B + type A): a transducer of accuracy class ``c``
(% of its nominal torque FS, DIN 51309 / VDI/VDE 2646 usage) bounds the combined zero,
sensitivity and linearity deviations by ``c/100 FS``; read as a rectangular distribution
that is ``u_class = c/100 FS / sqrt(3)``. It does not average out. The scatter of the mean
``s / sqrt(n)`` (ripple and noise, taken as independent samples) is added in quadrature.
With the relative uncertainties of the two torques and of the speed ratio

    u(eta) / eta = sqrt( (u_Tout/T_out)^2 + (u_Tin/T_in)^2 + (u_r/r)^2 ),

the angle term ``u_r/r = sqrt(2) u_angle / |d theta|`` on each shaft (two readings per
shaft). The expanded uncertainty is ``k u`` with k = 2 (about 95 %).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rv_te_bench.errors import TeInputError

__all__ = [
    'Breakaway',
    'EfficiencyPoint',
    'NoLoadPoint',
    'breakaway_torque',
    'class_uncertainty_nm',
    'efficiency_point',
    'mean_torque_uncertainty_nm',
    'no_load_torque',
]

#: Coverage factor of the expanded uncertainties (about 95 % for a normal distribution).
COVERAGE_K = 2.0


def _finite_1d(name: str, x: npt.ArrayLike, n: int | None = None) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1 or a.size < 2:
        msg = f'{name} must be a 1-D array of at least 2 samples, got shape {a.shape}'
        raise TeInputError(msg)
    if n is not None and a.size != n:
        msg = f'{name} has {a.size} samples, the other channels {n}'
        raise TeInputError(msg)
    if not np.all(np.isfinite(a)):
        msg = f'{name} holds NaN or inf (sample {int(np.argmin(np.isfinite(a)))})'
        raise TeInputError(msg)
    return a


def _nonneg(name: str, x: float) -> float:
    v = float(x)
    if not math.isfinite(v) or v < 0.0:
        msg = f'{name} must be finite and >= 0, got {x!r}'
        raise TeInputError(msg)
    return v


def class_uncertainty_nm(full_scale_nm: float, accuracy_class_pct: float) -> float:
    """Standard uncertainty of a transducer reading from its class [N m]:
    ``c/100 FS / sqrt(3)`` (the class band read as a rectangular distribution).

    Examples:
        >>> round(class_uncertainty_nm(1000.0, 0.1), 4)
        0.5774
    """
    fs = _nonneg('full_scale_nm', full_scale_nm)
    c = _nonneg('accuracy_class_pct', accuracy_class_pct)
    return c / 100.0 * fs / math.sqrt(3.0)


def mean_torque_uncertainty_nm(torque_nm: np.ndarray, u_class_nm: float) -> float:
    """Standard uncertainty of the mean of ``torque_nm``: class term and ``s/sqrt(n)``."""
    a = np.asarray(torque_nm, dtype=np.float64)
    s = float(np.std(a, ddof=1)) if a.size > 1 else 0.0
    return math.hypot(u_class_nm, s / math.sqrt(max(a.size, 1)))


@dataclass(frozen=True)
class EfficiencyPoint:
    """One efficiency-map point (SI units).

    Attributes:
        efficiency: eta = P_out / P_in (1 = lossless).
        u_efficiency: Its standard uncertainty (absolute, in units of eta).
        expanded_efficiency: ``COVERAGE_K * u_efficiency``.
        torque_in_nm, torque_out_nm: Mean input torque (signed like the motion) and mean
            output torque (bench convention: > 0 resists positive rotation).
        u_torque_in_nm, u_torque_out_nm: Their standard uncertainties.
        omega_in_rad_s, omega_out_rad_s: Mean speeds from the angles over the window.
        power_in_w, power_out_w, power_loss_w: P_in, P_out and their difference.
        temp_case_degc: Mean case temperature over the window (NaN: no channel).
        samples: Samples in the window.
    """

    efficiency: float
    u_efficiency: float
    expanded_efficiency: float
    torque_in_nm: float
    torque_out_nm: float
    u_torque_in_nm: float
    u_torque_out_nm: float
    omega_in_rad_s: float
    omega_out_rad_s: float
    power_in_w: float
    power_out_w: float
    power_loss_w: float
    temp_case_degc: float
    samples: int


def efficiency_point(time_s: npt.ArrayLike, theta_in_rad: npt.ArrayLike,
                     theta_out_rad: npt.ArrayLike, torque_in_nm: npt.ArrayLike,
                     torque_out_nm: npt.ArrayLike, *, u_class_in_nm: float,
                     u_class_out_nm: float, u_angle_rad: float = 0.0,
                     temp_case_degc: npt.ArrayLike | None = None) -> EfficiencyPoint:
    """Efficiency of one steady window (drive at constant speed and load).

    Args:
        time_s: Sample times [s], increasing.
        theta_in_rad, theta_out_rad: Unwrapped shaft angles [rad].
        torque_in_nm: Input transducer [N m], signed like the input motion.
        torque_out_nm: Output transducer [N m], bench convention (> 0 resists positive
            rotation, so a load absorbing power reads with the sign of the motion).
        u_class_in_nm, u_class_out_nm: The transducers' class uncertainties
            (:func:`class_uncertainty_nm`).
        u_angle_rad: Standard uncertainty of one angle reading (encoder accuracy), >= 0.
        temp_case_degc: Case temperature samples (optional, for the record).

    Raises:
        TeInputError: Mismatched, non-finite or too short channels; a shaft that does not
            turn; an input that does not deliver power (no efficiency is defined).
    """
    t = _finite_1d('time_s', time_s)
    n = t.size
    th_in = _finite_1d('theta_in_rad', theta_in_rad, n)
    th_out = _finite_1d('theta_out_rad', theta_out_rad, n)
    tq_in = _finite_1d('torque_in_nm', torque_in_nm, n)
    tq_out = _finite_1d('torque_out_nm', torque_out_nm, n)
    dur = float(t[-1] - t[0])
    if not dur > 0:
        msg = f'time_s must increase over the window, got a span of {dur!r} s'
        raise TeInputError(msg)
    d_in, d_out = float(th_in[-1] - th_in[0]), float(th_out[-1] - th_out[0])
    if d_in == 0.0 or d_out == 0.0:
        msg = 'a shaft did not turn over the window: no efficiency at standstill'
        raise TeInputError(msg)
    w_in, w_out = d_in / dur, d_out / dur
    t_in, t_out = float(np.mean(tq_in)), float(np.mean(tq_out))
    p_in, p_out = t_in * w_in, t_out * w_out
    if not p_in > 0.0:
        msg = (f'the input delivers no power (mean input torque {t_in:.4g} N m at '
               f'{w_in:.4g} rad/s): the output drives the gear, no forward efficiency')
        raise TeInputError(msg)
    u_in = mean_torque_uncertainty_nm(tq_in, _nonneg('u_class_in_nm', u_class_in_nm))
    u_out = mean_torque_uncertainty_nm(tq_out, _nonneg('u_class_out_nm', u_class_out_nm))
    ua = _nonneg('u_angle_rad', u_angle_rad)
    eta = p_out / p_in
    rel = math.sqrt((u_out / t_out) ** 2 + (u_in / t_in) ** 2
                    + 2.0 * (ua / d_in) ** 2 + 2.0 * (ua / d_out) ** 2) if t_out else math.inf
    temp = (float(np.mean(_finite_1d('temp_case_degc', temp_case_degc, n)))
            if temp_case_degc is not None else math.nan)
    u_eta = abs(eta) * rel
    return EfficiencyPoint(
        efficiency=eta, u_efficiency=u_eta, expanded_efficiency=COVERAGE_K * u_eta,
        torque_in_nm=t_in, torque_out_nm=t_out, u_torque_in_nm=u_in, u_torque_out_nm=u_out,
        omega_in_rad_s=w_in, omega_out_rad_s=w_out, power_in_w=p_in, power_out_w=p_out,
        power_loss_w=p_in - p_out, temp_case_degc=temp, samples=n)


@dataclass(frozen=True)
class NoLoadPoint:
    """No-load running torque at one input speed (SI units).

    Attributes:
        torque_nm: Mean input torque magnitude [N m] (the drag).
        u_torque_nm: Its standard uncertainty [N m].
        omega_in_rad_s: Mean input speed [rad/s] (signed).
        temp_case_degc: Mean case temperature [degC] (NaN: no channel).
        samples: Samples in the window.
    """

    torque_nm: float
    u_torque_nm: float
    omega_in_rad_s: float
    temp_case_degc: float
    samples: int


def no_load_torque(time_s: npt.ArrayLike, theta_in_rad: npt.ArrayLike,
                   torque_in_nm: npt.ArrayLike, *, u_class_nm: float,
                   temp_case_degc: npt.ArrayLike | None = None) -> NoLoadPoint:
    """The no-load running torque of one window at constant input speed.

    The drag resists the motion: its magnitude is ``sign(w) * mean(T_in)``.

    Raises:
        TeInputError: Bad channels, or an input that does not turn.
    """
    t = _finite_1d('time_s', time_s)
    th = _finite_1d('theta_in_rad', theta_in_rad, t.size)
    tq = _finite_1d('torque_in_nm', torque_in_nm, t.size)
    dur = float(t[-1] - t[0])
    d = float(th[-1] - th[0])
    if not dur > 0 or d == 0.0:
        msg = 'the input did not turn over the window: no running torque at standstill'
        raise TeInputError(msg)
    temp = (float(np.mean(_finite_1d('temp_case_degc', temp_case_degc, t.size)))
            if temp_case_degc is not None else math.nan)
    return NoLoadPoint(torque_nm=math.copysign(1.0, d) * float(np.mean(tq)),
                       u_torque_nm=mean_torque_uncertainty_nm(tq, _nonneg('u_class_nm',
                                                                          u_class_nm)),
                       omega_in_rad_s=d / dur, temp_case_degc=temp, samples=int(t.size))


@dataclass(frozen=True)
class Breakaway:
    """Where a shaft under a torque ramp started to turn (SI units).

    Attributes:
        found: Whether it moved by the threshold within the record.
        torque_nm: Torque magnitude at the first sample past the threshold [N m] (NaN if
            not found): the starting (or back-driving) torque as measured.
        torque_before_nm: Torque magnitude at the last sample before it [N m].
        time_s: Time of that first sample [s].
        threshold_rad: The detection threshold [rad] (shaft travel from its start).
        ramp_rate_nm_s: Fitted ramp rate of the torque magnitude [N m/s].
        max_torque_nm: Largest torque magnitude of the record [N m] (what it withstood when
            not found).
    """

    found: bool
    torque_nm: float
    torque_before_nm: float
    time_s: float
    threshold_rad: float
    ramp_rate_nm_s: float
    max_torque_nm: float


def breakaway_torque(time_s: npt.ArrayLike, torque_nm: npt.ArrayLike,
                     angle_rad: npt.ArrayLike, *, threshold_rad: float) -> Breakaway:
    """Starting or back-driving torque from a quasi-static torque ramp.

    The shaft is taken to turn at the first sample whose angle differs from the first
    sample's by more than ``threshold_rad`` (either way: forward and reverse ramps alike).
    The reading is biased high by the torque the ramp adds while the shaft travels the
    threshold after breakaway: a slower ramp and a smaller threshold (a few encoder counts
    above the angle noise) make that small; the test states both.

    Raises:
        TeInputError: Bad channels or a threshold that is not > 0.
    """
    t = _finite_1d('time_s', time_s)
    tq = np.abs(_finite_1d('torque_nm', torque_nm, t.size))
    ang = _finite_1d('angle_rad', angle_rad, t.size)
    thr = float(threshold_rad)
    if not math.isfinite(thr) or thr <= 0.0:
        msg = f'threshold_rad must be finite and > 0, got {threshold_rad!r}'
        raise TeInputError(msg)
    moved = np.abs(ang - ang[0]) > thr
    k = int(np.argmax(moved)) if np.any(moved) else t.size
    rate = float(np.polyfit(t[:k] - t[0], tq[:k], 1)[0]) if k > 2 else math.nan
    if k == t.size:
        return Breakaway(False, math.nan, math.nan, math.nan, thr, rate, float(np.max(tq)))
    return Breakaway(True, float(tq[k]), float(tq[max(k - 1, 0)]), float(t[k]), thr, rate,
                     float(np.max(tq)))
