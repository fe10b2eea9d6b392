"""Tolerance profiles and the verdict of a unit.

A profile (YAML; limits in catalogue units, the unit in the key; docs/ACCEPTANCE.md)::

    profile: rv-80e-101
    description: ...
    limits:
      te_pp_arcmin: {max: 1.0, source: "..."}
      lost_motion_arcmin: {max: 1.0, source: "..."}
      backlash_arcmin: {max: 1.0, source: "..."}
      torsional_rigidity_nm_per_arcmin: {min: 196, region: K, source: "..."}
    decision_rule: {kind: guarded, guard_fraction: 1.0, source: "lab procedure QP-12"}

Each limit applies to the measured metrics of its family: ``te_pp`` to the TE p-p of every
direction of every ``te`` step, ``torsional_rigidity`` to the named region (the smaller of
its two sides). A metric gets pass / fail / not_measured with its margin (distance to the
limit, positive inside); metrics without a limit are ``info``. The unit passes when every
limited metric passes: a limit whose metric the plan did not measure fails the unit. A
metric the plan measures but whose data could not be judged (a recorded test whose record
misses what the step needs, a step whose blocks were lost) is ``not_judged`` with the
reason, never a number; the unit is then ``not_judged`` unless a metric fails.

The profile names its decision rule (ILAC-G8, ISO 14253-1; :mod:`rv_te_bench.core.decision`):
``simple`` acceptance (the default: within the limit passes, the uncertainty is stated, not
applied) or ``guarded`` acceptance with a guard band w = guard_fraction x U: a metric
passes when it is inside the limit by w, fails when outside by w, and is
``indeterminate`` otherwise; the unit is indeterminate when nothing fails, every limit was
judged and something is indeterminate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NotRequired, TypedDict

from rv_te_bench.acceptance._files import parse_yaml_text, read_source, shipped, shown_keys
from rv_te_bench.core.decision import DecisionRule, decide
from rv_te_bench.core.units import ARCMIN_PER_RAD, ARCSEC_PER_RAD
from rv_te_bench.errors import TeConfigError, ToleranceError

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = [
    'LIMIT_KEYS',
    'DecisionRulePlain',
    'Limit',
    'LimitPlain',
    'Measured',
    'MetricVerdict',
    'MetricVerdictJson',
    'TolerancePlain',
    'ToleranceProfile',
    'evaluate',
    'load_tolerance',
    'parse_tolerance',
    'shipped_tolerances',
]

#: Limit key -> (family, SI value per unit of the key, SI unit).
LIMIT_KEYS: dict[str, tuple[str, float, str]] = {
    'te_pp_arcmin': ('te_pp', 1.0 / ARCMIN_PER_RAD, 'rad'),
    'te_pp_arcsec': ('te_pp', 1.0 / ARCSEC_PER_RAD, 'rad'),
    'lost_motion_arcmin': ('lost_motion', 1.0 / ARCMIN_PER_RAD, 'rad'),
    'lost_motion_arcsec': ('lost_motion', 1.0 / ARCSEC_PER_RAD, 'rad'),
    'backlash_arcmin': ('backlash', 1.0 / ARCMIN_PER_RAD, 'rad'),
    'backlash_arcsec': ('backlash', 1.0 / ARCSEC_PER_RAD, 'rad'),
    'torsional_rigidity_nm_per_arcmin': ('torsional_rigidity', ARCMIN_PER_RAD, 'N m/rad'),
    'hysteresis_loss_j': ('hysteresis_loss', 1.0, 'J'),
    'efficiency_pct': ('efficiency', 0.01, '1'),
    'no_load_torque_nm': ('no_load_torque', 1.0, 'N m'),
    'starting_torque_nm': ('starting_torque', 1.0, 'N m'),
    'back_driving_torque_nm': ('back_driving_torque', 1.0, 'N m'),
    'temperature_rise_k': ('temperature_rise', 1.0, 'K'),
    'trend_alarms': ('trend_alarms', 1.0, '1'),
}
#: Family -> the one metric it judges (the families judged by name; te_pp and torsional
#: rigidity match several).
_SINGLE_METRIC = {'lost_motion': 'lost_motion_rad', 'backlash': 'backlash_rad',
                  'hysteresis_loss': 'hysteresis_loss_j',
                  'efficiency': 'efficiency_at_max_load',
                  'no_load_torque': 'no_load_torque_max_nm',
                  'starting_torque': 'starting_torque_nm',
                  'back_driving_torque': 'back_driving_torque_nm',
                  'temperature_rise': 'temperature_rise_k', 'trend_alarms': 'trend_alarms'}
#: The sides a limit of each family may have: a unit is better with less TE, lost motion and
#: backlash (a ``min`` on them would fail the best units) and with more rigidity (a ``max``
#: likewise); the hysteresis loss may be held in a band (a lab's consistency check).
LIMIT_SIDES: dict[str, tuple[str, ...]] = {
    'te_pp': ('max',), 'lost_motion': ('max',), 'backlash': ('max',),
    'hysteresis_loss': ('min', 'max'), 'torsional_rigidity': ('min',),
    'efficiency': ('min',), 'no_load_torque': ('max',), 'starting_torque': ('max',),
    'back_driving_torque': ('min', 'max'), 'temperature_rise': ('max',),
    'trend_alarms': ('max',)}
#: Largest limit value in the key's unit (a typo of orders of magnitude is refused).
MAX_LIMIT_VALUE = 1e6


@dataclass(frozen=True)
class Limit:
    """One limit, in SI units."""

    key: str
    family: str
    unit: str
    min_si: float = math.nan
    max_si: float = math.nan
    region: str = ''
    source: str = ''

    def metric_matches(self, name: str) -> bool:
        """Whether measured metric ``name`` falls under this limit."""
        if self.family == 'te_pp':
            return name.startswith('te_pp_') and name.endswith('_rad')
        if self.family == 'torsional_rigidity':
            return name == f'torsional_rigidity_{self.region}_nm_per_rad'
        return name == _SINGLE_METRIC[self.family]

    @property
    def placeholder_name(self) -> str:
        """Metric name shown when nothing was measured for this limit."""
        return {'te_pp': 'te_pp_rad',
                'torsional_rigidity': f'torsional_rigidity_{self.region}_nm_per_rad',
                **_SINGLE_METRIC}[self.family]


class DecisionRulePlain(TypedDict):
    """A profile's decision rule in its record."""

    kind: str
    guard_fraction: float
    statement: str
    source: str


class LimitPlain(TypedDict):
    """A limit in a profile's record (SI; None: no bound)."""

    key: str
    family: str
    unit: str
    min_si: float | None
    max_si: float | None
    region: str
    source: str


class TolerancePlain(TypedDict):
    """:meth:`ToleranceProfile.to_plain`."""

    profile: str
    description: str
    decision_rule: DecisionRulePlain
    limits: list[LimitPlain]


@dataclass(frozen=True)
class ToleranceProfile:
    """A validated tolerance profile."""

    name: str
    limits: tuple[Limit, ...]
    description: str = ''
    origin: str = '<tolerance>'
    rule: DecisionRule = field(default_factory=DecisionRule)
    rule_source: str = ''

    def to_plain(self) -> TolerancePlain:
        """For records (SI limits)."""
        return {'profile': self.name, 'description': self.description,
                'decision_rule': {'kind': self.rule.kind,
                                  'guard_fraction': self.rule.guard_fraction,
                                  'statement': self.rule.describe(),
                                  'source': self.rule_source},
                'limits': [{'key': lim.key, 'family': lim.family, 'unit': lim.unit,
                            'min_si': None if math.isnan(lim.min_si) else lim.min_si,
                            'max_si': None if math.isnan(lim.max_si) else lim.max_si,
                            'region': lim.region, 'source': lim.source}
                           for lim in self.limits]}


def parse_tolerance(data: Any, origin: str = '<tolerance>') -> ToleranceProfile:
    """Validate a tolerance mapping (parsed YAML).

    Raises:
        ToleranceError: Anything wrong, named (file, key, rule, value).
    """
    def fail(what: str) -> None:
        msg = f'{origin}: {what}'
        raise ToleranceError(msg)

    if not isinstance(data, dict) or not {'profile', 'limits'} & set(data):
        fail('is not a tolerance profile (a mapping with "profile" and "limits"; nothing of '
             'it is shown)')
    unknown = set(data) - {'profile', 'description', 'limits', 'decision_rule'}
    if unknown:
        fail(f'unknown key(s) {shown_keys(unknown)}; allowed: profile, description, limits, '
             'decision_rule')
    name = data.get('profile')
    if not isinstance(name, str) or not name.strip():
        fail(f'profile must be a non-empty string, got {name!r}')
    limits_raw = data.get('limits')
    if not isinstance(limits_raw, dict) or not limits_raw:
        fail(f'limits must map limit keys ({", ".join(LIMIT_KEYS)}) to {{min|max, source}}')
    limits: list[Limit] = []
    seen: set[tuple[str, str]] = set()
    for key, spec in limits_raw.items():
        if key not in LIMIT_KEYS:
            fail(f'limit {key!r} unknown; known: {", ".join(LIMIT_KEYS)}')
        family, scale, unit = LIMIT_KEYS[key]
        if not isinstance(spec, dict):
            fail(f'limit {key}: must be a mapping like {{max: 1.0, source: "..."}}, got {spec!r}')
        allowed = {'min', 'max', 'source'} | ({'region'} if family == 'torsional_rigidity'
                                              else set())
        if bad := sorted(set(spec) - allowed):
            fail(f'limit {key}: unknown field(s) {bad}; allowed: {sorted(allowed)}')
        sides = LIMIT_SIDES[family]
        for other in {'min', 'max'} - set(sides):
            if other in spec:
                (only,) = sides
                fail(f'limit {key}: {other} is not allowed (only {only}: a unit is better '
                     f'with {"less" if only == "max" else "more"} {family.replace("_", " ")})')
        if not set(sides) & set(spec):
            fail(f'limit {key}: needs {" or ".join(sides)}')
        vals = {}
        for side in ('min', 'max'):
            if side in spec:
                v = spec[side]
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                        or not 0 <= v <= MAX_LIMIT_VALUE:
                    fail(f'limit {key}.{side} must be a number in 0..{MAX_LIMIT_VALUE:g}, '
                         f'got {v!r}')
                vals[side] = float(v) * scale
        if 'min' in vals and 'max' in vals and vals['min'] > vals['max']:
            fail(f'limit {key}: min {spec["min"]!r} > max {spec["max"]!r}')
        region = str(spec.get('region', 'K')) if family == 'torsional_rigidity' else ''
        source = spec.get('source', '')
        if not isinstance(source, str):
            fail(f'limit {key}.source must be a string, got {source!r}')
        if (family, region) in seen:
            fail(f'limit {key}: a second limit on {family}{" " + region if region else ""}')
        seen.add((family, region))
        limits.append(Limit(key=key, family=family, unit=unit,
                            min_si=vals.get('min', math.nan), max_si=vals.get('max', math.nan),
                            region=region, source=source))
    rule, rule_source = _decision_rule(data.get('decision_rule', 'simple'), fail)
    return ToleranceProfile(name=name.strip(), limits=tuple(limits),
                            description=str(data.get('description', '') or ''), origin=origin,
                            rule=rule, rule_source=rule_source)


def _decision_rule(raw: Any, fail: Callable[[str], None]) -> tuple[DecisionRule, str]:
    """``decision_rule: simple`` | ``guarded`` | ``{kind, guard_fraction, source}``."""
    spec = {'kind': raw} if isinstance(raw, str) else raw
    if not isinstance(spec, dict):
        fail(f'decision_rule must be "simple", "guarded" or a mapping {{kind, guard_fraction, '
             f'source}}, got {raw!r}')
    if bad := sorted(set(map(str, spec)) - {'kind', 'guard_fraction', 'source'}):
        fail(f'decision_rule: unknown field(s) {bad}; allowed: kind, guard_fraction, source')
    kind = spec.get('kind', 'simple')
    frac = spec.get('guard_fraction', 1.0)
    source = spec.get('source', '')
    if not isinstance(source, str):
        fail(f'decision_rule.source must be a string, got {source!r}')
    if kind == 'simple' and 'guard_fraction' in spec:
        fail('decision_rule: a guard_fraction goes with kind guarded, not simple')
    if isinstance(frac, bool) or not isinstance(frac, int | float):
        fail(f'decision_rule.guard_fraction must be a number, got {frac!r}')
    try:
        return DecisionRule(kind=kind, guard_fraction=float(frac)), source
    except TeConfigError as exc:
        fail(f'decision_rule: {exc}')
    raise AssertionError  # fail() raised


def shipped_tolerances() -> list[str]:
    """Names of the profiles shipped in ``rv_te_bench/acceptance/tolerances``."""
    return shipped('tolerances')


def load_tolerance(name_or_path: str | Path, *, relative_to: Path | None = None,
                   ) -> tuple[ToleranceProfile, str]:
    """Load a profile file (a path, also relative to a plan's folder, or a shipped name).

    Raises:
        ToleranceError: Missing or unreadable file, bad YAML, invalid profile.
    """
    text, origin = read_source(name_or_path, folder='tolerances', what='tolerance profile',
                               error=ToleranceError, relative_to=relative_to)
    return parse_tolerance(parse_yaml_text(text, origin, ToleranceError), origin), text


@dataclass(frozen=True)
class Measured:
    """A measured metric (SI) with its expanded uncertainty.

    Attributes:
        note: Why it could not be judged (value NaN).
        u95: U (about 95 %; NaN: no budget); ``u_below`` / ``u_above`` how far below /
            above the value its interval reaches when it is not symmetric (NaN: U).
        budget: The budget's JSON (for the record), or None.
    """

    name: str
    step: str
    unit: str
    value: float
    note: str = ''
    u95: float = math.nan
    u_below: float = math.nan
    u_above: float = math.nan
    budget: dict[str, Any] | None = field(default=None, compare=False, repr=False)


class MetricVerdictJson(TypedDict):
    """The JSON of :class:`MetricVerdict` (None: not finite; ``note`` and ``budget`` only
    when there is one)."""

    name: str
    step: str
    unit: str
    value: float | None
    u95: float | None
    limit_min: float | None
    limit_max: float | None
    margin: float | None
    verdict: str
    source: str
    guard: float | None
    pfa: float | None
    borderline: bool
    note: NotRequired[str]
    budget: NotRequired[dict[str, Any]]


@dataclass(frozen=True)
class MetricVerdict:
    """A metric, its limit and its verdict (SI)."""

    name: str
    step: str
    unit: str
    value: float
    limit_min: float
    limit_max: float
    margin: float
    verdict: str
    source: str
    note: str = ''
    u95: float = math.nan
    guard: float = math.nan
    pfa: float = math.nan
    borderline: bool = False
    budget: dict[str, Any] | None = field(default=None, compare=False, repr=False)

    def to_json_dict(self) -> MetricVerdictJson:
        """JSON-friendly (NaN -> None); ``u95`` the value's U in SI, ``guard`` the guard
        band applied, ``pfa`` the probability that the true value lies outside the limit
        (shown for borderline results)."""
        def fin(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None
        out: MetricVerdictJson = {'name': self.name, 'step': self.step, 'unit': self.unit,
               'value': fin(self.value), 'u95': fin(self.u95),
               'limit_min': fin(self.limit_min),
               'limit_max': fin(self.limit_max), 'margin': fin(self.margin),
               'verdict': self.verdict, 'source': self.source, 'guard': fin(self.guard),
               'pfa': fin(self.pfa), 'borderline': self.borderline}
        if self.note:
            out['note'] = self.note
        if self.budget is not None:
            out['budget'] = self.budget
        return out


def _judge(m: Measured, lim: Limit, rule: DecisionRule) -> MetricVerdict:
    if not math.isfinite(m.value):
        return MetricVerdict(m.name, m.step, m.unit, m.value, lim.min_si, lim.max_si,
                             math.nan, 'not_judged' if m.note else 'not_measured', lim.source,
                             m.note, u95=m.u95)
    d = decide(m.value, m.u95, lower=lim.min_si, upper=lim.max_si, rule=rule,
               u_below=m.u_below, u_above=m.u_above)
    return MetricVerdict(m.name, m.step, m.unit, m.value, lim.min_si, lim.max_si, d.margin,
                         d.verdict, lim.source, m.note, u95=m.u95, guard=d.guard, pfa=d.pfa,
                         borderline=d.borderline, budget=m.budget)


def evaluate(measured: list[Measured], profile: ToleranceProfile,
             ) -> tuple[list[MetricVerdict], str, str]:
    """Judge every measured metric under the profile's decision rule; returns
    (verdicts, 'pass' | 'fail' | 'not_judged' | 'indeterminate', reason).

    Every limit whose family was not measured appears once as ``not_measured``. A metric
    with a note and no value is ``not_judged``; the unit is then 'not_judged' unless a
    metric fails or a limit is not measured at all. Under guarded acceptance a metric
    neither proven in nor out is ``indeterminate``; the unit is then 'indeterminate' when
    nothing fails, nothing is missing and everything was judged.
    """
    out: list[MetricVerdict] = []
    used: set[int] = set()
    for m in measured:
        lim = next((x for x in profile.limits if x.metric_matches(m.name)), None)
        if lim is None:
            out.append(MetricVerdict(m.name, m.step, m.unit, m.value, math.nan, math.nan,
                                     math.nan, 'info', '', m.note, u95=m.u95, budget=m.budget))
            continue
        used.add(id(lim))
        out.append(_judge(m, lim, profile.rule))
    for lim in profile.limits:
        if id(lim) not in used:
            out.append(MetricVerdict(lim.placeholder_name, '', lim.unit, math.nan, lim.min_si,
                                     lim.max_si, math.nan, 'not_measured', lim.source))
    failed = [v.name for v in out if v.verdict == 'fail']
    missing = [v.name for v in out if v.verdict == 'not_measured']
    unjudged = [v for v in out if v.verdict == 'not_judged']
    open_ = [v.name for v in out if v.verdict == 'indeterminate']
    if not failed and not missing and not unjudged and not open_:
        return out, 'pass', ('every limited metric is within its limit' if profile.rule.kind
                             == 'simple' else 'every limited metric is within its limit by '
                             'at least its guard band')
    parts = []
    if failed:
        parts.append('out of limit: ' + ', '.join(failed))
    if missing:
        parts.append('not measured: ' + ', '.join(missing))
    if unjudged:
        steps = dict.fromkeys(f"step '{v.step}': {v.note}" for v in unjudged)
        parts.append('not judged: ' + '; '.join(steps))
    if open_:
        parts.append('neither conformance nor non-conformance proven (the value +- its '
                     'guard band straddles the limit): ' + ', '.join(open_))
    verdict = ('fail' if failed or missing else 'not_judged' if unjudged
               else 'indeterminate')
    return out, verdict, '; '.join(parts)
