"""Text longer than the results store keeps is refused up front, in one line (issue #21).

SQLite ignores column widths, PostgreSQL refuses ('value too long'): without the check a
129-character --serial was kept in the default SQLite store and made a PostgreSQL store
fail at the very end of the analysis; a plan named with 129 characters the same.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from rv_te_bench.acceptance.plan import PlanError, parse_plan

ROOT = Path(__file__).resolve().parents[2]
RV_TE = [sys.executable, '-m', 'rv_te_bench.cli.main']


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env.pop('RV_TE_DB', None)
    return subprocess.run([*RV_TE, *args], capture_output=True, text=True, timeout=300,
                          env=env, cwd=ROOT, check=False)


@pytest.mark.parametrize('command', [
    ['analyze', 'bags/sample', '--serial', 'S' * 129],
    ['fleet', 'analyze', 'bags/sample', '--serial', 'S' * 129],
])
def test_long_serial_is_one_line_exit_1(command: list[str], tmp_path: Path) -> None:
    """Refused before the analysis (fails before: analyze analysed the bag and stored the
    129-character serial in SQLite, exit 0)."""
    p = _run(*command, '--db', str(tmp_path / 'r.sqlite'))
    assert p.returncode == 1, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert lines == ["ERROR: --serial is 129 characters, the results store keeps at most "
                     f"128: {'S' * 40 + '...'!r}"]
    assert not (tmp_path / 'r.sqlite').exists()


def test_plan_name_longer_than_the_store_keeps_is_refused() -> None:
    steps = [{'name': 'te', 'kind': 'te', 'speed_rpm': 100, 'load_nm': 0,
              'directions': ['ccw']}]
    assert parse_plan({'plan': 'p' * 128, 'steps': steps}).name == 'p' * 128
    with pytest.raises(PlanError, match=r'^x.yaml: plan is 129 characters, the results store '
                       r'keeps at most 128, got') as exc:
        parse_plan({'plan': 'p' * 129, 'steps': steps}, 'x.yaml')
    assert '\n' not in str(exc.value)


def test_rv_te_test_refuses_long_serial_and_plan_name_before_any_work(tmp_path: Path) -> None:
    """``rv-te test``: a 129-character --serial or plan name is one line, exit 1, before the
    bench is contacted (the record would be refused after the whole test)."""
    p = _run('test', 'li2023-rv', '--serial', 'S' * 129, '--operator', 'kim', '--db',
             str(tmp_path / 'r.sqlite'))
    assert p.returncode == 1, (p.stdout, p.stderr)
    assert p.stderr.strip().splitlines() == [
        "ERROR: --serial is 129 characters, the results store keeps at most 128: "
        f"{'S' * 40 + '...'!r}"]
    plan = tmp_path / 'long.yaml'
    plan.write_text(f"plan: {'p' * 129}\nsteps:\n  - {{name: te, kind: te, speed_rpm: 100, "
                    "load_nm: 0, directions: [ccw]}\n")
    p = _run('test', str(plan), '--serial', 'SN1', '--operator', 'kim')
    assert p.returncode == 1, (p.stdout, p.stderr)
    (line,) = p.stderr.strip().splitlines()
    assert line.startswith(f'ERROR: {plan}: plan is 129 characters, the results store keeps '
                           'at most 128'), line
