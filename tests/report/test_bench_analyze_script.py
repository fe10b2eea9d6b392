"""Smoke test of benchmarks/bench_analyze.py (a tiny bag; the numbers are not checked:
timings belong to the benchmark run on a quiet machine, not to the test suite)."""

from __future__ import annotations

import pytest

from tests.benchmark_loader import load_benchmark


def test_bench_analyze_quick_run(capsys: pytest.CaptureFixture[str]) -> None:
    bench = load_benchmark('bench_analyze')
    assert bench.main(['--minutes', '0.05', '--blocks', '100', '--repeats', '1',
                       '--allocator', 'default', '--process-repeats', '1']) == 0
    rows = [r for r in capsys.readouterr().out.splitlines() if r.startswith('| 100')]
    assert [r.split('|')[2].strip()[:7] for r in rows[:3]] == ['rosbags', 'read_en', 'analyze']
    assert len(rows) == 5  # the budgets' row and the whole-command row
    budget = rows[3].split('|')
    assert float(budget[2]) > 0 and budget[4].strip().endswith('%')
