"""rv-te import on bad files (issue #19 s.3): one ERROR line naming the file, the column or
channel and the row or sample; exit code 1; nothing left behind (no bag, no hidden folder)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from tests.io import daq_files

N = 6000   # samples of the small session (3 s at 2 kHz)


@pytest.fixture(scope='module')
def session() -> daq_files.Session:
    return daq_files.simulate(duration_s=N / daq_files.RATE_HZ)


def csv_lines(s: daq_files.Session) -> list[str]:
    head = 't_s,theta_in_rad,theta_out_rad'
    rows = [f'{t!r},{a!r},{b!r}' for t, a, b in zip(s.t_s.tolist(), s.theta_in_rad.tolist(),
                                                     s.theta_out_rad.tolist(), strict=True)]
    return [head, *rows]


def run_import(tmp_path: Path, file: Path, capsys: pytest.CaptureFixture[str], *extra: str,
               cols: tuple[str, ...] = ('--theta-in', 'theta_in_rad', '--theta-out',
                                        'theta_out_rad')) -> tuple[int, str]:
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml')
    out = tmp_path / 'bags' / 'imported'
    code = main(['import', str(file), '--bench', str(bench), '--out', str(out),
                 '--chunk-samples', '1000', *cols, *extra])
    err = capsys.readouterr().err.strip()
    assert not out.exists()
    leftovers = list(out.parent.iterdir()) if out.parent.exists() else []
    assert leftovers == [], leftovers   # no hidden half-written folder either
    return code, err


def one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if not ln.startswith('note: ')]
    assert len(lines) == 1, err
    assert lines[0].startswith('ERROR: ')
    assert 'nothing written' in lines[0]
    return lines[0]


def edit_csv(tmp_path: Path, s: daq_files.Session, row: int, new: str) -> Path:
    """The session as CSV with sample ``row`` (file line row + 2) replaced by ``new``."""
    lines = csv_lines(s)
    lines[row + 1] = new
    p = tmp_path / 'run.csv'
    p.write_text('\n'.join(lines) + '\n', encoding='utf-8')
    return p


def test_good_csv_imports(tmp_path: Path, session: daq_files.Session,
                          capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / 'run.csv'
    p.write_text('\n'.join(csv_lines(session)) + '\n', encoding='utf-8')
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml')
    out = tmp_path / 'bag'
    assert main(['import', str(p), '--bench', str(bench), '--out', str(out), '--time', 't_s',
                 '--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad',
                 '--start-utc', '2026-11-24T09:30:00Z', '--json']) == 0
    import json
    summary = json.loads(capsys.readouterr().out)
    assert summary['samples'] == N and summary['blocks'] == N // 500
    assert summary['start_utc'].startswith('2026-11-24T09:30:00')
    assert summary['sample_rate_hz'] == pytest.approx(2000.0, rel=1e-9)
    # refuses to overwrite
    assert main(['import', str(p), '--bench', str(bench), '--out', str(out), '--theta-in', '1',
                 '--theta-out', '2']) == 1
    assert 'exists already' in capsys.readouterr().err


@pytest.mark.parametrize(('row', 'new', 'words'), [
    (4321, '2.1605,abc,0.1', ["column 'theta_in_rad'", 'line 4323', "'abc' is not a number"]),
    (3999, '1.9995,1.0', ["column 'theta_out_rad'", 'line 4001', 'missing']),
])
def test_bad_csv_cell(tmp_path: Path, session: daq_files.Session,
                      capsys: pytest.CaptureFixture[str], row: int, new: str,
                      words: list[str]) -> None:
    """Bad values after several blocks were written: still nothing left behind."""
    p = edit_csv(tmp_path, session, row, new)
    code, err = run_import(tmp_path, p, capsys, '--time', 't_s')
    assert code == 1
    line = one_error_line(err)
    assert str(p) in line
    for w in words:
        assert w in line, (w, line)


@pytest.mark.parametrize(('content', 'cols', 'words'), [
    ('', ('--theta-in', 'a', '--theta-out', 'b'), ['empty']),
    ('t_s,a,b\n', ('--theta-in', 'a', '--theta-out', 'b'), ['no data rows']),
    ('t_s,a,b\n0,1,2\n', ('--theta-in', 'a', '--theta-out', 'nope'),
     ["column 'nope' not found", "'t_s', 'a', 'b'"]),
    ('t_s,a [furlong],b\n0,1,2\n', ('--theta-in', 'a [furlong]', '--theta-out', 'b'),
     ["column 'a [furlong]'", "unknown unit 'furlong'"]),
])
def test_bad_csv_file(tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str,
                      cols: tuple[str, ...], words: list[str]) -> None:
    p = tmp_path / 'bad.csv'
    p.write_text(content, encoding='utf-8')
    code, err = run_import(tmp_path, p, capsys, cols=cols)
    assert code == 1
    line = one_error_line(err)
    assert str(p) in line
    for w in words:
        assert w in line, (w, line)


def test_counts_need_counts_per_rev(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / 'c.csv'
    p.write_text('a,b\n1,2\n3,4\n', encoding='utf-8')
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml', encoders={})
    code = main(['import', str(p), '--bench', str(bench), '--out', str(tmp_path / 'o'),
                 '--theta-in', 'a', '--theta-out', 'b', '--unit-in', 'counts'])
    err = capsys.readouterr().err
    assert code == 1
    assert "column 'a'" in one_error_line(err) and 'counts per revolution' in err


@pytest.mark.parametrize('fmt', ['tdms', 'mf4'])
@pytest.mark.parametrize('cut', [0.0, 0.5, 0.97])
def test_truncated_or_empty_daq_file(tmp_path: Path, session: daq_files.Session,
                                     capsys: pytest.CaptureFixture[str], fmt: str,
                                     cut: float) -> None:
    pytest.importorskip('nptdms' if fmt == 'tdms' else 'asammdf')
    full = tmp_path / f'full.{fmt}'
    (daq_files.write_tdms if fmt == 'tdms' else daq_files.write_mdf)(full, session)
    data = full.read_bytes()
    p = tmp_path / f'cut.{fmt}'
    p.write_bytes(data[:int(len(data) * cut)])
    code, err = run_import(tmp_path, p, capsys,
                           cols=('--theta-in', 'theta_in', '--theta-out', 'theta_out'))
    assert code == 1
    line = one_error_line(err)
    assert str(p) in line
    if cut == 0.0:
        assert 'empty' in line
    elif fmt == 'tdms':   # the channel that ends early and where
        assert 'truncated' in line and "channel 'encoders/" in line and 'sample ' in line
    else:
        assert 'truncated or damaged' in line


@pytest.mark.parametrize('fmt', ['tdms', 'mf4'])
def test_unknown_channel(tmp_path: Path, session: daq_files.Session,
                         capsys: pytest.CaptureFixture[str], fmt: str) -> None:
    pytest.importorskip('nptdms' if fmt == 'tdms' else 'asammdf')
    p = tmp_path / f'run.{fmt}'
    (daq_files.write_tdms if fmt == 'tdms' else daq_files.write_mdf)(p, session)
    code, err = run_import(tmp_path, p, capsys,
                           cols=('--theta-in', 'theta_in', '--theta-out', 'spindle'))
    assert code == 1
    line = one_error_line(err)
    assert "channel 'spindle' not found" in line and 'theta_out' in line


def test_tdms_unknown_unit(tmp_path: Path, session: daq_files.Session,
                           capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip('nptdms')
    p = daq_files.write_tdms(tmp_path / 'run.tdms', session, unit='furlong')
    code, err = run_import(tmp_path, p, capsys,
                           cols=('--theta-in', 'theta_in', '--theta-out', 'theta_out'))
    assert code == 1
    line = one_error_line(err)
    assert "column 'encoders/theta_in'" in line and "unknown unit 'furlong'" in line


@pytest.mark.parametrize(('fmt', 'module'), [('tdms', 'nptdms'), ('mf4', 'asammdf')])
def test_missing_extra_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                monkeypatch: pytest.MonkeyPatch, fmt: str, module: str) -> None:
    monkeypatch.setitem(sys.modules, module, None)   # import fails as when not installed
    p = tmp_path / f'run.{fmt}'
    p.write_bytes(b'x' * 100)
    code, err = run_import(tmp_path, p, capsys, cols=('--theta-in', 'a', '--theta-out', 'b'))
    assert code == 1
    line = one_error_line(err)
    assert f'needs the {module} library' in line and 'rv-te-bench[daq]' in line


def test_single_turn_counts_unwrapped(tmp_path: Path, session: daq_files.Session,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    """A 16-bit single-turn output encoder and a 2^20 input counter, both wrapping: the
    bag holds the unwrapped angles (quantised to one count)."""
    cpr_in, cpr_out = 2**20, 2**16
    c_in = np.floor(session.theta_in_rad / (2 * np.pi) * cpr_in) % cpr_in
    c_out = np.floor(session.theta_out_rad / (2 * np.pi) * cpr_out) % cpr_out
    p = tmp_path / 'counts.csv'
    np.savetxt(p, np.c_[c_in, c_out], fmt='%d', delimiter=',', header='in_counts,out_counts',
               comments='')
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml', encoders={
        'input': {'model': 'counter', 'counts_per_rev': cpr_in},
        'output': {'model': 'absolute-16bit', 'counts_per_rev': cpr_out}})
    out = tmp_path / 'bag'
    assert main(['import', str(p), '--bench', str(bench), '--out', str(out),
                 '--theta-in', 'in_counts', '--theta-out', 'out_counts']) == 0
    capsys.readouterr()
    from rv_te_bench.io.bag_reader import read_encoder_blocks

    blocks = list(read_encoder_blocks(out))
    th_out = np.concatenate([b.theta_out_rad for b in blocks])
    th_in = np.concatenate([b.theta_in_rad for b in blocks])
    start_out = np.floor(session.theta_out_rad[0] / (2 * np.pi)) * 2 * np.pi
    start_in = np.floor(session.theta_in_rad[0] / (2 * np.pi)) * 2 * np.pi
    np.testing.assert_allclose(th_out + start_out, session.theta_out_rad, rtol=0,
                               atol=2 * np.pi / cpr_out * 1.001)
    np.testing.assert_allclose(th_in + start_in, session.theta_in_rad, rtol=0,
                               atol=2 * np.pi / cpr_in * 1.001)
    assert np.all(np.diff(th_in) > 0)   # the input wrapped many times, unwrapped


def test_bag_without_jointstate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sample = Path(__file__).resolve().parents[2] / 'bags' / 'sample'
    code, err = run_import(tmp_path, sample, capsys, cols=())
    assert code == 1
    line = one_error_line(err)
    assert str(sample) in line and 'no topic of type sensor_msgs/msg/JointState' in line


def _wait_for(cond, timeout_s: float) -> bool:
    import time

    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.002)
    return False


def test_import_killed_mid_write_is_cleaned_up_by_the_next(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``rv-te import`` killed with SIGKILL while writing (no Python clean-up runs) leaves its
    hidden work folder beside the bag. The next import to the same bag removes it, says so
    in one note, and writes the bag; a work folder whose process is alive is left alone."""
    import os
    import signal
    import subprocess

    n = 600_000   # ~0.5 s of import: long enough to be killed while it writes
    t = np.arange(n) / daq_files.RATE_HZ
    th_in = 2 * np.pi * 5.0 * t
    big = tmp_path / 'big.csv'
    np.savetxt(big, np.c_[t, th_in, th_in / 79.0], fmt='%.12g', delimiter=',',
               header='t_s,theta_in_rad,theta_out_rad', comments='')
    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml')
    bags = tmp_path / 'bags'
    bags.mkdir()
    out = bags / 'unit7'
    argv = ['import', str(big), '--bench', str(bench), '--out', str(out), '--theta-in',
            'theta_in_rad', '--theta-out', 'theta_out_rad', '--chunk-samples', '20000']
    env = {**os.environ, 'PYTHONPATH': str(Path(__file__).resolve().parents[2])}
    p = subprocess.Popen([sys.executable, '-m', 'rv_te_bench.cli.main', *argv], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        def writing() -> bool:
            work = list(bags.glob('.unit7.importing-*/unit7/*.mcap'))
            return bool(work) and work[0].stat().st_size > 0

        assert _wait_for(lambda: writing() or p.poll() is not None, 60.0)
        assert p.poll() is None, f'the import ended before it could be killed: {p.stderr.read()}'
        p.send_signal(signal.SIGKILL)
    finally:
        if p.poll() is None:
            p.kill()
        p.wait()
    left = list(bags.iterdir())
    assert [x.name.split('-')[0] for x in left] == ['.unit7.importing'], left
    assert not out.exists()
    # a work folder of a live import to the same bag (this test's own parent: alive)
    alive = bags / f'.unit7.importing-{os.getppid()}-1'
    (alive / 'unit7').mkdir(parents=True)
    capsys.readouterr()
    small = daq_files.write_csv(tmp_path / 'small.csv', daq_files.simulate(duration_s=1.0))
    assert main(['import', str(small), '--bench', str(bench), '--out', str(out),
                 '--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad']) == 0
    err = capsys.readouterr().err
    removed = [ln for ln in err.splitlines() if 'left by an earlier import' in ln]
    assert len(removed) == 1, err
    assert str(left[0]) in removed[0] and f'process {p.pid} was killed' in removed[0]
    assert sorted(x.name for x in bags.iterdir()) == [alive.name, 'unit7']


# -- drop-outs, time units, unwrapping per channel (issue #32 s.1) ---------------------------

def _csv_json(tmp_path: Path, p: Path, capsys: pytest.CaptureFixture[str],
              *extra: str) -> dict:
    import json

    bench = daq_files.bench_yaml(tmp_path / 'bench.yaml')
    code = main(['import', str(p), '--bench', str(bench), '--out', str(tmp_path / 'bag'),
                 '--chunk-samples', '1000', '--theta-in', 'theta_in_rad', '--theta-out',
                 'theta_out_rad', '--json', *extra])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out) | {'_err': captured.err}


@pytest.mark.parametrize(('row', 'new', 'reason', 'dropped'), [
    (5000, '2.5,nan,0.2', 'non_finite', 1),
    (5000, '2.5,,0.2', 'non_finite', 1),          # pandas writes NaN as an empty cell
    (2500, '1.0,1.0,0.1', 'time_backwards', 1),
    (2500, 'nan,1.0,0.1', 'non_finite', 1),
])
def test_bad_row_is_a_reported_dropout(tmp_path: Path, session: daq_files.Session,
                                       capsys: pytest.CaptureFixture[str], row: int, new: str,
                                       reason: str, dropped: int) -> None:
    """A NaN, empty or backwards row is a drop-out (a gap in the bag, named in a note and
    in --json), not silently spliced and not a reason to throw the file away."""
    p = edit_csv(tmp_path, session, row, new)
    doc = _csv_json(tmp_path, p, capsys, '--time', 't_s')
    assert doc['samples'] == N - dropped and doc['samples_dropped'] == dropped
    (gap,) = doc['gaps']
    assert (gap['reason'], gap['samples_dropped'], gap['where']) == (reason, dropped,
                                                                    f'line {row + 2}')
    assert gap['t_before_s'] == pytest.approx((row - 1) / daq_files.RATE_HZ, abs=1e-9)
    assert f'drop-out at {(row - 1) / daq_files.RATE_HZ:.6g} s (line {row + 2})' in doc['_err']


@pytest.mark.parametrize(('header', 'scale', 'flags'), [
    ('t_ms', 1e3, ()), ('time [min]', 1 / 60, ()), ('time (s)', 1.0, ()),
    ('t_us', 1e6, ()), ('time', 1e3, ('--time-unit', 'ms')),
])
def test_time_unit_from_the_column_name(tmp_path: Path, session: daq_files.Session,
                                        capsys: pytest.CaptureFixture[str], header: str,
                                        scale: float, flags: tuple[str, ...]) -> None:
    p = tmp_path / 'run.csv'
    np.savetxt(p, np.c_[session.t_s * scale, session.theta_in_rad, session.theta_out_rad],
               fmt='%.17g', delimiter=',', comments='',
               header=f'{header},theta_in_rad,theta_out_rad')
    doc = _csv_json(tmp_path, p, capsys, '--time', header, *flags)
    assert doc['sample_rate_hz'] == pytest.approx(daq_files.RATE_HZ, rel=1e-9)
    assert doc['gaps'] == [] and doc['samples'] == N


def test_time_unit_never_assumed(tmp_path: Path, session: daq_files.Session,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    """A time column whose unit nothing states is refused in one line naming it (before:
    taken as seconds: a column in ms gave 2 Hz and TE over 1000x too few revolutions)."""
    p = tmp_path / 'run.csv'
    np.savetxt(p, np.c_[session.t_s * 1e3, session.theta_in_rad, session.theta_out_rad],
               fmt='%.17g', delimiter=',', comments='', header='time,theta_in_rad,theta_out_rad')
    code, err = run_import(tmp_path, p, capsys, '--time', 'time')
    assert code == 1
    line = one_error_line(err)
    assert "time column 'time'" in line and '--time-unit' in line


def test_no_unwrap_contradicts_unwrap_out(tmp_path: Path, session: daq_files.Session,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    p = edit_csv(tmp_path, session, 10, csv_lines(session)[11])
    with pytest.raises(SystemExit) as exc:
        run_import(tmp_path, p, capsys, '--time', 't_s', '--no-unwrap', '--unwrap-out')
    assert exc.value.code == 2
    assert '--no-unwrap and --unwrap-out contradict' in capsys.readouterr().err


def test_ambiguous_dropout_splits_into_segment_bags(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """A 10 s drop-out during which the drive slowed from 1500 to 600 rpm: the single-turn
    output's turns are ambiguous, so the record is split: OUT and OUT_seg2, each a session
    bag of its own (seq from 0), the split named; each analyses to TE = 0 here."""
    import json

    rate, ratio = 2000.0, 79.0
    w1, w2 = 2 * np.pi * 25.0, 2 * np.pi * 10.0
    t1, t2 = np.arange(0, 8.0, 1 / rate), np.arange(18.0, 26.0, 1 / rate)
    th_in = np.concatenate([w1 * t1, w1 * 8.0 + (w1 + w2) / 2 * 10.0 + w2 * (t2 - 18.0)])
    t = np.concatenate([t1, t2])
    p = tmp_path / 'run.csv'
    np.savetxt(p, np.c_[t, th_in, np.mod(th_in / ratio, 2 * np.pi)], fmt='%.17g',
               delimiter=',', comments='', header='t_s,theta_in_rad,theta_out_rad')
    doc = _csv_json(tmp_path, p, capsys, '--time', 't_s')
    bag, seg2 = tmp_path / 'bag', tmp_path / 'bag_seg2'
    assert doc['segments'] == [str(bag), str(seg2)]
    (gap,) = doc['gaps']
    assert gap['split'] and gap['how_out'] == 'ambiguous' and gap['advance_out_rev'] is None
    assert 'split into 2 segments' in doc['_err']
    for b in (bag, seg2):
        assert main(['analyze', str(b), '--no-advice', '--no-db', '--json']) == 0
        res = json.loads(capsys.readouterr().out)
        res = res['bags'][0] if 'bags' in res else res
        assert res['gaps'] == []
        assert res['cumulative']['te_pp_rad'] < 1e-9
