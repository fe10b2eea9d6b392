"""Smoke test of benchmarks/bench_identify.py (a tiny bag; the timings are not checked:
they belong to the benchmark run on a quiet machine, not to the test suite)."""

from __future__ import annotations

import pytest

from tests.benchmark_loader import load_benchmark


def test_bench_identify_quick_run(capsys: pytest.CaptureFixture[str]) -> None:
    bench = load_benchmark('bench_identify')
    assert bench.main(['--minutes', '0.05', '--repeats', '1']) == 0
    rows = [r for r in capsys.readouterr().out.splitlines() if r.startswith('| ')]
    assert [r.split('|')[1].strip() for r in rows[1:]] == ['with advice', 'no advice']
