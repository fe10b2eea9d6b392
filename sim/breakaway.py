"""A shaft under a quasi-static torque ramp: at rest until the breakaway torque, then turning.

The starting-torque test ramps the input torque (output free, or against a load) and the
back-driving test ramps the output torque (input free, unloaded) until the shaft turns.
With the applied torque ``T(t) = r t`` (r > 0 the ramp rate; the sign of the direction is
applied afterwards), the shaft is held by static friction while ``T < T_s`` (the breakaway
torque of :mod:`sim.losses`); from ``t_b = T_s / r`` it turns against the kinetic drag
``T_k`` (<= T_s) with the inertia ``J``:

    J theta'' = r t - T_k,     theta(t_b) = theta'(t_b) = 0,

whose exact solution for t >= t_b is

    theta(t) = [ r (t^3 - t_b^3) / 6 - r t_b^2 (t - t_b) / 2 - T_k (t - t_b)^2 / 2 ] / J.

(A reverse ramp is the mirror image.) The kinetic drag is taken as ``T_s / k_s`` (the
running drag at zero speed, :attr:`sim.losses.LossParams.static_to_kinetic`); the speed
dependence of the drag after breakaway is neglected over the few milliradians a test
watches. A gear that self-locks (``T_s`` infinite) never turns.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from sim._checks import real_number
from sim.errors import ModelInputError

if TYPE_CHECKING:
    from sim.losses import LossModel

__all__ = ['RampRecord', 'back_driving_ramp', 'ramp_angle_rad', 'ramp_breakaway',
           'shaft_friction', 'starting_ramp']

#: Inertia used when a preset gives none [kg m^2] (a small input shaft).
_DEFAULT_INERTIA_KGM2 = 1e-4


class RampRecord(NamedTuple):
    """Samples of a ramp test (SI units).

    Attributes:
        time_s: Sample times from the ramp's start [s].
        torque_nm: Applied torque [N m] (signed by the direction).
        angle_rad: Shaft angle from its start [rad] (signed by the direction).
        breakaway_nm: The true breakaway torque magnitude [N m] (inf: self-locking).
    """

    time_s: np.ndarray
    torque_nm: np.ndarray
    angle_rad: np.ndarray
    breakaway_nm: float


def ramp_breakaway(*, breakaway_nm: float, kinetic_nm: float, inertia_kgm2: float,
                   ramp_rate_nm_s: float, sample_rate_hz: float, duration_s: float,
                   direction: int = 1) -> RampRecord:
    """The exact samples of a torque ramp on a shaft with static friction (vectorised).

    Args:
        breakaway_nm: T_s > 0 (inf: never turns).
        kinetic_nm: T_k, 0 <= T_k <= T_s.
        inertia_kgm2: J > 0.
        ramp_rate_nm_s: r > 0.
        sample_rate_hz: Sampling rate > 0.
        duration_s: Length of the record > 0.
        direction: +1 or -1.

    Raises:
        ModelInputError: A value out of its range (named).
    """
    ts = math.inf if breakaway_nm == math.inf else real_number('breakaway_nm',
                                                                breakaway_nm, '>0')
    tk = real_number('kinetic_nm', kinetic_nm, '>=0')
    if not math.isinf(ts) and tk > ts:
        msg = f'kinetic_nm ({tk}) must not exceed breakaway_nm ({ts})'
        raise ModelInputError(msg)
    j = real_number('inertia_kgm2', inertia_kgm2, '>0')
    r = real_number('ramp_rate_nm_s', ramp_rate_nm_s, '>0')
    fs = real_number('sample_rate_hz', sample_rate_hz, '>0')
    dur = real_number('duration_s', duration_s, '>0')
    if direction not in (1, -1):
        msg = f'direction must be +1 or -1, got {direction!r}'
        raise ModelInputError(msg)
    t = np.arange(math.floor(dur * fs) + 1, dtype=np.float64) / fs
    return RampRecord(t, direction * r * t, direction * ramp_angle_rad(t, ts, tk, j, r), ts)


def ramp_angle_rad(t_s: np.ndarray, breakaway_nm: float, kinetic_nm: float,
                   inertia_kgm2: float, ramp_rate_nm_s: float) -> np.ndarray:
    """Shaft angle [rad] at times ``t_s`` from the ramp's start (the closed form above;
    zero before breakaway, everywhere for a self-locking gear). Values are not checked."""
    t = np.asarray(t_s, dtype=np.float64)
    angle = np.zeros_like(t)
    if math.isfinite(breakaway_nm):
        r, tk, j = ramp_rate_nm_s, kinetic_nm, inertia_kgm2
        tb = breakaway_nm / r
        m = t > tb
        x = t[m]
        angle[m] = (r * (x ** 3 - tb ** 3) / 6.0 - r * tb ** 2 * (x - tb) / 2.0
                    - tk * (x - tb) ** 2 / 2.0) / j
    return angle


def shaft_friction(model: LossModel, shaft: str) -> tuple[float, float, float]:
    """(T_s, T_k, J) of the ``'input'`` shaft (output free, unloaded: the starting torque)
    or the ``'output'`` shaft (input free: the back-driving torque, inertia J_in i^2)."""
    p = model.params
    j = p.inertia_in_kgm2 or _DEFAULT_INERTIA_KGM2
    if shaft == 'input':
        ts = float(model.starting_torque_nm(0.0))
    elif shaft == 'output':
        ts = model.back_driving_torque_nm()
        j *= p.gear_ratio ** 2
    else:
        msg = f"shaft must be 'input' or 'output', got {shaft!r}"
        raise ModelInputError(msg)
    return ts, (ts / p.static_to_kinetic if math.isfinite(ts) else 0.0), j


def starting_ramp(model: LossModel, *, ramp_rate_nm_s: float, sample_rate_hz: float,
                  duration_s: float, direction: int = 1, load_nm: float = 0.0) -> RampRecord:
    """Input torque ramp, output free (or against ``load_nm``): the input angle."""
    p = model.params
    ts = float(model.starting_torque_nm(load_nm))
    j = p.inertia_in_kgm2 or _DEFAULT_INERTIA_KGM2
    return ramp_breakaway(breakaway_nm=ts, kinetic_nm=ts / p.static_to_kinetic,
                          inertia_kgm2=j, ramp_rate_nm_s=ramp_rate_nm_s,
                          sample_rate_hz=sample_rate_hz, duration_s=duration_s,
                          direction=direction)


def back_driving_ramp(model: LossModel, *, ramp_rate_nm_s: float, sample_rate_hz: float,
                      duration_s: float, direction: int = 1) -> RampRecord:
    """Output torque ramp, input free and unloaded: the output angle (inertia J_in i^2)."""
    ts, tk, j = shaft_friction(model, 'output')
    return ramp_breakaway(breakaway_nm=ts, kinetic_nm=tk, inertia_kgm2=j,
                          ramp_rate_nm_s=ramp_rate_nm_s, sample_rate_hz=sample_rate_hz,
                          duration_s=duration_s, direction=direction)
