"""Hysteresis-curve metrics of a reducer: lost motion, backlash, torsional rigidity, loss.

The test (GB/T 35089-2018 bench test; reducer catalogues; docs/ACCEPTANCE.md): the input
shaft is locked and a torque is applied to the output quasi-statically,
0 -> +T_R -> 0 -> -T_R -> 0 (T_R the rated torque); the hysteresis curve is the output
torsion angle against that torque. Here the torque is the torque *applied to* the output,
positive in the positive (REP-103) sense of rotation, so that a positive torque twists the
output to a positive angle.

Branches. The record (in time order) is split at its torque maximum and minimum:

* descending branch: from the maximum to the minimum (+T_R -> 0 -> -T_R);
* ascending branch: from the minimum to the end (-T_R -> 0) for torques <= 0, and the first
  loading, from the start to the maximum (0 -> +T_R), for torques > 0 (the standard sequence
  has no second loading; the first one starts somewhere inside the backlash unless the unit
  was preloaded, so its point at zero torque is never used).

Points. This module reads curves of *points*: the dwell means of an equal-torque-step test
or noise-free samples. A value of a branch at torque T0 is the point at T0 (within
``match_nm``), else interpolated linearly between the two points around the branch's
crossing of T0 (a run of points exactly at T0 is averaged). A measured record (torque
noise, dwells whose torque is not exactly constant, several load cycles) is reduced to
such points, or read by local fits, by :mod:`rv_te_bench.core.hysteresis_measured`; the
first crossing of a noisy sample record would be biased (the noise crosses T0 early).

Metrics (catalogue definitions, our reading in docs/ACCEPTANCE.md):

* backlash: width of the curve at zero torque, phi_desc(0) - phi_asc(0);
* lost motion: distance between the mid-points of the curve's width at +t and -t, with
  t = lost_motion_fraction x T_R (makers use 3 %; some 5 %):
  (phi_asc(t) + phi_desc(t)) / 2 - (phi_asc(-t) + phi_desc(-t)) / 2;
* torsional rigidity of a region [lo, hi] x T_R: the secant slope of the loading branch,
  (hi - lo) T_R / (phi(hi T_R) - phi(lo T_R)), on the first loading for the positive side
  and on the descending branch below zero for the negative side (Nabtesco's b/a with
  50-100 % of rated torque is the default region; Harmonic-Drive style K1/K2/K3 are three
  regions);
* hysteresis loss: the area of the loop, the energy dissipated in one load cycle [J]
  (shoelace formula on the closed loop: descending branch, then the ascending one). It is
  exact when the first loading starts on the negative flank, i.e. after a preload to -T_R
  (the plan's hysteresis step does one); from the middle of the play it misses about
  T_f x backlash / 2.

Everything is SI: angles in rad, torques in N m, rigidity in N m/rad.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from rv_te_bench.errors import TeConfigError, TeInputError

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = [
    'DEFAULT_RIGIDITY_REGIONS',
    'Branch',
    'BranchPlan',
    'BranchReader',
    'CycleReadings',
    'HysteresisConfig',
    'HysteresisMetrics',
    'PointCycle',
    'RigidityRegion',
    'branch_plan',
    'branch_value',
    'cycle_metrics',
    'dwell_points',
    'hysteresis_metrics',
    'loop_area',
    'point_reader',
    'read_cycle',
    'read_plan',
]

#: Part of T_R by which a branch may fall short of a wanted torque and still be read at its
#: end (the turning point of a test that stopped a hair below the rated torque).
_END_TOLERANCE = 0.005


@dataclass(frozen=True)
class RigidityRegion:
    """A torque region [lo, hi] x T_R whose secant slope is a torsional rigidity.

    Attributes:
        name: Short name, e.g. ``'K'`` (catalogue b/a) or ``'K1'`` (Harmonic-Drive style).
        lo_fraction: Lower end as a fraction of the rated torque, > 0 (the loading branch
            starts inside the backlash, so its zero-torque point means nothing).
        hi_fraction: Upper end, lo_fraction < hi_fraction <= 1.
    """

    name: str
    lo_fraction: float
    hi_fraction: float

    def __post_init__(self) -> None:
        """Validate (TeConfigError names the region and the rule)."""
        if not isinstance(self.name, str) or not self.name.isidentifier():
            msg = f'rigidity region name must be an identifier, got {self.name!r}'
            raise TeConfigError(msg)
        lo, hi = self.lo_fraction, self.hi_fraction
        if not (isinstance(lo, int | float) and isinstance(hi, int | float)
                and math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi <= 1):
            msg = (f'rigidity region {self.name!r}: need 0 < lo_fraction < hi_fraction <= 1 '
                   f'(fractions of the rated torque), got [{lo!r}, {hi!r}]')
            raise TeConfigError(msg)


DEFAULT_RIGIDITY_REGIONS = (RigidityRegion('K', 0.5, 1.0),)


@dataclass(frozen=True)
class HysteresisConfig:
    """How the curve is read (SI units).

    Attributes:
        rated_torque_nm: T_R [N m], > 0.
        lost_motion_fraction: t / T_R of the lost motion, in (0, 0.5] (makers: 0.03).
        rigidity_regions: Regions of the torsional rigidity (names unique).
    """

    rated_torque_nm: float
    lost_motion_fraction: float = 0.03
    rigidity_regions: tuple[RigidityRegion, ...] = DEFAULT_RIGIDITY_REGIONS

    def __post_init__(self) -> None:
        """Validate (TeConfigError names the field and the rule)."""
        t = self.rated_torque_nm
        if isinstance(t, bool) or not isinstance(t, int | float) or not (
                math.isfinite(t) and t > 0):
            msg = f'rated_torque_nm must be finite and > 0, got {t!r}'
            raise TeConfigError(msg)
        f = self.lost_motion_fraction
        if isinstance(f, bool) or not isinstance(f, int | float) or not (0 < f <= 0.5):
            msg = f'lost_motion_fraction must lie in (0, 0.5], got {f!r}'
            raise TeConfigError(msg)
        regions = tuple(self.rigidity_regions)
        if not regions or not all(isinstance(r, RigidityRegion) for r in regions):
            msg = 'rigidity_regions must be a non-empty sequence of RigidityRegion'
            raise TeConfigError(msg)
        names = [r.name for r in regions]
        if len(set(names)) != len(names):
            msg = f'rigidity region names must be unique, got {names}'
            raise TeConfigError(msg)
        object.__setattr__(self, 'rigidity_regions', regions)

    def torque_points_nm(self) -> tuple[float, ...]:
        """Every torque the metrics read the curve at (a torque-step test must visit them)."""
        tr = self.rated_torque_nm
        fr = {0.0, self.lost_motion_fraction, 1.0}
        for r in self.rigidity_regions:
            fr |= {r.lo_fraction, r.hi_fraction}
        pts = sorted({s * f * tr for f in fr for s in (1.0, -1.0)})
        return tuple(float(p) for p in pts)


@dataclass(frozen=True)
class HysteresisMetrics:
    """What the hysteresis curve gives (SI units; NaN where a point was not reached).

    Attributes:
        backlash_rad: Width of the curve at zero torque [rad].
        lost_motion_rad: Lost motion at +-lost_motion_torque_nm [rad].
        lost_motion_torque_nm: The t of the lost motion [N m].
        rigidity_nm_per_rad: Region name -> (positive side, negative side) [N m/rad].
        hysteresis_loss_j: Area of the loop [J = N m rad].
        rated_torque_nm: T_R [N m].
        max_torque_nm, min_torque_nm: Extremes reached [N m].
        zero_width_rad: (phi_asc(0), phi_desc(0)), the ends of the backlash [rad].
        lost_motion_mid_rad: (mid-point at -t, mid-point at +t) [rad].
        rigidity_points: Region name -> ((T1, phi1, T2, phi2) positive, same negative).
        ascending: (torque_nm, angle_rad) of the ascending branch (-T_R -> 0, then 0 -> +T_R).
        descending: (torque_nm, angle_rad) of the descending branch (+T_R -> -T_R).
    """

    backlash_rad: float
    lost_motion_rad: float
    lost_motion_torque_nm: float
    rigidity_nm_per_rad: dict[str, tuple[float, float]]
    hysteresis_loss_j: float
    rated_torque_nm: float
    max_torque_nm: float
    min_torque_nm: float
    zero_width_rad: tuple[float, float]
    lost_motion_mid_rad: tuple[float, float]
    rigidity_points: dict[str, tuple[tuple[float, ...], tuple[float, ...]]]
    ascending: tuple[np.ndarray, np.ndarray] = field(repr=False)
    descending: tuple[np.ndarray, np.ndarray] = field(repr=False)

    def rigidity_min_nm_per_rad(self, region: str) -> float:
        """The smaller of the two sides of ``region`` (NaN when one is missing)."""
        pos, neg = self.rigidity_nm_per_rad[region]
        return float(min(pos, neg)) if math.isfinite(pos) and math.isfinite(neg) else math.nan


def _as_pair(torque_nm: npt.ArrayLike, angle_rad: npt.ArrayLike) -> tuple[np.ndarray, ...]:
    t = np.asarray(torque_nm, dtype=np.float64).ravel()
    a = np.asarray(angle_rad, dtype=np.float64).ravel()
    if t.shape != a.shape:
        msg = f'torque and angle differ in length: {t.size} vs {a.size}'
        raise TeInputError(msg)
    bad = ~(np.isfinite(t) & np.isfinite(a))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        msg = f'sample {i} is not finite (torque {t[i]!r}, angle {a[i]!r})'
        raise TeInputError(msg)
    return t, a


def dwell_points(torque_nm: npt.ArrayLike, angle_rad: npt.ArrayLike,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reduce runs of consecutive samples at *exactly* one torque to one point (mean angle).

    For records whose held torque reads exactly constant (a simulated loader). A measured
    torque is never exactly constant: group its dwells by time and stability with
    :func:`rv_te_bench.core.hysteresis_measured.find_dwells` instead.

    Returns:
        (torque_nm, angle_rad, count): one entry per run, in time order.

    Examples:
        >>> t, a, n = dwell_points([0, 0, 5, 5, 5], [1.0, 3.0, 4.0, 5.0, 6.0])
        >>> t.tolist(), a.tolist(), n.tolist()
        ([0.0, 5.0], [2.0, 5.0], [2, 3])
    """
    t, a = _as_pair(torque_nm, angle_rad)
    if t.size == 0:
        return t, a, np.zeros(0, dtype=np.int64)
    starts = np.flatnonzero(np.concatenate(([True], t[1:] != t[:-1])))
    counts = np.diff(np.append(starts, t.size))
    sums = np.add.reduceat(a, starts)
    return t[starts].copy(), sums / counts, counts


def branch_value(torque_nm: np.ndarray, angle_rad: np.ndarray, t0_nm: float, *,
                 direction: int, end_tolerance_nm: float = 0.0, match_nm: float = 0.0) -> float:
    """Angle of a branch of curve *points* at torque ``t0_nm`` [rad].

    The points are dwell means (a torque-step test) or noise-free samples, in time order,
    loaded monotonically along the branch (steps of it may repeat a torque).

    Args:
        torque_nm, angle_rad: The branch, in time order.
        t0_nm: Torque to read at [N m].
        direction: +1 for a branch loaded upwards, -1 for one loaded downwards.
        end_tolerance_nm: If the branch never reaches t0 but its extreme lies within this
            of it, the extreme's angle is returned.
        match_nm: A point whose torque lies within this of ``t0_nm`` is read directly
            (the nearest such point; a held torque a loader did not hit exactly). 0: only
            an exact match.

    Returns:
        The angle of the matching point, else the angle interpolated linearly between the
        two points around the branch's crossing of ``t0_nm`` (a run of points exactly at
        ``t0_nm`` gives the mean of their angles); NaN when the branch does not reach it.
    """
    return read_plan(branch_plan(torque_nm, t0_nm, direction=direction,
                                 end_tolerance_nm=end_tolerance_nm, match_nm=match_nm),
                     angle_rad)


class BranchPlan(NamedTuple):
    """Which points :func:`branch_value` reads, found from the torques alone.

    Attributes:
        kind: ``'nan'`` (the branch does not reach the torque), ``'point'`` (the angle of
            point ``k``), ``'mean'`` (the mean angle of points ``k`` to ``end - 1``, a run
            exactly at the torque) or ``'lerp'`` (between points ``k - 1`` and ``k`` with
            weight ``w`` on the change).
    """

    kind: str
    k: int = 0
    end: int = 0
    w: float = math.nan

    def points(self) -> range:
        """The indices of the points the reading takes."""
        if self.kind == 'point':
            return range(self.k, self.k + 1)
        if self.kind == 'mean':
            return range(self.k, self.end)
        if self.kind == 'lerp':
            return range(self.k - 1, self.k + 1)
        return range(0)


def branch_plan(torque_nm: np.ndarray, t0_nm: float, *, direction: int,
                end_tolerance_nm: float = 0.0, match_nm: float = 0.0) -> BranchPlan:
    """How :func:`branch_value` reads the branch at ``t0_nm`` (same arguments, no angles)."""
    if torque_nm.size == 0:
        return BranchPlan('nan')
    s = direction * (torque_nm - t0_nm)
    if match_nm > 0:
        near = np.abs(s)
        k = int(np.argmin(near))
        if near[k] <= match_nm and near[k] > 0:
            return BranchPlan('point', k)
    hit = np.flatnonzero(s >= 0)
    if hit.size == 0:
        k = int(np.argmax(s))
        return BranchPlan('point', k) if -s[k] <= end_tolerance_nm else BranchPlan('nan')
    k = int(hit[0])
    if s[k] == 0:
        run = np.flatnonzero(s[k:] != 0)
        return BranchPlan('mean', k, k + (int(run[0]) if run.size else s.size - k))
    if k == 0:
        return BranchPlan('point', 0)
    t1, t2 = torque_nm[k - 1], torque_nm[k]
    return BranchPlan('lerp', k, w=(t0_nm - t1) / (t2 - t1))


def read_plan(plan: BranchPlan, angle_rad: np.ndarray) -> float:
    """The angle a :class:`BranchPlan` reads from the branch's angles [rad]."""
    kind, k = plan.kind, plan.k
    if kind == 'point':
        return float(angle_rad[k])
    if kind == 'lerp':
        return float(angle_rad[k - 1] + plan.w * (angle_rad[k] - angle_rad[k - 1]))
    if kind == 'mean':
        return float(np.mean(angle_rad[k:plan.end]))
    return math.nan


class Branch(NamedTuple):
    """One branch of a load cycle, in time order (SI).

    Attributes:
        torque_nm: Applied torque of its points or samples [N m].
        angle_rad: Output torsion angle [rad].
        time_s: Sample times [s] (None for dwell points).
    """

    torque_nm: np.ndarray
    angle_rad: np.ndarray
    time_s: np.ndarray | None = None


#: Reads a branch at a torque: (branch, t0_nm, direction +1/-1, end tolerance) -> angle.
BranchReader = Callable[[Branch, float, int, float], float]


def point_reader(match_nm: float = 0.0) -> BranchReader:
    """The reader of curve points (:func:`branch_value`, points within ``match_nm``)."""
    def read(b: Branch, t0: float, direction: int, end_tol: float) -> float:
        return branch_value(b.torque_nm, b.angle_rad, t0, direction=direction,
                            end_tolerance_nm=end_tol, match_nm=match_nm)
    return read


def _loop_area(t_loop: np.ndarray, a_loop: np.ndarray) -> float:
    """Area of the closed polygon (angle, torque) [N m rad]."""
    if t_loop.size < 3:
        return math.nan
    # about the loop's own centre: the shoelace terms are then of the loop's size, not of
    # its distance from zero (an output angle of radians, a loop of micro-radians), so the
    # difference of the two sums does not cancel away the area's digits (the budget's
    # finite differences moved 2 % with the BLAS dot product's summation order)
    x, y = a_loop - a_loop.mean(), t_loop - t_loop.mean()
    # np.roll(v, -1), without its generic-axis overhead (this runs per perturbed point)
    y1, x1 = np.concatenate((y[1:], y[:1])), np.concatenate((x[1:], x[:1]))
    return float(0.5 * abs(np.dot(x, y1) - np.dot(y, x1)))


def hysteresis_metrics(torque_nm: npt.ArrayLike, angle_rad: npt.ArrayLike,
                       config: HysteresisConfig, *, match_nm: float = 0.0) -> HysteresisMetrics:
    """Lost motion, backlash, torsional rigidity and hysteresis loss of one load cycle.

    Args:
        torque_nm: Torque applied to the output [N m], in time order, one cycle
            0 -> +T_R -> 0 -> -T_R -> 0 (samples or dwell points, see :func:`dwell_points`).
        angle_rad: Output torsion angle at those samples [rad] (any constant offset).
        config: Rated torque, lost-motion torque, rigidity regions.
        match_nm: A point within this of a torque the metrics read is read directly
            (:func:`branch_value`); 0: exact matches only.

    Returns:
        The metrics; a point the record does not reach gives NaN for what needs it.

    Raises:
        TeInputError: Lengths differ, a sample is not finite, fewer than 5 points, or the
            record does not go both ways through zero torque.

    Examples:
        A linear unit (1e5 N m/rad) with 1e-3 rad of backlash and no friction:

        >>> k, b = 1e5, 1e-3
        >>> t = np.r_[np.linspace(0, 100, 11), np.linspace(90, -100, 20),
        ...           np.linspace(-90, 0, 10)]
        >>> phi = np.where(t > 0, b / 2 + t / k, np.where(t < 0, -b / 2 + t / k, 0.0))
        >>> phi[10:21] = b / 2 + t[10:21] / k        # unloading from +T_R ends at +b/2
        >>> phi[-1] = -b / 2                          # and from -T_R at -b/2
        >>> m = hysteresis_metrics(t, phi, HysteresisConfig(rated_torque_nm=100.0))
        >>> round(m.backlash_rad, 12), round(m.rigidity_nm_per_rad['K'][0])
        (0.001, 100000)
    """
    t, a = _as_pair(torque_nm, angle_rad)
    i_max, i_min = _turns(t)
    return cycle_metrics(Branch(t[:i_max + 1], a[:i_max + 1]),
                         Branch(t[i_max:i_min + 1], a[i_max:i_min + 1]),
                         Branch(t[i_min:], a[i_min:]), config, point_reader(match_nm))


def _turns(t: np.ndarray) -> tuple[int, int]:
    """Indices of the torque maximum and minimum of one cycle's points (validated)."""
    if t.size < 5:
        msg = f'a hysteresis record needs at least 5 points, got {t.size}'
        raise TeInputError(msg)
    i_max, i_min = int(np.argmax(t)), int(np.argmin(t))
    if not (t[i_max] > 0 > t[i_min]) or i_max >= i_min:
        msg = ('a hysteresis record must load to a positive torque first, then to a '
               f'negative one (0 -> +T_R -> 0 -> -T_R -> 0); its maximum {t[i_max]:.6g} N m '
               f'is at point {i_max}, its minimum {t[i_min]:.6g} N m at point {i_min}')
        raise TeInputError(msg)
    return i_max, i_min


class PointCycle:
    """One load cycle of curve points at fixed torques, read as :func:`hysteresis_metrics`
    reads it (exact matches only), with the points each reading takes.

    The torques alone decide which points a reading takes and with which weights, and
    which points make the loop: found once, the metrics of any angles at these torques
    follow without searching the branches again, and a change of one point's angle reads
    again only what that point enters (the uncertainty budget moves every point in turn:
    :mod:`rv_te_bench.core.hysteresis_uncertainty`). The values are those of
    :func:`hysteresis_metrics`, bit for bit.

    Raises:
        TeInputError: As :func:`hysteresis_metrics`.
    """

    def __init__(self, torque_nm: npt.ArrayLike, config: HysteresisConfig) -> None:
        """Find the readings' points and the loop of ``torque_nm`` under ``config``."""
        t = np.asarray(torque_nm, dtype=np.float64).ravel()
        _as_pair(t, t)
        i_max, i_min = _turns(t)
        self.config = config
        tol = _END_TOLERANCE * config.rated_torque_nm
        #: (direction, t0) -> (index of the branch's first point, how it is read)
        self.plans: dict[tuple[int, float], tuple[int, BranchPlan]] = {}

        def planned(direction: int, start: int, stop: int, t0: float) -> float:
            self.plans[direction, t0] = (start, branch_plan(
                t[start:stop], t0, direction=direction, end_tolerance_nm=tol))
            return 0.0

        read_cycle(lambda t0: planned(+1, *((i_min, t.size) if t0 <= 0 else (0, i_max + 1)),
                                      t0),
                   lambda t0: planned(-1, i_max, i_min + 1, t0), config)
        back_end = i_min + _to_zero(Branch(t[i_min:], t[i_min:]), tol)[0].size
        up_from = _first_positive(Branch(t[:i_max + 1], t[:i_max + 1]))
        #: The points of the loop, in the order :func:`loop_area` takes them.
        self.loop_index = np.concatenate((np.arange(i_max, i_min + 1),
                                          np.arange(i_min + 1, back_end),
                                          np.arange(up_from, i_max)))
        self._loop_t = t[self.loop_index]

    def points(self, key: tuple[int, float]) -> range:
        """The indices of the points a reading (key of :attr:`plans`) takes."""
        start, plan = self.plans[key]
        r = plan.points()
        return range(start + r.start, start + r.stop)

    def read(self, key: tuple[int, float], angle_rad: np.ndarray) -> float:
        """One reading of the cycle's angles [rad]."""
        start, plan = self.plans[key]
        return read_plan(plan, angle_rad[start:])

    def readings(self, angle_rad: np.ndarray) -> dict[tuple[int, float], float]:
        """Every reading of the cycle's angles [rad]."""
        return {key: self.read(key, angle_rad) for key in self.plans}

    def cycle(self, readings: dict[tuple[int, float], float]) -> CycleReadings:
        """Backlash, lost motion and rigidity from the readings."""
        return read_cycle(lambda t0: readings[+1, t0], lambda t0: readings[-1, t0],
                          self.config)

    def loss(self, angle_rad: np.ndarray) -> float:
        """The hysteresis loss (area of the loop) [J]."""
        return _loop_area(self._loop_t, angle_rad[self.loop_index])


def _to_zero(back: Branch, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The back branch up to zero torque (a multi-cycle record goes on to the next +T_R)."""
    above = np.flatnonzero(back.torque_nm > tol)
    end = int(above[0]) if above.size else back.torque_nm.size
    return back.torque_nm[:end], back.angle_rad[:end]


def _first_positive(up: Branch) -> int:
    first = np.flatnonzero(up.torque_nm > 0)
    return int(first[0]) if first.size else up.torque_nm.size


def loop_area(up: Branch, down: Branch, back: Branch, config: HysteresisConfig) -> float:
    """Area of one cycle's loop [J]: the descending branch, then -T_R -> 0, then the
    loading above zero torque, closed (shoelace formula over their points or samples)."""
    back_t, back_a = _to_zero(back, _END_TOLERANCE * config.rated_torque_nm)
    k = _first_positive(up)
    return _loop_area(np.concatenate((down.torque_nm, back_t[1:], up.torque_nm[k:-1])),
                      np.concatenate((down.angle_rad, back_a[1:], up.angle_rad[k:-1])))


class CycleReadings(NamedTuple):
    """What a load cycle's readings give, before the loop's area (SI units).

    Attributes:
        zero: (phi_asc(0), phi_desc(0)) [rad].
        mid_pos, mid_neg: Mid-points of the curve's width at +t and -t [rad].
        rigidity_nm_per_rad, rigidity_points: As :class:`HysteresisMetrics`'.
    """

    zero: tuple[float, float]
    mid_pos: float
    mid_neg: float
    rigidity_nm_per_rad: dict[str, tuple[float, float]]
    rigidity_points: dict[str, tuple[tuple[float, ...], tuple[float, ...]]]

    @property
    def backlash_rad(self) -> float:
        """Width of the curve at zero torque [rad]."""
        return float(self.zero[1] - self.zero[0])

    @property
    def lost_motion_rad(self) -> float:
        """Lost motion [rad]."""
        return float(self.mid_pos - self.mid_neg)


def read_cycle(asc: Callable[[float], float], desc: Callable[[float], float],
               config: HysteresisConfig) -> CycleReadings:
    """Backlash, lost motion and rigidity from the ascending and descending branches read
    at a torque (``asc(t0)``, ``desc(t0)`` [rad]): the readings of :func:`cycle_metrics`."""
    tr = config.rated_torque_nm
    zero = (asc(0.0), desc(0.0))
    lm_t = config.lost_motion_fraction * tr
    mid_pos = 0.5 * (asc(lm_t) + desc(lm_t))
    mid_neg = 0.5 * (asc(-lm_t) + desc(-lm_t))
    rigidity: dict[str, tuple[float, float]] = {}
    points: dict[str, tuple[tuple[float, ...], tuple[float, ...]]] = {}
    for reg in config.rigidity_regions:
        t1, t2 = reg.lo_fraction * tr, reg.hi_fraction * tr
        p1, p2 = asc(t1), asc(t2)
        n1, n2 = desc(-t1), desc(-t2)
        k_pos = (t2 - t1) / (p2 - p1) if p2 != p1 else math.nan
        k_neg = (t2 - t1) / (n1 - n2) if n1 != n2 else math.nan
        rigidity[reg.name] = (float(k_pos), float(k_neg))
        points[reg.name] = ((t1, p1, t2, p2), (-t1, n1, -t2, n2))
    return CycleReadings(zero, mid_pos, mid_neg, rigidity, points)


def cycle_metrics(up: Branch, down: Branch, back: Branch, config: HysteresisConfig,
                  read: BranchReader) -> HysteresisMetrics:
    """The metrics of one load cycle from its three branches.

    Args:
        up: The loading to +T_R (its part above zero torque is used: the first loading,
            or the loading from the previous cycle's -T_R).
        down: +T_R -> -T_R.
        back: -T_R -> 0 (it may go on to the next cycle's +T_R: only its part up to zero
            torque is used).
        config: Rated torque, lost-motion torque, rigidity regions.
        read: How a branch is read at a torque (:func:`point_reader` for dwell points,
            :func:`rv_te_bench.core.hysteresis_measured.sample_reader` for noisy samples).

    Returns:
        The metrics; NaN where a branch does not reach a torque a metric needs.
    """
    tol = _END_TOLERANCE * config.rated_torque_nm

    def asc(t0: float) -> float:
        return read(back if t0 <= 0 else up, t0, +1, tol)

    def desc(t0: float) -> float:
        return read(down, t0, -1, tol)

    r = read_cycle(asc, desc, config)
    up_t, up_a = up.torque_nm, up.angle_rad
    dn_t, dn_a = down.torque_nm, down.angle_rad
    back_t, back_a = _to_zero(back, tol)
    up_from = _first_positive(up)
    asc_t = np.concatenate((back_t, up_t[up_from:]))
    asc_a = np.concatenate((back_a, up_a[up_from:]))
    for arr in (asc_t, asc_a):
        arr.setflags(write=False)
    return HysteresisMetrics(
        backlash_rad=r.backlash_rad,
        lost_motion_rad=r.lost_motion_rad,
        lost_motion_torque_nm=float(config.lost_motion_fraction * config.rated_torque_nm),
        rigidity_nm_per_rad=r.rigidity_nm_per_rad,
        hysteresis_loss_j=loop_area(up, down, back, config),
        rated_torque_nm=float(config.rated_torque_nm),
        max_torque_nm=float(np.max(up_t)) if up_t.size else math.nan,
        min_torque_nm=float(np.min(dn_t)) if dn_t.size else math.nan,
        zero_width_rad=(float(r.zero[0]), float(r.zero[1])),
        lost_motion_mid_rad=(float(r.mid_neg), float(r.mid_pos)),
        rigidity_points=r.rigidity_points,
        ascending=(asc_t, asc_a),
        descending=(dn_t.copy(), dn_a.copy()),
    )
