"""Measurement-system analysis (MSA): type 1 study and gauge R&R by ANOVA (issue 35).

**Type 1 study** (Bosch booklet 10 procedure 1; VDA 5; Minitab "Type 1 Gage Study"): one
reference unit measured n >= 25 times (here: re-mounted between repeats). With the
tolerance T, the repeats' mean x_bar and standard deviation s, and the reference value
x_m::

    Cg  = (K / 100) T / (L s)                       K = 20 %, L = 6: 0.2 T / (6 s)
    Cgk = ((K / 200) T - |x_bar - x_m|) / (L / 2 s)         (0.1 T - |bias|) / (3 s)

capable when both are >= 1.33; the bias is tested against zero with t = bias / (s /
sqrt(n)), n - 1 degrees of freedom.

**Gauge R&R by ANOVA** (AIAG MSA 4th ed., ch. III section B; Montgomery, Introduction to
Statistical Quality Control, s. 8.7): p parts x o operators (here: mountings, operators,
benches) x r repeats, balanced. The two-way crossed random-effects ANOVA gives the mean
squares of parts, operators, their interaction and the repeats (equipment); the
interaction is pooled into the repeatability when it is not significant (p > 0.25, AIAG),
and the variance components are the expected-mean-square estimates (negative ones set to
0)::

    sigma_e^2  = MS_E                                   repeatability (EV)
    sigma_op^2 = (MS_O - MS_OP) / (p r)                  reproducibility (AV)
    sigma_int^2 = (MS_OP - MS_E) / r                     interaction
    sigma_p^2  = (MS_P - MS_OP) / (o r)                  part variation (PV)

(with MS_OP and MS_E replaced by the pooled MS when pooled). GRR = sqrt(EV^2 + AV^2 +
INT^2), TV = sqrt(GRR^2 + PV^2); %GRR of the process variation = 100 GRR / TV (or of a
stated process sigma); %GRR of the tolerance = 100 x 6 GRR / T; ndc = floor(1.41 PV /
GRR) (>= 5 wanted). AIAG's guide: %GRR <= 10 % acceptable, <= 30 % may be acceptable
(conditional), above: not acceptable.

Pure numpy + scipy (F and t tails); no file reading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
import numpy.typing as npt

from rv_te_bench.errors import MsaError

__all__ = [
    'AnovaRow',
    'AnovaRowJson',
    'GaugeRR',
    'GaugeRRJson',
    'MsaError',
    'Type1Study',
    'Type1StudyJson',
    'gauge_rr_anova',
    'type1_study',
]

#: Minimum repeats of a type 1 study (Bosch booklet 10, AIAG: 25; 50 preferred).
TYPE1_MIN_REPEATS = 25
#: Cg, Cgk threshold of a capable gauge.
CAPABLE = 1.33
#: AIAG: pool the interaction into the repeatability when its p-value exceeds this.
POOL_ALPHA = 0.25


def _fin(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


class Type1StudyJson(TypedDict):
    """The JSON of :class:`Type1Study` (None: not finite)."""

    n: int
    mean: float
    std: float
    tolerance: float
    reference: float | None
    cg: float | None
    cgk: float | None
    bias: float | None
    t_bias: float | None
    p_bias: float | None
    k_percent: float
    sigma_multiplier: float
    capable: bool | None
    criterion: str


class AnovaRowJson(TypedDict):
    """The JSON of :class:`AnovaRow` (None: not finite)."""

    source: str
    dof: int
    ss: float
    ms: float | None
    f: float | None
    p: float | None


class GaugeRRJson(TypedDict):
    """The JSON of :class:`GaugeRR` (None: not finite)."""

    parts: int
    operators: int
    repeats: int
    anova: list[AnovaRowJson]
    interaction_pooled: bool
    variance: dict[str, float]
    ev: float
    av: float
    interaction: float
    grr: float
    pv: float
    tv: float
    tolerance: float | None
    process_sigma: float | None
    pct_grr_of_process: float | None
    pct_grr_of_tolerance: float | None
    ndc: int
    verdict: str
    criteria: str


@dataclass(frozen=True)
class Type1Study:
    """A type 1 study (same unit as the values: SI).

    Attributes:
        n: Repeats.
        mean: Their mean x_bar.
        std: Their standard deviation s (n - 1).
        tolerance: T = USL - LSL (or the one-sided limit's distance from the natural zero).
        reference: Reference value x_m (NaN: not known -> no bias, no Cgk).
        cg: 0.2 T / (6 s) (with the stated K and L).
        cgk: (0.1 T - |bias|) / (3 s); NaN without a reference.
        bias: x_bar - x_m.
        t_bias: bias / (s / sqrt(n)).
        p_bias: Two-sided p-value of the bias (Student t, n - 1 dof).
        k_percent, sigma_multiplier: K and L of the formulas.
    """

    n: int
    mean: float
    std: float
    tolerance: float
    reference: float
    cg: float
    cgk: float
    bias: float
    t_bias: float
    p_bias: float
    k_percent: float = 20.0
    sigma_multiplier: float = 6.0

    @property
    def capable(self) -> bool | None:
        """Cg and Cgk >= 1.33 (None when Cgk is not known)."""
        if not math.isfinite(self.cgk):
            return None
        return self.cg >= CAPABLE and self.cgk >= CAPABLE

    def to_json_dict(self) -> Type1StudyJson:
        """JSON (values in the unit of the data)."""
        return {'n': self.n, 'mean': self.mean, 'std': self.std, 'tolerance': self.tolerance,
                'reference': _fin(self.reference), 'cg': _fin(self.cg), 'cgk': _fin(self.cgk),
                'bias': _fin(self.bias), 't_bias': _fin(self.t_bias),
                'p_bias': _fin(self.p_bias), 'k_percent': self.k_percent,
                'sigma_multiplier': self.sigma_multiplier, 'capable': self.capable,
                'criterion': f'Cg and Cgk >= {CAPABLE}'}


def type1_study(values: npt.ArrayLike, *, tolerance: float, reference: float = math.nan,
                k_percent: float = 20.0, sigma_multiplier: float = 6.0,
                min_repeats: int = TYPE1_MIN_REPEATS) -> Type1Study:
    """Cg and Cgk of repeated measurements of one reference unit.

    Args:
        values: The repeats (finite).
        tolerance: T > 0, in the values' unit.
        reference: The unit's reference value (NaN: unknown; Cgk and the bias are NaN).
        k_percent: K, the part of the tolerance the gauge may use (20 %).
        sigma_multiplier: L, the spread in standard deviations (6).
        min_repeats: Fewest repeats accepted (25).

    Raises:
        MsaError: Too few repeats, a non-finite value, T <= 0, zero spread.

    Examples:
        >>> s = type1_study([10.0, 10.2] * 13, tolerance=6.0, reference=10.05)
        >>> round(s.cg, 3), round(s.cgk, 3)
        (1.961, 1.798)
    """
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size < min_repeats:
        msg = f'a type 1 study needs at least {min_repeats} repeats, got {x.size}'
        raise MsaError(msg)
    if not np.all(np.isfinite(x)):
        msg = f'repeat {int(np.flatnonzero(~np.isfinite(x))[0])} is not finite'
        raise MsaError(msg)
    if not (math.isfinite(tolerance) and tolerance > 0):
        msg = f'tolerance must be finite and > 0, got {tolerance!r}'
        raise MsaError(msg)
    n = int(x.size)
    mean = float(np.mean(x))
    s = float(np.std(x, ddof=1))
    if s <= 0:
        msg = 'the repeats do not vary (s = 0): resolution too coarse for a type 1 study'
        raise MsaError(msg)
    cg = (k_percent / 100.0) * tolerance / (sigma_multiplier * s)
    bias = t = p = cgk = math.nan
    if math.isfinite(reference):
        bias = mean - reference
        cgk = ((k_percent / 200.0) * tolerance - abs(bias)) / (sigma_multiplier / 2.0 * s)
        t = bias / (s / math.sqrt(n))
        from scipy.stats import t as student_t

        p = float(2.0 * student_t.sf(abs(t), n - 1))
    return Type1Study(n=n, mean=mean, std=s, tolerance=float(tolerance),
                      reference=float(reference), cg=cg, cgk=cgk, bias=bias, t_bias=t,
                      p_bias=p, k_percent=k_percent, sigma_multiplier=sigma_multiplier)


@dataclass(frozen=True)
class AnovaRow:
    """One row of the ANOVA table."""

    source: str
    dof: int
    ss: float
    ms: float
    f: float = math.nan
    p: float = math.nan

    def to_json_dict(self) -> AnovaRowJson:
        """JSON."""
        return {'source': self.source, 'dof': self.dof, 'ss': self.ss, 'ms': _fin(self.ms),
                'f': _fin(self.f), 'p': _fin(self.p)}


@dataclass(frozen=True)
class GaugeRR:
    """A gauge R&R study by ANOVA (standard deviations in the unit of the data).

    Attributes:
        parts, operators, repeats: The design (p, o, r).
        anova: Parts, operators, interaction, repeatability (equipment), total.
        interaction_pooled: The interaction was pooled into the repeatability.
        var: Variance components: ``repeatability``, ``reproducibility``, ``interaction``,
            ``part``.
        tolerance: T (NaN: none stated).
        process_sigma: Stated process standard deviation (NaN: the study's PV is used).
    """

    parts: int
    operators: int
    repeats: int
    anova: tuple[AnovaRow, ...]
    interaction_pooled: bool
    var: dict[str, float] = field(default_factory=dict)
    tolerance: float = math.nan
    process_sigma: float = math.nan

    @property
    def ev(self) -> float:
        """Repeatability (equipment variation), a standard deviation."""
        return math.sqrt(self.var['repeatability'])

    @property
    def av(self) -> float:
        """Reproducibility (appraiser variation)."""
        return math.sqrt(self.var['reproducibility'])

    @property
    def interaction(self) -> float:
        """Part x operator interaction."""
        return math.sqrt(self.var['interaction'])

    @property
    def grr(self) -> float:
        """sqrt(EV^2 + AV^2 + INT^2)."""
        return math.sqrt(self.var['repeatability'] + self.var['reproducibility']
                         + self.var['interaction'])

    @property
    def pv(self) -> float:
        """Part variation."""
        return math.sqrt(self.var['part'])

    @property
    def tv(self) -> float:
        """Total variation: sqrt(GRR^2 + PV^2), or the stated process sigma."""
        if math.isfinite(self.process_sigma):
            return self.process_sigma
        return math.hypot(self.grr, self.pv)

    @property
    def pct_process(self) -> float:
        """%GRR of the process (total) variation."""
        return 100.0 * self.grr / self.tv if self.tv > 0 else math.nan

    @property
    def pct_tolerance(self) -> float:
        """%GRR of the tolerance: 100 x 6 GRR / T."""
        return 600.0 * self.grr / self.tolerance if math.isfinite(self.tolerance) else math.nan

    @property
    def ndc(self) -> int:
        """Number of distinct categories, floor(1.41 PV / GRR) (AIAG: >= 5)."""
        pv = self.pv if not math.isfinite(self.process_sigma) else math.sqrt(
            max(self.process_sigma ** 2 - self.grr ** 2, 0.0))
        if self.grr <= 0:
            return 10 ** 6
        return math.floor(1.41 * pv / self.grr)

    def verdict(self) -> str:
        """AIAG guide on the %GRR (of the tolerance when stated, else of the process):
        ``acceptable`` (<= 10 %), ``conditional`` (<= 30 %), ``unacceptable``."""
        pct = self.pct_tolerance if math.isfinite(self.tolerance) else self.pct_process
        if not math.isfinite(pct):
            return 'unknown'
        return 'acceptable' if pct <= 10 else 'conditional' if pct <= 30 else 'unacceptable'

    def to_json_dict(self) -> GaugeRRJson:
        """JSON (standard deviations in the unit of the data, percentages in %)."""
        return {'parts': self.parts, 'operators': self.operators, 'repeats': self.repeats,
                'anova': [r.to_json_dict() for r in self.anova],
                'interaction_pooled': self.interaction_pooled,
                'variance': dict(self.var),
                'ev': self.ev, 'av': self.av, 'interaction': self.interaction, 'grr': self.grr,
                'pv': self.pv, 'tv': self.tv, 'tolerance': _fin(self.tolerance),
                'process_sigma': _fin(self.process_sigma),
                'pct_grr_of_process': _fin(self.pct_process),
                'pct_grr_of_tolerance': _fin(self.pct_tolerance),
                'ndc': self.ndc, 'verdict': self.verdict(),
                'criteria': 'AIAG: %GRR <= 10 % acceptable, <= 30 % conditional; ndc >= 5'}


def gauge_rr_anova(values: npt.ArrayLike, *, tolerance: float = math.nan,
                   process_sigma: float = math.nan, pool_alpha: float = POOL_ALPHA,
                   ) -> GaugeRR:
    """Gauge R&R of a balanced crossed study by two-way ANOVA.

    Args:
        values: Array (parts, operators, repeats), finite, each dimension >= 2 (repeats
            >= 2; parts and operators >= 2).
        tolerance: T in the values' unit (NaN: no %GRR of tolerance).
        process_sigma: A known process standard deviation (NaN: the study's TV).
        pool_alpha: Pool the interaction when its p-value exceeds this (AIAG 0.25; 1.0:
            never pool).

    Raises:
        MsaError: Wrong shape, too few levels, non-finite values.

    Examples:
        Two parts, two operators, two repeats, no interaction (worked by hand: MS_P = 200,
        MS_O = 32, MS_E = 2, interaction pooled: MS = 1.6):

        >>> x = [[[10, 12], [14, 16]], [[20, 22], [24, 26]]]
        >>> g = gauge_rr_anova(x)
        >>> g.interaction_pooled, g.var['repeatability'], g.var['reproducibility']
        (True, 1.6, 7.6)
    """
    y = np.asarray(values, dtype=np.float64)
    if y.ndim != 3:
        msg = f'gauge R&R needs an array (parts, operators, repeats), got shape {y.shape}'
        raise MsaError(msg)
    p, o, r = y.shape
    if p < 2 or o < 2 or r < 2:
        msg = (f'gauge R&R needs >= 2 parts, >= 2 operators and >= 2 repeats, got {p} x {o} '
               f'x {r}')
        raise MsaError(msg)
    if not np.all(np.isfinite(y)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(y))[0])
        msg = f'value at (part, operator, repeat) {idx} is not finite'
        raise MsaError(msg)
    from scipy.stats import f as f_dist

    grand = y.mean()
    part_m = y.mean(axis=(1, 2))
    op_m = y.mean(axis=(0, 2))
    cell_m = y.mean(axis=2)
    ss_p = o * r * float(np.sum((part_m - grand) ** 2))
    ss_o = p * r * float(np.sum((op_m - grand) ** 2))
    ss_po = r * float(np.sum((cell_m - part_m[:, None] - op_m[None, :] + grand) ** 2))
    ss_e = float(np.sum((y - cell_m[:, :, None]) ** 2))
    ss_t = float(np.sum((y - grand) ** 2))
    df_p, df_o, df_po, df_e = p - 1, o - 1, (p - 1) * (o - 1), p * o * (r - 1)
    ms_p, ms_o, ms_po, ms_e = ss_p / df_p, ss_o / df_o, ss_po / df_po, ss_e / df_e
    f_po = ms_po / ms_e if ms_e > 0 else math.inf
    p_po = float(f_dist.sf(f_po, df_po, df_e)) if math.isfinite(f_po) else 0.0
    pooled = p_po > pool_alpha
    if pooled:
        ms_err = (ss_po + ss_e) / (df_po + df_e)
        df_err = df_po + df_e
        denom_p = denom_o = ms_err
        var_int = 0.0
    else:
        ms_err, df_err = ms_e, df_e
        denom_p = denom_o = ms_po
        var_int = max((ms_po - ms_e) / r, 0.0)
    df_denom = df_err if pooled else df_po
    f_p = ms_p / denom_p if denom_p > 0 else math.inf
    f_o = ms_o / denom_o if denom_o > 0 else math.inf
    rows = (
        AnovaRow('parts', df_p, ss_p, ms_p, f_p, float(f_dist.sf(f_p, df_p, df_denom))),
        AnovaRow('operators', df_o, ss_o, ms_o, f_o, float(f_dist.sf(f_o, df_o, df_denom))),
        AnovaRow('parts x operators', df_po, ss_po, ms_po, f_po, p_po),
        AnovaRow('repeatability (equipment)', df_e, ss_e, ms_e),
        AnovaRow('total', p * o * r - 1, ss_t, math.nan),
    )
    var = {'repeatability': ms_err,
           'reproducibility': max((ms_o - denom_o) / (p * r), 0.0),
           'interaction': var_int,
           'part': max((ms_p - denom_p) / (o * r), 0.0)}
    return GaugeRR(parts=p, operators=o, repeats=r, anova=rows, interaction_pooled=pooled,
                   var=var, tolerance=float(tolerance), process_sigma=float(process_sigma))
