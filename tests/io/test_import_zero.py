"""rv-te import + analyze with encoders that are not zeroed to the reducer (issue 33 s.1).

A single-turn absolute output encoder read as degrees in a CSV written by numpy: starting at
359.998 deg (no zeros declared: the TE is referred to its first sample), or mounted 123.4 deg
off with that zero declared in the bench description (encoders.output.zero_offset_deg: the
TE keeps the reducer's own mean). Expected values come from the session's arrays here.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from tests.io import daq_files

if TYPE_CHECKING:
    from pathlib import Path


@pytest.fixture(scope='module')
def session() -> daq_files.Session:
    return daq_files.simulate(duration_s=33.0)   # two output revolutions of 15.8 s


def _analyse(tmp_path: Path, capsys: pytest.CaptureFixture[str], s: daq_files.Session,
             name: str, **bench_changes: object) -> dict:
    csv = daq_files.write_csv(tmp_path / f'{name}.csv', s, unit='deg', single_turn=True)
    bench = daq_files.bench_yaml(tmp_path / f'{name}.yaml', **bench_changes)
    out = tmp_path / name
    assert main(['import', str(csv), '--bench', str(bench), '--out', str(out), '--time',
                 't_s', '--theta-in', 'theta_in_deg', '--theta-out', 'theta_out_deg']) == 0
    capsys.readouterr()
    assert main(['analyze', str(out), '--json', '--no-advice', '--no-db', '--quiet']) == 0
    doc = json.loads(capsys.readouterr().out)
    return doc['bags'][0]


def test_output_encoder_at_359_998_deg(tmp_path: Path, session: daq_files.Session,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    shifted = replace(session, theta_out_rad=session.theta_out_rad + math.radians(359.998))
    te = session.theta_out_rad - session.theta_in_rad / 79.0
    one = _analyse(tmp_path, capsys, shifted, 'turn')
    assert one['te_reference']['method'] == 'first-sample'
    assert one['te_reference']['removed_within_turn_deg'] == pytest.approx(
        -0.002 + math.degrees(te[0]), abs=1e-6)
    mean = math.radians(one['cumulative']['te_mean_arcmin'] / 60.0)
    assert mean == pytest.approx((te - te[0]).mean(), abs=1e-9)
    assert abs(one['cumulative']['te_mean_arcmin']) < 5.0     # not 21,600'


def test_declared_zero_of_a_mounting_offset(tmp_path: Path, session: daq_files.Session,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    shifted = replace(session, theta_out_rad=session.theta_out_rad + math.radians(123.4))
    te = session.theta_out_rad - session.theta_in_rad / 79.0
    enc = {'input': {'model': 'heidenhain-ron886'},
           'output': {'model': 'heidenhain-ron886', 'zero_offset_deg': 123.4}}
    one = _analyse(tmp_path, capsys, shifted, 'mount', encoders=enc)
    assert one['te_reference']['method'] == 'encoders'
    assert 'zero_offset_deg' in one['te_reference']['source']
    mean = math.radians(one['cumulative']['te_mean_arcmin'] / 60.0)
    amp = math.radians(one['cumulative']['te_amplitude_arcmin'] / 60.0)
    assert mean == pytest.approx(te.mean(), abs=1e-9)
    assert amp == pytest.approx(np.abs(te).max(), abs=1e-9)
