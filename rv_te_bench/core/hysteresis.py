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

A value of a branch at torque T0 is read at the branch's first crossing of T0 in time order,
interpolated linearly between the two samples around it (a run of samples exactly at T0,
as in an equal-torque-step test, is averaged).

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
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.errors import TeConfigError, TeInputError

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = [
    'DEFAULT_RIGIDITY_REGIONS',
    'HysteresisConfig',
    'HysteresisMetrics',
    'RigidityRegion',
    'branch_value',
    'dwell_points',
    'hysteresis_metrics',
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
    """Reduce runs of consecutive samples at one torque to one point (their mean angle).

    An equal-torque-step test holds each step for a dwell; averaging the dwell takes out
    the encoder noise. A continuously loaded record has no runs and comes back unchanged.

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
    starts = np.flatnonzero(np.r_[True, t[1:] != t[:-1]])
    counts = np.diff(np.r_[starts, t.size])
    sums = np.add.reduceat(a, starts)
    return t[starts].copy(), sums / counts, counts


def branch_value(torque_nm: np.ndarray, angle_rad: np.ndarray, t0_nm: float, *,
                 direction: int, end_tolerance_nm: float = 0.0) -> float:
    """Angle of a branch at its first crossing of ``t0_nm`` in time order [rad].

    Args:
        torque_nm, angle_rad: The branch, in time order.
        t0_nm: Torque to read at [N m].
        direction: +1 for a branch loaded upwards (first sample with T >= t0), -1 for one
            loaded downwards (first sample with T <= t0).
        end_tolerance_nm: If the branch never reaches t0 but its extreme lies within this
            of it, the extreme's angle is returned.

    Returns:
        The interpolated angle; NaN when the branch does not reach ``t0_nm``. A run of
        samples exactly at ``t0_nm`` gives the mean of its angles.
    """
    if torque_nm.size == 0:
        return math.nan
    s = direction * (torque_nm - t0_nm)
    hit = np.flatnonzero(s >= 0)
    if hit.size == 0:
        k = int(np.argmax(s))
        return float(angle_rad[k]) if -s[k] <= end_tolerance_nm else math.nan
    k = int(hit[0])
    if s[k] == 0:
        run = np.flatnonzero(s[k:] != 0)
        end = k + (int(run[0]) if run.size else s.size - k)
        return float(np.mean(angle_rad[k:end]))
    if k == 0:
        return float(angle_rad[0])
    t1, t2 = torque_nm[k - 1], torque_nm[k]
    w = (t0_nm - t1) / (t2 - t1)
    return float(angle_rad[k - 1] + w * (angle_rad[k] - angle_rad[k - 1]))


def _loop_area(t_loop: np.ndarray, a_loop: np.ndarray) -> float:
    """Area of the closed polygon (angle, torque) [N m rad]."""
    if t_loop.size < 3:
        return math.nan
    x, y = a_loop, t_loop
    return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def hysteresis_metrics(torque_nm: npt.ArrayLike, angle_rad: npt.ArrayLike,
                       config: HysteresisConfig) -> HysteresisMetrics:
    """Lost motion, backlash, torsional rigidity and hysteresis loss of one load cycle.

    Args:
        torque_nm: Torque applied to the output [N m], in time order, one cycle
            0 -> +T_R -> 0 -> -T_R -> 0 (samples or dwell points, see :func:`dwell_points`).
        angle_rad: Output torsion angle at those samples [rad] (any constant offset).
        config: Rated torque, lost-motion torque, rigidity regions.

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
    if t.size < 5:
        msg = f'a hysteresis record needs at least 5 points, got {t.size}'
        raise TeInputError(msg)
    i_max, i_min = int(np.argmax(t)), int(np.argmin(t))
    if not (t[i_max] > 0 > t[i_min]) or i_max >= i_min:
        msg = ('a hysteresis record must load to a positive torque first, then to a '
               f'negative one (0 -> +T_R -> 0 -> -T_R -> 0); its maximum {t[i_max]:.6g} N m '
               f'is at point {i_max}, its minimum {t[i_min]:.6g} N m at point {i_min}')
        raise TeInputError(msg)
    tr = config.rated_torque_nm
    tol = _END_TOLERANCE * tr
    up_t, up_a = t[:i_max + 1], a[:i_max + 1]           # first loading 0 -> +T_R
    dn_t, dn_a = t[i_max:i_min + 1], a[i_max:i_min + 1]  # +T_R -> -T_R
    back_t, back_a = t[i_min:], a[i_min:]               # -T_R -> 0

    def asc(t0: float) -> float:
        if t0 <= 0:
            return branch_value(back_t, back_a, t0, direction=+1, end_tolerance_nm=tol)
        return branch_value(up_t, up_a, t0, direction=+1, end_tolerance_nm=tol)

    def desc(t0: float) -> float:
        return branch_value(dn_t, dn_a, t0, direction=-1, end_tolerance_nm=tol)

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
    # the loop: descending branch, then -T_R -> 0, then the first loading above zero torque
    first_pos = np.flatnonzero(up_t > 0)
    up_from = int(first_pos[0]) if first_pos.size else up_t.size
    loop_t = np.r_[dn_t, back_t[1:], up_t[up_from:-1]]
    loop_a = np.r_[dn_a, back_a[1:], up_a[up_from:-1]]
    asc_t = np.r_[back_t, up_t[up_from:]]
    asc_a = np.r_[back_a, up_a[up_from:]]
    for arr in (asc_t, asc_a, dn_t, dn_a):
        arr.setflags(write=False)
    return HysteresisMetrics(
        backlash_rad=float(zero[1] - zero[0]),
        lost_motion_rad=float(mid_pos - mid_neg),
        lost_motion_torque_nm=float(lm_t),
        rigidity_nm_per_rad=rigidity,
        hysteresis_loss_j=_loop_area(loop_t, loop_a),
        rated_torque_nm=float(tr),
        max_torque_nm=float(t[i_max]),
        min_torque_nm=float(t[i_min]),
        zero_width_rad=(float(zero[0]), float(zero[1])),
        lost_motion_mid_rad=(float(mid_neg), float(mid_pos)),
        rigidity_points=points,
        ascending=(asc_t, asc_a),
        descending=(dn_t.copy(), dn_a.copy()),
    )
