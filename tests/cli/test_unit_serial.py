"""Issue 33 s.6: the unit's serial from the bench description or the file name when not given
on the command line, the output saying where it came from.

A DAQ export named after the unit (``SN-2026-0042_cw.csv``, written with numpy as a bench PC
writes it) imported with a bench description that states no serial: the bag's metadata (read
back with rosbags) holds SN-2026-0042 and says it came from the file name. Precedence:
--serial, then the bench description, then the file name. Before: the serial was the bench
description's or nothing, and nothing said where it came from.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rv_te_bench.cli.main import main
from tests.io import daq_files

N = 4000   # 2 s at 2 kHz
COLS = ('--time', 't_s', '--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad',
        '--torque', 'torque_nm')
NO_SERIAL = {'operator': 'pytest', 'temperature_c': 22.0}


@pytest.fixture(scope='module')
def session() -> daq_files.Session:
    return daq_files.simulate(duration_s=N / daq_files.RATE_HZ)


def _custom(bag: Path) -> dict[str, str]:
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        return dict(reader.storage.metadata.custom or {})


def _import(tmp_path: Path, name: str, session: daq_files.Session,
            capsys: pytest.CaptureFixture[str], *extra: str,
            unit: dict[str, object] | None = None) -> tuple[dict[str, str], str, str]:
    csv = daq_files.write_csv(tmp_path / name, session)
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml', unit_under_test=unit or NO_SERIAL)
    out = tmp_path / f'bag_{len(list(tmp_path.iterdir()))}'
    assert main(['import', str(csv), '--bench', str(bench), '--out', str(out), *COLS,
                 *extra]) == 0
    cap = capsys.readouterr()
    return _custom(out), cap.out, cap.err


def test_serial_from_the_file_name(tmp_path: Path, session: daq_files.Session,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    custom, out, _err = _import(tmp_path, 'SN-2026-0042_cw.csv', session, capsys)
    assert custom['unit_serial'] == 'SN-2026-0042'
    assert 'file name SN-2026-0042_cw.csv' in custom['unit_serial_source']
    assert 'unit serial SN-2026-0042 (from the file name SN-2026-0042_cw.csv' in out


def test_the_bench_description_wins_over_the_file_name(
        tmp_path: Path, session: daq_files.Session, capsys: pytest.CaptureFixture[str]) -> None:
    custom, out, _err = _import(tmp_path, 'SN-2026-0042_cw.csv', session, capsys,
                                unit={**NO_SERIAL, 'serial': 'RV80E-0007'})
    assert custom['unit_serial'] == 'RV80E-0007'
    assert 'bench description' in custom['unit_serial_source']
    assert 'unit serial RV80E-0007 (from bench description' in out


def test_the_command_line_wins(tmp_path: Path, session: daq_files.Session,
                               capsys: pytest.CaptureFixture[str]) -> None:
    custom, out, _err = _import(tmp_path, 'SN-2026-0042_cw.csv', session, capsys,
                                '--serial', 'X-1', unit={**NO_SERIAL, 'serial': 'RV80E-0007'})
    assert custom['unit_serial'] == 'X-1'
    assert '--serial' in custom['unit_serial_source'] and '(from the command line' in out


def test_own_pattern_and_no_serial(tmp_path: Path, session: daq_files.Session,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    custom, _out, _err = _import(tmp_path, 'unit-RV80E-0042-ccw.csv', session, capsys,
                                 '--serial-pattern', r'unit-(.+)-c?cw')
    assert custom['unit_serial'] == 'RV80E-0042'
    assert "pattern 'unit-(.+)-c?cw'" in custom['unit_serial_source']
    custom, out, _err = _import(tmp_path, 'run_7.csv', session, capsys)
    assert custom['unit_serial'] == ''
    assert 'unit serial: not stated (no --serial, none in the bench description, none in ' \
           'the file name run_7.csv' in out


def test_bad_pattern_is_one_line(tmp_path: Path, session: daq_files.Session,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    csv = daq_files.write_csv(tmp_path / 'run.csv', session)
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml', unit_under_test=NO_SERIAL)
    assert main(['import', str(csv), '--bench', str(bench), '--out', str(tmp_path / 'b'),
                 *COLS, '--serial-pattern', '(unclosed']) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith('ERROR: --serial-pattern') and '\n' not in err, err


def test_analyze_takes_the_serial_from_the_bag_name(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.report.synthetic_bags import Harmonic, write_bag

    bag = tmp_path / 'SN-0099_run3'     # a bag without unit_serial in its metadata
    write_bag(bag, harmonics=[Harmonic(25.0, 1e-4, 0.0)], duration_s=2.0,
              sample_rate_hz=4000.0, block_size=400)
    assert main(['analyze', str(bag), '--json', '--no-db', '--quiet']) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    assert doc['bags'][0]['session']['unit_serial'] == 'SN-0099'
    assert f'{bag}: unit serial SN-0099 (from the file name SN-0099_run3' in cap.err
    assert main(['analyze', str(bag), '--json', '--no-db', '--quiet', '--serial', 'K-5']) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)['bags'][0]['session']['unit_serial'] == 'K-5'
    assert '(from the command line' in cap.err


def test_test_from_a_file_needs_no_serial_when_its_name_has_one(
        tmp_path: Path, session: daq_files.Session, capsys: pytest.CaptureFixture[str]) -> None:
    csv = daq_files.write_csv(tmp_path / 'SN-2026-0042_cw.csv', session)
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml', unit_under_test=NO_SERIAL)
    main(['test', 'wang2020-2kv', '--operator', 'kim', '--from', str(csv), '--bench',
          str(bench), '--out-dir', str(tmp_path / 'tests'), '--no-db', *COLS])
    err = capsys.readouterr().err
    assert 'unit serial SN-2026-0042 (from the file name SN-2026-0042_cw.csv' in err, err
    assert [p.name.split('_')[0] for p in (tmp_path / 'tests').iterdir()] == ['SN-2026-0042']
    run = daq_files.write_csv(tmp_path / 'run.csv', session)
    assert main(['test', 'wang2020-2kv', '--operator', 'kim', '--from', str(run), '--bench',
                 str(bench), '--out-dir', str(tmp_path / 'tests2'), '--no-db', *COLS]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith('ERROR: no unit serial: give --serial') and '\n' not in err, err
