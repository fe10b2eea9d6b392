"""The results-store record of one acceptance test (``rv-te test``), from its unit record.

One :class:`rv_te_bench.store.UnitRecord` with ``test='test-plan'``, the plan's name, the
session bag's content hash, the unit's verdict and every measured metric with its limits and
verdict. The TE p-p of a direction goes in as ``te_pp_revolution_max_rad`` with that
direction (the name ``rv-te analyze`` uses for the same quantity), so SPC charts across units
mix both; the other metrics keep their names (direction 'all'). Unmeasured metrics (NaN) are
left out: the store keeps values.

A life / run-in step's checkpoints (issue 38) are rows too, one per tracked quantity and
checkpoint, named ``life_cpNN_<quantity>`` (``te_pp_rad``, ``no_load_torque_nm``,
``temp_case_degc``, and each crank-order line the trend tracks, ``line_<label>_rad``) with
no limit and no verdict (the step's verdict is its ``trend_alarms`` metric): ``rv-te
results`` lists and exports them like the other metrics, a trend across checkpoints and
units from the store alone.
"""

from __future__ import annotations

import math
import re
from datetime import datetime
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pathlib import Path

    from rv_te_bench.store import MetricValue, UnitRecord
    from rv_te_bench.store.records import Direction, Verdict

__all__ = ['life_rows', 'record_of_report', 'store_record']

_VERDICT: dict[str, Verdict | None] = {'pass': 'pass', 'fail': 'fail',
                                       'indeterminate': 'indeterminate',
                                       'not_measured': 'not-measured',
                                       'not_judged': 'not-judged', 'info': None}
#: Unit verdicts that are a judgement (the record's status is 'ok').
_JUDGED = {'pass', 'fail', 'indeterminate'}


def store_record(report: dict[str, Any], bag: Path, *, software_version: str = '',
                 ) -> UnitRecord:
    """The store record of ``report`` (:func:`rv_te_bench.acceptance.build_report`)."""
    from rv_te_bench.store import bag_fingerprint

    sha, size, mtime = bag_fingerprint(bag)
    return record_of_report(report, bag_path=str(bag), bag_sha256=sha, bag_size_bytes=size,
                            bag_mtime_ns=mtime, software_version=software_version)


def _slug(label: str) -> str:
    return re.sub(r'[^a-z0-9]+', '_', label.lower()).strip('_')


def life_rows(report: dict[str, Any]) -> list[MetricValue]:
    """The checkpoints of the report's life steps as store metrics (see the module doc)."""
    from rv_te_bench.store import MetricValue

    out = []
    lives = [s for s in report.get('steps', []) if s.get('kind') == 'life']
    for j, step in enumerate(lives):
        prefix = 'life' if len(lives) == 1 else f'life{j + 1}'
        tracked = {name for name, t in (step.get('trends') or {}).items()
                   if t.get('tracked')}
        for row in step.get('checkpoints') or []:
            cp = f"{prefix}_cp{int(row['checkpoint']):02d}"
            values = [(q, row.get(q)) for q in ('te_pp_rad', 'no_load_torque_nm',
                                                'temp_case_degc')]
            values += [(f'line_{_slug(lab)}_rad', v) for lab, v in
                       (row.get('lines') or {}).items() if f'line {lab}' in tracked]
            for q, v in values:
                name = f'{cp}_{q}'
                if isinstance(v, int | float) and math.isfinite(v) and len(name) <= 64:
                    out.append(MetricValue(name=name, value=float(v)))
    return out


def record_of_report(report: dict[str, Any], *, bag_path: str, bag_sha256: str,
                     bag_size_bytes: int | None = None, bag_mtime_ns: int | None = None,
                     software_version: str = '', details: dict[str, Any] | None = None,
                     lot: str | None = None) -> UnitRecord:
    """The store record of ``report`` with the bag's identity given (a simulated run
    without a bag names itself in ``bag_path`` and gives a hash of its settings)."""
    from rv_te_bench.store import MetricValue, UnitRecord

    metrics = []
    for m in report['metrics']:
        if m['value'] is None or not math.isfinite(m['value']):
            continue
        name: str = m['name']
        direction: Direction = 'all'
        sides: tuple[Direction, ...] = ('ccw', 'cw')
        for d in sides:
            if name == f'te_pp_{d}_rad':
                name, direction = 'te_pp_revolution_max_rad', d
        budget = m.get('budget') or {}
        metrics.append(MetricValue(name=name, value=float(m['value']), direction=direction,
                                   limit_low=m['limit_min'], limit_high=m['limit_max'],
                                   verdict=_VERDICT.get(m['verdict']), u95=m.get('u95'),
                                   uc=budget.get('u_c')))
    metrics += life_rows(report)
    b, u = report['bench'], report['unit']
    verdict: Verdict = report['verdict'] if report['verdict'] in _JUDGED else 'not-judged'
    return UnitRecord(
        test='test-plan', plan=report['plan']['plan'], bag_path=bag_path,
        bag_sha256=bag_sha256,
        tested_at=datetime.fromisoformat(u['date_utc']), serial=u['serial'], lot=lot,
        bench_id=b.get('bench_id') or None, preset=b.get('preset') or None,
        reducer_type=b.get('reducer_type') or None, operator=u['operator'],
        status='ok' if report['verdict'] in _JUDGED else (
            'partial' if report['verdict'] == 'not_judged' else 'failed'),
        failure=None if report['verdict'] in _JUDGED else report['reason'],
        verdict=verdict, command='test --from' if 'source' in report else 'test',
        software_version=software_version,
        bag_size_bytes=bag_size_bytes, bag_mtime_ns=bag_mtime_ns, metrics=tuple(metrics),
        details={'tolerance': report['tolerance']['profile'],
                 'decision_rule': report['tolerance'].get('decision_rule'),
                 'conditions': report.get('conditions', {}), 'reason': report['reason'],
                 **({'source': {k: v for k, v in report['source'].items() if k != 'steps'}}
                    if 'source' in report else {}),
                 **(details or {})})
