"""Hysteresis curves as a bench measures them: torque noise, loader ramps, several cycles.

:mod:`rv_te_bench.core.hysteresis` reads one load cycle from curve *points*. A measured
record is not that: the torque sensor is noisy (a 500 N m transducer reads some 0.1 N m
rms), a loader ramps from one held torque to the next and its held torque is never
exactly constant, and a lab loads the unit several times. Here such a record is turned
into cycles and read without the biases of the naive readings:

* **Dwells by time and stability** (:func:`find_dwells`, equal-torque-step tests): a held
  torque is a run of samples over which the mean torque of the ``window`` samples before
  and of the ``window`` samples after each sample differ by less than a threshold set by
  the torque noise (5 standard deviations of that difference) and by the resolution (a
  quarter of the smallest planned torque step). Ramps and the first and last ``window``
  samples of a dwell are left out; a dwell is the mean torque and the mean angle of its
  stable samples. Grouping by exact equality of the torque reading finds no dwell at all
  in a noisy record (every sample is its own "dwell").
* **Readings without the first-crossing bias.** Dwell points are read where a point lies
  within the resolution of the wanted torque (else interpolated between the two points
  around it). A continuously loaded record (constant-speed method) is read by
  :func:`sample_reader`: the samples around the crossing (smoothed torque within
  ``half_width_nm`` of T0) are fitted by straight lines of torque and of angle against
  *time*, which carries no noise; the angle is taken at the time the torque line crosses
  T0. The first sample at or past T0 would be biased: noise crosses T0 early, on both
  branches in opposite directions, so the width at zero torque (backlash) comes out too
  large by about twice the noise excursion over the rigidity.
* **Several cycles** (:func:`split_cycles`): the record's excursions beyond +-T_R/2
  alternate; each positive one followed by a negative one is a cycle 0 -> +T_R -> 0 ->
  -T_R -> 0 (a preload to -T_R before the first is the loading branch's start). Every
  cycle gives its metrics; the values are their means and the spread their sample
  standard deviation.

SI units throughout (rad, N m, s).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from rv_te_bench.core.hysteresis import (
    Branch,
    HysteresisConfig,
    HysteresisMetrics,
    cycle_metrics,
    loop_area,
    point_reader,
)
from rv_te_bench.errors import TeConfigError, TeInputError

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy.typing as npt

    from rv_te_bench.core.hysteresis import BranchReader

__all__ = [
    'CycleBounds',
    'DwellSet',
    'HysteresisReading',
    'MeasuredHysteresis',
    'find_dwells',
    'measured_hysteresis',
    'sample_reader',
    'split_cycles',
    'torque_noise_nm',
]

#: Excursions: a point beyond this fraction of T_R (either sign) belongs to one.
_EXCURSION = 0.5
#: Standard deviations of the before/after difference a dwell's torque may move by.
_STABLE_SIGMAS = 5.0


def torque_noise_nm(torque_nm: npt.ArrayLike) -> float:
    """Robust standard deviation of the white noise of a torque record [N m].

    From the first differences (the median absolute deviation about their median, over
    sqrt 2): steps, ramps and slow drifts move few differences or shift them all alike.

    Examples:
        >>> rng = np.random.default_rng(0)
        >>> t = np.repeat([0.0, 50.0, 100.0], 2000) + rng.normal(0, 0.4, 6000)
        >>> round(torque_noise_nm(t), 1)
        0.4
    """
    t = np.asarray(torque_nm, dtype=np.float64).ravel()
    if t.size < 3:
        return 0.0
    d = np.diff(t)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))


@dataclass(frozen=True)
class DwellSet:
    """Held torques found in a record, one entry per dwell, in time order (SI).

    Attributes:
        start, stop: Sample range of the averaged (stable) part, stop exclusive.
        torque_nm: Mean torque of the stable part [N m].
        angle_rad: Mean angle of the stable part [rad].
        torque_sd_nm: Standard deviation of the torque over it [N m].
        noise_nm: The record's torque noise (:func:`torque_noise_nm`) [N m].
        window: Samples compared before and after each sample.
    """

    start: np.ndarray
    stop: np.ndarray
    torque_nm: np.ndarray
    angle_rad: np.ndarray
    torque_sd_nm: np.ndarray
    noise_nm: float
    window: int

    @property
    def count(self) -> np.ndarray:
        """Samples averaged in each dwell."""
        n: npt.NDArray[np.int64] = self.stop - self.start
        return n


def _moving_sum(x: np.ndarray, w: int) -> np.ndarray:
    """Sums of x[i:i+w] for i = 0..n-w."""
    c = np.concatenate([[0.0], np.cumsum(x)])
    sums: npt.NDArray[np.float64] = c[w:] - c[:-w]
    return sums


def find_dwells(torque_nm: npt.ArrayLike, angle_rad: npt.ArrayLike, *, min_samples: int,
                resolution_nm: float, noise_nm: float | None = None) -> DwellSet:
    """The held torques of an equal-torque-step record, grouped by time and stability.

    Args:
        torque_nm: Applied torque per sample [N m], in time order.
        angle_rad: Output torsion angle per sample [rad].
        min_samples: Samples of the shortest dwell that counts (e.g. 0.3 x the planned
            dwell x the sample rate), >= 5.
        resolution_nm: The smallest torque change that is a new dwell [N m], > 0 (a
            quarter of the smallest planned step).
        noise_nm: The torque noise; None: :func:`torque_noise_nm` of the record.

    Returns:
        The dwells (possibly none).

    Raises:
        TeInputError: Lengths differ, a sample is not finite, bad settings, or the noise is
            too large to tell a step of ``resolution_nm`` apart within a dwell (named).

    Examples:
        Three held torques with noise and 20-sample ramps between them:

        >>> rng = np.random.default_rng(1)
        >>> t = np.r_[np.zeros(300), np.linspace(0, 50, 20), np.full(300, 50.0),
        ...           np.linspace(50, 100, 20), np.full(300, 100.0)]
        >>> d = find_dwells(t + rng.normal(0, 0.4, t.size), t / 1e5, min_samples=60,
        ...                 resolution_nm=2.0)
        >>> np.round(d.torque_nm).astype(int).tolist(), d.count.tolist()
        ([0, 50, 100], [284, 286, 284])
    """
    t = np.asarray(torque_nm, dtype=np.float64).ravel()
    a = np.asarray(angle_rad, dtype=np.float64).ravel()
    if t.shape != a.shape:
        msg = f'torque and angle differ in length: {t.size} vs {a.size}'
        raise TeInputError(msg)
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a))):
        i = int(np.flatnonzero(~(np.isfinite(t) & np.isfinite(a)))[0])
        msg = f'sample {i} is not finite (torque {t[i]!r}, angle {a[i]!r})'
        raise TeInputError(msg)
    if isinstance(min_samples, bool) or not isinstance(min_samples, int) or min_samples < 5:
        msg = f'min_samples must be an integer >= 5, got {min_samples!r}'
        raise TeConfigError(msg)
    if not (math.isfinite(resolution_nm) and resolution_nm > 0):
        msg = f'resolution_nm must be finite and > 0, got {resolution_nm!r}'
        raise TeConfigError(msg)
    sigma = torque_noise_nm(t) if noise_nm is None else float(noise_nm)
    # compare windows long enough that the noise of their difference stays well below
    # half the resolution, and short enough to fit twice in a dwell
    want = math.ceil(2.0 * (2.0 * _STABLE_SIGMAS * sigma / resolution_nm) ** 2)
    w = max(2, min_samples // 6, want)
    if 2 * w > min_samples:
        msg = (f'the torque noise ({sigma:.3g} N m) is too large to tell torque steps of '
               f'{resolution_nm:.3g} N m apart within a dwell of {min_samples} samples '
               f'(needs {2 * w}): hold each torque longer or filter the torque channel')
        raise TeInputError(msg)
    empty = np.zeros(0, dtype=np.int64)
    none = DwellSet(empty, empty, np.zeros(0), np.zeros(0), np.zeros(0), sigma, w)
    n = t.size
    if n < 2 * w + 1:
        return none
    thr = max(_STABLE_SIGMAS * sigma * math.sqrt(2.0 / w), 0.5 * resolution_nm)
    sums = _moving_sum(t, w) / w                 # mean of t[i:i+w]
    # sample i (w <= i <= n - w): before = mean t[i-w:i], after = mean t[i:i+w]
    diff = np.abs(sums[w:] - sums[:-w])          # index j -> sample i = j + w
    stable = np.zeros(n, dtype=bool)
    stable[w:n - w + 1] = diff <= thr
    edges = np.diff(np.r_[0, stable.astype(np.int8), 0])
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    keep = (stops - starts) >= max(3, min_samples - 2 * w)
    starts, stops = starts[keep], stops[keep]
    if starts.size == 0:
        return none
    csum_t = np.concatenate([[0.0], np.cumsum(t)])
    # merge neighbours that hold the same torque (a glitch split one dwell)
    out_s, out_e = [int(starts[0])], [int(stops[0])]
    for s0, e0 in zip(starts[1:].tolist(), stops[1:].tolist(), strict=True):
        ps, pe = out_s[-1], out_e[-1]
        prev = (csum_t[pe] - csum_t[ps]) / (pe - ps)
        cur = (csum_t[e0] - csum_t[s0]) / (e0 - s0)
        if abs(cur - prev) < 0.5 * resolution_nm:
            out_e[-1] = e0
        else:
            out_s.append(s0)
            out_e.append(e0)
    st, en = np.asarray(out_s, dtype=np.int64), np.asarray(out_e, dtype=np.int64)
    cnt = (en - st).astype(np.float64)
    bounds = np.ravel(np.column_stack([st, en]))
    if bounds[-1] == n:
        bounds = bounds[:-1]
    mt = np.add.reduceat(t, bounds)[::2] / cnt
    ma = np.add.reduceat(a, bounds)[::2] / cnt
    var = np.maximum(np.add.reduceat(t * t, bounds)[::2] / cnt - mt * mt, 0.0)
    for arr in (st, en, mt, ma):
        arr.setflags(write=False)
    return DwellSet(st, en, mt, ma, np.sqrt(var), sigma, w)


@dataclass(frozen=True)
class CycleBounds:
    """One load cycle in a record of points or samples (indices into it).

    The cycle is ``up`` = [up_start, peak], ``down`` = [peak, trough], ``back`` =
    [trough, back_end] (inclusive ends).
    """

    up_start: int
    peak: int
    trough: int
    back_end: int


def split_cycles(torque_nm: npt.ArrayLike, rated_torque_nm: float) -> list[CycleBounds]:
    """The load cycles of a record: each excursion beyond +T_R/2 followed by one below
    -T_R/2 (see the module docstring).

    Args:
        torque_nm: Torque of the points or (smoothed) samples, in time order [N m].
        rated_torque_nm: T_R [N m].

    Returns:
        The cycles in time order (possibly none).

    Examples:
        A preload to -T_R, then two cycles:

        >>> t = [0, -100, 0, 100, 0, -100, 0, 100, 0, -100, 0]
        >>> [(c.up_start, c.peak, c.trough, c.back_end) for c in split_cycles(t, 100.0)]
        [(1, 3, 5, 7), (5, 7, 9, 10)]
    """
    t = np.asarray(torque_nm, dtype=np.float64).ravel()
    if t.size == 0:
        return []
    lvl = np.where(t >= _EXCURSION * rated_torque_nm, 1,
                   np.where(t <= -_EXCURSION * rated_torque_nm, -1, 0))
    idx = np.flatnonzero(lvl != 0)
    if idx.size == 0:
        return []
    signs = lvl[idx]
    brk = np.flatnonzero(np.diff(signs) != 0) + 1
    groups = np.split(idx, brk)
    extremes: list[tuple[int, int]] = []     # (sign, index of the extreme)
    for g in groups:
        sign = int(lvl[g[0]])
        k = int(g[np.argmax(t[g])]) if sign > 0 else int(g[np.argmin(t[g])])
        extremes.append((sign, k))
    out = []
    for j, (sign, k) in enumerate(extremes):
        if sign < 0 or j + 1 >= len(extremes):
            continue
        trough = extremes[j + 1][1]
        up_start = extremes[j - 1][1] if j > 0 else 0
        back_end = extremes[j + 2][1] if j + 2 < len(extremes) else t.size - 1
        out.append(CycleBounds(up_start, k, trough, back_end))
    return out


def _refine(c: CycleBounds, tq: np.ndarray, k: int) -> CycleBounds:
    """The cycle's turns at the raw extremes within k samples of the smoothed ones."""
    def at(i: int, sign: int) -> int:
        a, b = max(0, i - k), min(tq.size, i + k + 1)
        seg = tq[a:b]
        return a + int(np.argmax(seg) if sign > 0 else np.argmin(seg))

    peak, trough = at(c.peak, 1), at(c.trough, -1)
    up = c.up_start if c.up_start == 0 else at(c.up_start, -1)
    back = c.back_end if c.back_end == tq.size - 1 else at(c.back_end, 1)
    return CycleBounds(up, peak, trough, back)


def sample_reader(half_width_nm: float, smooth: int = 1) -> BranchReader:
    """Reads a branch of noisy *samples* at a torque by local fits against time.

    Args:
        half_width_nm: Samples whose smoothed torque lies within this of T0 around the
            crossing are fitted (>= 3 x the torque noise; below the friction torque, so
            that the window stays on one side of a jump across the play).
        smooth: Moving-average length used to find the crossing (>= 1 sample).

    Returns:
        A reader for :func:`rv_te_bench.core.hysteresis.cycle_metrics`.
    """
    if not (math.isfinite(half_width_nm) and half_width_nm > 0):
        msg = f'half_width_nm must be finite and > 0, got {half_width_nm!r}'
        raise TeConfigError(msg)

    def read(b: Branch, t0: float, direction: int, end_tol: float) -> float:
        tq, ang = b.torque_nm, b.angle_rad
        n = tq.size
        if n == 0:
            return math.nan
        time = b.time_s if b.time_s is not None else np.arange(n, dtype=np.float64)
        if smooth > 1 and n >= smooth:
            k = smooth
            sm = np.convolve(tq, np.ones(k) / k, mode='same')
            sm[:k // 2] = sm[k // 2]
            sm[n - (k - 1) // 2:] = sm[n - (k - 1) // 2 - 1]
        else:
            sm = tq
        s = direction * (sm - t0)
        hit = np.flatnonzero(s >= 0)
        if hit.size:
            k0 = int(hit[0])
        else:
            k0 = int(np.argmax(s))
            if -s[k0] > end_tol:
                return math.nan
        # the window: from the last sample below T0 - w before the crossing to the first
        # above T0 + w after it (or the branch's end)
        below = np.flatnonzero(s[:k0] < -half_width_nm)
        j0 = int(below[-1]) + 1 if below.size else 0
        above = np.flatnonzero(s[k0:] > half_width_nm)
        j1 = k0 + int(above[0]) if above.size else n
        # stop at the branch's extreme (a hold there is not the ramp)
        j1 = min(j1, int(np.argmax(s)) + 1) if not above.size else j1
        if j1 - j0 < 4:
            return _interpolate(tq, ang, sm, s, k0)
        tt, yy, aa = time[j0:j1], tq[j0:j1], ang[j0:j1]
        tm = float(np.mean(tt))
        dt = tt - tm
        sxx = float(np.dot(dt, dt))
        if sxx <= 0:
            return float(np.mean(aa))
        beta = float(np.dot(dt, yy - yy.mean())) / sxx
        delta = float(np.dot(dt, aa - aa.mean())) / sxx
        if direction * beta <= 0:
            return float(np.mean(aa))
        t_star = tm + (t0 - float(yy.mean())) / beta
        span = float(tt[-1] - tt[0])
        t_star = min(max(t_star, float(tt[0]) - 0.5 * span), float(tt[-1]) + 0.5 * span)
        return float(aa.mean()) + delta * (t_star - tm)

    return read


def _interpolate(tq: np.ndarray, ang: np.ndarray, sm: np.ndarray, s: np.ndarray,
                 k: int) -> float:
    """The crossing of the smoothed torque, linearly interpolated (steep branches)."""
    if k == 0 or s[k] < 0 or s[k] == s[k - 1]:
        return float(ang[k])
    w = -s[k - 1] / (s[k] - s[k - 1])
    return float(ang[k - 1] + w * (ang[k] - ang[k - 1]))


@dataclass(frozen=True)
class HysteresisReading:
    """How a measured hysteresis record is read (SI units).

    Attributes:
        method: ``'torque_steps'`` (dwell points) or ``'constant_speed'`` (samples).
        min_dwell_samples: Torque steps: the shortest dwell that counts [samples] (>= 5).
        resolution_nm: Torque steps: the smallest step that is a new dwell, and how close
            a dwell must lie to a torque the metrics read to be read directly [N m] (> 0).
        half_width_nm: Constant speed: half-width of the local fits around a reading
            [N m]; NaN: max(3 x the torque noise, 0.4 % of T_R).
    """

    method: Literal['torque_steps', 'constant_speed']
    min_dwell_samples: int = 60
    resolution_nm: float = 1.0
    half_width_nm: float = math.nan

    def __post_init__(self) -> None:
        """Validate (TeConfigError names the field)."""
        if self.method not in ('torque_steps', 'constant_speed'):
            msg = f"method must be 'torque_steps' or 'constant_speed', got {self.method!r}"
            raise TeConfigError(msg)
        m = self.min_dwell_samples
        if isinstance(m, bool) or not isinstance(m, int) or m < 5:
            msg = f'min_dwell_samples must be an integer >= 5, got {m!r}'
            raise TeConfigError(msg)
        if not (math.isfinite(self.resolution_nm) and self.resolution_nm > 0):
            msg = f'resolution_nm must be finite and > 0, got {self.resolution_nm!r}'
            raise TeConfigError(msg)


@dataclass(frozen=True)
class MeasuredHysteresis:
    """The cycles of a measured record and their averaged metrics (SI units).

    Attributes:
        cycles: Each cycle's metrics, in time order.
        values: Metric name -> mean over the cycles (rigidity: the smaller side of the
            per-side means); names as the acceptance step reports them.
        spread: Metric name -> sample standard deviation over the cycles (NaN for one).
        torque_noise_nm: The record's torque noise [N m].
        points: (torque_nm, angle_rad) of the curve read: dwell means, or the samples.
        dwells: Number of dwells found (0 for the constant-speed method).
        missing: Readings a metric needed that no cycle reached, as text (empty: none).
    """

    cycles: tuple[HysteresisMetrics, ...]
    values: dict[str, float]
    spread: dict[str, float]
    torque_noise_nm: float
    points: tuple[np.ndarray, np.ndarray] = field(repr=False)
    dwells: int = 0
    missing: tuple[str, ...] = ()


def metric_names(config: HysteresisConfig) -> list[str]:
    """The metric names a hysteresis step reports (SI suffixes)."""
    return ['lost_motion_rad', 'backlash_rad', 'hysteresis_loss_j',
            *(f'torsional_rigidity_{r.name}_nm_per_rad' for r in config.rigidity_regions)]


def _aggregate(cycles: list[HysteresisMetrics], config: HysteresisConfig,
               ) -> tuple[dict[str, float], dict[str, float]]:
    def mean_sd(x: list[float]) -> tuple[float, float]:
        arr = np.asarray(x, dtype=np.float64)
        if not np.all(np.isfinite(arr)):
            return math.nan, math.nan
        return float(arr.mean()), float(arr.std(ddof=1)) if arr.size > 1 else math.nan

    values, spread = {}, {}
    getters: tuple[tuple[str, Callable[[HysteresisMetrics], float]], ...] = (
        ('lost_motion_rad', lambda m: m.lost_motion_rad),
        ('backlash_rad', lambda m: m.backlash_rad),
        ('hysteresis_loss_j', lambda m: m.hysteresis_loss_j))
    for name, get in getters:
        values[name], spread[name] = mean_sd([get(m) for m in cycles])
    for r in config.rigidity_regions:
        pos, _ = mean_sd([m.rigidity_nm_per_rad[r.name][0] for m in cycles])
        neg, _ = mean_sd([m.rigidity_nm_per_rad[r.name][1] for m in cycles])
        name = f'torsional_rigidity_{r.name}_nm_per_rad'
        values[name] = min(pos, neg) if math.isfinite(pos) and math.isfinite(neg) \
            else math.nan
        _, spread[name] = mean_sd([m.rigidity_min_nm_per_rad(r.name) for m in cycles])
    return values, spread


def _missing(m: HysteresisMetrics, config: HysteresisConfig) -> list[str]:
    """Which readings of one cycle came out NaN, in words."""
    out = []
    tr = config.rated_torque_nm
    if not math.isfinite(m.zero_width_rad[0]):
        out.append('the loading from -T_R does not come back to 0 N m')
    if not math.isfinite(m.zero_width_rad[1]):
        out.append('the unloading from +T_R does not reach 0 N m')
    if not math.isfinite(m.lost_motion_rad) and all(map(math.isfinite, m.zero_width_rad)):
        out.append(f'a branch does not reach +-{m.lost_motion_torque_nm:.4g} N m')
    for r in config.rigidity_regions:
        pos, neg = m.rigidity_nm_per_rad[r.name]
        if not (math.isfinite(pos) and math.isfinite(neg)):
            out.append(f'rigidity {r.name} needs +-{r.hi_fraction * tr:.4g} N m (reached '
                       f'{m.max_torque_nm:+.4g} / {m.min_torque_nm:+.4g} N m)')
    return out


def measured_hysteresis(time_s: npt.ArrayLike, torque_nm: npt.ArrayLike,
                        angle_rad: npt.ArrayLike, config: HysteresisConfig,
                        reading: HysteresisReading) -> MeasuredHysteresis:
    """Lost motion, backlash, rigidity and loss of a measured record, averaged over cycles.

    Args:
        time_s: Sample times [s] (any origin), increasing.
        torque_nm: Torque applied to the output per sample [N m] (positive twists it
            positively).
        angle_rad: Output torsion angle per sample [rad] (any constant offset).
        config: Rated torque, lost-motion torque, rigidity regions.
        reading: Dwell detection / local-fit settings.

    Returns:
        The cycles and their averaged metrics.

    Raises:
        TeInputError: Lengths differ, a sample is not finite, too few held torques, or no
            complete load cycle (the message says what the record reaches).
    """
    tm = np.asarray(time_s, dtype=np.float64).ravel()
    tq = np.asarray(torque_nm, dtype=np.float64).ravel()
    an = np.asarray(angle_rad, dtype=np.float64).ravel()
    if not (tm.size == tq.size == an.size):
        msg = f'time, torque and angle differ in length: {tm.size}, {tq.size}, {an.size}'
        raise TeInputError(msg)
    tr = config.rated_torque_nm
    noise = torque_noise_nm(tq)
    if reading.method == 'torque_steps':
        d = find_dwells(tq, an, min_samples=reading.min_dwell_samples,
                        resolution_nm=reading.resolution_nm, noise_nm=noise)
        pt, pa, ptime = np.asarray(d.torque_nm), np.asarray(d.angle_rad), None
        read = point_reader(reading.resolution_nm)
        n_dwells = int(d.torque_nm.size)
        cyc_t = pt
    else:
        w = reading.half_width_nm
        if not math.isfinite(w):
            w = max(3.0 * noise, 0.004 * tr)
        smooth = max(1, math.ceil((4.0 * noise / w) ** 2))
        read = sample_reader(w, smooth)
        pt, pa, ptime = tq, an, tm
        n_dwells = 0
        k = max(1, min(tq.size // 50 or 1, 25))
        cyc_t = np.convolve(tq, np.ones(k) / k, mode='same') if tq.size >= k else tq
    bounds = split_cycles(cyc_t, tr)
    if reading.method != 'torque_steps' and bounds:
        # the smoothed record finds the turns; the raw samples say where exactly they are
        # (a reversal drops the torque by twice the friction at once: smoothing shifts the
        # extreme before it)
        bounds = [_refine(c, tq, k) for c in bounds]
    if not bounds:
        hi = float(np.max(tq)) if tq.size else math.nan
        lo = float(np.min(tq)) if tq.size else math.nan
        msg = (f'no complete load cycle 0 -> +T_R -> 0 -> -T_R -> 0 (T_R = {tr:.6g} N m): '
               f'the torque reaches {hi:+.4g} / {lo:+.4g} N m, and a cycle needs '
               f'+{_EXCURSION * tr:.4g} N m followed by -{_EXCURSION * tr:.4g} N m'
               + (f' ({n_dwells} held torques found)' if reading.method == 'torque_steps'
                  else ''))
        raise TeInputError(msg)
    if reading.method == 'torque_steps':
        short = [j + 1 for j, c in enumerate(bounds)
                 if min(c.peak - c.up_start, c.trough - c.peak, c.back_end - c.trough) < 2]
        if short:
            msg = (f'too few held torques on a branch of cycle {short[0]} (torque noise '
                   f'{noise:.3g} N m; dwells shorter than {reading.min_dwell_samples} samples '
                   'are not counted)')
            raise TeInputError(msg)
    def br(a: int, b: int) -> Branch:
        return Branch(pt[a:b + 1], pa[a:b + 1], None if ptime is None else ptime[a:b + 1])

    cycles = [cycle_metrics(br(c.up_start, c.peak), br(c.peak, c.trough),
                            br(c.trough, c.back_end), config, read) for c in bounds]
    if reading.method == 'torque_steps':
        # the loop's area from the samples: the loader's path between the held torques
        # (its ramps) is where the play is crossed; the polygon of the dwell points would
        # cut those corners. Noise in the torque adds no area on average.
        def sb(a: int, b: int) -> Branch:
            return Branch(tq[int(d.start[a]):int(d.stop[b])], an[int(d.start[a]):int(d.stop[b])])

        cycles = [dataclasses.replace(m, hysteresis_loss_j=loop_area(
            sb(c.up_start, c.peak), sb(c.peak, c.trough), sb(c.trough, c.back_end), config))
            for m, c in zip(cycles, bounds, strict=True)]
    values, spread = _aggregate(cycles, config)
    missing: list[str] = []
    for j, m in enumerate(cycles):
        missing += [f'cycle {j + 1}: {x}' for x in _missing(m, config)]
    for arr in (pt, pa):
        arr.setflags(write=False)
    return MeasuredHysteresis(cycles=tuple(cycles), values=values, spread=spread,
                              torque_noise_nm=noise, points=(pt, pa), dwells=n_dwells,
                              missing=tuple(missing))
