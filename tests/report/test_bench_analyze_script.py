"""Smoke test of benchmarks/bench_analyze.py (a tiny bag; the numbers are not checked:
timings belong to the benchmark run on a quiet machine, not to the test suite)."""

from __future__ import annotations

import math
from pathlib import Path

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


def test_bench_analyze_floor_rows(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """--floor: the least-work row between the reader and the analysis, a CPU ratio on every
    row, and the least work spans every complete window the analysis computed a spectrum of."""
    bench = load_benchmark('bench_analyze')
    assert bench.main(['--minutes', '0.6', '--rate-hz', '1000', '--blocks', '100',
                       '--repeats', '1', '--allocator', 'default', '--process-repeats', '0',
                       '--floor', '--bag-dir', str(tmp_path)]) == 0
    rows = [r for r in capsys.readouterr().out.splitlines() if r.startswith('| 100 (')]
    assert [r.split('|')[2].strip()[:7] for r in rows] == ['rosbags', 'read_en', 'our rea',
                                                           'analyze']
    assert rows[0].split('|')[-2].strip() == '1.00'      # the rosbags read over itself
    assert all(float(r.split('|')[-2]) > 0 for r in rows)

    from rv_te_bench.report.analysis import analyze_bag

    bag = next(tmp_path.iterdir())
    windows = bench._spectrum_inputs(bag)
    res = analyze_bag(bag, with_advice=False)
    with_spectrum = [w for w in res.windows if w.complete and w.spectrum is not None]
    assert len(windows) == len(with_spectrum) >= 1
    for phi, te, revolutions in windows:
        assert phi.shape == te.shape and phi.size > 1000 and revolutions == 1
        # a complete window of one output revolution: phi spans 2 pi less one sample step
        assert abs(abs(phi[-1] - phi[0]) - 2 * math.pi) <= 2 * abs(phi[1] - phi[0])


def test_baseline_core_has_its_own_order_set() -> None:
    """--baseline REV: the old spectrum reads its lines from the order set of REV (since
    issue 41 the current one caches them), and the old analysis builds that order set."""
    import sys

    import rv_te_bench.core.orders as current

    root = Path(__file__).resolve().parents[2]
    sys.path.insert(0, str(root / 'benchmarks'))
    try:
        from _baseline import load_core_at, swapped
    finally:
        sys.path.remove(str(root / 'benchmarks'))
    core = load_core_at('HEAD')
    old_orders = core['rv_te_bench.core.orders']
    assert old_orders is not current
    with swapped(core):
        from rv_te_bench.core.orders import OrderSet
        assert OrderSet is old_orders.OrderSet
        assert sys.modules['rv_te_bench.core.spectrum'] is core['rv_te_bench.core.spectrum']
    assert sys.modules['rv_te_bench.core.orders'] is current
