"""Bounds, hangs and tracebacks on the surfaces of the last wave (issue #32 s.3): test
plans and tolerance profiles with no upper limits, times a ROS 2 stamp cannot hold, MDF
channels that are not numbers, FIFOs that hung the opener, a silent Dask scheduler, lines
without end in a CSV, limits fleet did not share with analyze, one YAML number rule. Each
case ends within its time limit with one clear line (or, where the input is fine, works),
and leaves nothing behind."""

from __future__ import annotations

import datetime as dt
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from rv_te_bench.cli.main import main
from tests.io import daq_files

RV_TE = [sys.executable, '-m', 'rv_te_bench.cli.main']


def _env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items()
            if k not in ('_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'RV_TE_DB')}


def _one_error(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith('note: ')]
    assert len(lines) == 1, err
    assert 'Traceback' not in err
    return lines[0]


# -- plans and tolerances ------------------------------------------------------------------------

PLAN_HEAD = 'plan: p\nsteps:\n'


@pytest.mark.parametrize(('step', 'words'), [
    ('{kind: te, speed_rpm: 100, revolutions: 1000000000}', 'revolutions must be an integer '
     'in 1..100'),
    ('{kind: sweep, speeds_rpm: [1e300]}', 'speeds_rpm[0] must be finite and >= 0 and <= '
     '100000'),
    ('{kind: sweep, speeds_rpm: [100], loads_nm: [1.0e+12]}', 'loads_nm[0]'),
    ('{kind: te, speed_rpm: 100, settle_s: 86400}', 'settle_s must be <= 600'),
    ('{kind: te, speed_rpm: 100, load_nm: 1.0e+9}', 'load_nm must be <= 1e+06'),
    ('{kind: hysteresis, rated_torque_nm: 1.0e+9}', 'rated_torque_nm must be <= 1e+06'),
])
def test_plan_values_have_upper_limits(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                       step: str, words: str) -> None:
    """Refused before anything starts (before: 1e9 revolutions ran for ever, 1e300 rpm an
    OverflowError inside the test)."""
    plan = tmp_path / 'plan.yaml'
    plan.write_text(PLAN_HEAD + f'  - {step}\n', encoding='utf-8')
    code = main(['test', str(plan), '--serial', 'X1', '--operator', 'kim', '--launch',
                 'wang2020-2kv', '--out-dir', str(tmp_path / 'out')])
    assert code == 1
    assert words in _one_error(capsys.readouterr().err)
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize(('limit', 'words'), [
    ('te_pp_arcmin: {min: 0.2, max: 1.0}', 'min is not allowed (only max'),
    ('backlash_arcmin: {min: 0.1}', 'min is not allowed (only max'),
    ('torsional_rigidity_nm_per_arcmin: {max: 500}', 'max is not allowed (only min'),
    ('lost_motion_arcmin: {max: 1.0e+300}', 'must be a number in 0..1e+06'),
])
def test_tolerance_sides_and_bounds(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    limit: str, words: str) -> None:
    """A min where only a max makes sense would fail the best units: refused."""
    tol = tmp_path / 'tol.yaml'
    tol.write_text(f'profile: t\nlimits:\n  {limit}\n', encoding='utf-8')
    plan = tmp_path / 'plan.yaml'
    plan.write_text(PLAN_HEAD + '  - {kind: te, speed_rpm: 100}\n', encoding='utf-8')
    code = main(['test', str(plan), '--tolerance', str(tol), '--serial', 'X1', '--operator',
                 'kim', '--launch', 'wang2020-2kv', '--out-dir', str(tmp_path / 'out')])
    assert code == 1
    assert words in _one_error(capsys.readouterr().err)


@pytest.mark.parametrize('content', [
    'root:$6$S3CRETHASH:19000:0:99999:7:::\ndaemon:*:19000:0:99999:7:::\n',
    'S3CRETKEY: abc\nother: 1\n',
    'profile: x\nS3CRET-with space: 1\nlimits: {te_pp_arcmin: {max: 1}}\n',
])
def test_an_error_never_prints_the_file_it_was_pointed_at(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str) -> None:
    """``tolerance: /etc/shadow`` in a plan (and the same as --tolerance): the error names
    the file, never its lines (before: they were printed as 'unknown keys')."""
    secret = tmp_path / 'shadow'
    secret.write_text(content, encoding='utf-8')
    plan = tmp_path / 'plan.yaml'
    plan.write_text(f'plan: p\ntolerance: {secret}\nsteps:\n  - {{kind: te, speed_rpm: 100}}\n',
                    encoding='utf-8')
    for extra in ((), ('--tolerance', str(secret))):
        code = main(['test', str(plan), *extra, '--serial', 'X1', '--operator', 'kim',
                     '--launch', 'wang2020-2kv', '--out-dir', str(tmp_path / 'out')])
        line = _one_error(capsys.readouterr().err)
        assert code == 1 and str(secret) in line and 'S3CRET' not in line


@pytest.mark.parametrize('args', [
    ['--wait-s', 'nan'], ['--wait-s', '-1'], ['--serial', ''], ['--serial', '   '],
    ['--operator', ''], ['--speed-factor', 'inf'],
])
def test_test_command_refuses_bad_flags_before_starting(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str]) -> None:
    argv = ['test', 'wang2020-2kv', '--serial', 'X1', '--operator', 'kim', '--launch',
            'wang2020-2kv', '--out-dir', str(tmp_path / 'out'), *args]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert args[0] in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()


def test_one_yaml_number_rule(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``2e3`` is a number in a bench description, a plan and a tolerance profile, as in a
    parameter file (before: the text '2e3', refused as 'must be a number')."""
    from rv_te_bench.acceptance import load_plan, load_tolerance
    from rv_te_bench.io.bench_description import load_bench_description

    bench = tmp_path / 'bench.yaml'
    bench.write_text('bench_id: b\nsample_rate_hz: 2e3\nreducer: {kind: other, gear_ratio: '
                     '7.9e1, crank_per_output: 2.5e1}\n', encoding='utf-8')
    desc = load_bench_description(bench)
    assert (desc.sample_rate_hz, desc.bench_info().gear_ratio) == (2000.0, 79.0)
    plan = tmp_path / 'plan.yaml'
    plan.write_text(PLAN_HEAD + '  - {kind: te, speed_rpm: 1.5e3, load_nm: 2e2}\n',
                    encoding='utf-8')
    (step,) = load_plan(plan)[0].steps
    assert (step.speed_rpm, step.load_nm) == (1500.0, 200.0)   # type: ignore[union-attr]
    tol = tmp_path / 'tol.yaml'
    tol.write_text('profile: t\nlimits:\n  te_pp_arcmin: {max: 1e0}\n', encoding='utf-8')
    (lim,) = load_tolerance(tol)[0].limits
    assert lim.max_si == pytest.approx(np.pi / 10800)
    # quoted, it stays text (as in a parameter file)
    plan.write_text(PLAN_HEAD + "  - {kind: te, speed_rpm: '1.5e3'}\n", encoding='utf-8')
    from rv_te_bench.errors import PlanError
    with pytest.raises(PlanError, match='speed_rpm must be a finite number'):
        load_plan(plan)


# -- import: times a stamp cannot hold, MDF channels, names, long lines --------------------------

def _csv(tmp_path: Path) -> Path:
    s = daq_files.simulate(duration_s=1.0)
    return daq_files.write_csv(tmp_path / 'run.csv', s)


def _import(tmp_path: Path, src: Path, *extra: str, out: str = 'bag',
            cols: tuple[str, ...] = ('--time', 't_s', '--theta-in', 'theta_in_rad',
                                     '--theta-out', 'theta_out_rad')) -> tuple[int, str]:
    p = subprocess.run([*RV_TE, 'import', os.fsencode(src), '--bench',
                        str(daq_files.bench_yaml(tmp_path / 'bench.yaml')), '--out',
                        os.fsencode(tmp_path / out), *cols, *extra],
                       capture_output=True, text=True, timeout=120, env=_env(), check=False)
    return p.returncode, p.stderr


@pytest.mark.parametrize(('extra', 'words'), [
    (('--start-utc', '1960-01-01T00:00:00Z'), 'the start time from --start-utc is 1960'),
    (('--start-utc', '2040-06-01T00:00:00Z'), 'the start time from --start-utc is 2040'),
    (('--start-utc', '2038-01-19T03:14:07.5Z'), 'the time of the sample'),
    (('--rate', '1e-300'), '--rate must be between'),
])
def test_times_a_ros_stamp_cannot_hold(tmp_path: Path, extra: tuple[str, ...],
                                       words: str) -> None:
    """Before 1970 or after 2038-01-19T03:14:07Z (int32 seconds): one line, no bag (before:
    struct.error / OverflowError tracebacks)."""
    src = _csv(tmp_path)
    cols = (('--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad')
            if '--rate' in extra else ('--time', 't_s', '--theta-in', 'theta_in_rad',
                                       '--theta-out', 'theta_out_rad'))
    code, err = _import(tmp_path, src, *extra, cols=cols)
    assert code == 1 and words in _one_error(err), err
    assert not (tmp_path / 'bag').exists()


def test_file_start_times_out_of_range(tmp_path: Path) -> None:
    """A file modification time of 1960, a TDMS wf_start_time of 1950, an MDF start of
    2045, negative JointState stamps: one line each naming where the time came from."""
    from asammdf import MDF, Signal
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    s = daq_files.simulate(duration_s=1.0)
    src = _csv(tmp_path)
    os.utime(src, ns=(0, -315_619_200 * 10**9))   # 1960-01-01
    code, err = _import(tmp_path, src)
    assert code == 1 and 'the start time from the file modification time is 1960' in \
        _one_error(err)
    tdms = tmp_path / 'old.tdms'
    with TdmsWriter(str(tdms)) as w:
        props = {'wf_increment': 1 / daq_files.RATE_HZ,
                 'wf_start_time': np.datetime64('1950-01-01T00:00:00', 'us')}
        w.write_segment([GroupObject('g'), ChannelObject('g', 'a', s.theta_in_rad, props),
                         ChannelObject('g', 'b', s.theta_out_rad, props)])
    code, err = _import(tmp_path, tdms, cols=('--theta-in', 'g/a', '--theta-out', 'g/b'))
    assert code == 1 and 'the start time from the file is 1950' in _one_error(err)
    mf4 = tmp_path / 'late.mf4'
    mdf = MDF(version='4.10')
    mdf.header.start_time = dt.datetime(2045, 1, 1, tzinfo=dt.UTC)
    mdf.append([Signal(s.theta_in_rad, s.t_s, name='a'), Signal(s.theta_out_rad, s.t_s,
                                                                 name='b')])
    mdf.save(str(mf4), overwrite=True)
    mdf.close()
    code, err = _import(tmp_path, mf4, cols=('--theta-in', 'a', '--theta-out', 'b'))
    assert code == 1 and 'the start time from the file is 2045' in _one_error(err)
    short = daq_files.Session(*(a[:500] for a in (s.t_s, s.theta_in_rad, s.theta_out_rad,
                                                  s.torque_nm)))
    bag = daq_files.write_jointstate_bag(
        tmp_path / 'neg', short, stamp_ns={k: -10**9 + k * 500_000 for k in range(500)})
    code, err = _import(tmp_path, bag, cols=())
    assert code == 1 and 'the start time from the file is' in _one_error(err)


def test_mdf_channels_that_are_not_numbers(tmp_path: Path) -> None:
    """A value-to-text channel and a structure channel named as an angle: one line each
    (before: ValueError / TypeError tracebacks); a master time going backwards or NaN is a
    drop-out (before: KeyError: 'time')."""
    from asammdf import MDF, Signal

    t = np.arange(3000) / 1000.0
    a = 2 * np.pi * 0.3 * t
    pair = np.rec.fromarrays([a, a], names='x,y')
    conv = {'val_0': 0, 'text_0': b'off', 'val_1': 1, 'text_1': b'on', 'default': b'?'}
    path = tmp_path / 'odd.mf4'
    mdf = MDF(version='4.10')
    mdf.header.start_time = daq_files.START
    mdf.append([Signal(a, t, name='a', unit='rad'),
                Signal((a > 1).astype(np.uint8), t, name='state', conversion=conv),
                Signal(pair, t, name='pair')])
    mdf.save(str(path), overwrite=True)
    mdf.close()
    for ch, words in (('state', "channel 'state' holds text"),
                      ('pair', "channel 'pair' is a structure (fields x, y)")):
        code, err = _import(tmp_path, path, cols=('--theta-in', 'a', '--theta-out', ch))
        assert code == 1 and words in _one_error(err)
    for name, tt in (('back', np.concatenate([t[:1000], t[1000:] - 0.5])),
                     ('nan', np.where(np.arange(t.size) == 700, np.nan, t))):
        path = tmp_path / f'{name}.mf4'
        mdf = MDF(version='4.10')
        mdf.header.start_time = daq_files.START
        mdf.append([Signal(a, tt, name='a', unit='rad'), Signal(a / 79, tt, name='b',
                                                                  unit='rad')])
        mdf.save(str(path), overwrite=True)
        mdf.close()
        code, err = _import(tmp_path, path, '--json', out=f'o_{name}',
                            cols=('--theta-in', 'a', '--theta-out', 'b'))
        assert code == 0 and 'Traceback' not in err and 'drop-out at' in err, err


def test_non_utf8_names(tmp_path: Path) -> None:
    """An input file whose name is not UTF-8 is imported (its name shown with U+FFFD in the
    bag's metadata); an --out name that is not UTF-8 is refused in one line (before: a
    UnicodeEncodeError traceback from the MCAP writer)."""
    src = _csv(tmp_path)
    odd = Path(os.fsdecode(bytes(tmp_path) + b'/r\xff.csv'))
    src.rename(odd)
    code, err = _import(tmp_path, odd)
    assert code == 0, err
    meta = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text(encoding='utf-8'))
    custom = meta['rosbag2_bagfile_information']['custom_data']
    assert custom['imported_from'].endswith('r\N{REPLACEMENT CHARACTER}.csv')
    code, err = _import(tmp_path, odd, out=os.fsdecode(b'o\xfe'))
    assert code == 1 and 'is not UTF-8 text' in _one_error(err)
    assert not any(p.name.startswith('.o') for p in tmp_path.iterdir())


def test_csv_line_length_is_bounded(tmp_path: Path) -> None:
    """A 200 MB CSV line (a file without line breaks): refused after reading a block, the
    memory of the command bounded (before: the whole line in memory, 11x its size)."""
    p = tmp_path / 'long.csv'
    with p.open('w', encoding='utf-8') as f:
        f.write('t_s,theta_in_rad,theta_out_rad\n')
        chunk = '1,' * (1 << 20)
        for _ in range(100):
            f.write(chunk)
    # a small launcher runs the command and reports its peak RSS: a child forked from the
    # test process itself would count the pages it shares with that (large) parent
    launcher = ('import resource, subprocess, sys; '
                'p = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, '
                'stderr=subprocess.PIPE, text=True); '
                'sys.stderr.write(p.stderr); '
                'print(p.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)')
    run = subprocess.run(
        [sys.executable, '-c', launcher, *RV_TE, 'import', str(p), '--bench',
         str(daq_files.bench_yaml(tmp_path / 'b.yaml')), '--out', str(tmp_path / 'bag'),
         '--time', 't_s', '--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad'],
        capture_output=True, text=True, timeout=120, env=_env(), check=False)
    code, peak_kb = (int(x) for x in run.stdout.split())
    assert code == 1 and 'longer than 1048576 characters' in _one_error(run.stderr)
    assert peak_kb < 400_000, peak_kb   # kB; the line alone is 200 MB


# -- FIFOs, a silent scheduler, fleet's limits, filters --------------------------------------------

@pytest.mark.parametrize(('argv', 'words'), [
    (['launch', '{fifo}', '--check'], 'parameter file {fifo}: not a regular file'),
    (['model', '{fifo}.toml', '--json'], 'preset {fifo}.toml: not a regular file'),
    (['import', 'x.csv', '--bench', '{fifo}', '--out', '{dir}/o'],
     'bench description {fifo}: not a regular file'),
])
def test_fifo_is_refused_not_waited_on(tmp_path: Path, argv: list[str], words: str) -> None:
    """A FIFO where a file is read: one line at once (before: hung for ever in open())."""
    fifo = tmp_path / 'pipe'
    os.mkfifo(fifo)
    os.mkfifo(f'{fifo}.toml')
    argv = [a.format(fifo=fifo, dir=tmp_path) for a in argv]
    t0 = time.monotonic()
    p = subprocess.run([*RV_TE, *argv], capture_output=True, text=True, timeout=60,
                       env=_env(), check=False)
    assert time.monotonic() - t0 < 30
    assert p.returncode == 1
    assert words.format(fifo=fifo) in _one_error(p.stderr)


def test_silent_scheduler_times_out(monkeypatch: pytest.MonkeyPatch) -> None:
    """An endpoint that accepts and never answers: an error after the timeout (before: a
    hang past it), and malformed addresses in one line."""
    pytest.importorskip('distributed')
    import socket

    from rv_te_bench.errors import RvTeError
    from rv_te_bench.fleet import _run

    monkeypatch.setattr(_run, 'SCHEDULER_TIMEOUT_S', 1.5)
    srv = socket.socket()
    srv.bind(('127.0.0.1', 0))
    srv.listen(4)
    accepted: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                accepted.append(srv.accept()[0])
            except OSError:
                pass

    th = threading.Thread(target=accept, daemon=True)
    th.start()
    try:
        t0 = time.monotonic()
        with pytest.raises(RvTeError, match=r'did not answer within 1\.5 s'):
            _run._probe_scheduler(f'tcp://127.0.0.1:{srv.getsockname()[1]}')
        assert time.monotonic() - t0 < 10
    finally:
        stop.set()
        th.join()
        for c in accepted:
            c.close()
        srv.close()
    for bad in ('garbage', 'tcp://host:port', 'tcp://127.0.0.1:99999', 'inproc://x'):
        with pytest.raises(RvTeError, match='is not a Dask scheduler address'):
            _run._probe_scheduler(bad)


@pytest.mark.parametrize('args', [['--harmonics', '100000'], ['--window-revolutions', '1e9'],
                                  ['--window-revolutions', '100000']])
def test_fleet_takes_the_limits_of_analyze(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                           args: list[str]) -> None:
    for cmd in ('analyze', 'fleet'):
        argv = [cmd, *(['analyze'] if cmd == 'fleet' else []), str(tmp_path / 'none'), *args]
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        assert args[0] in capsys.readouterr().err


def test_result_filters(tmp_path: Path) -> None:
    """``--until 9999-12-31`` is the end of time (before: OverflowError); a filter value that
    is not UTF-8 is refused in one line (before: UnicodeEncodeError from the driver)."""
    from rv_te_bench.store import open_store
    from tests.store.conftest import make_record

    db = tmp_path / 'r.sqlite'
    with open_store(db) as st:
        st.upsert(make_record(1))
    p = subprocess.run([*RV_TE, 'results', '--db', str(db), '--until', '9999-12-31'],
                       capture_output=True, text=True, timeout=60, env=_env(), check=False)
    assert p.returncode == 0 and '1 record(s)' in p.stdout, p.stderr
    for cmd in (['results'], ['spc', 'te_pp_rad']):
        p = subprocess.run([*RV_TE, *cmd, '--db', str(db), '--serial', b'\xff'],
                           capture_output=True, text=True, timeout=60, env=_env(), check=False)
        assert p.returncode == 2 and 'is not UTF-8 text' in p.stderr
        assert 'Traceback' not in p.stderr


def test_db_url_with_a_bad_port_is_one_line(tmp_path: Path) -> None:
    p = subprocess.run([*RV_TE, 'results', '--db', 'postgresql://qa:pw@db-host:port/x'],
                       capture_output=True, text=True, timeout=60, env=_env(), check=False)
    assert p.returncode == 1
    line = _one_error(p.stderr)
    assert 'pw' not in line.replace('postgresql', '')
