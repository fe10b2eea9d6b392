"""Statistical process control across units: control charts, run rules, capability.

A quality lab charts one metric per unit (TE peak-to-peak, lost motion, the 1 f_w line
amplitude, ...) in test order, so that a drifting part shows before units fail:

* **individuals and moving range (I-MR)**: one value per unit. The centre line is the mean
  of a stated baseline; the process sigma is estimated within the baseline from the average
  moving range of consecutive units, sigma = MR-bar / d2(2) (d2(2) = 1.128), so that a
  drift inside the baseline does not inflate it. Limits: centre +- 3 sigma; the MR chart
  has centre MR-bar and upper limit D4(2) MR-bar.
* **X-bar and R by lot**: one subgroup per lot (2-25 units). Centre X-bar-bar and R-bar of
  the baseline lots; sigma = R-bar / d2(n) (n the lots' size); X-bar limits
  X-bar-bar +- 3 sigma / sqrt(n) (= A2 R-bar for constant n); R limits D3 R-bar, D4 R-bar
  (D3/D4 = 1 -+ 3 d3/d2). Lots of unequal size get their own limits.
* **run rules** on the standardised values z = (x - centre) / sigma_chart (Nelson 1984;
  the Western Electric Handbook 1956 set is rules 1, 5, 6 and "8 in a row on one side").
  A rule is flagged at the point that completes its pattern.
* **capability** against a tolerance: Cp = (USL - LSL) / 6 sigma, Cpk = min(USL - mu,
  mu - LSL) / 3 sigma with the within sigma (Pp, Ppk with the overall standard deviation);
  a one-sided tolerance (TE <= 1 arcmin) gives Cpk only.

The constants d2(n) and d3(n) are computed from the normal range distribution (Tippett
1925) by quadrature, not copied from a table; the tests compare them with the published
table. All functions are pure numpy; values are in whatever unit the caller uses (SI in
this suite), the charts convert at the edge.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, TypedDict

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from rv_te_bench.errors import SpcError

if TYPE_CHECKING:
    from collections.abc import Sequence

    import numpy.typing as npt

__all__ = ['NELSON_RULES', 'WESTERN_ELECTRIC_RULES', 'Capability', 'CapabilityJson',
           'ControlChart', 'ControlChartJson', 'RuleHit', 'capability', 'd2', 'd3',
           'individuals_chart', 'run_rules', 'xbar_r_chart']

RuleSet = Literal['nelson', 'western-electric']

#: Rule name -> what it means (Nelson 1984 numbering).
NELSON_RULES: dict[str, str] = {
    'N1': '1 point beyond 3 sigma',
    'N2': '9 points in a row on one side of the centre line',
    'N3': '6 points in a row steadily increasing or decreasing',
    'N4': '14 points in a row alternating up and down',
    'N5': '2 of 3 points in a row beyond 2 sigma on one side',
    'N6': '4 of 5 points in a row beyond 1 sigma on one side',
    'N7': '15 points in a row within 1 sigma of the centre line',
    'N8': '8 points in a row beyond 1 sigma, on either side',
}
#: The Western Electric Handbook rules.
WESTERN_ELECTRIC_RULES: dict[str, str] = {
    'WE1': '1 point beyond 3 sigma',
    'WE2': '2 of 3 points in a row beyond 2 sigma on one side',
    'WE3': '4 of 5 points in a row beyond 1 sigma on one side',
    'WE4': '8 points in a row on one side of the centre line',
}
_MIN_BASELINE = 2
_MAX_SUBGROUP = 25


@functools.lru_cache(maxsize=64)
def _range_moments(n: int) -> tuple[float, float]:
    """E[W], E[W^2] of the range W of n standard normal values (quadrature)."""
    x = np.linspace(-9.0, 9.0, 3601)
    w = np.linspace(0.0, 14.0, 2801)
    phi = np.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi)
    from scipy.special import ndtr
    cdf = ndtr(x)
    xw = x[None, :] + w[:, None]
    inner = phi[None, :] * np.exp(-0.5 * xw * xw) / math.sqrt(2.0 * math.pi) \
        * np.clip(ndtr(xw) - cdf[None, :], 0.0, 1.0) ** (n - 2)
    pdf = n * (n - 1) * np.trapezoid(inner, x, axis=1)
    return float(np.trapezoid(w * pdf, w)), float(np.trapezoid(w * w * pdf, w))


def _check_n(n: int) -> int:
    if not (isinstance(n, (int, np.integer)) and 2 <= n <= _MAX_SUBGROUP):
        msg = f'subgroup size must be an integer in [2, {_MAX_SUBGROUP}], got {n!r}'
        raise SpcError(msg)
    return int(n)


def d2(n: int) -> float:
    """Mean range of ``n`` standard normal values (control-chart constant d2)."""
    return _range_moments(_check_n(n))[0]


def d3(n: int) -> float:
    """Standard deviation of the range of ``n`` standard normal values (constant d3)."""
    m1, m2 = _range_moments(_check_n(n))
    return math.sqrt(max(m2 - m1 * m1, 0.0))


class RuleHitJson(TypedDict):
    """A rule hit in :class:`ControlChartJson`."""

    rule: str
    index: int
    description: str


class ControlChartJson(TypedDict):
    """The JSON of :class:`ControlChart` (values scaled; None: not finite)."""

    kind: Literal['individuals', 'xbar-r']
    unit: str
    rules: RuleSet
    centre: float
    process_sigma: float
    values: list[float | None]
    lcl: list[float | None]
    ucl: list[float | None]
    spread: list[float | None]
    spread_centre: float
    spread_ucl: list[float | None]
    spread_lcl: list[float | None]
    sizes: list[int]
    baseline: list[int]
    hits: list[RuleHitJson]


class CapabilityJson(TypedDict):
    """The JSON of :class:`Capability` (limits, mean and sigmas scaled; None: none)."""

    unit: str
    lsl: float | None
    usl: float | None
    mean: float
    sigma_within: float
    sigma_overall: float
    n: int
    cp: float | None
    cpk: float | None
    pp: float | None
    ppk: float | None
    fraction_out: float
    sigma_measurement: float | None
    cp_corrected: float | None
    cpk_corrected: float | None
    pp_corrected: float | None
    ppk_corrected: float | None


@dataclass(frozen=True, slots=True)
class RuleHit:
    """One run rule fired at ``index`` (the point completing the pattern)."""

    rule: str
    index: int
    description: str


@dataclass(frozen=True)
class ControlChart:
    """A control chart of one metric (values in the caller's unit).

    Attributes:
        kind: 'individuals' (I-MR) or 'xbar-r'.
        values: Plotted statistic per point (unit values, or lot means).
        centre: Centre line.
        sigma: Sigma of one plotted point (the limits are centre +- 3 sigma), per point.
        lcl, ucl: Control limits per point.
        spread: Moving ranges (I-MR; first is NaN) or lot ranges.
        spread_centre, spread_lcl, spread_ucl: MR-bar or R-bar and its limits, per point.
        process_sigma: Within sigma of one unit (MR-bar / d2(2) or R-bar / d2(n)).
        baseline: Indices of the points that set the centre and sigma.
        hits: Run-rule hits, in index order.
        rules: The rule set applied.
        sizes: Units per point (1 for individuals).
    """

    kind: Literal['individuals', 'xbar-r']
    values: np.ndarray
    centre: float
    sigma: np.ndarray
    lcl: np.ndarray
    ucl: np.ndarray
    spread: np.ndarray
    spread_centre: float
    spread_lcl: np.ndarray
    spread_ucl: np.ndarray
    process_sigma: float
    baseline: np.ndarray
    hits: tuple[RuleHit, ...]
    rules: RuleSet
    sizes: np.ndarray = field(default_factory=lambda: np.ones(0, dtype=np.int64))

    def __post_init__(self) -> None:
        for name in ('values', 'sigma', 'lcl', 'ucl', 'spread', 'spread_lcl', 'spread_ucl',
                     'baseline', 'sizes'):
            getattr(self, name).setflags(write=False)

    @property
    def out_of_control(self) -> np.ndarray:
        """Indices flagged by any rule (sorted, unique)."""
        return np.unique(np.array([h.index for h in self.hits], dtype=np.int64))

    def first_signal(self) -> int | None:
        """Index of the first point any rule flags, or None."""
        return self.hits[0].index if self.hits else None

    def to_json_dict(self, scale: float = 1.0, unit: str = '') -> ControlChartJson:
        """JSON form; values multiplied by ``scale`` (e.g. rad -> arcmin) and tagged."""
        def arr(a: np.ndarray) -> list[float | None]:
            return [None if not math.isfinite(v) else float(v) * scale for v in a]
        return {
            'kind': self.kind, 'unit': unit, 'rules': self.rules,
            'centre': self.centre * scale, 'process_sigma': self.process_sigma * scale,
            'values': arr(self.values), 'lcl': arr(self.lcl), 'ucl': arr(self.ucl),
            'spread': arr(self.spread), 'spread_centre': self.spread_centre * scale,
            'spread_ucl': arr(self.spread_ucl), 'spread_lcl': arr(self.spread_lcl),
            'sizes': [int(s) for s in self.sizes],
            'baseline': [int(i) for i in self.baseline],
            'hits': [{'rule': h.rule, 'index': h.index, 'description': h.description}
                     for h in self.hits],
        }


def _finite_series(values: npt.ArrayLike, name: str) -> np.ndarray:
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 1:
        msg = f'{name} must be one-dimensional, got shape {x.shape}'
        raise SpcError(msg)
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        msg = f'{name}[{int(bad[0])}] is {float(x[bad[0]])!r}: every value must be finite'
        raise SpcError(msg)
    return x


def _baseline_index(n: int, baseline: slice | Sequence[int] | None, minimum: int) -> np.ndarray:
    if baseline is None:
        idx = np.arange(n)
    elif isinstance(baseline, slice):
        idx = np.arange(n)[baseline]
    else:
        idx = np.asarray(baseline, dtype=np.int64).ravel()
    if idx.size and (idx.min() < 0 or idx.max() >= n):
        msg = f'baseline indices must lie in [0, {n - 1}], got {idx.min()}..{idx.max()}'
        raise SpcError(msg)
    idx = np.unique(idx)
    if idx.size < minimum:
        msg = f'the baseline needs at least {minimum} points, got {idx.size}'
        raise SpcError(msg)
    return idx


def individuals_chart(values: npt.ArrayLike, *, baseline: slice | Sequence[int] | None = None,
                      rules: RuleSet = 'nelson') -> ControlChart:
    """I-MR chart of one value per unit in test order.

    Args:
        values: The metric per unit, in test order.
        baseline: Points that set the centre line and sigma (default: all). Limits from a
            stated in-control baseline are what make later points judgeable.
        rules: 'nelson' (N1-N8) or 'western-electric' (WE1-WE4).

    Raises:
        SpcError: Fewer than 2 baseline points, non-finite values, or zero variation.
    """
    x = _finite_series(values, 'values')
    base = _baseline_index(x.size, baseline, _MIN_BASELINE)
    mr = np.full(x.size, np.nan)
    mr[1:] = np.abs(np.diff(x))
    # moving ranges inside the baseline: consecutive baseline points only
    pairs = base[1:][np.diff(base) == 1]
    if pairs.size == 0:
        msg = 'the baseline needs two consecutive points for a moving range'
        raise SpcError(msg)
    mr_bar = float(mr[pairs].mean())
    sigma = mr_bar / d2(2)
    if not sigma > 0.0:
        msg = 'the baseline values do not vary (moving range 0): no sigma to chart against'
        raise SpcError(msg)
    centre = float(x[base].mean())
    s = np.full(x.size, sigma)
    d4 = 1.0 + 3.0 * d3(2) / d2(2)
    return ControlChart(
        kind='individuals', values=x, centre=centre, sigma=s, lcl=centre - 3 * s,
        ucl=centre + 3 * s, spread=mr, spread_centre=mr_bar,
        spread_lcl=np.zeros(x.size), spread_ucl=np.full(x.size, d4 * mr_bar),
        process_sigma=sigma, baseline=base,
        hits=tuple(run_rules((x - centre) / sigma, rules=rules)), rules=rules,
        sizes=np.ones(x.size, dtype=np.int64))


def xbar_r_chart(values: npt.ArrayLike, lots: Sequence[object], *,
                 baseline: slice | Sequence[int] | None = None,
                 rules: RuleSet = 'nelson') -> ControlChart:
    """X-bar/R chart with one subgroup per lot, lots in order of first appearance.

    Args:
        values: The metric per unit.
        lots: The lot of each unit (same length); a lot is a subgroup of 2-25 units.
        baseline: Subgroup indices that set the centre lines (default: all lots).
        rules: Run rules applied to the lot means.

    Raises:
        SpcError: A lot of 1 or more than 25 units, mismatched lengths, no variation.
    """
    x = _finite_series(values, 'values')
    if len(lots) != x.size:
        msg = f'lots has {len(lots)} entries for {x.size} values'
        raise SpcError(msg)
    keys = list(dict.fromkeys(lots))
    groups = [x[[i for i, lot in enumerate(lots) if lot == k]] for k in keys]
    for k, g in zip(keys, groups, strict=True):
        if not 2 <= g.size <= _MAX_SUBGROUP:
            msg = f'lot {k!r} has {g.size} unit(s): X-bar/R needs 2-{_MAX_SUBGROUP} per lot'
            raise SpcError(msg)
    n = np.array([g.size for g in groups])
    means = np.array([g.mean() for g in groups])
    ranges = np.array([np.ptp(g) for g in groups])
    base = _baseline_index(len(groups), baseline, _MIN_BASELINE)
    d2n = np.array([d2(int(k)) for k in n])
    d3n = np.array([d3(int(k)) for k in n])
    sigma = float(np.mean(ranges[base] / d2n[base]))
    if not sigma > 0.0:
        msg = 'the baseline lots do not vary (all ranges 0): no sigma to chart against'
        raise SpcError(msg)
    centre = float(np.average(means[base], weights=n[base]))
    s_mean = sigma / np.sqrt(n)
    r_centre = sigma * d2n
    return ControlChart(
        kind='xbar-r', values=means, centre=centre, sigma=s_mean, lcl=centre - 3 * s_mean,
        ucl=centre + 3 * s_mean, spread=ranges, spread_centre=float(np.mean(r_centre[base])),
        spread_lcl=np.maximum(r_centre - 3 * sigma * d3n, 0.0),
        spread_ucl=r_centre + 3 * sigma * d3n, process_sigma=sigma, baseline=base,
        hits=tuple(run_rules((means - centre) / s_mean, rules=rules)), rules=rules,
        sizes=n)


def _runs(flags: np.ndarray, length: int) -> np.ndarray:
    """Indices i where flags[i - length + 1 .. i] are all true."""
    if flags.size < length:
        return np.zeros(0, dtype=np.int64)
    win = sliding_window_view(flags, length).all(axis=1)
    return np.flatnonzero(win) + length - 1


def _k_of_m(flags: np.ndarray, k: int, m: int) -> np.ndarray:
    """Indices i where at least k of flags[i - m + 1 .. i] are true and flags[i] is."""
    if flags.size < m:
        return np.zeros(0, dtype=np.int64)
    count = sliding_window_view(flags.astype(np.int64), m).sum(axis=1)
    end = np.arange(m - 1, flags.size)
    idx: npt.NDArray[np.int64] = end[(count >= k) & flags[m - 1:]]
    return idx


def run_rules(z: npt.ArrayLike, *, rules: RuleSet = 'nelson') -> list[RuleHit]:
    """Run rules on standardised values z = (x - centre) / sigma, in index order.

    Each hit is the point that completes the pattern (for "2 of 3 beyond 2 sigma" the
    second point beyond 2 sigma). Patterns need the points on one side where stated.
    """
    z = np.asarray(z, dtype=np.float64)
    up, dn = z > 0, z < 0
    d = np.diff(z)
    hits: dict[str, np.ndarray] = {}
    beyond3 = np.flatnonzero(np.abs(z) > 3.0)
    two_of_3 = np.union1d(_k_of_m(z > 2.0, 2, 3), _k_of_m(z < -2.0, 2, 3))
    four_of_5 = np.union1d(_k_of_m(z > 1.0, 4, 5), _k_of_m(z < -1.0, 4, 5))
    if rules == 'nelson':
        hits['N1'] = beyond3
        hits['N2'] = np.union1d(_runs(up, 9), _runs(dn, 9))
        hits['N3'] = np.union1d(_runs(d > 0, 5), _runs(d < 0, 5)) + 1
        alt = (d[1:] * d[:-1]) < 0          # direction changes between consecutive steps
        hits['N4'] = _runs(alt, 12) + 2
        hits['N5'] = two_of_3
        hits['N6'] = four_of_5
        hits['N7'] = _runs(np.abs(z) < 1.0, 15)
        hits['N8'] = _runs(np.abs(z) > 1.0, 8)
        text = NELSON_RULES
    elif rules == 'western-electric':
        hits['WE1'] = beyond3
        hits['WE2'] = two_of_3
        hits['WE3'] = four_of_5
        hits['WE4'] = np.union1d(_runs(up, 8), _runs(dn, 8))
        text = WESTERN_ELECTRIC_RULES
    else:
        msg = f"rules must be 'nelson' or 'western-electric', got {rules!r}"
        raise SpcError(msg)
    out = [RuleHit(name, int(i), text[name]) for name, idx in hits.items() for i in idx]
    return sorted(out, key=lambda h: (h.index, h.rule))


@dataclass(frozen=True, slots=True)
class Capability:
    """Process capability against a tolerance (None where a limit is missing).

    ``cp``/``cpk`` use the within sigma of the chart, ``pp``/``ppk`` the overall
    standard deviation of the values they were computed from; ``n`` values. With the
    measurement's standard uncertainty ``sigma_measurement`` (the u_c of the values'
    budgets, root mean square), the observed spread holds the measurement's:
    sigma_process^2 = sigma^2 - sigma_measurement^2, and the ``*_corrected`` indices are
    the unit population's own (None when the measurement spread is not below the
    observed one: the data cannot tell the process spread).
    """

    lsl: float | None
    usl: float | None
    mean: float
    sigma_within: float
    sigma_overall: float
    n: int
    cp: float | None
    cpk: float | None
    pp: float | None
    ppk: float | None
    fraction_out: float
    sigma_measurement: float = math.nan
    cp_corrected: float | None = None
    cpk_corrected: float | None = None
    pp_corrected: float | None = None
    ppk_corrected: float | None = None

    def to_json_dict(self, scale: float = 1.0, unit: str = '') -> CapabilityJson:
        """JSON form; the limits, mean and sigmas multiplied by ``scale``."""
        def sc(v: float | None) -> float | None:
            return None if v is None else v * scale
        return {'unit': unit, 'lsl': sc(self.lsl), 'usl': sc(self.usl), 'mean': self.mean * scale,
                'sigma_within': self.sigma_within * scale,
                'sigma_overall': self.sigma_overall * scale, 'n': self.n, 'cp': self.cp,
                'cpk': self.cpk, 'pp': self.pp, 'ppk': self.ppk,
                'fraction_out': self.fraction_out,
                'sigma_measurement': (self.sigma_measurement * scale
                                      if math.isfinite(self.sigma_measurement) else None),
                'cp_corrected': self.cp_corrected, 'cpk_corrected': self.cpk_corrected,
                'pp_corrected': self.pp_corrected, 'ppk_corrected': self.ppk_corrected}


def capability(values: npt.ArrayLike, *, sigma_within: float, lsl: float | None = None,
               usl: float | None = None, sigma_measurement: float = math.nan) -> Capability:
    """Cp, Cpk (within sigma) and Pp, Ppk (overall) of ``values`` against LSL/USL; with
    ``sigma_measurement`` also corrected for the measurement's spread (see
    :class:`Capability`).

    Examples:
        >>> c = capability([1.0, 3.0, 2.0, 4.0], sigma_within=1.0, usl=8.0, lsl=-4.0,
        ...                sigma_measurement=0.6)
        >>> c.cp, round(c.cp_corrected, 9)     # 12 / (6 x 1), 12 / (6 x sqrt(1 - 0.36))
        (2.0, 2.5)

    Raises:
        SpcError: No limit, LSL >= USL, non-finite values, or sigma_within <= 0.
    """
    x = _finite_series(values, 'values')
    if lsl is None and usl is None:
        msg = 'capability needs a lower or an upper specification limit'
        raise SpcError(msg)
    for name, v in (('lsl', lsl), ('usl', usl)):
        if v is not None and not math.isfinite(v):
            msg = f'{name} must be finite, got {v!r}'
            raise SpcError(msg)
    if lsl is not None and usl is not None and not lsl < usl:
        msg = f'lsl ({lsl!r}) must be below usl ({usl!r})'
        raise SpcError(msg)
    if not (math.isfinite(sigma_within) and sigma_within > 0):
        msg = f'sigma_within must be finite and > 0, got {sigma_within!r}'
        raise SpcError(msg)
    if x.size < 2:
        msg = f'capability needs at least 2 values, got {x.size}'
        raise SpcError(msg)
    mu = float(x.mean())
    s_all = float(x.std(ddof=1))

    def idx(s: float) -> tuple[float | None, float | None]:
        if not s > 0:
            return None, None
        upper = None if usl is None else (usl - mu) / (3 * s)
        lower = None if lsl is None else (mu - lsl) / (3 * s)
        both = None if (usl is None or lsl is None) else (usl - lsl) / (6 * s)
        k = min(v for v in (upper, lower) if v is not None)
        return both, k
    cp, cpk = idx(sigma_within)
    pp, ppk = idx(s_all)
    corr: dict[str, float | None] = {}
    sm = float(sigma_measurement)
    if not (math.isnan(sm) or (math.isfinite(sm) and sm >= 0)):
        msg = f'sigma_measurement must be finite and >= 0, got {sigma_measurement!r}'
        raise SpcError(msg)
    if math.isfinite(sm):
        for name, sig in (('c', sigma_within), ('p', s_all)):
            rest = sig * sig - sm * sm
            both, k = idx(math.sqrt(rest)) if rest > 0 else (None, None)
            corr[f'{name}p_corrected'], corr[f'{name}pk_corrected'] = both, k
    out = np.zeros(x.size, dtype=bool)
    if usl is not None:
        out |= x > usl
    if lsl is not None:
        out |= x < lsl
    return Capability(lsl=lsl, usl=usl, mean=mu, sigma_within=sigma_within,
                      sigma_overall=s_all, n=int(x.size), cp=cp, cpk=cpk, pp=pp, ppk=ppk,
                      fraction_out=float(out.mean()), sigma_measurement=sm, **corr)
