"""scripts/wang2020_readings.py: the scans docs/DESIGN_NOTES.md quotes for Wang 2020's NLTE.

The fast parts run here (record windows, the named angle laws); the full integer scan and
the Eq. 21 grid under other laws are marked slow. The script computes the NLTE from
Wang 2020 Eqs 1-8 itself; the first test checks it against the independent transcription
in tests/wang2020_reference.py.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests import wang2020_reference as ref

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def wr() -> Any:
    spec = importlib.util.spec_from_file_location('wang2020_readings',
                                                  ROOT / 'scripts' / 'wang2020_readings.py')
    mod = importlib.util.module_from_spec(spec)     # type: ignore[arg-type]
    sys.modules['wang2020_readings'] = mod
    spec.loader.exec_module(mod)                    # type: ignore[union-attr]
    return mod


def test_script_nlte_is_the_reference(wr: Any) -> None:
    """The script's Eqs 1-8 under the kinematic law equal tests/wang2020_reference.py."""
    phi = np.linspace(0.0, 2 * math.pi, 20_000, endpoint=False)
    got = wr.nlte_arcmin(phi, wr.TABLE2, wr.SUITE)
    want = ref.nlte_rad(phi, ref.table2_unit()) * 10800.0 / math.pi
    assert np.max(np.abs(got - want)) < 1e-9


def test_record_windows(wr: Any) -> None:
    """No record [0, T], T = 3..31.6 s, gives Table 4's std 0.637' before optimisation: the
    std stays within 0.30'..0.57'; the first 3 s hold p-p 0.94', amplitude 0.77'."""
    w = wr.window_scan()
    assert w['std_min_arcmin'] == pytest.approx(0.30, abs=0.005)
    assert w['std_max_arcmin'] == pytest.approx(0.57, abs=0.005)
    assert w['std_max_arcmin'] < 0.637 * 0.95
    assert w['pp_at_3s_arcmin'] == pytest.approx(0.94, abs=0.005)
    assert w['amp_at_3s_arcmin'] == pytest.approx(0.77, abs=0.005)


def test_named_angle_laws(wr: Any) -> None:
    """The kinematic law reproduces Table 3 (paper's rounding + 1 %) and misses the paper's
    NLTE numbers by at most 20 %; 'planet -26', 'revolution -26' and 'planet spin +1' lose
    Table 3 and move Fig. 5a's p-p and amplitude by 22-61 % (and its mean's sign); the law
    (4, 4, 3) misses by 16 % at most (the best of the full scan: slow test below), though it
    does not reproduce Table 3 within its rounding."""
    rates = np.array([*wr.NAMED.values(), (4, 4, 3)], dtype=float)
    err = wr.reading_errors(rates)
    score = wr.score(err)
    assert list(err['table3_fit']) == [True, False, False, False, False]
    assert score[0] == pytest.approx(0.20, abs=0.005)
    assert score[4] == pytest.approx(0.16, abs=0.005)
    moves = [abs(v) for name in ('planet -26', 'revolution -26', 'planet spin +1')
             for v in wr.fig5a_change(wr.NAMED[name])[:2]]
    assert min(moves) == pytest.approx(0.22, abs=0.005)
    assert max(moves) == pytest.approx(0.61, abs=0.005)
    for name in ('planet -26', 'revolution -26', 'planet spin +1'):
        assert wr.fig5a_change(wr.NAMED[name])[2] < -1.0          # mean turns positive


@pytest.mark.slow
def test_full_rate_scan(wr: Any) -> None:
    """All 21,168 integer laws: 194 reproduce Table 3, all with a common planet/revolution
    rate; the best over all the paper's NLTE numbers is (+-4, +-4, +-3) at 16 %."""
    out = wr.rate_scan()
    assert out['readings'] == 21_168
    assert len(out['table3_fit']) == 194
    assert all(r[0] == r[1] for r in out['table3_fit'])
    assert [abs(v) for v in out['best'][0]['rates']] == [4, 4, 3]
    assert out['best'][0]['score'] == pytest.approx(0.160, abs=0.001)


@pytest.mark.slow
def test_optimum_under_other_laws(wr: Any) -> None:
    """The Eq. 21 optimum on the 10 deg grid: the kinematic law returns the paper's
    [-70, 120, 110, 40] deg; the others move it."""
    want = {'suite (-25, -25, +1)': [-70.0, 120.0, 110.0, 40.0],
            'planet -26': [80.0, -170.0, 140.0, -100.0],
            'revolution -26': [50.0, 170.0, 60.0, 60.0],
            'planet spin +1': [-70.0, 120.0, 40.0, 110.0]}
    for name, phases in want.items():
        assert wr.grid_optimum(wr.NAMED[name])['optimum_deg'] == phases, name
