"""rv-te import (issue #19 s.3): a simulated session exported to CSV, TDMS and MDF4 with the
libraries themselves, imported back and analysed, gives the original bag's window statistics
and spectral lines; the imported bag is read by rosbags and by mcap.

Tolerances: float64 formats (CSV written with 17 significant digits, TDMS float64, MDF4
float64) carry the angles exactly, so statistics and lines agree to 1e-11 rad (rounding of
the unwrapping / unit arithmetic on angles of ~1000 rad); the CSV in degrees with 12
significant digits carries theta_in (up to ~60,000 deg) to ~1e-7 deg = 2e-9 rad, and TE
= theta_out - theta_in / 79 to ~3e-11 rad, compared at 1e-9 rad (2e-5 arcsec).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.io.bench_description import load_bench_description
from rv_te_bench.io.importers import ImportOptions, import_file
from rv_te_bench.report.analysis import analyze_bag
from tests.io import daq_files

pytest.importorskip('nptdms')
pytest.importorskip('asammdf')


@pytest.fixture(scope='module')
def session(tmp_path_factory: pytest.TempPathFactory) -> tuple[daq_files.Session, Path, object]:
    d = tmp_path_factory.mktemp('daq')
    s = daq_files.simulate()
    bag = daq_files.original_bag(d / 'original', s)
    return s, d, analyze_bag(bag, with_advice=False)


CASES = {
    'csv-rad': (lambda p, s: daq_files.write_csv(p / 'run.csv', s), 'run.csv',
                {'time': 't_s', 'theta_in': 'theta_in_rad', 'theta_out': 'theta_out_rad',
                 'torque': 'torque_nm'}, 1e-11),
    'csv-deg-12-digits-single-turn-semicolon': (
        lambda p, s: daq_files.write_csv(p / 'deg.csv', s, unit='deg', fmt='%.12g',
                                         single_turn=True, delimiter=';'),
        'deg.csv', {'time': 't_s', 'theta_in': 'theta_in_deg', 'theta_out': 'theta_out_deg'},
        1e-9),
    'csv-arcsec-fixed-rate-by-index': (
        lambda p, s: daq_files.write_csv(p / 'as.csv', s, unit='arcsec'), 'as.csv',
        {'rate_hz': daq_files.RATE_HZ, 'theta_in': '1', 'theta_out': '2'}, 1e-11),
    'tdms': (lambda p, s: daq_files.write_tdms(p / 'run.tdms', s), 'run.tdms',
             {'theta_in': 'encoders/theta_in', 'theta_out': 'theta_out',
              'torque': 'encoders/torque'}, 1e-11),
    'mdf4': (lambda p, s: daq_files.write_mdf(p / 'run.mf4', s), 'run.mf4',
             {'theta_in': 'theta_in', 'theta_out': 'theta_out', 'torque': 'torque'}, 1e-11),
}


@pytest.mark.parametrize('case', list(CASES))
def test_round_trip_same_statistics_and_lines(session: tuple, tmp_path: Path, case: str) -> None:
    s, _, ref = session
    write, name, opts, atol = CASES[case]
    write(tmp_path, s)
    desc = load_bench_description(daq_files.bench_yaml(tmp_path / 'bench.yaml'))
    out = tmp_path / 'imported'
    summary = import_file(tmp_path / name, desc, out,
                          options=ImportOptions(chunk_samples=7777, **opts))
    assert summary.samples == s.t_s.size
    assert summary.blocks == math.ceil(s.t_s.size / 500)
    if 'single-turn' in case:   # the wraps found = whole turns of each shaft in the record
        assert summary.wraps_in == int(s.theta_in_rad[-1] // (2 * math.pi)) \
            - int(s.theta_in_rad[0] // (2 * math.pi))
    got = analyze_bag(out, with_advice=False)
    assert len(got.windows) == len(ref.windows) >= 2
    for a, b in zip(got.windows, ref.windows, strict=True):
        assert a.complete == b.complete
        # the 12-digit file rounds theta_in by up to 2e-9 rad: the sample at a window's edge
        # (|phi - phi_s| = 2 pi, to that rounding) may fall on either side of it
        # (one sample of N more or less moves the mean and std by at most 2 |TE|max / N)
        edge = 0 if atol <= 1e-11 else 1
        assert abs(a.stats.n_samples - b.stats.n_samples) <= edge
        tol = atol + (2 * b.stats.amplitude_rad / b.stats.n_samples
                      if a.stats.n_samples != b.stats.n_samples else 0.0)
        for f in ('pp_rad', 'amplitude_rad', 'mean_rad', 'std_rad'):
            assert getattr(a.stats, f) == pytest.approx(getattr(b.stats, f), abs=tol, rel=0)
    assert got.spectrum is not None and ref.spectrum is not None
    # lines by output order (the preset names two meshes, the original BenchInfo one)
    mine = {round(ln.output_order, 6): ln for ln in got.spectrum.lines}
    theirs = {round(ln.output_order, 6): ln for ln in ref.spectrum.lines}
    common = sorted(set(mine) & set(theirs))
    assert len(common) >= 12 and 25.0 in common and 1300.0 in common and 1.0 in common
    for order in common:
        assert mine[order].amplitude_rad == pytest.approx(theirs[order].amplitude_rad,
                                                          abs=atol, rel=0), order
        if theirs[order].amplitude_rad > 1e3 * atol:   # a phase is defined
            assert math.remainder(mine[order].phase_rad - theirs[order].phase_rad,
                                  2 * math.pi) == pytest.approx(0.0, abs=1e-6), order
    # the lines carry the signal: the 1 f_w line of the 2K-V is well above the tolerance
    assert max(ln.amplitude_rad for ln in ref.spectrum.lines) > 1e-6
    assert got.bench.preset == 'wang2020-2kv'
    assert got.bench.gear_ratio == pytest.approx(79.0)
    assert got.bench.crank_per_output == pytest.approx(25.0)
    assert got.session.unit_serial == 'SN-DAQ-1'


def test_imported_bag_read_by_rosbags_and_mcap(session: tuple, tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    from rv_te_bench.io.msgdefs import rv_te_typestore

    s, _, _ = session
    daq_files.write_tdms(tmp_path / 'run.tdms', s)
    desc = load_bench_description(daq_files.bench_yaml(tmp_path / 'bench.yaml'))
    out = tmp_path / 'bag'
    import_file(tmp_path / 'run.tdms', desc, out, options=ImportOptions(
        theta_in='theta_in', theta_out='theta_out', torque='torque'))
    seqs, n, first_topic = [], 0, None
    with AnyReader([out], default_typestore=rv_te_typestore()) as reader:
        for conn, t_ns, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            first_topic = first_topic or conn.topic
            if conn.topic == '/bench/encoders':
                stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
                assert stamp == t_ns == daq_files.START_NS + round(n / daq_files.RATE_HZ * 1e9)
                np.testing.assert_array_equal(msg.theta_in_rad,
                                              s.theta_in_rad[n:n + msg.theta_in_rad.size])
                np.testing.assert_allclose(msg.time_offset_s,
                                           np.arange(msg.theta_in_rad.size) / 2000.0,
                                           rtol=0, atol=1e-12)
                assert msg.torque_out_nm.size == msg.theta_in_rad.size
                seqs.append(msg.seq)
                n += msg.theta_in_rad.size
            else:
                assert conn.topic == '/bench/info'
                assert msg.gear_ratio == pytest.approx(79.0)
                assert msg.block_size == 500
    assert first_topic == '/bench/info'
    assert seqs == list(range(len(seqs)))
    assert n == s.t_s.size
    counts: dict[str, int] = {}
    (mcap,) = out.glob('*.mcap')
    with mcap.open('rb') as f:
        for _schema, channel, _message in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts == {'/bench/info': 1, '/bench/encoders': len(seqs)}


@pytest.mark.parametrize(('separate', 'storage'), [(False, 'mcap'), (True, 'sqlite3')])
def test_jointstate_bag_round_trip(session: tuple, tmp_path: Path, separate: bool,
                                   storage: str) -> None:
    """ros2_control's JointState (joints in one message, or one message per joint paired
    by stamp; MCAP or sqlite3) imported back: float64 positions, so exact (1e-11 rad)."""
    s, _, ref = session
    bag = daq_files.write_jointstate_bag(tmp_path / 'js', s, separate=separate,
                                         storage=storage)
    desc = load_bench_description(daq_files.bench_yaml(tmp_path / 'bench.yaml'))
    out = tmp_path / 'imported'
    summary = import_file(bag, desc, out, options=ImportOptions(chunk_samples=5000,
                                                                torque='output_joint'))
    assert summary.samples == s.t_s.size
    assert summary.start_utc.startswith('2026-11-24T09:30:00')
    assert summary.sample_rate_hz == pytest.approx(daq_files.RATE_HZ, rel=1e-6)
    got = analyze_bag(out, with_advice=False)
    assert len(got.windows) == len(ref.windows)
    for a, b in zip(got.windows, ref.windows, strict=True):
        assert a.stats.n_samples == b.stats.n_samples
        assert a.stats.pp_rad == pytest.approx(b.stats.pp_rad, abs=1e-11, rel=0)
        assert a.stats.mean_rad == pytest.approx(b.stats.mean_rad, abs=1e-11, rel=0)


def test_jointstate_missing_partner_and_backwards_stamp(session: tuple, tmp_path: Path) -> None:
    """A position without its partner leaves its sample out (counted) and, inside the
    record, a drop-out; a stamp going backwards is dropped and reported as a drop-out (as
    the live adapter does), not a reason to refuse the bag."""
    s, _, _ = session
    short = daq_files.Session(*(a[:3000] for a in (s.t_s, s.theta_in_rad, s.theta_out_rad,
                                                   s.torque_nm)))
    desc = load_bench_description(daq_files.bench_yaml(tmp_path / 'bench.yaml'))
    bag = daq_files.write_jointstate_bag(tmp_path / 'gap', short, separate=True,
                                         skip=(10, 1500, 2999))
    notes: list[str] = []
    summary = import_file(bag, desc, tmp_path / 'o1', options=ImportOptions(chunk_samples=700),
                          on_note=notes.append)
    assert summary.samples == 3000 - 3
    assert any('3 joint positions had no partner' in n for n in notes)
    # samples 10 and 1500 missing inside the record: two drop-outs of one sample each
    assert [(g.reason, g.samples_missing) for g in summary.gaps] == [('time_step', 1)] * 2
    assert [round(g.t_before_s * daq_files.RATE_HZ) for g in summary.gaps] == [9, 1499]
    back = daq_files.write_jointstate_bag(
        tmp_path / 'back', short, stamp_ns={1234: daq_files.START_NS + 5})
    summary = import_file(back, desc, tmp_path / 'o2', options=ImportOptions(chunk_samples=700))
    assert summary.samples == 3000 - 1 and summary.samples_dropped == 1
    (gap,) = summary.gaps
    assert gap.reason == 'time_backwards' and gap.samples_dropped == 1
    assert gap.where == 'sample 1234'
    assert gap.t_before_s == pytest.approx(1233 / daq_files.RATE_HZ, abs=1e-9)
    assert gap.t_after_s == pytest.approx(1235 / daq_files.RATE_HZ, abs=1e-9)


def test_report_shows_the_unit(session: tuple, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    """The bench description's unit under test reaches the report (title, table, JSON)."""
    import json

    from rv_te_bench.cli.main import main

    s, _, _ = session
    daq_files.write_csv(tmp_path / 'run.csv', s)
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml')
    out = tmp_path / 'unit7'
    assert main(['import', str(tmp_path / 'run.csv'), '--bench', str(bench), '--out', str(out),
                 '--time', 't_s', '--theta-in', 'theta_in_rad', '--theta-out',
                 'theta_out_rad', '--start-utc', '2026-11-24T09:30:00Z']) == 0
    capsys.readouterr()
    assert main(['analyze', str(out), '--report', str(tmp_path / 'rep'), '--no-advice',
                 '--no-db', '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    doc = doc['bags'][0] if 'bags' in doc else doc
    assert doc['title'] == ('wang2020-2kv, bench daq-bench, session unit7 '
                            '(2026-11-24T09:30:00.000+00:00), unit SN-DAQ-1')
    assert doc['session']['operator'] == 'pytest'
    assert doc['session']['temperature_c'] == '22'
    page = (tmp_path / 'rep' / 'report.html').read_text(encoding='utf-8')
    assert '<th class="l">operator</th><td class="l">pytest</td>' in page
    assert 'temperature [degC]' in page and str(tmp_path / 'run.csv') in page


@pytest.mark.parametrize(('write', 'name', 'listed'), [
    (daq_files.write_tdms, 'run.tdms', 'encoders/theta_in, encoders/theta_out, encoders/torque'),
    (daq_files.write_mdf, 'run.mf4', 'theta_in'),
])
def test_named_channel_files_need_both_angle_channels(session: tuple, tmp_path: Path,
                                                       write: object, name: str,
                                                       listed: str) -> None:
    """TDMS and MDF have no column order to fall back on: without --theta-in / --theta-out
    the import stops with one line that lists the file's channels, and writes nothing."""
    from rv_te_bench.errors import DataImportError

    s, _, _ = session
    short = daq_files.Session(*(a[:2000] for a in (s.t_s, s.theta_in_rad, s.theta_out_rad,
                                                   s.torque_nm)))
    path = write(tmp_path / name, short)   # type: ignore[operator]
    desc = load_bench_description(daq_files.bench_yaml(tmp_path / 'bench.yaml'))
    with pytest.raises(DataImportError) as exc:
        import_file(path, desc, tmp_path / 'out', options=ImportOptions(theta_out='theta_out'))
    text = str(exc.value)
    assert text.startswith(f'{path}: name the angle channels with --theta-in and --theta-out')
    assert listed in text
    assert not (tmp_path / 'out').exists()
