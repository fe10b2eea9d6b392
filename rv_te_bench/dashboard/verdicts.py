"""The test panel's metric table while a test runs: each metric against its limit.

The test sequencer decides each metric as soon as its data is complete (a TE direction, a
sweep point: when its segment ends; a hysteresis step's metrics: when the step ends) and
publishes every metric decided so far against its limit on ``test/report`` (verdict
'running', the limits not measured yet 'pending'); the table shows those rows, with the unit
report's labels and display units (:func:`rv_te_bench.report.unit.metric_rows`), and the
final ``test/report`` replaces them with its own.

A sequencer that sends no running metrics (a bag recorded before it did): a step's measured
values from ``test/step`` when it finishes (``result_yaml``, SI) are judged here against the
tolerance profile the goal carried, or the one its plan or the bench's preset names, with
the sequencer's own rule (:func:`rv_te_bench.acceptance.tolerance.evaluate`).
"""

from __future__ import annotations

import math
from typing import Any

from rv_te_bench.acceptance.plan import parse_plan
from rv_te_bench.acceptance.tolerance import (
    Measured,
    ToleranceProfile,
    evaluate,
    load_tolerance,
    parse_tolerance,
)
from rv_te_bench.errors import RvTeError
from rv_te_bench.report.unit import metric_rows
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, load_yaml

__all__ = ['live_rows', 'plan_steps', 'unit_of']


def unit_of(name: str) -> str:
    """SI unit of a metric from the one metric unit table ('' when it has none)."""
    from rv_te_bench.core.units import metric_unit

    try:
        return metric_unit(name).si
    except KeyError:
        return ''


def _yaml(text: str, what: str) -> Any:
    try:
        return load_yaml(text, origin=what, limits=DOCUMENT_LIMITS) if text.strip() else None
    except (RvTeError, ValueError):
        return None


def plan_steps(plan_yaml: str) -> list[dict[str, str]]:
    """[{name, kind}] of the plan the goal carried ([] when it does not parse)."""
    data = _yaml(plan_yaml, 'plan (test/report)')
    try:
        plan = parse_plan(data, 'plan (test/report)')
    except (RvTeError, ValueError, TypeError, AttributeError):
        return []
    return [{'name': s.name, 'kind': s.kind} for s in plan.steps]


def profile_of(report: dict[str, Any], preset: str) -> ToleranceProfile | None:
    """The tolerance profile of the running test (None when none can be read)."""
    text = report.get('tolerance_yaml', '')
    try:
        if text.strip():
            return parse_tolerance(_yaml(text, 'tolerance (test/report)'),
                                   'tolerance (test/report)')
        data = _yaml(report.get('plan_yaml', ''), 'plan (test/report)')
        name = data.get('tolerance') if isinstance(data, dict) else None
        if name or preset:
            return load_tolerance(name or preset)[0]
    except (RvTeError, ValueError, TypeError, OSError):
        return None
    return None


def live_rows(report: dict[str, Any], steps: list[dict[str, Any]],
              preset: str) -> list[dict[str, str]]:
    """The metric table: the report's (final, or decided so far), or else the finished
    steps' values judged now."""
    if report.get('metrics'):   # the final report's, or those decided so far
        return metric_rows({'metrics': [_si(m) for m in report['metrics']]})
    measured = []
    for s in steps:
        if s.get('state') != 'finished':
            continue
        values = _yaml(s.get('result_yaml', ''), 'step result')
        if not isinstance(values, dict):
            continue
        for name, value in values.items():
            v = float(value) if isinstance(value, int | float) else math.nan
            measured.append(Measured(str(name), s['step_name'], unit_of(str(name)), v))
    profile = profile_of(report, preset)
    if profile is None:
        rows = [{'name': m.name, 'step': m.step, 'unit': m.unit, 'value': m.value,
                 'limit_min': None, 'limit_max': None, 'margin': None, 'verdict': 'info',
                 'source': ''} for m in measured]
        return metric_rows({'metrics': rows})
    verdicts, _, _ = evaluate(measured, profile)
    rows = [v.to_json_dict() for v in verdicts]
    for r in rows:
        if r['verdict'] == 'not_measured' and not r['step']:
            r['verdict'] = 'pending'
    return metric_rows({'metrics': rows})


def _si(m: dict[str, Any]) -> dict[str, Any]:
    def fin(x: Any) -> float | None:
        return float(x) if isinstance(x, int | float) and math.isfinite(x) else None
    return {**m, 'value': fin(m.get('value')), 'limit_min': fin(m.get('limit_min')),
            'limit_max': fin(m.get('limit_max')), 'margin': fin(m.get('margin'))}
