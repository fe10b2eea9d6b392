"""push_batch (offline path) gives exactly what pushing the same blocks one by one gives.

The reference is StreamingTeAnalyzer.push, block by block (itself checked against one-shot
computations in test_stream.py). Streams carry random faults: sequence jumps, time going
backwards, NaN in any array, a zero rate, time offsets out of order, blocks of unequal
lengths and empty blocks (the last two cannot be batched: a bag reader hands them over as
single blocks, and so does this test).
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from rv_te_bench.core.offline import analyze_blocks
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.stream import StreamingTeAnalyzer
from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData, TeAnalysisConfig
from rv_te_bench.errors import TeInputError

RATIO = 79.0
FS_HZ = 2000.0
ORDERS = OrderSet(gear_ratio=RATIO, crank_per_output=25.0, n_crank_harmonics=3)
FAULTS = ('ok', 'seq_jump', 'time_backwards', 'nan_in', 'nan_out', 'nan_time', 'zero_rate',
          'offsets_unordered', 'length_mismatch', 'empty')
SINGLE_ONLY = ('length_mismatch', 'empty')


def _stream(sizes: list[int], faults: list[str], direction: float) -> list[EncoderBlockData]:
    """Blocks of a 79:1 reducer turning ~2 output rev/s (+-30 %), with faults applied."""
    n = sum(sizes)
    t = np.arange(n) / FS_HZ
    w = direction * 2 * math.pi * 2.0 * RATIO
    theta_in = 0.7 + w * (t + 0.3 * (1 - np.cos(5.0 * t)) / 5.0)
    phi = theta_in / RATIO
    theta_out = phi + 3e-4 * np.cos(25 * phi + 0.2) + 1e-4 * np.cos(phi)
    edges = np.concatenate([[0], np.cumsum(sizes)])
    out: list[EncoderBlockData] = []
    seq_shift = 0
    for k, (a, b) in enumerate(itertools.pairwise(edges)):
        stamp = float(t[a])
        block = EncoderBlockData(seq=k + seq_shift, stamp_s=stamp, sample_rate_hz=FS_HZ,
                                 time_offset_s=t[a:b] - stamp, theta_in_rad=theta_in[a:b],
                                 theta_out_rad=theta_out[a:b])
        kind = faults[k]
        if kind == 'seq_jump':
            seq_shift += 5
            block = dataclasses.replace(block, seq=k + seq_shift)
        elif kind == 'time_backwards':
            block = dataclasses.replace(block, stamp_s=stamp - 0.5)
        elif kind in ('nan_in', 'nan_out', 'nan_time'):
            field = {'nan_in': 'theta_in_rad', 'nan_out': 'theta_out_rad',
                     'nan_time': 'time_offset_s'}[kind]
            arr = np.array(getattr(block, field))
            arr[arr.size // 2] = math.nan
            block = dataclasses.replace(block, **{field: arr})
        elif kind == 'zero_rate':
            block = dataclasses.replace(block, sample_rate_hz=0.0)
        elif kind == 'offsets_unordered' and b - a >= 2:
            offs = np.array(block.time_offset_s)
            offs[[0, -1]] = offs[[-1, 0]]
            block = dataclasses.replace(block, time_offset_s=offs)
        elif kind == 'length_mismatch' and b - a >= 2:
            block = dataclasses.replace(block, theta_in_rad=block.theta_in_rad[:-1])
        elif kind == 'empty':
            e = np.empty(0)
            block = dataclasses.replace(block, time_offset_s=e, theta_in_rad=e, theta_out_rad=e)
        out.append(block)
    return out


def _group(blocks: list[EncoderBlockData], faults: list[str],
           cuts: set[int]) -> list[EncoderBlockData | EncoderBatch]:
    """Batches of consecutive blocks (cut before the indices in ``cuts``) and single blocks."""
    items: list[EncoderBlockData | EncoderBatch] = []
    run: list[EncoderBlockData] = []
    for k, (block, kind) in enumerate(zip(blocks, faults, strict=True)):
        if run and k in cuts:
            items.append(EncoderBatch.from_blocks(run))
            run = []
        if kind in SINGLE_ONLY:
            if run:
                items.append(EncoderBatch.from_blocks(run))
                run = []
            items.append(block)
        else:
            run.append(block)
    if run:
        items.append(EncoderBatch.from_blocks(run))
    return items


def draw_faulty_stream(data: st.DataObject) -> tuple[list[int], list[str], set[int]]:
    """Block sizes, a fault per block and the batch cuts of a random stream (for _stream
    and _group)."""
    n_blocks = data.draw(st.integers(1, 40), label='n_blocks')
    sizes = data.draw(st.lists(st.integers(1, 400), min_size=n_blocks, max_size=n_blocks),
                      label='sizes')
    faults = data.draw(st.lists(st.sampled_from(FAULTS), min_size=n_blocks,
                                max_size=n_blocks), label='faults')
    cuts = set(data.draw(st.lists(st.integers(1, max(1, n_blocks - 1)), max_size=8),
                         label='cuts'))
    return sizes, faults, cuts


def _window_key(w: object) -> tuple:
    spec = w.spectrum
    lines = None if spec is None else tuple((ln.label, ln.amplitude_rad, ln.phase_rad)
                                            for ln in spec.lines)
    return (w.index, w.start_stamp_s, w.end_stamp_s, w.complete, w.stats, w.first_seq,
            w.last_seq, w.close_reason, lines)


@settings(max_examples=60, deadline=None)
@given(data=st.data(), direction=st.sampled_from([1.0, -1.0]),
       window_revolutions=st.sampled_from([1, 2]),
       max_window_samples=st.sampled_from([2_000_000, 1500]))
def test_push_batch_equals_block_by_block(data: st.DataObject, direction: float,
                                          window_revolutions: int,
                                          max_window_samples: int) -> None:
    sizes, faults, cuts = draw_faulty_stream(data)
    blocks = _stream(sizes, faults, direction)
    config = TeAnalysisConfig(orders=ORDERS, window_revolutions=window_revolutions,
                              max_window_samples=max_window_samples, decimated_rate_hz=170.0)

    ref = StreamingTeAnalyzer(config)
    ref_windows, ref_gaps = [], []
    for block in blocks:
        up = ref.push(block)
        ref_windows += up.windows
        ref_gaps += up.gaps
    fast = StreamingTeAnalyzer(config)
    fast_windows, fast_gaps = [], []
    for item in _group(blocks, faults, cuts):
        up = fast.push_batch(item) if isinstance(item, EncoderBatch) else fast.push(item)
        fast_windows += up.windows
        fast_gaps += up.gaps

    assert fast_gaps == ref_gaps
    assert fast.counters == ref.counters
    assert [_window_key(w) for w in fast_windows] == [_window_key(w) for w in ref_windows]
    a, b = fast.cumulative, ref.cumulative
    assert (a.n_samples, a.pp_rad, a.amplitude_rad) == (b.n_samples, b.pp_rad, b.amplitude_rad)
    assert_allclose([a.mean_rad, a.std_rad, a.revolutions], [b.mean_rad, b.std_rad, b.revolutions],
                    rtol=1e-12, atol=1e-18)
    # the display decimation continues in phase: the next block decimates the same way
    last = blocks[-1]
    n = 37
    nxt = EncoderBlockData(seq=last.seq + 1, stamp_s=float(last.stamp_s) + 1000.0,
                           sample_rate_hz=FS_HZ, time_offset_s=np.arange(n) / FS_HZ,
                           theta_in_rad=np.linspace(0.0, 0.1, n),
                           theta_out_rad=np.linspace(0.0, 0.1, n) / RATIO)
    assert_allclose(fast.push(nxt).time_s, ref.push(nxt).time_s, rtol=0, atol=0)
    assert [_window_key(w) for w in fast.flush()] == [_window_key(w) for w in ref.flush()]


def test_analyze_blocks_on_window_streams_the_windows() -> None:
    blocks = _stream([500] * 30, ['ok'] * 30, 1.0)
    config = TeAnalysisConfig(orders=ORDERS)
    kept = analyze_blocks(blocks, config)
    seen = []
    streamed = analyze_blocks([EncoderBatch.from_blocks(blocks[:13]),
                               EncoderBatch.from_blocks(blocks[13:])], config,
                              on_window=seen.append)
    assert streamed.windows == ()
    assert len(seen) == len(kept.windows) >= 3
    assert [_window_key(w) for w in seen] == [_window_key(w) for w in kept.windows]
    assert streamed.counters == kept.counters


@pytest.mark.parametrize(('kwargs', 'match'), [
    ({'starts': np.array([0, 2, 2])}, 'strictly increasing'),
    ({'starts': np.array([1, 2, 4])}, 'from 0 to 4'),
    ({'seq': np.array([0])}, 'do not fit'),
    ({'theta_out_rad': np.zeros(3)}, 'do not fit'),
    # every array's shape on its own (issue 41 compares them one by one)
    ({'stamp_s': np.zeros(3)}, 'do not fit'),
    ({'sample_rate_hz': np.ones(1)}, 'do not fit'),
    ({'time_offset_s': np.zeros(5)}, 'do not fit'),
    ({'theta_in_rad': np.zeros((2, 2))}, 'do not fit'),
    ({'theta_out_rad': np.zeros((4, 1))}, 'do not fit'),
    ({'seq': np.zeros(0, dtype=np.int64), 'stamp_s': np.zeros(0),
      'sample_rate_hz': np.ones(0), 'starts': np.array([0])}, 'do not fit'),
])
def test_batch_structure_is_checked(kwargs: dict, match: str) -> None:
    good = {'seq': np.array([0, 1]), 'stamp_s': np.zeros(2), 'sample_rate_hz': np.ones(2),
            'starts': np.array([0, 2, 4]), 'time_offset_s': np.zeros(4),
            'theta_in_rad': np.zeros(4), 'theta_out_rad': np.zeros(4)}
    EncoderBatch(**good)
    with pytest.raises(TeInputError, match=match):
        EncoderBatch(**{**good, **kwargs})
