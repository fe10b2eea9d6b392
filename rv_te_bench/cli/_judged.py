"""The record of a plan judged from measured data (``rv-te test PLAN --from ...``), kept so
that ``rv-te unit-report`` can judge it again as it does a live test's session bag.

A live test leaves its ``test/report`` in the session bag; a record judged offline has no
such message (the bag is the user's, or an import of a DAQ file). ``rv-te test --from``
writes ``judged.json`` into its output folder ``<out-dir>/<serial>_<time>/`` (beside the
imported bag): the plan and tolerance texts, how the record was read (torque topic,
matching tolerances), the judged bag's path and the report. ``rv-te unit-report`` given
that folder, or the imported bag in it, reads the bag again, judges it again with the same
settings, checks every metric equals the recorded one and writes the unit report.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from rv_te_bench.errors import AcceptanceError

__all__ = ['JUDGED_FILE', 'find_judged', 'rejudge', 'write_judged']

JUDGED_FILE = 'judged.json'
_KIND = 'rv-te judged record'


def write_judged(out_dir: Path, *, bag: Path, plan_text: str, tolerance_text: str,
                 torque: dict[str, Any] | None, settings: dict[str, float],
                 report: dict[str, Any],
                 channel_topics: dict[str, dict[str, Any]] | None = None,
                 topics_bag: Path | None = None) -> Path:
    """Write ``out_dir/judged.json`` (see the module docstring); its path.
    ``channel_topics``: the input-torque / case-temperature topics read (``torque_in``,
    ``temperature`` -> TorqueTopic fields), when not bench/channels; ``topics_bag``: the bag
    holding the topics when it is not ``bag`` (an imported JointState bag's original)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    doc = {'kind': _KIND, 'version': 1, 'bag': str(Path(bag).resolve()),
           'plan_yaml': plan_text, 'tolerance_yaml': tolerance_text, 'torque_topic': torque,
           'channel_topics': channel_topics or {},
           'topics_bag': str(Path(topics_bag).resolve()) if topics_bag else '',
           'settings': settings, 'report': report}
    path = out_dir / JUDGED_FILE
    tmp = path.with_suffix('.json.tmp')
    tmp.write_text(json.dumps(doc, indent=1), encoding='utf-8')
    tmp.replace(path)
    return path


def find_judged(path: Path) -> Path | None:
    """The judged record for ``path``: the folder's own ``judged.json``, or the one beside a
    bag that names this bag; None when there is none."""
    for cand in (path / JUDGED_FILE, path.parent / JUDGED_FILE):
        if not cand.is_file():
            continue
        if cand.parent == path:
            return cand
        try:
            named = json.loads(cand.read_text(encoding='utf-8')).get('bag', '')
        except (OSError, ValueError, AttributeError):
            continue
        if named and Path(named).resolve() == path.resolve():
            return cand
    return None


def _load(path: Path) -> dict[str, Any]:
    try:
        doc = json.loads(path.read_text(encoding='utf-8'))
    except (OSError, ValueError) as exc:
        msg = f'{path}: not a readable judged record ({type(exc).__name__})'
        raise AcceptanceError(msg) from None
    keys = {'bag', 'plan_yaml', 'tolerance_yaml', 'settings', 'report'}
    if not isinstance(doc, dict) or doc.get('kind') != _KIND or not keys <= set(doc):
        msg = f'{path}: not a judged record of rv-te test --from (keys {sorted(keys)})'
        raise AcceptanceError(msg)
    return doc


def rejudge(judged: Path, *, report_dir: Path | None, as_json: bool,
            differences: Any, pdf: bool = False) -> int:
    """Judge the record again from its bag, compare, write the unit report; exit code."""
    from rv_te_bench.acceptance import parse_plan, parse_tolerance
    from rv_te_bench.acceptance._files import parse_yaml_text
    from rv_te_bench.acceptance.recorded import JudgeSettings, judge_record
    from rv_te_bench.cli._test_report import show_report, verdict_exit
    from rv_te_bench.errors import ToleranceError
    from rv_te_bench.io.measured_record import TorqueTopic, read_measured_record

    doc = _load(judged)
    old = doc['report']
    bag = Path(doc['bag'])
    if not bag.exists():
        msg = f'{judged}: the judged bag {bag} is gone'
        raise AcceptanceError(msg)
    plan = parse_plan(parse_yaml_text(doc['plan_yaml'], 'judged plan', AcceptanceError),
                      'judged plan')
    profile = parse_tolerance(parse_yaml_text(doc['tolerance_yaml'], 'judged tolerance',
                                              ToleranceError), 'judged tolerance')
    torque = TorqueTopic(**doc['torque_topic']) if doc.get('torque_topic') else None
    topics = {k: TorqueTopic(**v) for k, v in (doc.get('channel_topics') or {}).items()
              if k in ('torque_in', 'temperature')}
    record = read_measured_record(bag, torque=torque, **topics,
                                  topics_from=doc.get('topics_bag') or None)
    new = judge_record(plan, profile, record, serial=old['unit']['serial'],
                       operator=old['unit']['operator'], conditions=old.get('conditions'),
                       settings=JudgeSettings(**doc['settings']))
    new['source']['imported_from'] = old.get('source', {}).get('imported_from', '')
    new['bench']['bag'] = str(bag)
    show_report(new, report_dir or judged.parent / 'unit-report', as_json=as_json, pdf=pdf)
    diffs = differences(new, old)
    if diffs:
        print(f'ERROR: judged again from {bag}, {len(diffs)} metric(s) differ from the '
              f'recorded result: {"; ".join(diffs[:3])}', file=sys.stderr)
        return 1
    print(f'judged again from {record.samples} samples of {bag}: every metric equals the '
          'recorded result', file=sys.stderr)
    return verdict_exit(new['verdict'], old['unit']['serial'], new['reason'], new,
                        as_json=as_json)
