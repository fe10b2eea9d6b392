"""The order of a parallel run's files (tests/conftest.py): on a fresh clone (no .pytest_cache,
as on CI) the committed table of seconds per file puts the longest files first, so that no
long file starts last and runs alone at the end; the cache's own times win where present."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

from tests import conftest

ROOT = Path(__file__).resolve().parents[1]


class _Item:
    def __init__(self, nodeid: str) -> None:
        self.nodeid = nodeid

    def get_closest_marker(self, _name: str) -> None:
        return None


class _Cache:
    def __init__(self, seconds: dict[str, float]) -> None:
        self.seconds = seconds

    def get(self, _key: str, default: Any) -> Any:
        return self.seconds or default


def _files(items: list[Any]) -> list[str]:
    return list(dict.fromkeys(i.nodeid.split('::')[0] for i in items))


def test_committed_table_names_existing_test_files_with_their_seconds() -> None:
    table = conftest.committed_seconds()
    assert len(table) >= 150
    assert all((ROOT / f).is_file() and f.startswith('tests/') for f in table)
    assert all(s >= 0.0 for s in table.values())
    # the heavy files of the suite are among the longest of the table
    longest = sorted(table, key=table.__getitem__, reverse=True)[:10]
    assert 'tests/package/test_colcon_workspace.py' in longest


def test_fresh_clone_orders_longest_file_first_from_the_committed_table() -> None:
    table = conftest.committed_seconds()
    short, long_ = sorted(table, key=table.__getitem__)[0], max(table, key=table.__getitem__)
    items = [_Item(f'{short}::test_a'), _Item(f'{long_}::test_b'), _Item(f'{long_}::test_c')]
    conftest._heaviest_files_first(SimpleNamespace(cache=None), items)  # type: ignore[arg-type]
    assert _files(items) == [long_, short]
    assert [i.nodeid for i in items][:2] == [f'{long_}::test_b', f'{long_}::test_c']


def test_cached_seconds_win_over_the_committed_table() -> None:
    table = conftest.committed_seconds()
    short, long_ = sorted(table, key=table.__getitem__)[0], max(table, key=table.__getitem__)
    items = [_Item(f'{long_}::test_b'), _Item(f'{short}::test_a')]
    cache = _Cache({short: table[long_] + 1.0})
    conftest._heaviest_files_first(SimpleNamespace(cache=cache), items)  # type: ignore[arg-type]
    assert _files(items) == [short, long_]
