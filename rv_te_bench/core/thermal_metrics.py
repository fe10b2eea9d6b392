"""Temperature rise of a reducer run at constant speed and load until its case settles.

The case temperature is sampled while the unit runs; it has *settled* when the rate of
change has fallen below a stated limit (e.g. 0.05 K/min, i.e. 3 K/h). The rate is the
least-squares slope over a sliding window of ``window_s`` (vectorised with cumulative
sums): it estimates the rate at the window's centre, averaging the sensor noise (the slope
of n samples of noise sigma spread over W has the standard deviation
``sigma sqrt(12 / n) / W``). A test running live can only decide at the window's end, so
the result gives both: ``settle_time_s`` (centre of the first window whose rate is below
the limit: the comparable figure, biased only by the window's curvature, O(W^2 / tau^2))
and ``decided_at_s`` (its end). The rise is the temperature at the settling time (the
window's fitted value) minus the one at the start (a parabola fitted to the first window,
at its first sample).

For a first-order case (:mod:`sim.thermal`) after a constant loss step the truth is
``t_s = tau ln(|T_inf - T_0| / (tau r))`` and ``rise = (T_inf - T_0)(1 - exp(-t_s/tau))``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rv_te_bench.errors import TeInputError

__all__ = ['TemperatureRise', 'sliding_rate', 'temperature_rise']


@dataclass(frozen=True)
class TemperatureRise:
    """A temperature-rise run (SI-ish: kelvin, seconds; the limit also in K/min).

    Attributes:
        settled: Whether the rate fell below the limit within the record.
        rise_k: Temperature at settling (or at the end) minus at the start [K].
        settle_time_s: Time from the start at which the rate fell below the limit [s]
            (window centre; NaN if not settled).
        decided_at_s: When a live test could know it (window end) [s] (NaN if not).
        temp_start_degc, temp_settled_degc: Fitted temperatures at the start and at
            settling (or at the end) [degC].
        rate_limit_k_per_min: The stated limit.
        final_rate_k_per_min: Rate of the last window [K/min].
        window_s: The rate window [s].
        u_rate_k_per_min: Standard uncertainty of one window's rate from the scatter of the
            samples about the fitted line [K/min].
    """

    settled: bool
    rise_k: float
    settle_time_s: float
    decided_at_s: float
    temp_start_degc: float
    temp_settled_degc: float
    rate_limit_k_per_min: float
    final_rate_k_per_min: float
    window_s: float
    u_rate_k_per_min: float


def sliding_rate(time_s: np.ndarray, temp_degc: np.ndarray, n: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares slope [K/s], centre time [s] and fitted centre value of every window
    of ``n`` consecutive samples (vectorised; windows ``k .. k+n-1``)."""
    t0 = float(time_s[0])
    t = time_s - t0

    def wsum(x: np.ndarray) -> np.ndarray:
        c = np.concatenate(([0.0], np.cumsum(x)))
        return c[n:] - c[:-n]

    st, sy = wsum(t), wsum(temp_degc)
    stt, sty = wsum(t * t), wsum(t * temp_degc)
    den = n * stt - st * st
    slope = (n * sty - st * sy) / den
    tc = st / n
    yc = sy / n                       # the fitted line passes through the means
    return slope, tc + t0, yc


def temperature_rise(time_s: npt.ArrayLike, temp_degc: npt.ArrayLike, *,
                     rate_limit_k_per_min: float, window_s: float) -> TemperatureRise:
    """Rise and time to settle of a case temperature record (see the module docstring).

    Args:
        time_s: Sample times [s], strictly increasing (the first is the run's start).
        temp_degc: Case temperature samples [degC].
        rate_limit_k_per_min: Settled when |dT/dt| is below this [K/min], > 0.
        window_s: Length of the rate window [s], > 0; at least 3 samples and at most half
            the record.

    Raises:
        TeInputError: Bad channels or settings (named).
    """
    t = np.asarray(time_s, dtype=np.float64)
    y = np.asarray(temp_degc, dtype=np.float64)
    if t.ndim != 1 or y.shape != t.shape or t.size < 6:
        msg = (f'time_s and temp_degc must be 1-D of equal length >= 6, got shapes '
               f'{t.shape} and {y.shape}')
        raise TeInputError(msg)
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        msg = 'time_s or temp_degc holds NaN or inf'
        raise TeInputError(msg)
    if not np.all(np.diff(t) > 0):
        msg = 'time_s must be strictly increasing'
        raise TeInputError(msg)
    lim = float(rate_limit_k_per_min)
    w = float(window_s)
    if not (math.isfinite(lim) and lim > 0):
        msg = f'rate_limit_k_per_min must be finite and > 0, got {rate_limit_k_per_min!r}'
        raise TeInputError(msg)
    dt = float(np.median(np.diff(t)))
    n = round(w / dt) + 1 if math.isfinite(w) and w > 0 else 0
    if n < 3 or n > t.size // 2:
        msg = (f'window_s {window_s!r} must span 3 samples to half the record '
               f'({3 * dt:.3g} .. {(t.size // 2 - 1) * dt:.3g} s here)')
        raise TeInputError(msg)
    slope, tc, yc = sliding_rate(t, y, n)
    per_min = slope * 60.0
    below = np.abs(per_min) < lim
    # residual scatter about the local lines (first window): the rate's noise
    tt = t[:n] - np.mean(t[:n])
    resid = y[:n] - (yc[0] + slope[0] * tt)
    sigma = float(np.std(resid, ddof=2))
    u_rate = sigma / math.sqrt(float(np.sum(tt * tt))) * 60.0
    # the start: a parabola through the first window at t[0] (a line would miss the
    # curvature of the early rise by ~T'' W^2 / 12)
    start = float(np.polyval(np.polyfit(t[:n] - t[0], y[:n], 2), 0.0))
    if np.any(below):
        k = int(np.argmax(below))
        return TemperatureRise(
            settled=True, rise_k=float(yc[k] - start), settle_time_s=float(tc[k] - t[0]),
            decided_at_s=float(t[k + n - 1] - t[0]), temp_start_degc=float(start),
            temp_settled_degc=float(yc[k]), rate_limit_k_per_min=lim,
            final_rate_k_per_min=float(per_min[-1]), window_s=w, u_rate_k_per_min=u_rate)
    end = yc[-1] + slope[-1] * (t[-1] - tc[-1])
    return TemperatureRise(
        settled=False, rise_k=float(end - start), settle_time_s=math.nan,
        decided_at_s=math.nan, temp_start_degc=float(start), temp_settled_degc=float(end),
        rate_limit_k_per_min=lim, final_rate_k_per_min=float(per_min[-1]), window_s=w,
        u_rate_k_per_min=u_rate)
