"""What comes in must be a reducer on this bench (issue 33 s.2).

DAQ exports written by pandas the way a bench PC writes them (seconds column, angles in
degrees; a European export: ``;`` between columns, ``,`` as the decimal mark); the bags by
rosbags (tests.unit_bags). The bench is the 2K-V of Wang 2020, i = 79 (the paper).

Before: swapped --theta-in/--theta-out imported and analysed to a TE of millions of arcmin
with exit 0; ``--time-unit ms`` on a seconds column gave a 2 MHz bag with a note; a
decimal-comma export was refused as "'0,0005' is not a number" with no way to read it.
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
import pytest

from rv_te_bench.cli.main import main
from rv_te_bench.core.plausibility import check_measured_ratio, check_sample_rate
from tests.io import daq_files
from tests.unit_bags import write_unit_bag

if TYPE_CHECKING:
    from pathlib import Path

RATIO = 79.0     # Wang 2020 2K-V


@pytest.fixture(scope='module')
def session() -> daq_files.Session:
    return daq_files.simulate(duration_s=17.0)     # 1.08 output revolutions at 300 rpm


def _frame(s: daq_files.Session) -> pd.DataFrame:
    return pd.DataFrame({'t_s': s.t_s, 'theta_in_deg': np.degrees(s.theta_in_rad),
                         'theta_out_deg': np.degrees(s.theta_out_rad)})


def _import(tmp_path: Path, csv: Path, *extra: str, swap: bool = False) -> list[str]:
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml')
    cols = ['theta_out_deg', 'theta_in_deg'] if swap else ['theta_in_deg', 'theta_out_deg']
    return ['import', str(csv), '--bench', str(bench), '--out', str(tmp_path / 'bag'),
            '--time', 't_s', '--theta-in', cols[0], '--theta-out', cols[1],
            '--start-utc', '2026-11-24T09:30:00Z', *extra]


def _one_error_line(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.startswith('ERROR')]
    assert len(lines) == 1, err
    assert 'Traceback' not in err
    return lines[0]


# -- swapped input and output -----------------------------------------------------------------

def test_swapped_columns_refused_at_import(tmp_path: Path, session: daq_files.Session,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    csv = tmp_path / 'run.csv'
    _frame(session).to_csv(csv, index=False)
    assert main(_import(tmp_path, csv, swap=True)) == 1
    line = _one_error_line(capsys.readouterr().err)
    # measured: input advance / output advance with the columns as given = 1 / 79
    measured = float(line.split('measured ratio ')[1].split()[0])
    assert measured == pytest.approx(1.0 / RATIO, rel=2e-3)
    assert 'bench ratio 79' in line and 'swapped' in line
    assert "'theta_out_deg'" in line and "'theta_in_deg'" in line
    assert not (tmp_path / 'bag').exists()
    assert not list(tmp_path.glob('.bag.importing-*'))
    # the right way round: imported
    assert main(_import(tmp_path, csv)) == 0


def test_swapped_encoders_in_a_bag_refused_by_analyze(
        tmp_path: Path, session: daq_files.Session,
        capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_unit_bag(tmp_path / 'swapped', session.theta_out_rad, session.theta_in_rad,
                         rate_hz=daq_files.RATE_HZ, block=1000)
    assert main(['analyze', str(bag), '--no-db', '--no-advice', '--quiet']) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert 'measured ratio 0.01266' in line and 'bench ratio 79' in line
    assert 'swapped' in line
    good = write_unit_bag(tmp_path / 'good', session.theta_in_rad, session.theta_out_rad,
                          rate_hz=daq_files.RATE_HZ, block=1000)
    assert main(['analyze', str(good), '--no-db', '--no-advice', '--quiet', '--json']) == 0
    pp = json.loads(capsys.readouterr().out)['bags'][0]['cumulative']['te_pp_arcmin']
    assert pp < 10.0


def test_ratio_rule_closed_form() -> None:
    two_pi = 2 * math.pi
    assert check_measured_ratio(two_pi * RATIO * 3, two_pi * 3, RATIO) is None
    assert check_measured_ratio(two_pi * RATIO * 1.09, two_pi, RATIO) is None   # 9 %: kept
    assert 'is not the bench ratio' in check_measured_ratio(two_pi * RATIO * 1.2, two_pi,
                                                            RATIO)
    assert 'other way' in check_measured_ratio(-two_pi * RATIO, two_pi, RATIO)
    # a hysteresis record (input locked, output twisted 10 arcmin): not judged
    assert check_measured_ratio(1e-4, math.radians(10 / 60), RATIO) is None


# -- the time unit -----------------------------------------------------------------------------

def test_absurd_time_unit_is_one_line_error(tmp_path: Path, session: daq_files.Session,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    csv = tmp_path / 'run.csv'
    _frame(session).rename(columns={'t_s': 'time'}).to_csv(csv, index=False)
    argv = _import(tmp_path, csv, '--time-unit', 'ms')
    argv[argv.index('t_s')] = 'time'
    assert main(argv) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert 'sample rate 2e+06 Hz' in line and "bench's 2000 Hz" in line
    assert '--time-unit s?' in line
    assert not (tmp_path / 'bag').exists()
    argv[argv.index('ms')] = 's'
    assert main(argv) == 0


def test_rate_rule_closed_form() -> None:
    assert check_sample_rate(250.0, 1000.0, time_unit='s', source='x') is None   # Hu 2020
    assert check_sample_rate(1e6, 1000.0, time_unit='ms', source='x') is not None
    # a microsecond column read as ms: 1 Hz instead of 1000 Hz
    assert '--time-unit us?' in check_sample_rate(1.0, 1e3, time_unit='ms', source='x')
    low = check_sample_rate(1000.0 / 60.0, 1000.0, time_unit='min', source='x')
    assert low is not None and '--time-unit s?' in low      # a seconds column read as min


# -- decimal comma ----------------------------------------------------------------------------

def test_decimal_comma_export(tmp_path: Path, session: daq_files.Session,
                              capsys: pytest.CaptureFixture[str]) -> None:
    eu = tmp_path / 'eu.csv'
    _frame(session).to_csv(eu, index=False, sep=';', decimal=',')
    assert ',' in eu.read_text(encoding='utf-8').splitlines()[2]
    assert main(_import(tmp_path, eu)) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert 'is not a number' in line and '--decimal ,' in line
    assert main(_import(tmp_path, eu, '--decimal', ',', '--json')) == 0
    got = json.loads(capsys.readouterr().out)
    assert got['samples'] == session.t_s.size
    assert got['sample_rate_hz'] == pytest.approx(daq_files.RATE_HZ, rel=1e-9)
    # the same TE as the dot export of the same data
    dot = tmp_path / 'dot.csv'
    _frame(session).to_csv(dot, index=False)
    pp = []
    for name, csv, extra in (('bag', eu, ('--decimal', ',')), ('dotbag', dot, ())):
        if name == 'dotbag':
            argv = _import(tmp_path, csv, *extra)
            argv[argv.index('--out') + 1] = str(tmp_path / name)
            assert main(argv) == 0
        capsys.readouterr()
        assert main(['analyze', str(tmp_path / name), '--no-db', '--no-advice', '--quiet',
                     '--json']) == 0
        pp.append(json.loads(capsys.readouterr().out)['bags'][0]['cumulative']['te_pp_arcmin'])
    assert pp[0] == pytest.approx(pp[1], rel=1e-12)


def test_decimal_comma_with_comma_delimiter_refused(tmp_path: Path,
                                                    session: daq_files.Session,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    csv = tmp_path / 'run.csv'
    _frame(session).to_csv(csv, index=False)
    assert main(_import(tmp_path, csv, '--decimal', ',', '--delimiter', ',')) == 1
    assert 'cannot be both' in _one_error_line(capsys.readouterr().err)
