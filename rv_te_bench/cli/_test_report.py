"""What ``rv-te test`` does with a finished test, whichever route judged it (a live
session, ``--sim`` in this process, ``--from`` a recording, ``rv-te unit-report`` judging
again): the unit report written and shown, the record kept in the results store, the
verdict line and the exit code.

A module of its own so that the routes (``_test_from``, ``_test_offline``, ``_judged``)
and ``rv-te test`` import it, not each other.
"""

from __future__ import annotations

import json
import sys
from typing import TYPE_CHECKING, Any

from rv_te_bench import __version__
from rv_te_bench.cli._db import db_for_bags, store_summary
from rv_te_bench.errors import StoreError

if TYPE_CHECKING:
    import argparse
    from pathlib import Path

__all__ = ['DEFAULT_TE_MODE', 'EXIT_FAIL', 'EXIT_INDETERMINATE', 'record_in_store',
           'show_report', 'verdict_exit']

#: Exit code of a unit that fails.
EXIT_FAIL = 3
#: Exit code of a unit whose conformance the guarded decision rule could not prove.
EXIT_INDETERMINATE = 4
#: Reducer model -> TE model mode a simulated session uses.
DEFAULT_TE_MODE = {'wang2020-2kv': 'nlte', 'hu2020-rv': 'elastic', 'li2023-rv': 'dte'}


def show_report(report: dict[str, Any], directory: Path, *, as_json: bool,
                pdf: bool = False) -> None:
    """Write the unit report (and ``pdf``: report.pdf printed by Chromium; a failure to print
    is a warning, the test's record and verdict go on); print the record as JSON (the one
    document on stdout; the report's path on stderr) or the verdict table and its path."""
    from rv_te_bench.errors import RvTeError
    from rv_te_bench.report.print_pdf import print_to_pdf
    from rv_te_bench.report.unit import write_unit_report

    paths = write_unit_report(report, directory)
    if pdf:
        try:
            print(f'report PDF: {print_to_pdf(paths["html"], directory / "report.pdf")}',
                  file=sys.stderr)
        except RvTeError as exc:
            print(f'WARNING: no report.pdf: {exc}', file=sys.stderr)
    if as_json:
        print(json.dumps(report, indent=1), flush=True)
        print(f'report: {paths["html"]}', file=sys.stderr)
    else:
        _print_table(report)
        print(f'report: {paths["html"]}')


def verdict_exit(verdict: str, serial: str, reason: str,
                 report: dict[str, Any] | None, *, as_json: bool = False) -> int:
    """The verdict line (stderr with --json: stdout holds only the JSON) and the exit code:
    0 pass, 3 fail, 4 indeterminate (guarded acceptance: conformance not proven), 1 anything
    else."""
    from rv_te_bench.report.unit import human_reason

    out = sys.stderr if as_json else sys.stdout
    if report is not None:
        reason = human_reason(report)
    if verdict == 'pass':
        print(f'VERDICT: PASS  unit {serial}: {reason}', file=out)
        return 0
    if verdict == 'fail':
        print(f'VERDICT: FAIL  unit {serial}: {reason}', file=out)
        return EXIT_FAIL
    if verdict == 'indeterminate':
        print(f'VERDICT: INDETERMINATE  unit {serial}: {reason}', file=out)
        return EXIT_INDETERMINATE
    if verdict == 'not_judged':
        print(f'VERDICT: NOT JUDGED  unit {serial}: {reason}', file=out)
        return 1
    print(f'ERROR: test of unit {serial} {verdict}: {reason}', file=sys.stderr)
    return 1


def record_in_store(args: argparse.Namespace, report: dict[str, Any], bag: Path, *,
            beside_bag: bool = False) -> None:
    """The test's record in the results store (the user's one store by default, as
    ``rv-te analyze``; ``beside_bag`` is kept for the callers and changes nothing)."""
    from rv_te_bench.acceptance._store import store_record
    from rv_te_bench.store import open_store

    db = db_for_bags(args, [bag if beside_bag else bag.parent])
    if db is None or not (bag / 'metadata.yaml').exists():
        return
    try:
        with open_store(db) as store:
            store.upsert(store_record(report, bag, software_version=__version__))
            print(f'recorded in the {store_summary(store.url, store.count())}',
                  file=sys.stderr if args.json else sys.stdout)
    except StoreError as exc:   # a result not stored is an error (issue #32), --no-db to skip
        msg = f'the test was not recorded in the results store: {exc} (--db elsewhere, or --no-db)'
        raise StoreError(msg) from None


def _print_table(report: dict[str, Any]) -> None:
    from rv_te_bench.report.unit import decision_rule_text, metric_rows

    print(f"unit {report['unit']['serial']}  operator {report['unit']['operator']}  "
          f"{report['unit']['date_utc']}  plan {report['plan']['plan']}  "
          f"tolerance {report['tolerance']['profile']}")
    print(f'decision rule: {decision_rule_text(report)}')
    print(f"{'metric':<34} {'value':>12} {'+-U':>8} {'limit':>14} {'margin':>12}  verdict")
    for r in metric_rows(report):
        pfa = f"  (P false accept {r['pfa']})" if r['pfa'] else ''
        print(f"{r['label']:<34} {r['value']:>12} {r['u95']:>8} {r['limit']:>14} "
              f"{r['margin']:>12}  {r['verdict']}{pfa}")
