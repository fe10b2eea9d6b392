"""Every metric the results store holds has its unit from the one table (issue 33 s.3).

The store is filled the way the commands fill it: rv-te analyze's records of a rosbags bag
and rv-te test's records of plans run on the simulated bench (TE both ways, hysteresis with
the Harmonic-Drive regions K1..K3, a sweep). The expected units and scales are written here
from the definitions (1 rad = 10800 / pi arcmin), not read from the code's table.
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.acceptance import load_tolerance, parse_plan, run_plan_offline
from rv_te_bench.acceptance._store import record_of_report
from rv_te_bench.cli.main import main
from rv_te_bench.core.units import metric_unit
from rv_te_bench.store import open_store, records_from_analysis_json
from sim.program import ProgramSimulator
from tests import wang2020_reference as ref
from tests.unit_bags import unit_bag

if TYPE_CHECKING:
    from pathlib import Path

ARCMIN_PER_RAD = 10800.0 / math.pi
PLAN = {'plan': 'units', 'steps': [
    {'kind': 'te', 'name': 'te', 'speed_rpm': 3000, 'settle_s': 0.2},
    {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': 450.0, 'dwell_s': 0.1,
     'rigidity': {'K1': [0.03, 0.25], 'K2': [0.25, 0.7], 'K3': [0.7, 1.0]}},
    {'kind': 'sweep', 'name': 'sweep', 'speeds_rpm': [3000], 'loads_nm': [0, 450],
     'settle_s': 0.2}]}


def _expected(name: str) -> tuple[str, float]:
    """(unit shown, shown per SI) from what each family of names means."""
    base = name.removeprefix('sweep:')
    if name.startswith('torsional_rigidity_'):
        return 'N m/arcmin', 1.0 / ARCMIN_PER_RAD       # N m/rad -> N m/arcmin
    if name == 'hysteresis_loss_j':
        return 'J', 1.0
    if base.startswith(('te_', 'lost_motion', 'backlash')):
        return 'arcmin', ARCMIN_PER_RAD
    if name in ('samples_count', 'gaps_count'):
        return 'count', 1.0
    if name == 'revolutions':
        return 'rev', 1.0
    raise AssertionError(f'a stored metric this test does not know: {name}')


@pytest.fixture(scope='module')
def store_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp('units')
    db = tmp / 'store.sqlite'
    profile, _ = load_tolerance('li2023-rv')
    records = []
    for seed in range(5):
        sim = ProgramSimulator(preset='li2023-rv', te_mode='dte', sample_rate_hz=1000.0,
                               block_size=100, seed=seed)
        report = run_plan_offline(parse_plan(PLAN), profile, serial=f'LI-{seed}',
                                  operator='t', sim=sim)
        records.append(record_of_report(report, bag_path=f'sim-{seed}',
                                        bag_sha256=f'{seed:064x}'))
    bag = unit_bag(tmp / 'bag', ref.table2_unit(), np.random.default_rng(1), rate_hz=1000.0,
                   duration_s=33.0)
    from rv_te_bench.report.analysis import analyze_bag
    from rv_te_bench.report.html import report_json

    doc = report_json([analyze_bag(bag, with_advice=False)])
    records += records_from_analysis_json(doc, bag_paths=[bag], command='analyze',
                                          software_version='test')
    with open_store(db) as st:
        for r in records:
            st.upsert(r)
    return db


def test_every_stored_metric_has_its_unit(store_path: Path) -> None:
    with open_store(store_path, create=False) as st:
        names = sorted({n for n, _ in st.metric_names()})
    assert {'torsional_rigidity_K1_nm_per_rad', 'torsional_rigidity_K3_nm_per_rad',
            'hysteresis_loss_j', 'lost_motion_rad', 'te_pp_revolution_max_rad',
            'te_mean_rad', 'revolutions', 'gaps_count'} <= set(names), names
    for name in names:
        unit = metric_unit(name)
        shown, per_si = _expected(name)
        assert (unit.shown, name) == (shown, name)
        assert unit.per_si == pytest.approx(per_si, rel=1e-12), name
        # the derived uncertainty key carries its metric's unit
        assert metric_unit(f'{name}_u95') == unit


def test_spc_of_rigidity_in_n_m_per_arcmin(store_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    """``rv-te spc torsional_rigidity_K2_nm_per_rad --lsl 108``: the centre in N m/arcmin and
    the LSL read in that unit (before: 'arcmin', centre 2.5e9, Cpk 745)."""
    with open_store(store_path, create=False) as st:
        k_si = np.array(st.series('torsional_rigidity_K2_nm_per_rad').values)
    assert main(['spc', 'torsional_rigidity_K2_nm_per_rad', '--db', str(store_path),
                 '--lsl', '108', '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc['unit'] == 'N m/arcmin'
    k = k_si / ARCMIN_PER_RAD
    assert doc['chart']['centre'] == pytest.approx(k.mean(), rel=1e-9)
    sigma = np.abs(np.diff(k)).mean() / 1.128379     # MR-bar / d2(2)
    assert doc['capability']['cpk'] == pytest.approx((k.mean() - 108.0) / (3 * sigma),
                                                     rel=1e-3)
    assert 100 < k.mean() < 1000      # a rigidity in N m/arcmin, not 2.5e9


def test_hysteresis_loss_has_joules(store_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['spc', 'hysteresis_loss_j', '--db', str(store_path), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['unit'] == 'J'


def test_whole_reducer_metrics_have_their_units() -> None:
    """The loss / thermal / life steps' metric names (acceptance._loss_results)."""
    for name, shown in (('efficiency_at_max_load', '1'),
                        ('sweep:efficiency_3000rpm_200nm', '1'),   # not N m: an efficiency
                        ('temperature_rise_k', 'K'), ('no_load_torque_max_nm', 'N m'),
                        ('sweep:temperature_settle_time_s', 's'), ('trend_alarms', 'count'),
                        ('sweep:life_te_pp_cp2_rad', 'arcmin')):
        assert metric_unit(name).shown == shown, name
