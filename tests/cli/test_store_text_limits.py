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
                          env=env, cwd=ROOT)


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
