"""What the results store keeps is what the user asked for: the worst and the mean
per-revolution TE p-p under their own names (SPC charts the worst), and a store URL whose
password never reaches the output.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from rv_te_bench.cli.main import main
from rv_te_bench.errors import StoreError
from rv_te_bench.store import open_store, records_from_analysis_json

ROOT = Path(__file__).resolve().parents[2]
SECRET = 's3cret-Pw0rd'


def _analysis_doc(window_pps: list[float | None], complete: list[bool]) -> dict:
    """An ``rv-te analyze --json`` document of one bag with windows of the given p-p."""
    windows = [{'index': j, 'complete': c, 'te_pp_rad': pp, 'start_stamp_s': 1.7e9 + 10 * j}
               for j, (pp, c) in enumerate(zip(window_pps, complete, strict=True))]
    return {'bags': [{'bench': {'preset': 'wang2020-2kv', 'unit_serial': 'SN-1'},
                      'cumulative': {'te_pp_rad': 7e-4, 'revolutions': 3.0},
                      'windows': windows, 'counters': {'gaps': 0}}]}


def _bag(tmp_path: Path) -> Path:
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    return bag


def test_worst_and_mean_revolution_te_stored_under_their_own_names(tmp_path: Path) -> None:
    """Windows of one revolution with p-p 1, 2, 6 (x 1e-4 rad) and an unfinished one of 9:
    worst 6e-4, mean 3e-4 (the unfinished window counts in neither), read back by name
    from the store and as the SPC series."""
    doc = _analysis_doc([1e-4, 2e-4, 6e-4, 9e-4], [True, True, True, False])
    (rec,) = records_from_analysis_json(doc, bag_paths=[_bag(tmp_path)], command='analyze',
                                        software_version='t')
    with open_store(tmp_path / 'r.sqlite') as store:
        store.upsert(rec)
        (row,) = store.query()
        worst = store.series('te_pp_revolution_max_rad')
        mean = store.series('te_pp_revolution_mean_rad')
    assert row.metrics[('te_pp_revolution_max_rad', 'all')] == pytest.approx(6e-4, rel=1e-12)
    assert row.metrics[('te_pp_revolution_mean_rad', 'all')] == pytest.approx(3e-4, rel=1e-12)
    assert row.metrics[('te_pp_rad', 'all')] == pytest.approx(7e-4, rel=1e-12)
    assert worst.values == pytest.approx([6e-4], rel=1e-12)
    assert mean.values == pytest.approx([3e-4], rel=1e-12)


def test_no_complete_revolution_stores_no_revolution_te(tmp_path: Path) -> None:
    doc = _analysis_doc([9e-4], [False])
    (rec,) = records_from_analysis_json(doc, bag_paths=[_bag(tmp_path)], command='analyze',
                                        software_version='t')
    names = {m.name for m in rec.metrics}
    assert 'te_pp_revolution_max_rad' not in names
    assert 'te_pp_revolution_mean_rad' not in names


def test_password_of_an_unreachable_store_is_not_shown(
        capsys: pytest.CaptureFixture[str]) -> None:
    url = f'postgresql://rvte:{SECRET}@127.0.0.1:1/x'
    with pytest.raises(StoreError, match=r'cannot open results store') as exc:
        open_store(url)
    assert SECRET not in str(exc.value)
    assert 'rvte:***@127.0.0.1:1/x' in str(exc.value)
    # the command line: one error line, no password
    assert main(['results', '--db', url]) == 1
    out, err = capsys.readouterr()
    assert SECRET not in out + err
    assert err.startswith('ERROR: ') and err.count('\n') == 1, err


def test_password_of_a_live_store_is_not_shown(fresh_pg_db: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """The session's server trusts 127.0.0.1, so a URL with a password opens it; the name
    the store and ``rv-te analyze`` show has the password replaced by ***."""
    url = fresh_pg_db.replace('postgresql://rvte@', f'postgresql://rvte:{SECRET}@')
    assert SECRET in url
    with open_store(url) as store:
        assert SECRET not in store.url
        assert 'rvte:***@127.0.0.1' in store.url
    assert main(['analyze', str(ROOT / 'bags' / 'sample'), '--db', url, '--quiet']) == 0
    out, err = capsys.readouterr()
    assert 'recorded in the results store postgresql+psycopg://rvte:***@' in out
    assert SECRET not in out + err
    with open_store(url) as store:
        (row,) = store.query()
    assert SECRET not in repr(row)
