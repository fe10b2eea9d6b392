"""StreamingTeAnalyzer: windows equal a one-shot computation, faults counted, bounded memory."""

from __future__ import annotations

import dataclasses
import itertools
import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from rv_te_bench.core.offline import analyze_blocks
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.spectrum import order_spectrum
from rv_te_bench.core.stream import StreamingTeAnalyzer
from rv_te_bench.core.stream_records import EncoderBlockData, TeAnalysisConfig, WindowResult
from rv_te_bench.core.te import te_statistics, transmission_error_rad
from rv_te_bench.core.units import arcmin_to_rad
from rv_te_bench.errors import TeConfigError, TeInputError

RATIO = 79.0
FS_HZ = 4000.0
BLOCK = 1000
OUTPUT_HZ = 1.0  # fast output so that windows are short: ~4000 samples per revolution
ORDERS = OrderSet(gear_ratio=RATIO, crank_per_output=25.0, n_crank_harmonics=3,
                  mesh_orders_out=(250.0,), mesh_labels=('mesh',))
# label -> (order, amplitude rad, phase rad); 250 has 16 samples/period at the top speed
LINES = {'f_out': (1.0, float(arcmin_to_rad(0.8)), 0.4),
         '1 f_w': (25.0, float(arcmin_to_rad(2.0)), -1.0),
         '2 f_w': (50.0, float(arcmin_to_rad(0.3)), 2.9),
         'f_w + f_out': (26.0, float(arcmin_to_rad(0.05)), -2.2),
         'mesh': (250.0, float(arcmin_to_rad(0.1)), 1.3)}
REL = 1e-9  # streaming vs one-shot


def _samples(n: int, speed_variation: float = 0.5) -> dict[str, np.ndarray]:
    t = np.arange(n) / FS_HZ
    w = 2 * math.pi * OUTPUT_HZ * RATIO
    b = 2 * math.pi / 0.37
    theta_in = 0.3 + w * (t + speed_variation * (1 - np.cos(b * t)) / b)
    phi = theta_in / RATIO
    te = np.full(n, 1e-5)
    for order, amp, phase in LINES.values():
        te += amp * np.cos(order * phi + phase)
    return {'t': t, 'theta_in': theta_in, 'theta_out': phi + te}


def _blocks(s: dict[str, np.ndarray], sizes: list[int] | None = None) -> list[EncoderBlockData]:
    n = s['t'].size
    if sizes is None:
        sizes = [BLOCK] * (n // BLOCK)
    edges = np.concatenate([[0], np.cumsum(sizes)])
    out = []
    for seq, (a, b) in enumerate(itertools.pairwise(edges)):
        stamp = float(s['t'][a])
        out.append(EncoderBlockData(seq=seq, stamp_s=stamp, sample_rate_hz=FS_HZ,
                                    time_offset_s=s['t'][a:b] - stamp,
                                    theta_in_rad=s['theta_in'][a:b],
                                    theta_out_rad=s['theta_out'][a:b]))
    return out


def _reference_windows(t: np.ndarray, theta_in: np.ndarray, theta_out: np.ndarray,
                       w_rev: int = 1) -> list[tuple[int, int]]:
    """Independent window cut, one sample at a time: [start, stop) index pairs."""
    phi = theta_in / RATIO
    out, start = [], 0
    for k in range(phi.size):
        if abs(phi[k] - phi[start]) >= 2 * math.pi * w_rev:
            out.append((start, k))
            start = k
    return out


def _assert_window_matches(win: WindowResult, s: dict[str, np.ndarray], a: int, b: int) -> None:
    te = transmission_error_rad(s['theta_in'][a:b], s['theta_out'][a:b], gear_ratio=RATIO)
    ref = te_statistics(te, revolutions=1.0)
    assert win.complete
    assert_allclose([win.start_stamp_s, win.end_stamp_s], [s['t'][a], s['t'][b - 1]],
                    rtol=0, atol=1e-12)  # stamp_s + time_offset_s, equal to rounding
    assert win.stats.n_samples == b - a
    for name in ('pp_rad', 'amplitude_rad', 'mean_rad', 'std_rad', 'revolutions'):
        assert_allclose(getattr(win.stats, name), getattr(ref, name), rtol=REL, err_msg=name)
    spec = order_spectrum(s['theta_in'][a:b] / RATIO, te, ORDERS,
                          duration_s=s['t'][b - 1] - s['t'][a], revolutions=1)
    assert win.spectrum is not None
    assert_allclose(win.spectrum.amplitude_rad, spec.amplitude_rad, rtol=REL, atol=1e-18)
    assert_allclose(win.spectrum.output_hz, spec.output_hz, rtol=REL)
    for ln in win.spectrum.lines:
        if ln.label in LINES:  # and against the injected truth (0.5 %, 1 degree)
            _, amp, phase = LINES[ln.label]
            assert_allclose(ln.amplitude_rad, amp, rtol=5e-3, err_msg=ln.label)
            assert abs((ln.phase_rad - phase + math.pi) % (2 * math.pi) - math.pi) < 0.0175


@pytest.mark.parametrize('sizes', ['uniform', 'ragged'])
def test_streaming_windows_equal_one_shot(sizes: str) -> None:
    s = _samples(20 * BLOCK)
    rng = np.random.default_rng(7)
    block_sizes = None
    if sizes == 'ragged':
        block_sizes = list(rng.integers(1, 2500, 60))
        block_sizes = block_sizes[:int(np.searchsorted(np.cumsum(block_sizes), s['t'].size))]
    blocks = _blocks(s, block_sizes)
    n_used = sum(b.theta_in_rad.size for b in blocks)
    result = analyze_blocks(blocks, TeAnalysisConfig(orders=ORDERS))
    ref = _reference_windows(s['t'][:n_used], s['theta_in'][:n_used], s['theta_out'][:n_used])
    complete = [w for w in result.windows if w.complete]
    assert len(complete) == len(ref) >= 3
    for win, (a, b) in zip(complete, ref, strict=True):
        _assert_window_matches(win, s, a, b)
    last = result.windows[-1]
    assert (last.complete, last.close_reason, last.spectrum) == (False, 'flush', None)
    assert last.stats.n_samples == n_used - ref[-1][1]
    te_all = transmission_error_rad(s['theta_in'][:n_used], s['theta_out'][:n_used],
                                    gear_ratio=RATIO)
    cum = te_statistics(te_all)
    assert result.cumulative.n_samples == n_used
    for name in ('pp_rad', 'amplitude_rad', 'mean_rad', 'std_rad'):
        assert_allclose(getattr(result.cumulative, name), getattr(cum, name), rtol=REL)
    travelled = (s['theta_in'][n_used - 1] - s['theta_in'][0]) / RATIO / (2 * math.pi)
    assert_allclose(result.cumulative.revolutions, travelled, rtol=1e-12)
    assert result.counters['gaps'] == 0
    assert result.counters['samples'] == n_used


def _fault(kind: str, blocks: list[EncoderBlockData], k: int) -> tuple[list, int]:
    """Spoil block k; return the blocks and the sample index where the next window starts."""
    a0 = k * BLOCK
    b = blocks[k]
    if kind == 'seq_jump':
        later = [dataclasses.replace(x, seq=x.seq + 7) for x in blocks[k:]]
        return blocks[:k] + later, a0
    if kind == 'time_backwards':
        back = dataclasses.replace(b, stamp_s=b.stamp_s - 1.0)
        return [*blocks[:k], back, *blocks[k + 1:]], a0
    if kind == 'non_finite':
        bad = b.theta_out_rad.copy()
        bad[17] = math.nan
        return [*blocks[:k], dataclasses.replace(b, theta_out_rad=bad), *blocks[k + 1:]], a0 + BLOCK
    if kind == 'length_mismatch':
        bad = dataclasses.replace(b, theta_in_rad=b.theta_in_rad[:-1])
        return [*blocks[:k], bad, *blocks[k + 1:]], a0 + BLOCK
    assert kind == 'empty'
    empty = EncoderBlockData(seq=b.seq, stamp_s=b.stamp_s, sample_rate_hz=FS_HZ,
                             time_offset_s=np.empty(0), theta_in_rad=np.empty(0),
                             theta_out_rad=np.empty(0))
    shifted = [dataclasses.replace(x, seq=x.seq + 1) for x in blocks[k:]]
    return [*blocks[:k], empty, *shifted], a0


@pytest.mark.parametrize(('kind', 'counter'), [
    ('seq_jump', 'seq_jumps'), ('time_backwards', 'time_backwards'),
    ('non_finite', 'non_finite'), ('length_mismatch', 'malformed'), ('empty', 'malformed')])
def test_fault_counted_and_next_clean_window_correct(kind: str, counter: str) -> None:
    s = _samples(14 * BLOCK)
    blocks, a0 = _fault(kind, _blocks(s), 6)
    analyzer = StreamingTeAnalyzer(TeAnalysisConfig(orders=ORDERS))
    windows, gaps = [], []
    for block in blocks:
        up = analyzer.push(block)  # must not raise
        windows += up.windows
        gaps += up.gaps
    c = analyzer.counters
    assert c['gaps'] == 1
    assert c[counter] == 1
    assert [g.kind for g in gaps] == [kind if counter != 'malformed' else 'malformed']
    assert c['dropped_blocks'] == (1 if counter in ('non_finite', 'malformed') else 0)
    gap_closed = [w for w in windows if w.close_reason == 'gap']
    assert len(gap_closed) == 1
    assert (gap_closed[0].complete, gap_closed[0].spectrum) == (False, None)
    # the window after the fault starts at the first clean sample after it
    after = [w for w in windows if w.complete and w.index > gap_closed[0].index]
    assert after
    ref = _reference_windows(s['t'][a0:], s['theta_in'][a0:], s['theta_out'][a0:])
    a, b = ref[0]
    if kind == 'time_backwards':  # block 6 was used with its stamp moved back by 1 s
        assert_allclose(after[0].start_stamp_s, s['t'][a0] - 1.0, rtol=0, atol=1e-12)
        te = transmission_error_rad(s['theta_in'][a0 + a:a0 + b],
                                    s['theta_out'][a0 + a:a0 + b], gear_ratio=RATIO)
        assert_allclose(after[0].stats.pp_rad, np.ptp(te), rtol=REL)
    else:
        _assert_window_matches(after[0], s, a0 + a, a0 + b)
    dropped = BLOCK if kind in ('non_finite', 'length_mismatch') else 0
    assert c['samples'] == 14 * BLOCK - dropped


def test_garbage_never_raises() -> None:
    analyzer = StreamingTeAnalyzer(TeAnalysisConfig(orders=ORDERS))
    bad: list[Any] = [
        SimpleNamespace(seq='x'),
        SimpleNamespace(seq=0),
        EncoderBlockData(0, 0.0, 1000.0, None, None, None),  # type: ignore[arg-type]
        EncoderBlockData(0, math.nan, 1000.0, np.zeros(2), np.zeros(2), np.zeros(2)),
        EncoderBlockData(0, 10**400, 1000.0, np.zeros(2), np.zeros(2), np.zeros(2)),
        EncoderBlockData(0, 0.0, 1000.0, [[0.0], [1.0, 2.0]], np.zeros(2), np.zeros(2)),  # type: ignore[arg-type]
        EncoderBlockData(0, 0.0, 1000.0, np.arange(2.0), np.full(2, 1e308), np.zeros(2)),
        EncoderBlockData(0, 0.0, 0.0, np.arange(2.0), np.zeros(2), np.zeros(2)),
        EncoderBlockData(0, 0.0, 1000.0, np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2))),
        EncoderBlockData(0, 0.0, 1000.0, np.array([0.0, 0.0]), np.zeros(2), np.zeros(2)),
    ]
    for block in bad:
        up = analyzer.push(block)
        assert up.te_rad.size == 0
        assert [g.kind for g in up.gaps] == ['malformed']
    assert analyzer.counters['malformed'] == len(bad)
    assert analyzer.cumulative.n_samples == 0


@pytest.mark.parametrize(('change', 'match'), [
    ({'time_offset_s': []}, 'array lengths differ'),
    ({'time_offset_s': [], 'theta_in_rad': [], 'theta_out_rad': []}, 'empty block'),
    ({'theta_in_rad': [0.0, math.inf]}, r'theta_in_rad\[1\] is inf'),
    ({'theta_out_rad': [math.nan, 0.0]}, r'theta_out_rad\[0\] is nan'),
    ({'time_offset_s': [0.0, -1.0]}, 'not strictly increasing'),
    ({'sample_rate_hz': -5.0}, 'sample_rate_hz must be finite and > 0'),
    ({'torque_out_nm': [1.0]}, 'torque_out_nm has 1 samples'),
])
def test_checked_names_the_problem(change: dict[str, Any], match: str) -> None:
    kwargs: dict[str, Any] = {'seq': 3, 'stamp_s': 0.0, 'sample_rate_hz': 1000.0,
                              'time_offset_s': [0.0, 0.001], 'theta_in_rad': [0.0, 1.0],
                              'theta_out_rad': [0.0, 0.01]}
    kwargs.update(change)
    with pytest.raises(TeInputError, match=match):
        EncoderBlockData.checked(**kwargs)


def test_decimation_is_phase_continuous_across_blocks() -> None:
    s = _samples(6 * BLOCK)
    sizes = [333, 1000, 17, 1650, 1000, 2000]
    analyzer = StreamingTeAnalyzer(TeAnalysisConfig(orders=ORDERS, decimated_rate_hz=200.0))
    te_d, t_d = [], []
    for block in _blocks(s, sizes):
        up = analyzer.push(block)
        te_d.append(up.te_rad)
        t_d.append(up.time_s)
        assert up.period_s == 20 / FS_HZ
        if up.te_rad.size:
            assert up.stamp_s == up.time_s[0]
    te_all = transmission_error_rad(s['theta_in'], s['theta_out'], gear_ratio=RATIO)
    assert_allclose(np.concatenate(te_d), te_all[::20], rtol=0, atol=0)
    assert_allclose(np.concatenate(t_d), s['t'][::20], rtol=0, atol=1e-12)


def test_stopped_bench_bounded_by_overflow() -> None:
    n = 10 * BLOCK
    still = {'t': np.arange(n) / FS_HZ, 'theta_in': np.full(n, 5.0),
             'theta_out': np.full(n, 5.0 / RATIO)}
    cfg = TeAnalysisConfig(orders=ORDERS, max_window_samples=2500)
    result = analyze_blocks(_blocks(still), cfg)
    overflow = [w for w in result.windows if w.close_reason == 'overflow']
    assert [w.stats.n_samples for w in overflow] == [2500, 2500, 2500]
    assert (result.windows[-1].close_reason, result.windows[-1].stats.n_samples) == ('flush', 2500)
    assert result.counters['complete_windows'] == 0
    assert result.cumulative.pp_rad == 0.0


def test_reconfigure_closes_window_and_resets_on_new_ratio() -> None:
    s = _samples(3 * BLOCK)
    blocks = _blocks(s)
    analyzer = StreamingTeAnalyzer(TeAnalysisConfig(orders=ORDERS))
    analyzer.push(blocks[0])
    analyzer.reconfigure(TeAnalysisConfig(orders=ORDERS, decimated_rate_hz=10.0))
    assert analyzer.cumulative.n_samples == BLOCK  # same ratio: kept
    up = analyzer.push(blocks[1])
    assert [w.close_reason for w in up.windows] == ['reconfigure']
    assert up.windows[0].stats.n_samples == BLOCK
    assert up.te_rad.size == 3  # 4000 Hz / 10 Hz -> samples 0, 400, 800 of 1000
    other = OrderSet(gear_ratio=81.0, crank_per_output=25.0)
    analyzer.reconfigure(TeAnalysisConfig(orders=other))
    assert analyzer.cumulative.n_samples == 0
    assert [w.close_reason for w in analyzer.flush()] == ['reconfigure']


@pytest.mark.parametrize(('kwargs', 'match'), [
    ({'window_revolutions': 0.0}, 'window_revolutions'),
    ({'window_revolutions': 1.5}, 'window_revolutions'),
    ({'window_revolutions': math.nan}, 'window_revolutions'),
    ({'decimated_rate_hz': 0.0}, 'decimated_rate_hz'),
    ({'max_window_samples': 3}, 'max_window_samples'),
    ({'samples_per_rev': 2}, 'samples_per_rev'),
    ({'orders': 79.0}, 'orders must be an OrderSet'),
])
def test_config_validation(kwargs: dict[str, Any], match: str) -> None:
    kwargs = {'orders': ORDERS, **kwargs}
    with pytest.raises(TeConfigError, match=match):
        TeAnalysisConfig(**kwargs)


def test_two_revolution_windows() -> None:
    s = _samples(20 * BLOCK, speed_variation=0.0)  # 5 revolutions
    result = analyze_blocks(_blocks(s), TeAnalysisConfig(orders=ORDERS, window_revolutions=2))
    ref = _reference_windows(s['t'], s['theta_in'], s['theta_out'], w_rev=2)
    complete = [w for w in result.windows if w.complete]
    assert len(complete) == len(ref) >= 2
    for win, (a, b) in zip(complete, ref, strict=True):
        assert win.stats.n_samples == b - a
        assert win.spectrum is not None
        assert win.spectrum.revolutions == 2.0
        assert_allclose(win.spectrum.line('1 f_w').amplitude_rad, LINES['1 f_w'][1], rtol=5e-3)


def test_reversal_inside_window_gives_stats_but_no_spectrum() -> None:
    # forward 0.7 rev, back 0.2 rev, forward again: travel from the start reaches 1 rev
    # (complete window), but TE is not a single-valued function of phi there.
    n = 6000
    u = np.linspace(0.0, 1.0, n)
    phi = 2 * np.pi * np.interp(u, [0.0, 0.4, 0.55, 1.0], [0.0, 0.7, 0.5, 1.3])
    s = {'t': np.arange(n) / FS_HZ, 'theta_in': RATIO * phi, 'theta_out': phi + 1e-4}
    result = analyze_blocks(_blocks(s), TeAnalysisConfig(orders=ORDERS))
    complete = [w for w in result.windows if w.complete]
    assert len(complete) == 1
    assert complete[0].spectrum is None
    assert_allclose(complete[0].stats.mean_rad, 1e-4, rtol=1e-9)


@settings(max_examples=25)
@given(cuts=st.lists(st.integers(1, 9 * BLOCK - 1), max_size=12, unique=True))
def test_windows_do_not_depend_on_block_cuts(cuts: list[int]) -> None:
    s = _SPLIT_SAMPLES
    edges = [0, *sorted(cuts), 9 * BLOCK]
    sizes = list(np.diff(edges))
    one = analyze_blocks(_blocks(s, [9 * BLOCK]), TeAnalysisConfig(orders=ORDERS))
    many = analyze_blocks(_blocks(s, sizes), TeAnalysisConfig(orders=ORDERS))
    assert [(w.stats.n_samples, w.complete) for w in many.windows] == \
        [(w.stats.n_samples, w.complete) for w in one.windows]
    for a, b in zip(many.windows, one.windows, strict=True):
        # stamps are rebuilt as stamp_s + time_offset_s: equal to rounding
        assert_allclose([a.start_stamp_s, a.end_stamp_s], [b.start_stamp_s, b.end_stamp_s],
                        rtol=0, atol=1e-12)
        assert_allclose(a.stats.std_rad, b.stats.std_rad, rtol=REL)
        if a.spectrum is not None:
            assert b.spectrum is not None
            assert_allclose(a.spectrum.amplitude_rad, b.spectrum.amplitude_rad, rtol=REL,
                            atol=1e-18)
    assert_allclose(many.cumulative.std_rad, one.cumulative.std_rad, rtol=REL)


_SPLIT_SAMPLES = _samples(9 * BLOCK)


def test_benchmark_script_quick_run(capsys: pytest.CaptureFixture[str]) -> None:
    # smoke test of benchmarks/bench_te_core.py (numbers not checked: shared machine)
    from tests.benchmark_loader import load_benchmark

    assert load_benchmark('bench_te_core').main(['--quick']) == 0
    rows = [r for r in capsys.readouterr().out.splitlines() if r.startswith('|')]
    assert len(rows) == 7
    assert 'M samples/s' in rows[2]


def test_non_finite_torque_does_not_cost_the_angles() -> None:
    """The TE analysis does not use torque: a NaN torque sample keeps the block."""
    orders = OrderSet(gear_ratio=79.0, crank_per_output=25.0)
    an = StreamingTeAnalyzer(TeAnalysisConfig(orders=orders))
    n = 100
    th = np.linspace(0.0, 1.0, n)
    torque = np.zeros(n)
    torque[3] = np.nan
    upd = an.push(EncoderBlockData(seq=0, stamp_s=0.0, sample_rate_hz=1000.0,
                                   time_offset_s=np.arange(n) / 1000.0, theta_in_rad=th,
                                   theta_out_rad=th / 79.0, torque_out_nm=torque))
    assert upd.gaps == ()
    assert an.counters['blocks'] == 1
    assert an.counters['samples'] == n


def test_cumulative_read_mid_window_matches_the_samples_so_far() -> None:
    """The cumulative statistics fold the open window in when read (issue #23): read after
    every block they equal the statistics of every sample pushed so far, and reading them
    or not gives the same final values (to rounding)."""
    s = _samples(9 * BLOCK + 137)
    blocks = _blocks(s, [BLOCK] * 9 + [137])
    te_all = s['theta_out'] - s['theta_in'] / RATIO
    reading = StreamingTeAnalyzer(TeAnalysisConfig(orders=ORDERS))
    silent = StreamingTeAnalyzer(TeAnalysisConfig(orders=ORDERS))
    pushed = 0
    for k, block in enumerate(blocks):
        reading.push(block)
        silent.push(block)
        pushed += block.theta_in_rad.size
        got = reading.cumulative
        want = te_statistics(te_all[:pushed])
        assert got.n_samples == pushed
        assert (got.pp_rad, got.amplitude_rad) == (want.pp_rad, want.amplitude_rad)
        assert_allclose([got.mean_rad, got.std_rad], [want.mean_rad, want.std_rad], rtol=REL)
        if k == 4:
            reading.cumulative  # noqa: B018 - a second read folds nothing twice
            assert reading.cumulative.n_samples == pushed
    reading.flush()
    silent.flush()
    a, b = reading.cumulative, silent.cumulative
    assert (a.n_samples, a.pp_rad, a.amplitude_rad) == (b.n_samples, b.pp_rad, b.amplitude_rad)
    assert_allclose([a.mean_rad, a.std_rad], [b.mean_rad, b.std_rad], rtol=1e-12)
