"""Drop-outs in measured files are gaps (issue #32 s.1): files written by pandas, nptdms,
asammdf and rosbags the way a bench writes them (tests/io/dropout_files.py: a multi-turn
input counter beside a single-turn output encoder, 1500 rpm, drop-outs of 25 ms to 10 s).

After ``rv-te import``: ``rv-te analyze`` (JSON and the HTML report) and ``rv-te identify``
list every drop-out as a gap with its time and length; no window holding one is complete;
the TE p-p of every complete window and of the whole record is within 0.5 % of the true
p-p (dense grid of the closed-form TE), and the f_out, 1 f_w and 2 f_w lines within 0.5 %
in amplitude and 1 deg in phase of the injected ones. (Before the fix: TE p-p 10,937' for
a true 1.11', no gap listed.)
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from tests.io import dropout_files as df

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path

pytest.importorskip('pandas')

ANGLES = ('--theta-in', 'theta_in', '--theta-out', 'theta_out')
CASES: dict[str, tuple[float, Callable[[Path, df.Record], Path], tuple[str, ...],
                       tuple[tuple[float, float], ...]]] = {
    # name: (rate, writer, import flags, drop-outs written as NaN rows)
    'pandas-csv-t_s': (2000.0, lambda p, r: df.write_pandas_csv(p / 'run.csv', r),
                       ('--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad',
                        '--time', 't_s'), ()),
    'pandas-csv-t_ms-nan-rows': (
        2000.0, lambda p, r: df.write_pandas_csv(p / 'run.csv', r, time='t_ms',
                                                 nan_rows=((12.0, 0.04),)),
        ('--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad', '--time', 't_ms'),
        ((12.0, 0.04),)),
    'pandas-csv-epoch-ns': (
        2000.0, lambda p, r: df.write_pandas_csv(p / 'run.csv', r, time='t_ns'),
        ('--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad', '--time', 't_ns'),
        ()),
    'nptdms-timestamps': (2000.0, lambda p, r: df.write_nptdms(p / 'run.tdms', r),
                          ('--theta-in', 'daq/theta_in', '--theta-out', 'daq/theta_out',
                           '--time', 'daq/time'), ()),
    'asammdf-mdf4': (2000.0, lambda p, r: df.write_asammdf(p / 'run.mf4', r), ANGLES, ()),
    'rosbags-jointstate': (1000.0, lambda p, r: df.write_jointstate_bag(p / 'js', r), (), ()),
}


@pytest.fixture(scope='module')
def truth() -> tuple[float, dict[float, tuple[float, float]]]:
    return df.true_pp_rad(), df.true_lines()


def _import(tmp: Path, case: str, capsys: pytest.CaptureFixture[str]) -> tuple[df.Record,
                                                                                  dict, Path]:
    rate, write, flags, nan_rows = CASES[case]
    # drop-outs written as NaN rows are in the record (the writer blanks them)
    r = df.record(rate_hz=rate, dropouts=tuple(d for d in df.DROPOUTS if d not in nan_rows))
    src = write(tmp, r)
    bench = df.bench_yaml(tmp / 'bench.yaml', rate)
    out = tmp / 'bag'
    code = main(['import', str(src), '--bench', str(bench), '--out', str(out), '--json',
                 '--chunk-samples', '7777', *flags])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    summary = json.loads(captured.out)
    assert summary['samples'] == r.k.size - sum(round(n * rate) for _, n in nan_rows)
    return r, summary, out


@pytest.mark.parametrize('case', list(CASES))
def test_dropouts_are_gaps_and_te_is_right(case: str, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str],
                                           truth: tuple) -> None:
    pp_true, lines_true = truth
    r, summary, bag = _import(tmp_path, case, capsys)
    rate = r.rate_hz
    # the import names every drop-out: time of the last good sample, length, samples
    got = [(g['t_before_s'], g['missing_s'], g['samples_missing'] + g['samples_dropped'])
           for g in summary['gaps']]
    want = [(t0 - 1 / rate, n, round(n * rate)) for t0, n in df.DROPOUTS]
    assert len(got) == len(want), summary['gaps']
    for (a, b, c), (x, y, z) in zip(got, want, strict=True):
        assert a == pytest.approx(x, abs=1e-6)
        assert b == pytest.approx(y, abs=1e-6)
        assert c == z
    assert summary['segments'] == [str(bag)]   # no ambiguity at a steady speed

    rep = tmp_path / 'report'
    assert main(['analyze', str(bag), '--no-advice', '--no-db', '--json',
                 '--report', str(rep)]) == 0
    doc = json.loads(capsys.readouterr().out)
    doc = doc['bags'][0] if 'bags' in doc else doc
    assert doc['blocks_read'] == summary['blocks']
    gaps = doc['gaps']
    assert [g['kind'] for g in gaps] == ['seq_jump'] * len(df.DROPOUTS)
    for g, (t0, n) in zip(gaps, df.DROPOUTS, strict=True):
        assert g['at_s'] == pytest.approx(t0 - 1 / rate, abs=1e-5)
        assert g['missing_s'] == pytest.approx(n, abs=1e-5)
        assert f'no data for {n:.6g} s' in g['detail']
    # no complete window holds a drop-out; as many as the stretches between them hold
    spans = [(g['t_before_s'], g['t_after_s']) for g in gaps]
    complete = [w for w in doc['windows'] if w['complete']]
    for w in complete:
        assert all(w['end_stamp_s'] <= a or w['start_stamp_s'] >= b for a, b in spans), w
    period_out = 60.0 * df.RATIO / df.RPM_IN
    edges = [0.0, *[x for t0, n in df.DROPOUTS for x in (t0, t0 + n)], df.DURATION_S]
    stretches = [edges[i + 1] - edges[i] for i in range(0, len(edges), 2)]
    assert len(complete) == sum(math.floor(s / period_out) for s in stretches) == 13
    arcmin = 10800 / math.pi
    for w in complete:
        assert w['te_pp_rad'] == pytest.approx(pp_true, rel=5e-3)
    assert doc['cumulative']['te_pp_rad'] == pytest.approx(pp_true, rel=5e-3)
    assert pp_true * arcmin == pytest.approx(1.1124, abs=1e-4)   # the check's own scale
    lines = {round(ln['output_order'], 6): ln for ln in doc['spectrum']['lines']}
    for order, (amp, phase) in lines_true.items():
        ln = lines[order]
        assert ln['amplitude_arcmin'] / arcmin == pytest.approx(amp, rel=5e-3), ln
        d_deg = math.degrees(math.remainder(math.radians(ln['phase_deg']) - phase, 2 * math.pi))
        assert abs(d_deg) < 1.0, ln
    # the report's gap table: one row per drop-out, with its time and length
    page = (rep / 'report.html').read_text(encoding='utf-8')
    assert page.count('<td class="l">seq_jump</td>') == len(df.DROPOUTS)
    for t0, n in df.DROPOUTS:
        assert f'<td>{n:.6g}</td>' in page and f'<td>{t0 - 1 / rate:.6g}</td>' in page

    assert main(['identify', str(bag), '--json', '--no-recommend', '--quiet',
                 '--preset', 'wang2020-2kv', '--ratio', str(df.RATIO)]) == 0
    ident = json.loads(capsys.readouterr().out)
    assert [(g['kind'], round(g['missing_s'], 5)) for g in ident['gaps']] == \
        [('seq_jump', n) for _, n in df.DROPOUTS]


def test_epoch_nanoseconds_are_exact(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A t_ns column of epoch nanoseconds (19 digits) gives the start time and every block
    stamp to the nanosecond (float64 would round them to 256 ns)."""
    from rosbags.highlevel import AnyReader

    _, summary, bag = _import(tmp_path, 'pandas-csv-epoch-ns', capsys)
    assert summary['start_from'] == 'the time column (epoch)'
    assert summary['start_utc'] == '2026-11-24T09:30:00.000+00:00'
    with AnyReader([bag]) as reader:   # an independent reader, the bag's own definitions
        conns = [c for c in reader.connections if c.topic == '/bench/encoders']
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs])
    assert stamps[0] == df.START_NS
    assert np.all((stamps - df.START_NS) % 500_000 == 0)   # whole sample periods, exactly


@pytest.mark.parametrize(('unit', 'scale', 'error'), [
    ('ms', 1e3, None), ('s', 1.0, None), ('', 1.0, "time column 'daq/t'"),
])
def test_tdms_time_channel_unit(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                unit: str, scale: float, error: str | None) -> None:
    """A TDMS time channel of numbers is read in the unit its unit_string states; without
    one the import is refused in one line naming the channel (never taken as seconds)."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    r = df.record(dropouts=((1.0, 0.3),), duration_s=3.0)
    path = tmp_path / 'run.tdms'
    with TdmsWriter(str(path)) as w:
        w.write_segment([GroupObject('daq'),
                         ChannelObject('daq', 't', r.t_s * scale,
                                       properties={'unit_string': unit} if unit else {}),
                         ChannelObject('daq', 'a', r.theta_in_rad),
                         ChannelObject('daq', 'b', r.theta_out_rad)])
    code = main(['import', str(path), '--bench', str(df.bench_yaml(tmp_path / 'b.yaml')),
                 '--out', str(tmp_path / 'bag'), '--theta-in', 'daq/a', '--theta-out', 'daq/b',
                 '--time', 'daq/t', '--json'])
    captured = capsys.readouterr()
    if error is not None:
        assert code == 1 and error in captured.err and not (tmp_path / 'bag').exists()
        return
    assert code == 0, captured.err
    summary = json.loads(captured.out)
    assert summary['sample_rate_hz'] == pytest.approx(2000.0)
    assert [round(g['missing_s'], 6) for g in summary['gaps']] == [0.3]


def test_tdms_text_wf_increment_is_one_line(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    path = tmp_path / 'run.tdms'
    with TdmsWriter(str(path)) as w:
        w.write_segment([GroupObject('daq'),
                         ChannelObject('daq', 'a', np.arange(10.0),
                                       properties={'wf_increment': 'fast'}),
                         ChannelObject('daq', 'b', np.arange(10.0))])
    code = main(['import', str(path), '--bench', str(df.bench_yaml(tmp_path / 'b.yaml')),
                 '--out', str(tmp_path / 'bag'), '--theta-in', 'daq/a', '--theta-out', 'daq/b'])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1
    assert "wf_increment 'fast' is not a positive number of seconds" in err[0]
