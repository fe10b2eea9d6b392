"""GUM uncertainty budgets: inputs, law of propagation, effective degrees of freedom, U.

The Guide to the expression of uncertainty in measurement (JCGM 100:2008, "GUM") in the
form a budget table shows it. A measurement result ``y = f(x_1, ..., x_N)`` is given with

* one :class:`UncertaintyInput` per input quantity: its standard uncertainty ``u(x_i)``
  (type A: from the spread of repeated observations, with ``nu_i = n - 1`` degrees of
  freedom; type B: from a data sheet, certificate or bound, with the distribution stated:
  a bound +-a taken as rectangular gives ``u = a / sqrt(3)`` (GUM 4.3.7), a sinusoid of
  amplitude A and unknown phase is arcsine, ``u = A / sqrt(2)``) and its sensitivity
  coefficient ``c_i = df/dx_i`` (closed form where the maths is, else a central
  difference, :func:`numeric_sensitivity`);
* the combined standard uncertainty by the law of propagation for uncorrelated inputs,
  ``u_c^2 = sum (c_i u_i)^2`` (GUM 5.1.2; correlated inputs are entered as one input);
* each input's share ``(c_i u_i)^2 / u_c^2``;
* the effective degrees of freedom by Welch-Satterthwaite (GUM G.4.1),
  ``nu_eff = u_c^4 / sum ((c_i u_i)^4 / nu_i)``;
* the expanded uncertainty ``U = k u_c`` for a coverage probability p = 95.45 %.

The coverage factor k. With many inputs of similar size the sum is close to normal and
k = 2 (p = 95.45 %); with few degrees of freedom k = t_p(nu_eff) (GUM G.4). When one
input that is not normal dominates (an encoder's graduation error is a sinusoid of
unknown phase: arcsine; a bound: rectangular) k = 2 overstates the interval (GUM G.2.3,
G.6.5: a rectangular needs k = 1.65 for 95 %). So k is computed here as the p quantile of
the distribution of the linearised model ``sum c_i X_i``, the inputs with their stated
shapes (type A inputs as Student t with their degrees of freedom, as GUM G.3 and
Supplement 1 6.4.9 treat them): the numerical convolution of their distributions
(:func:`coverage_factor`). It is k = 2 for a normal budget, t_p(nu_eff) (to the
Welch-Satterthwaite approximation) for normal and type A inputs with >= 30 dof each,
1.65 x 1.0 for one dominant rectangular input at 95 %. A type A input with fewer dof
(two windows of a short record: one dof) is convolved as the t it is: Welch-Satterthwaite
would turn a 0.6 % share of a one-dof t into nu_eff = 28,000 and k = 2.00 where the
distribution's is 2.34 (Supplement 1's Monte Carlo samples that t and finds the latter).
``k_basis`` in each budget says which.

Supplement 1 (JCGM 101:2008) propagates the distributions themselves by Monte Carlo; the
coverage interval it gives checks the linearisation (:func:`monte_carlo_interval`). A
Monte Carlo run is a validation tool here (benchmarks/bench_uncertainty.py) or on
request, never part of every analysis.

Pure numpy: no file reading, no rclpy. Units: every value, u and U of one budget are in
the measurand's SI unit (rad, N m/rad, m); inputs carry their own unit beside ``u``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, TypedDict

import numpy as np

from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    import numpy.typing as npt

__all__ = [
    'COVERAGE_PROBABILITY',
    'DISTRIBUTIONS',
    'Budget',
    'Distribution',
    'UncertaintyInput',
    'UncertaintyInputJson',
    'combine',
    'coverage_factor',
    'coverage_interval',
    'monte_carlo_interval',
    'numeric_sensitivity',
    'sample_input',
    't_quantile',
    'type_a',
    'type_b',
    'welch_satterthwaite',
]

#: Coverage probability of U, 95.45 % (GUM 6.2.2: k = 2 for a normal distribution).
COVERAGE_PROBABILITY = math.erf(math.sqrt(2.0))   # 0.95450: k = 2 exactly for a normal

Distribution = Literal['normal', 'rectangular', 'triangular', 'arcsine', 't', 'tabulated']
DISTRIBUTIONS: tuple[str, ...] = ('normal', 'rectangular', 'triangular', 'arcsine', 't',
                                  'tabulated')
#: Standard uncertainty per half-width (or amplitude) of the bounded shapes.
_U_PER_HALF_WIDTH = {'rectangular': 1.0 / math.sqrt(3.0), 'triangular': 1.0 / math.sqrt(6.0),
                     'arcsine': 1.0 / math.sqrt(2.0)}
#: Bins of the convolution grid (each input's distribution on [-S, S]).
_GRID_BINS = 1024
#: Below this share of u_c^2 for all non-normal inputs together, k = t_p(nu_eff).
_NEAR_NORMAL_SHARE = 0.1
#: A type A input with fewer degrees of freedom than this is convolved as the Student t
#: it is (GUM Supplement 1, 6.4.9), never summarised by Welch-Satterthwaite nor lumped into
#: the normal remainder: WS replaces a small share of a t with few dof by a t with very
#: many (nu_eff = nu / share^2) and drops its heavy tails. Measured against the exact
#: convolution (scipy quadrature; docs/UNCERTAINTY.md): a share of 0.6 % of u_c^2 with
#: nu = 1 makes WS's k 14.5 % short, nu = 2: 1.8 %; at nu >= 30 WS is within 1 % for every
#: share.
_WS_MIN_DOF = 30.0
#: A type A input with fewer dof than this (n < 4: the t's variance is not finite, GUM
#: Supplement 1 6.4.9.4) gets a note in its budget saying what it does to k.
_FEW_REPEATS_DOF = 3.0


class UncertaintyInputJson(TypedDict):
    """An input of a budget's JSON (SI; ``dof`` None when infinite, ``share`` its part of
    u_c^2)."""

    name: str
    type: Literal['A', 'B']
    u: float
    unit: str
    distribution: Distribution
    dof: float | None
    sensitivity: float
    contribution: float
    share: float
    source: str
    note: str


@dataclass(frozen=True)
class UncertaintyInput:
    """One input quantity of a budget.

    Attributes:
        name: What the input is, for people (``'output encoder: graduation, order 2'``).
        kind: ``'A'`` (from the data's own spread) or ``'B'`` (data sheet, bound, bench
            description).
        u: Standard uncertainty of the input quantity [``unit``], >= 0.
        sensitivity: Sensitivity coefficient c_i [measurand unit per ``unit``].
        distribution: Shape of the input's distribution (``DISTRIBUTIONS``); type A inputs
            are ``'t'`` (normal when ``dof`` is infinite).
        dof: Degrees of freedom (inf for type B inputs taken as exactly known).
        unit: Unit of ``u`` (SI: rad, s, N m, K, m, 1).
        source: Where the value comes from (data sheet, bench description, the data).
        note: How the sensitivity was obtained (``'closed form: ...'``, ``'numeric'``).
        shape: For ``'tabulated'``: equally likely values of the input per unit half-width
            (max |shape| = 1), e.g. a harmonic's first- and second-order terms on a grid of
            its one unknown phase; u = half-width x std(shape).
    """

    name: str
    kind: Literal['A', 'B']
    u: float
    sensitivity: float
    distribution: Distribution = 'normal'
    dof: float = math.inf
    unit: str = 'rad'
    source: str = ''
    note: str = field(default='', compare=False)
    shape: tuple[float, ...] = field(default=(), compare=False, repr=False)

    def __post_init__(self) -> None:
        """Validate (TeInputError names the field and the value)."""
        if self.kind not in ('A', 'B'):
            msg = f'input {self.name!r}: kind must be "A" or "B", got {self.kind!r}'
            raise TeInputError(msg)
        if self.distribution not in DISTRIBUTIONS:
            msg = (f'input {self.name!r}: distribution must be one of {list(DISTRIBUTIONS)}, '
                   f'got {self.distribution!r}')
            raise TeInputError(msg)
        u = float(self.u)
        if not (math.isfinite(u) and u >= 0):
            msg = f'input {self.name!r}: u must be finite and >= 0, got {self.u!r}'
            raise TeInputError(msg)
        c = float(self.sensitivity)
        if not math.isfinite(c):
            msg = f'input {self.name!r}: sensitivity must be finite, got {self.sensitivity!r}'
            raise TeInputError(msg)
        dof = float(self.dof)
        if not dof >= 1:
            msg = f'input {self.name!r}: dof must be >= 1 (inf for exact), got {self.dof!r}'
            raise TeInputError(msg)
        if (self.distribution == 'tabulated') != bool(self.shape):
            msg = f'input {self.name!r}: a shape goes with (only) the tabulated distribution'
            raise TeInputError(msg)
        object.__setattr__(self, 'u', u)
        object.__setattr__(self, 'sensitivity', c)
        object.__setattr__(self, 'dof', dof)

    @property
    def contribution(self) -> float:
        """|c_i| u(x_i), in the measurand's unit."""
        return abs(self.sensitivity) * self.u

    @property
    def half_width(self) -> float:
        """Half-width (rectangular, triangular) or amplitude (arcsine) of the input; NaN for
        the unbounded shapes."""
        if self.distribution == 'tabulated':
            return self.u / _shape_std(self.shape)
        f = _U_PER_HALF_WIDTH.get(self.distribution)
        return self.u / f if f else math.nan

    def to_json_dict(self, share: float) -> UncertaintyInputJson:
        """JSON (SI; ``share`` is this input's part of u_c^2)."""
        return {'name': self.name, 'type': self.kind, 'u': self.u, 'unit': self.unit,
                'distribution': self.distribution,
                'dof': None if math.isinf(self.dof) else self.dof,
                'sensitivity': self.sensitivity, 'contribution': self.contribution,
                'share': share, 'source': self.source, 'note': self.note}


def _shape_std(shape: npt.ArrayLike) -> float:
    return float(np.std(np.asarray(shape, dtype=np.float64)))


def type_b(name: str, *, sensitivity: float, distribution: Distribution,
           half_width: float | None = None, u: float | None = None, unit: str = 'rad',
           source: str = '', note: str = '', shape: npt.ArrayLike = ()) -> UncertaintyInput:
    """A type B input from a bound (rectangular/triangular half-width, arcsine amplitude)
    or from a standard uncertainty (normal).

    Examples:
        >>> round(type_b('q', sensitivity=1.0, distribution='rectangular',
        ...              half_width=3.0).u ** 2, 12)
        3.0
    """
    if (half_width is None) == (u is None):
        msg = f'input {name!r}: give one of half_width and u'
        raise TeInputError(msg)
    if distribution == 'tabulated':
        tab = np.asarray(shape, dtype=np.float64)
        if half_width is None or tab.size < 8 or not np.all(np.isfinite(tab)) \
                or float(np.max(np.abs(tab))) == 0.0:
            msg = f'input {name!r}: a tabulated input needs half_width and a finite shape'
            raise TeInputError(msg)
        tab = tab / float(np.max(np.abs(tab)))
        return UncertaintyInput(name=name, kind='B', u=half_width * _shape_std(tab),
                                sensitivity=sensitivity, distribution='tabulated', unit=unit,
                                source=source, note=note, shape=tuple(tab.tolist()))
    if half_width is not None:
        f = _U_PER_HALF_WIDTH.get(distribution)
        if f is None:
            msg = f'input {name!r}: a {distribution} input takes u, not half_width'
            raise TeInputError(msg)
        if not (math.isfinite(half_width) and half_width >= 0):
            msg = f'input {name!r}: half_width must be finite and >= 0, got {half_width!r}'
            raise TeInputError(msg)
        u = half_width * f
    assert u is not None
    return UncertaintyInput(name=name, kind='B', u=u, sensitivity=sensitivity,
                            distribution=distribution, unit=unit, source=source, note=note)


def type_a(name: str, values: npt.ArrayLike, *, sensitivity: float = 1.0, of_mean: bool = True,
           unit: str = 'rad', source: str = '', note: str = '') -> UncertaintyInput | None:
    """A type A input from repeated observations (GUM 4.2): s / sqrt(n) for a mean
    (``of_mean``), s for a single observation; n - 1 degrees of freedom.

    Returns:
        The input, or None with fewer than two finite observations (no spread to evaluate).

    Examples:
        >>> x = type_a('rep', [1.0, 2.0, 3.0])
        >>> round(x.u, 12), x.dof
        (0.57735026919, 2.0)
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size < 2:
        return None
    s = float(np.std(v, ddof=1))
    u = s / math.sqrt(v.size) if of_mean else s
    return UncertaintyInput(name=name, kind='A', u=u, sensitivity=sensitivity,
                            distribution='t', dof=float(v.size - 1), unit=unit,
                            source=source or f'{v.size} observations of this run',
                            note=note)


def welch_satterthwaite(contributions: npt.ArrayLike, dofs: npt.ArrayLike) -> float:
    """Effective degrees of freedom (GUM G.4.1); inf when every input's dof is infinite.

    Examples:
        >>> welch_satterthwaite([1.0, 1.0], [4.0, 4.0])
        8.0
    """
    c = np.asarray(contributions, dtype=np.float64)
    nu = np.asarray(dofs, dtype=np.float64)
    total = float(np.sum(c * c))
    finite = np.isfinite(nu) & (c > 0)
    den = float(np.sum(c[finite] ** 4 / nu[finite]))
    if den == 0.0:
        return math.inf
    return total * total / den


# --------------------------------------------------------------------------------------
# coverage factor from the distribution of the linear model


def _bin_masses(shape: str, sigma: float, dof: float, edges: np.ndarray,
                centres: np.ndarray, h: float, table: tuple[float, ...] = ()) -> np.ndarray:
    """Probability of each bin for c_i X_i (sigma = |c_i| u_i) on the grid."""
    n = centres.size
    if shape == 'tabulated':
        tab = np.asarray(table, dtype=np.float64)
        vals = tab / float(np.std(tab)) * sigma
        m, _ = np.histogram(np.clip(vals, edges[0], edges[-1]), bins=edges)
        return m / float(m.sum())
    if shape == 't' and math.isfinite(dof):
        # the t's own CDF at the bin edges (its tails beyond the grid in the end bins): a
        # t narrower than a bin keeps the tails that a point mass would lose
        from scipy.special import stdtr

        cdf = np.asarray(stdtr(dof, edges / sigma), dtype=np.float64)
        cdf[0], cdf[-1] = 0.0, 1.0
        return np.diff(cdf)
    if sigma <= 0.25 * h:                       # narrower than a bin: a point mass at 0
        m = np.zeros(n)
        m[int(np.searchsorted(edges, 0.0, side='right')) - 1] = 1.0
        return m
    if shape in ('rectangular', 'triangular', 'arcsine'):
        a = sigma / _U_PER_HALF_WIDTH[shape]
        x = np.clip(edges / a, -1.0, 1.0)
        if shape == 'rectangular':
            cdf = 0.5 * (x + 1.0)
        elif shape == 'triangular':
            cdf = np.where(x < 0, 0.5 * (1.0 + x) ** 2, 1.0 - 0.5 * (1.0 - x) ** 2)
        else:
            cdf = 0.5 + np.arcsin(x) / math.pi
        return np.diff(cdf)
    z = centres / sigma
    pdf = np.exp(-0.5 * z * z)
    tail = 0.5 * math.erfc(float(edges[-1]) / sigma / math.sqrt(2.0))
    m = np.asarray(pdf / pdf.sum() * (1.0 - 2.0 * tail), dtype=np.float64)
    m[0] += tail
    m[-1] += tail
    return m


def _t_tail(x: float, dof: float) -> float:
    """P(T > x) of Student's t with ``dof`` degrees of freedom (x >= 0), by quadrature of
    the density in the variable s = 1/t (bounded range, smooth)."""
    if x <= 0:
        return 0.5
    # P(T > x) = int_x^inf f(t) dt = int_0^{1/x} f(1/s) / s^2 ds
    s = np.linspace(0.0, 1.0 / x, 2001)[1:]
    with np.errstate(over='ignore', under='ignore'):
        g = (1.0 + 1.0 / (s * s * dof)) ** (-(dof + 1.0) / 2.0) / (s * s)
    g = np.r_[0.0, g]
    norm = math.exp(math.lgamma((dof + 1) / 2) - math.lgamma(dof / 2)) / math.sqrt(dof * math.pi)
    return float(norm * np.trapezoid(g, dx=1.0 / x / 2000))


def coverage_factor(inputs: Sequence[UncertaintyInput], p: float = COVERAGE_PROBABILITY,
                    ) -> tuple[float, str]:
    """k such that P(|sum c_i X_i| <= k u_c) = p, the inputs with their stated shapes.

    Inputs contributing less than 1 % of u_c each are lumped into one normal input, except
    a type A input with fewer than 30 degrees of freedom: its heavy tails reach the 95 %
    quantile from far below 1 % (a t with one dof at 0.3 % of u_c moves k by 0.6 %). The
    distributions are discretised on one grid (bin probabilities from the exact CDF for
    the bounded shapes and the t, the density for the normal) and convolved by FFT.

    Returns:
        (k, basis): basis ``'normal'`` (k = z_p exactly: every input normal with infinite
        dof), ``'t (nu_eff = ...)'`` (k = t_p(nu_eff) when the bounded, non-normal inputs
        together make less than 10 % of u_c^2 and every type A input has >= 30 dof: the sum
        is then normal or t to within 1 % of the Welch-Satterthwaite approximation),
        ``'t (nu_i = ...; convolved)'`` (the same, but a type A input has fewer dof: WS
        drops a few-dof t's heavy tails, 14 % of k for one dof at 0.6 % of u_c^2, so the
        t is convolved as it is, as GUM Supplement 1 6.4.9 propagates it), otherwise
        ``'distribution'`` (convolution). k is NaN when u_c = 0.

    Examples:
        >>> x = type_b('r', sensitivity=1.0, distribution='rectangular', half_width=1.0)
        >>> round(coverage_factor([x], 0.95)[0], 3)    # GUM G.2.3: 1.65 for a rectangular
        1.645
    """
    k, basis, parts, uc = _coverage_plan(inputs, p)
    return (k, basis) if parts is None else (_convolved_k(parts, uc, p), basis)


_Part = tuple[Distribution, float, float, tuple[float, ...]]


def _coverage_plan(inputs: Sequence[UncertaintyInput], p: float,
                   ) -> tuple[float, str, list[_Part] | None, float]:
    """What :func:`coverage_factor` does: (k, basis, None, u_c) where k follows without a
    convolution, else (NaN, basis, the parts to convolve, u_c)."""
    if not 0.5 < p < 1.0:
        msg = f'coverage probability must lie in (0.5, 1), got {p!r}'
        raise TeInputError(msg)
    sig = np.array([x.contribution for x in inputs], dtype=np.float64)
    uc = math.sqrt(float(np.sum(sig * sig)))
    if uc == 0.0:
        return math.nan, 'normal', None, uc
    shapes: list[Distribution] = [
        'normal' if (x.distribution == 't' and math.isinf(x.dof)) else x.distribution
        for x in inputs]
    if all(s == 'normal' for s in shapes):
        return _normal_quantile(0.5 + p / 2.0), 'normal', None, uc
    bounded = sum(float(g) ** 2 for s, g in zip(shapes, sig, strict=True)
                  if s not in ('normal', 't'))
    few_dof = np.array([s == 't' and x.dof < _WS_MIN_DOF for s, x in
                        zip(shapes, inputs, strict=True)], dtype=bool) & (sig > 0)
    if bounded < _NEAR_NORMAL_SHARE * uc * uc and not few_dof.any():
        nu = welch_satterthwaite(sig, [x.dof for x in inputs])
        if math.isinf(nu):
            return _normal_quantile(0.5 + p / 2.0), 'normal', None, uc
        return t_quantile(p, round(nu, 2)), f't (nu_eff = {nu:.3g})', None, uc
    basis = 'distribution'
    if bounded < _NEAR_NORMAL_SHARE * uc * uc:
        nus = sorted({float(x.dof) for x, f in zip(inputs, few_dof, strict=True) if f})
        basis = f't (nu_i = {", ".join(f"{v:g}" for v in nus)}; convolved)'
    big = (sig >= 0.01 * uc) | few_dof
    small_var = float(np.sum(sig[~big] ** 2))
    parts = [(s, float(g), x.dof, _signed(x)) for s, g, x, b in zip(shapes, sig, inputs, big,
                                                                     strict=True) if b]
    if small_var > 0:
        parts.append(('normal', math.sqrt(small_var), math.inf, ()))
    return math.nan, basis, parts, uc


def _convolved_k(parts: list[_Part], uc: float, p: float) -> float:
    """k of the convolved parts, the grid widened until the quantile lies well inside."""
    span = 6.0 * uc
    for _ in range(6):
        k, ok = _convolved_quantile(parts, span, uc, p)
        if ok:
            return k
        span *= 3.0
    return k


def _signed(x: UncertaintyInput) -> tuple[float, ...]:
    """A tabulated input's shape as c_i X_i sees it (a negative c flips it)."""
    return tuple(-v for v in x.shape) if x.sensitivity < 0 else x.shape


def coverage_interval(inputs: Sequence[UncertaintyInput], p: float = COVERAGE_PROBABILITY,
                      ) -> tuple[float, float] | None:
    """The probabilistically symmetric p interval [q_lo, q_hi] of ``sum c_i X_i`` (GUM
    Supplement 1, 7.7: the (1 - p) / 2 and (1 + p) / 2 quantiles), where a tabulated input
    makes the sum's distribution asymmetric; None where every input is symmetric (then the
    interval is +-k u_c, :func:`coverage_factor`).

    A harmonic's second-order term (the points read at positions the error itself moved)
    shares its phase with the first-order one: their sum over a uniform phase is skewed
    when the first-order term's weights cancel and the second's do not (a closed loop's
    area). Its symmetric interval about zero then reaches the long tail; this one does not.
    """
    xs = [x for x in inputs if x.contribution > 0]
    if not any(x.distribution == 'tabulated' for x in xs):
        return None
    sig = np.array([x.contribution for x in xs], dtype=np.float64)
    uc = math.sqrt(float(np.sum(sig * sig)))
    shapes: list[Distribution] = [
        'normal' if (x.distribution == 't' and math.isinf(x.dof)) else x.distribution
        for x in xs]
    few = np.array([s == 't' and x.dof < _WS_MIN_DOF for s, x in zip(shapes, xs, strict=True)],
                   dtype=bool)
    big = (sig >= 0.01 * uc) | few | np.array([s == 'tabulated' for s in shapes], dtype=bool)
    parts = [(s, float(g), x.dof, _signed(x)) for s, g, x, b in zip(shapes, sig, xs, big,
                                                                     strict=True) if b]
    small_var = float(np.sum(sig[~big] ** 2))
    if small_var > 0:
        parts.append(('normal', math.sqrt(small_var), math.inf, ()))
    span = 6.0 * uc
    for _ in range(6):
        x, cdf = _convolved_cdf(parts, span)
        lo, hi = np.interp([(1.0 - p) / 2.0, (1.0 + p) / 2.0], cdf, x)
        if max(-lo, hi) <= 0.6 * span:
            return float(lo), float(hi)
        span *= 3.0
    return float(lo), float(hi)


def _convolved_cdf(parts: list[tuple[Distribution, float, float, tuple[float, ...]]],
                   span: float) -> tuple[np.ndarray, np.ndarray]:
    """CDF of the sum at the right edges of its bins (x, F(x)), strictly increasing F."""
    n = _GRID_BINS
    edges = np.linspace(-span, span, n + 1)
    h = edges[1] - edges[0]
    centres = 0.5 * (edges[:-1] + edges[1:])
    size = 1 << math.ceil(math.log2(len(parts) * (n - 1) + 1))
    acc = np.ones(size // 2 + 1, dtype=np.complex128)
    for shape, sigma, dof, table in parts:
        acc *= np.fft.rfft(_bin_masses(shape, sigma, dof, edges, centres, h, table), size)
    total = np.clip(np.fft.irfft(acc, size)[:len(parts) * (n - 1) + 1], 0.0, None)
    kk = len(parts)
    x = -kk * span + (np.arange(total.size) + kk / 2.0) * h + 0.5 * h
    cdf = np.cumsum(total)
    cdf /= cdf[-1]
    keep = np.r_[True, np.diff(cdf) > 0]
    return x[keep], cdf[keep]


def _convolved_quantile(parts: list[tuple[Distribution, float, float, tuple[float, ...]]],
                        span: float,
                        uc: float,
                        p: float) -> tuple[float, bool]:
    n = _GRID_BINS
    edges = np.linspace(-span, span, n + 1)
    h = edges[1] - edges[0]
    centres = 0.5 * (edges[:-1] + edges[1:])
    size = 1 << math.ceil(math.log2(len(parts) * (n - 1) + 1))
    acc = np.ones(size // 2 + 1, dtype=np.complex128)
    for shape, sigma, dof, table in parts:
        acc *= np.fft.rfft(_bin_masses(shape, sigma, dof, edges, centres, h, table), size)
    total = np.fft.irfft(acc, size)[:len(parts) * (n - 1) + 1]
    total = np.clip(total, 0.0, None)
    # bin j of the sum is centred at sum of the parts' centres: -K S + (j + K/2) h
    kk = len(parts)
    x = -kk * span + (np.arange(total.size) + kk / 2.0) * h
    cdf = np.cumsum(total)
    cdf /= cdf[-1]
    # P(|Y| <= y) on a grid of y by interpolating the CDF at the bin edges
    xe = x + 0.5 * h
    ys = np.linspace(0.0, min(abs(x[0]), x[-1]), 4000)
    inside = np.interp(ys, xe, cdf) - np.interp(-ys, xe, cdf, left=0.0, right=1.0)
    j = int(np.searchsorted(inside, p))
    if j >= ys.size or ys[j] > 0.6 * span:
        return float(ys[-1]) / uc, False
    y0, y1 = ys[j - 1], ys[j]
    f0, f1 = inside[j - 1], inside[j]
    y = y0 + (p - f0) * (y1 - y0) / (f1 - f0) if f1 > f0 else y1
    return float(y) / uc, True


@functools.lru_cache(maxsize=512)
def t_quantile(p: float, dof: float) -> float:
    """k with P(|T| <= k) = p for Student's t with ``dof`` (>= 1) degrees of freedom (GUM
    Table G.2), by bisection on the tail; the normal quantile for infinite ``dof``.

    Examples:
        >>> round(t_quantile(0.9545, 4.0), 2), round(t_quantile(0.9545, math.inf), 3)
        (2.87, 2.0)
    """
    if math.isinf(dof) or dof > 1e7:
        return _normal_quantile(0.5 + p / 2.0)
    lo, hi = 0.0, 1e4
    target = (1.0 - p) / 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _t_tail(mid, dof) > target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _normal_quantile(q: float) -> float:
    """Inverse of the standard normal CDF (bisection on erfc; 1e-12 accurate)."""
    lo, hi = -10.0, 10.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if 0.5 * math.erfc(-mid / math.sqrt(2.0)) < q:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# --------------------------------------------------------------------------------------
# the budget


@dataclass(frozen=True)
class Budget:
    """The uncertainty budget of one result (everything in the measurand's SI unit).

    Attributes:
        measurand: Name of the result (``'te_pp_ccw_rad'``, ``'line 1 f_w amplitude'``).
        unit: Its SI unit.
        value: The result y.
        inputs: The inputs, largest contribution first.
        u_c: Combined standard uncertainty.
        nu_eff: Effective degrees of freedom (Welch-Satterthwaite; inf: type B only).
        k: Coverage factor.
        expanded: U = k u_c.
        coverage_probability: p of U.
        k_basis: How k was obtained (``'normal'``, ``'distribution'``).
        notes: What the budget leaves out or assumes, one line each.
        bias_bound: Bound of an uncorrected one-sided bias upwards: the value may read
            high by up to this (a p-p of samples reads the crest of fast errors).
        bias_low_bound: Bound of an uncorrected one-sided bias downwards: the value may
            read low by up to this (the smaller of two uncertain values, E[min] <= min E).
        shift: Centre of the coverage interval minus the value, where the distribution is
            asymmetric (:func:`coverage_interval`; ``expanded`` is then the half-width of
            the probabilistically symmetric interval); 0 for a symmetric one.
        parts: The budgets a derived result was taken over (the two sides of a minimum).
    """

    measurand: str
    unit: str
    value: float
    inputs: tuple[UncertaintyInput, ...]
    u_c: float
    nu_eff: float
    k: float
    expanded: float
    coverage_probability: float = COVERAGE_PROBABILITY
    k_basis: str = 'normal'
    notes: tuple[str, ...] = ()
    bias_bound: float = 0.0
    bias_low_bound: float = 0.0
    parts: tuple[Budget, ...] = field(default=(), compare=False)
    shift: float = 0.0

    @property
    def u95(self) -> float:
        """The U reported beside the value, symmetric about it: the farther of the
        interval's two ends (``expanded`` plus the bound of an uncorrected one-sided bias,
        GUM F.2.4.5, plus the ``shift`` of an asymmetric distribution's interval)."""
        return max(self.u_below, self.u_above)

    @property
    def u_below(self) -> float:
        """How far below the value the interval reaches: U + the upward bias bound - the
        shift."""
        return self.expanded + self.bias_bound - self.shift

    @property
    def u_above(self) -> float:
        """How far above the value the interval reaches: U + the downward bias bound +
        the shift."""
        return self.expanded + self.bias_low_bound + self.shift

    @property
    def interval(self) -> tuple[float, float]:
        """Where the measurand lies with probability p: [y - U - b_high, y + U + b_low]."""
        return (self.value - self.u_below, self.value + self.u_above)

    @property
    def shares(self) -> tuple[float, ...]:
        """Each input's share of u_c^2 (sums to 1)."""
        if self.u_c <= 0:
            return tuple(0.0 for _ in self.inputs)
        return tuple((x.contribution / self.u_c) ** 2 for x in self.inputs)

    def input(self, name: str) -> UncertaintyInput:
        """The input of that name (KeyError when absent)."""
        for x in self.inputs:
            if x.name == name:
                return x
        raise KeyError(name)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON (SI values; NaN/inf -> None)."""
        def fin(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None
        return {'measurand': self.measurand, 'unit': self.unit, 'value': fin(self.value),
                'u_c': fin(self.u_c), 'nu_eff': fin(self.nu_eff), 'k': fin(self.k),
                'expanded': fin(self.expanded), 'bias_bound': fin(self.bias_bound),
                'bias_low_bound': fin(self.bias_low_bound), 'shift': fin(self.shift),
                'u95': fin(self.u95), 'interval': [fin(x) for x in self.interval],
                'coverage_probability': self.coverage_probability, 'k_basis': self.k_basis,
                'inputs': [x.to_json_dict(s) for x, s in zip(self.inputs, self.shares,
                                                             strict=True)],
                'notes': list(self.notes),
                **({'parts': [{'measurand': b.measurand, 'value': fin(b.value),
                               'u_c': fin(b.u_c), 'k': fin(b.k), 'expanded': fin(b.expanded)}
                              for b in self.parts]} if self.parts else {})}


def combine(measurand: str, value: float, inputs: Sequence[UncertaintyInput | None], *,
            unit: str = 'rad', p: float = COVERAGE_PROBABILITY,
            notes: Sequence[str] = (), bias_bound: float = 0.0,
            bias_low_bound: float = 0.0, parts: Sequence[Budget] = ()) -> Budget:
    """The budget of ``value`` from its inputs (None entries are skipped).

    Examples:
        Two equal normal inputs of 3 and 4: u_c = 5, k = 2.00 (p = 95.45 %):

        >>> b = combine('y', 10.0, [type_b('a', sensitivity=1.0, distribution='normal', u=3.0),
        ...                         type_b('b', sensitivity=2.0, distribution='normal', u=2.0)])
        >>> b.u_c, round(b.k, 3), round(b.expanded, 2), [round(s, 2) for s in b.shares]
        (5.0, 2.0, 10.0, [0.64, 0.36])
    """
    xs = sorted((x for x in inputs if x is not None), key=lambda x: -x.contribution)
    contrib = np.array([x.contribution for x in xs], dtype=np.float64)
    uc = math.sqrt(float(np.sum(contrib * contrib)))
    nu = welch_satterthwaite(contrib, [x.dof for x in xs]) if xs else math.inf
    k, basis, to_convolve, uc_k = (_coverage_plan(xs, p) if uc > 0
                                   else (math.nan, 'normal', None, 0.0))
    qq = coverage_interval(xs, p) if uc > 0 else None
    asymmetric = qq is not None and (qq[1] + qq[0]) != 0.0
    if to_convolve is not None and not asymmetric:   # an asymmetric interval gives k itself
        k = _convolved_k(to_convolve, uc_k, p)
    expanded = k * uc if uc > 0 else 0.0
    shift = 0.0
    if qq is not None and asymmetric:
        # measured = true + sum c_i X_i: the true value lies in [y - q_hi, y - q_lo]
        expanded = 0.5 * (qq[1] - qq[0])
        shift = -0.5 * (qq[1] + qq[0])
        k = expanded / uc
        basis = f'{basis}; interval of the asymmetric distribution (GUM S1 7.7)'
    few = [x for x in xs if x.kind == 'A' and x.dof < _FEW_REPEATS_DOF and x.contribution > 0]
    if few and uc > 0:
        notes = [*notes, *(f'{x.name}: {x.dof + 1:g} observations ({x.dof:g} dof, '
                           f'{100 * (x.contribution / uc) ** 2:.2g} % of u_c^2), taken as '
                           f'the Student t it is (GUM Supplement 1, 6.4.9): its tails make '
                           f'k = {k:.3g}; more repeats (revolutions, windows) lower it'
                           for x in few)]
    return Budget(measurand=measurand, unit=unit, value=float(value), inputs=tuple(xs),
                  u_c=uc, nu_eff=nu, k=k, expanded=expanded, coverage_probability=p,
                  k_basis=basis, notes=tuple(notes), bias_bound=float(bias_bound),
                  bias_low_bound=float(bias_low_bound), parts=tuple(parts), shift=shift)


def numeric_sensitivity(f: Callable[[float], float], x0: float, step: float) -> float:
    """Central-difference sensitivity df/dx at ``x0`` with ``step`` (> 0).

    Examples:
        >>> round(numeric_sensitivity(lambda x: x ** 2, 3.0, 1e-3), 9)
        6.0
    """
    if not (math.isfinite(step) and step > 0):
        msg = f'step must be finite and > 0, got {step!r}'
        raise TeInputError(msg)
    return (f(x0 + step) - f(x0 - step)) / (2.0 * step)


# --------------------------------------------------------------------------------------
# Monte Carlo (GUM Supplement 1)


def sample_input(x: UncertaintyInput, size: int, rng: np.random.Generator) -> np.ndarray:
    """Draws of the input's error (zero mean, standard deviation u; t: scale u)."""
    if x.distribution == 'normal' or (x.distribution == 't' and math.isinf(x.dof)):
        return x.u * rng.standard_normal(size)
    if x.distribution == 't':
        return x.u * rng.standard_t(x.dof, size)
    a = x.half_width
    if x.distribution == 'tabulated':
        return a * np.asarray(x.shape)[rng.integers(0, len(x.shape), size)]
    if x.distribution == 'rectangular':
        return rng.uniform(-a, a, size)
    if x.distribution == 'triangular':
        return rng.triangular(-a, 0.0, a, size)
    return a * np.sin(rng.uniform(0.0, 2.0 * math.pi, size))


def monte_carlo_interval(samples: npt.ArrayLike, value: float,
                         p: float = COVERAGE_PROBABILITY) -> tuple[float, float, float]:
    """Supplement 1 (7.7): the probabilistically symmetric p interval of the output draws.

    Returns:
        (U_mc, low, high): U_mc is the half-width of [low, high]; ``value`` is not used
        for the interval, only to check the draws are finite around it.
    """
    y = np.asarray(samples, dtype=np.float64).ravel()
    y = y[np.isfinite(y)]
    if y.size < 100 or not math.isfinite(value):
        msg = f'a Monte Carlo interval needs >= 100 finite draws, got {y.size}'
        raise TeInputError(msg)
    lo, hi = np.quantile(y, [(1.0 - p) / 2.0, (1.0 + p) / 2.0])
    return float(hi - lo) / 2.0, float(lo), float(hi)
