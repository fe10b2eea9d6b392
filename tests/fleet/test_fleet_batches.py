"""How run_fleet cuts the bags into tasks (issue 41: the hand-over per bag kept small)."""

from __future__ import annotations

import pytest

from rv_te_bench.fleet._run import MAX_BATCH, batches


@pytest.mark.parametrize('n', [0, 1, 2, 5, 7, 50, 100, 1000])
@pytest.mark.parametrize('workers', [1, 2, 4, 16])
def test_every_bag_once_in_order_and_the_end_single(n: int, workers: int) -> None:
    bags = [f'b{i}' for i in range(n)]
    got = batches(bags, workers)
    assert [b for g in got for b in g] == bags
    assert all(1 <= len(g) <= MAX_BATCH for g in got)
    sizes = [len(g) for g in got]
    assert sizes == sorted(sizes, reverse=True)       # large first, shrinking
    # the last 3 x workers bags go one per task: the workers finish together
    assert all(s == 1 for s in sizes[-min(n, 3 * workers):])


def test_100_bags_on_2_workers_are_far_fewer_tasks() -> None:
    """The hand-over is paid per task: 100 bags on 2 workers take 26 tasks, not 100. By hand,
    a task takes (bags left) // 6, between 1 and 8: 8 x 7 (100 -> 44 left), 7, 6, 5, 4, 3,
    3, 2, 2, 2 (-> 10 left), then 10 single bags."""
    got = batches(list(range(100)), 2)
    assert [len(g) for g in got] == [8] * 7 + [7, 6, 5, 4, 3, 3, 2, 2, 2] + [1] * 10
    assert got[0] == list(range(8))
