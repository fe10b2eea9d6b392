"""A measured record cut into what an acceptance plan's steps need: speed and load plateaus
(TE in each direction, sweep points) and stretches with the input locked (hysteresis).

A record of a real bench has no step markers: the input turns at one speed, then another,
the brake holds one load, then another, the input is locked while the output is loaded.
:func:`find_runs` finds those stretches from the data alone:

* the input speed before and after each sample is the angle travelled over the ``window``
  samples before and after it; a sample is steady when the two agree within
  ``speed_tolerance`` of the speed (plus ``lock_speed_rad_s``, so that a locked input is
  steady too); the torque likewise, within ``load_resolution_nm``;
* a run is a stretch of steady samples; it is taken to begin ``window`` samples before its
  first steady sample (where an instant change of speed or load happened) and to end
  ``window`` samples after its last;
* a run whose input speed is below ``lock_speed_rad_s`` is *locked*; the others are
  *plateaus* (constant speed and load), their speed signed: positive turns the output
  positively (ccw);
* a record is never read across a break (a drop-out, a lost block): runs end there.

SI units: seconds, radians, N m.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.errors import TeConfigError, TeInputError

if TYPE_CHECKING:
    import numpy.typing as npt

    from sim.bench_info import BenchInfoData

__all__ = ['MeasuredRecord', 'Run', 'RunSettings', 'find_runs']

RAD_S_PER_RPM = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class MeasuredRecord:
    """A measured record (SI units).

    Attributes:
        info: The bench's record (``bench/info``).
        time_s: Sample times since the first sample [s].
        theta_in_rad, theta_out_rad: Unwrapped encoder angles [rad].
        torque_out_nm: Output torque, bench convention [N m]; None without a torque channel.
        breaks: Sample indices that follow a break (lost blocks, drop-outs, time jumps).
        start_utc: Time of the first sample (ISO 8601, UTC).
        source: Where it was read from (the bag).
        torque_from: What gave the torque ('encoder blocks', 'topic /x (WrenchStamped.z)',
            or why there is none).
        torque_in_nm: Input-shaft torque [N m]; None without that channel (issue 38).
        temp_case_degc: Case temperature [degC]; None without that channel.
        channels_from: What gave those two (or why there are none).
    """

    info: BenchInfoData
    time_s: np.ndarray = field(repr=False)
    theta_in_rad: np.ndarray = field(repr=False)
    theta_out_rad: np.ndarray = field(repr=False)
    torque_out_nm: np.ndarray | None = field(repr=False)
    breaks: np.ndarray = field(repr=False)
    start_utc: str
    source: str
    torque_from: str
    torque_in_nm: np.ndarray | None = field(default=None, repr=False)
    temp_case_degc: np.ndarray | None = field(default=None, repr=False)
    channels_from: str = 'none'

    @property
    def samples(self) -> int:
        """Number of samples."""
        return int(self.time_s.size)


@dataclass(frozen=True)
class RunSettings:
    """How runs are found (SI units).

    Attributes:
        window_s: Length of the stretches compared before and after each sample [s] (> 0).
        speed_tolerance: Relative change of the input speed still counted steady (> 0).
        lock_speed_rad_s: Input speeds below this are a locked input [rad/s] (> 0).
        load_resolution_nm: Torque changes below this are one load [N m] (> 0).
        min_duration_s: The shortest run reported [s] (>= 0).
    """

    window_s: float = 0.02
    speed_tolerance: float = 0.02
    lock_speed_rad_s: float = 0.01 * RAD_S_PER_RPM
    load_resolution_nm: float = 1.0
    min_duration_s: float = 0.1

    def __post_init__(self) -> None:
        """Validate (TeConfigError names the field and the rule)."""
        for name in ('window_s', 'speed_tolerance', 'lock_speed_rad_s', 'load_resolution_nm'):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (
                    math.isfinite(v) and v > 0):
                msg = f'{name} must be finite and > 0, got {v!r}'
                raise TeConfigError(msg)
        if not (math.isfinite(self.min_duration_s) and self.min_duration_s >= 0):
            msg = f'min_duration_s must be finite and >= 0, got {self.min_duration_s!r}'
            raise TeConfigError(msg)


@dataclass(frozen=True)
class Run:
    """A stretch of constant input speed and load (SI units).

    Attributes:
        start, stop: Sample range, stop exclusive.
        t_start_s, t_end_s: Times of its first and last sample [s].
        speed_rad_s: Mean input speed, signed [rad/s] (0 when locked).
        load_nm: Mean torque channel value [N m] (NaN without one); a plateau's load in
            the bench convention (positive resists positive rotation).
        locked: True when the input is locked.
    """

    start: int
    stop: int
    t_start_s: float
    t_end_s: float
    speed_rad_s: float
    load_nm: float
    locked: bool

    @property
    def speed_rpm(self) -> float:
        """Mean input speed [rpm], signed."""
        return self.speed_rad_s / RAD_S_PER_RPM

    @property
    def duration_s(self) -> float:
        """t_end_s - t_start_s [s]."""
        return self.t_end_s - self.t_start_s


def _steady(x: np.ndarray, time: np.ndarray, w: int, rate: bool,
            tol_rel: float, tol_abs: float) -> np.ndarray:
    """Samples whose value (or rate of change, ``rate``) over the w samples before and
    after agree within tol_rel x |value| + tol_abs."""
    n = x.size
    out = np.zeros(n, dtype=bool)
    if n < 2 * w + 1:
        return out
    i = np.arange(w, n - w + (0 if rate else 1))
    if rate:
        before = (x[i] - x[i - w]) / (time[i] - time[i - w])
        after = (x[i + w] - x[i]) / (time[i + w] - time[i])
    else:
        c = np.concatenate([[0.0], np.cumsum(x)])
        before = (c[i] - c[i - w]) / w
        after = (c[i + w] - c[i]) / w
    scale = np.maximum(np.abs(before), np.abs(after))
    out[i] = np.abs(after - before) <= tol_rel * scale + tol_abs
    return out


def find_runs(time_s: npt.ArrayLike, theta_in_rad: npt.ArrayLike,
              torque_nm: npt.ArrayLike | None, settings: RunSettings, *,
              breaks: npt.ArrayLike = ()) -> list[Run]:
    """The runs of constant input speed and load of a record (see the module docstring).

    Args:
        time_s: Sample times [s], increasing.
        theta_in_rad: Unwrapped input angle [rad].
        torque_nm: The torque channel [N m], or None.
        settings: Window, tolerances, lock speed, shortest run.
        breaks: Sample indices where the record breaks (sample i follows a drop-out).

    Returns:
        Runs in time order; they never span a break.

    Raises:
        TeInputError: Lengths differ or time does not increase.

    Examples:
        Locked for 1 s, then 600 rpm for 2 s, then 600 rpm against 50 N m for 2 s:

        >>> t = np.arange(5000) / 1000.0
        >>> w = np.where(t < 1.0, 0.0, 600 * RAD_S_PER_RPM)
        >>> theta = np.cumsum(w) / 1000.0
        >>> load = np.where(t < 3.0, 0.0, 50.0)
        >>> [(r.start, r.stop, round(r.speed_rpm), r.load_nm, r.locked)
        ...  for r in find_runs(t, theta, load, RunSettings())]
        [(0, 1000, 0, 0.0, True), (1000, 3000, 600, 0.0, False), (3000, 5000, 600, 50.0, False)]
    """
    t = np.asarray(time_s, dtype=np.float64).ravel()
    th = np.asarray(theta_in_rad, dtype=np.float64).ravel()
    tq = None if torque_nm is None else np.asarray(torque_nm, dtype=np.float64).ravel()
    if t.size != th.size or (tq is not None and tq.size != t.size):
        msg = (f'time, input angle and torque differ in length: {t.size}, {th.size}, '
               f'{"-" if tq is None else tq.size}')
        raise TeInputError(msg)
    if t.size > 1 and not np.all(np.diff(t) > 0):
        at = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        msg = f'sample times must increase; sample {at} is at {t[at]!r} s after {t[at - 1]!r} s'
        raise TeInputError(msg)
    cuts = sorted({0, t.size, *(int(b) for b in np.asarray(breaks, dtype=np.int64).ravel()
                                if 0 < int(b) < t.size)})
    runs: list[Run] = []
    for a, b in itertools.pairwise(cuts):
        runs += _runs_of_piece(t, th, tq, settings, a, b)
    return runs


def _spans(mask: np.ndarray, w: int, lo: int, hi: int, *, tail: int) -> list[tuple[int, int]]:
    """Runs of True in mask[lo:hi], widened by w before and ``tail`` after (within lo..hi
    and never into the previous one): a sample steady over the rates (levels) of the w
    samples before and after it vouches for w before and w (w - 1) after it."""
    edges = np.diff(np.r_[0, mask[lo:hi].astype(np.int8), 0])
    starts, stops = np.flatnonzero(edges == 1) + lo, np.flatnonzero(edges == -1) + lo
    out: list[tuple[int, int]] = []
    for s0, e0 in zip(starts.tolist(), stops.tolist(), strict=True):
        a = max(out[-1][1] if out else lo, s0 - w)
        out.append((a, min(hi, e0 + tail)))
    return out


def _runs_of_piece(t: np.ndarray, th: np.ndarray, tq: np.ndarray | None,
                   s: RunSettings, a: int, b: int) -> list[Run]:
    tp, thp = t[a:b], th[a:b]
    n = tp.size
    if n < 3:
        return []
    period = float(np.median(np.diff(tp)))
    w = max(1, round(s.window_s / period))
    steady_speed = _steady(thp, tp, w, True, s.speed_tolerance, s.lock_speed_rad_s)
    steady_load = None if tq is None else _steady(tq[a:b], tp, w, False, 0.0,
                                                   0.5 * s.load_resolution_nm)
    out: list[Run] = []

    def add(lo: int, hi: int, locked: bool) -> None:
        if hi - lo < 2 or tp[hi - 1] - tp[lo] < s.min_duration_s:
            return
        # speed and load from the inner part (the widened ends hold the change)
        i0, i1 = min(lo + w, hi - 1), max(hi - w, lo + 1)
        if i1 - 1 <= i0:
            i0, i1 = lo, hi
        speed = (thp[i1 - 1] - thp[i0]) / (tp[i1 - 1] - tp[i0]) if i1 - 1 > i0 else 0.0
        load = float(np.mean(tq[a + i0:a + i1])) if tq is not None else math.nan
        out.append(Run(start=a + lo, stop=a + hi, t_start_s=float(tp[lo]),
                       t_end_s=float(tp[hi - 1]), speed_rad_s=0.0 if locked else float(speed),
                       load_nm=load, locked=locked))

    for lo, hi in _spans(steady_speed, w, 0, n, tail=w):
        inner = slice(min(lo + w, hi - 1), max(hi - w, lo + 1))
        dt = tp[inner.stop - 1] - tp[inner.start]
        speed = (thp[inner.stop - 1] - thp[inner.start]) / dt if dt > 0 else 0.0
        if abs(speed) < s.lock_speed_rad_s:
            add(lo, hi, True)
        elif steady_load is None:
            add(lo, hi, False)
        else:
            for lo2, hi2 in _spans(steady_load, w, lo, hi, tail=w - 1):
                add(lo2, hi2, False)
    return out
