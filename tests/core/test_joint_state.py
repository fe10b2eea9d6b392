"""JointState assembler: closed-form ramps in, expected blocks and gaps out (no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from rv_te_bench.core.joint_state import (
    JointStateAssembler,
    JointStateBlock,
    JointStateConfig,
    JointStateGap,
)
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.stream import StreamingTeAnalyzer
from rv_te_bench.core.stream_records import TeAnalysisConfig
from rv_te_bench.errors import TeConfigError

RATE_HZ = 1000.0
PERIOD_NS = 1_000_000
T0_NS = 1_700_000_000_000_000_000   # a wall-clock epoch stamp: float seconds lose ns here
RATIO = 79.0
W_IN = 2.0 * math.pi * 5.0          # 300 rpm input [rad/s]


def cfg(**kw: object) -> JointStateConfig:
    base: dict[str, object] = {'input_joint': 'input_joint', 'output_joint': 'output_joint',
                               'sample_rate_hz': RATE_HZ, 'block_size': 100}
    base.update(kw)
    return JointStateConfig(**base)  # type: ignore[arg-type]


def ramp(n: int, w: float = W_IN, theta0: float = 0.25) -> tuple[np.ndarray, np.ndarray,
                                                                   np.ndarray]:
    """Stamps [ns], input and output angle of a constant-speed ideal reducer."""
    k = np.arange(n)
    th_in = theta0 + w * k / RATE_HZ
    return T0_NS + k * PERIOD_NS, th_in, th_in / RATIO


def feed(asm: JointStateAssembler, stamps: np.ndarray, th_in: np.ndarray, th_out: np.ndarray,
         *, skip: set[int] = frozenset(), effort: np.ndarray | None = None,
         ) -> list[JointStateBlock | JointStateGap]:
    out: list[JointStateBlock | JointStateGap] = []
    names = ['output_joint', 'input_joint']   # any order
    for i in range(len(stamps)):
        if i in skip:
            continue
        eff = [] if effort is None else [float(effort[i]), 0.0]
        out.extend(asm.push(int(stamps[i]), names, [float(th_out[i]), float(th_in[i])], eff))
    out.extend(asm.finish())
    return out


def blocks_of(items: list[JointStateBlock | JointStateGap]) -> list[JointStateBlock]:
    return [b for b in items if isinstance(b, JointStateBlock)]


def gaps_of(items: list[JointStateBlock | JointStateGap]) -> list[JointStateGap]:
    return [g for g in items if isinstance(g, JointStateGap)]


def cat(blocks: list[JointStateBlock], name: str) -> np.ndarray:
    return np.concatenate([getattr(b, name) for b in blocks])


def test_ramp_in_one_message_gives_contiguous_blocks() -> None:
    stamps, th_in, th_out = ramp(1000)
    items = feed(JointStateAssembler(cfg()), stamps, th_in, th_out)
    blocks = blocks_of(items)
    assert not gaps_of(items)
    assert [b.seq for b in blocks] == list(range(10))
    assert all(len(b.theta_in_rad) == 100 for b in blocks)
    assert blocks[3].stamp_ns == T0_NS + 300 * PERIOD_NS   # exact integer stamp
    assert_allclose(blocks[3].time_offset_s, np.arange(100) * 1e-3, rtol=0, atol=1e-15)
    assert_array_equal(cat(blocks, 'theta_in_rad'), th_in)
    assert_array_equal(cat(blocks, 'theta_out_rad'), th_out)
    assert blocks[0].torque_out_nm.size == 0
    assert not blocks[0].theta_in_rad.flags.writeable


@pytest.mark.parametrize('out_first', [False, True])
def test_separate_messages_paired_within_tolerance(out_first: bool) -> None:
    stamps, th_in, th_out = ramp(450)
    asm = JointStateAssembler(cfg(pairing_tolerance_s=100e-6))
    items: list[JointStateBlock | JointStateGap] = []
    for i in range(450):
        msgs = [(int(stamps[i]), ['input_joint'], [float(th_in[i])]),
                (int(stamps[i]) + 60_000, ['output_joint'], [float(th_out[i])])]  # 60 us later
        for m in (msgs[::-1] if out_first else msgs):
            items.extend(asm.push(*m))
    items.extend(asm.finish())
    assert not gaps_of(items)
    blocks = blocks_of(items)
    assert [len(b.theta_in_rad) for b in blocks] == [100] * 4 + [50]
    assert blocks[0].stamp_ns == T0_NS   # the input joint's stamp
    assert_array_equal(cat(blocks, 'theta_in_rad'), th_in)
    assert_array_equal(cat(blocks, 'theta_out_rad'), th_out)


def test_separate_messages_reordered_between_joints() -> None:
    """All input halves of 5 samples first, then the output halves: still paired."""
    stamps, th_in, th_out = ramp(200)
    asm = JointStateAssembler(cfg(max_unpaired=8))
    items: list[JointStateBlock | JointStateGap] = []
    for j in range(0, 200, 5):
        for i in range(j, j + 5):
            items.extend(asm.push(int(stamps[i]), ['input_joint'], [th_in[i]]))
        for i in range(j, j + 5):
            items.extend(asm.push(int(stamps[i]), ['output_joint'], [th_out[i]]))
    items.extend(asm.finish())
    assert not gaps_of(items)
    assert_array_equal(cat(blocks_of(items), 'theta_out_rad'), th_out)


def test_stamp_jump_closes_the_block_and_skips_one_seq() -> None:
    stamps, th_in, th_out = ramp(1000)
    items = feed(JointStateAssembler(cfg()), stamps, th_in, th_out, skip=set(range(250, 255)))
    (gap,) = gaps_of(items)
    assert gap.reason == 'stamp_jump'
    assert gap.stamp_before_ns == stamps[249]
    assert gap.stamp_after_ns == stamps[255]
    assert (gap.samples_missing, gap.samples_dropped) == (5, 0)
    blocks = blocks_of(items)
    assert [b.seq for b in blocks][:5] == [0, 1, 2, 4, 5]
    assert len(blocks[2].theta_in_rad) == 50          # closed early at the gap, not spliced
    assert blocks[3].stamp_ns == stamps[255]
    assert gap.seq_after == 4
    assert items.index(gap) == items.index(blocks[2]) + 1   # in stream order


def test_one_missing_sample_is_a_gap_but_jitter_is_not() -> None:
    stamps, th_in, th_out = ramp(300)
    # +-0.2 period: steps 0.6-1.4
    jitter = stamps + np.where(np.arange(300) % 2 == 0, 200_000, -200_000)
    jitter[0] = stamps[0]
    items = feed(JointStateAssembler(cfg()), jitter, th_in, th_out)
    assert not gaps_of(items)
    items = feed(JointStateAssembler(cfg()), stamps, th_in, th_out, skip={150})  # 2 periods
    (gap,) = gaps_of(items)
    assert (gap.reason, gap.samples_missing) == ('stamp_jump', 1)


def test_stamp_backwards_is_a_gap_and_the_stream_goes_on() -> None:
    stamps, th_in, th_out = ramp(400)
    stamps = stamps.copy()
    stamps[200:] -= 10 * PERIOD_NS   # the DAQ clock stepped back 10 ms
    items = feed(JointStateAssembler(cfg()), stamps, th_in, th_out)
    (gap,) = gaps_of(items)
    assert gap.reason == 'stamp_backwards'
    assert (gap.stamp_before_ns, gap.stamp_after_ns) == (stamps[199], stamps[200])
    assert (gap.samples_missing, gap.samples_dropped) == (0, 0)
    assert [b.seq for b in blocks_of(items)] == [0, 1, 3, 4]
    assert_array_equal(cat(blocks_of(items), 'theta_in_rad'), th_in)


def test_missing_joint_and_nan_drop_the_sample_and_report_it() -> None:
    stamps, th_in, th_out = ramp(600)
    asm = JointStateAssembler(cfg())
    items: list[JointStateBlock | JointStateGap] = []
    for i in range(600):
        names, pos = ['input_joint', 'output_joint'], [th_in[i], th_out[i]]
        if i == 300:
            names, pos = ['input_joint'], [th_in[i]]              # output joint missing
        if i == 450:
            pos = [th_in[i], math.nan]                            # non-finite position
        items.extend(asm.push(int(stamps[i]), names, pos))
    items.extend(asm.finish())
    g1, g2 = gaps_of(items)
    assert (g1.reason, g1.stamp_before_ns, g1.stamp_after_ns) == (
        'missing_joint', stamps[299], stamps[301])
    assert (g1.samples_dropped, g1.samples_missing) == (1, 0)
    assert (g2.reason, g2.samples_dropped) == ('non_finite', 1)
    assert (g2.stamp_before_ns, g2.stamp_after_ns) == (stamps[449], stamps[451])
    kept = np.setdiff1d(np.arange(600), [300, 450])
    assert_array_equal(cat(blocks_of(items), 'theta_out_rad'), th_out[kept])
    assert [b.seq for b in blocks_of(items)] == [0, 1, 2, 4, 5, 7, 8]
    assert asm.counters['missing_joint'] == 1
    assert asm.counters['non_finite'] == 1
    assert asm.counters['stamp_jump'] == 0   # the step over a dropped sample is not another
    assert asm.counters['gaps'] == 2


def test_problems_in_a_row_make_one_gap() -> None:
    stamps, th_in, th_out = ramp(300)
    th_out = th_out.copy()
    th_out[100:110] = np.inf
    items = feed(JointStateAssembler(cfg()), stamps, th_in, th_out, skip=set(range(110, 120)))
    (gap,) = gaps_of(items)
    assert (gap.reason, gap.samples_dropped, gap.samples_missing) == ('non_finite', 10, 10)


def test_stream_ending_in_a_gap_reports_it() -> None:
    stamps, th_in, th_out = ramp(150)
    th_in = th_in.copy()
    th_in[140:] = math.nan
    items = feed(JointStateAssembler(cfg()), stamps, th_in, th_out)
    gap = items[-1]
    assert isinstance(gap, JointStateGap)
    assert (gap.stamp_before_ns, gap.stamp_after_ns, gap.samples_dropped) == (
        stamps[139], None, 10)


@pytest.mark.parametrize('w', [W_IN, -W_IN])          # both directions of rotation
@pytest.mark.parametrize('centred', [False, True])    # [0, 2 pi) or [-pi, pi)
def test_wrapped_absolute_encoder_is_unwrapped(w: float, centred: bool) -> None:
    stamps, th_in, th_out = ramp(3000, w=w, theta0=1.0)   # 15 input turns, 3 gaps of blocks
    shift = math.pi if centred else 0.0
    wrapped_in = np.mod(th_in + shift, 2 * math.pi) - shift
    wrapped_out = np.mod(th_out + shift, 2 * math.pi) - shift
    items = feed(JointStateAssembler(cfg(wrap_in=True, wrap_out=True)), stamps, wrapped_in,
                 wrapped_out, skip={777, 1500})
    assert [g.reason for g in gaps_of(items)] == ['stamp_jump', 'stamp_jump']
    kept = np.setdiff1d(np.arange(3000), [777, 1500])
    assert_allclose(cat(blocks_of(items), 'theta_in_rad'), th_in[kept], rtol=0, atol=1e-12)
    assert_allclose(cat(blocks_of(items), 'theta_out_rad'), th_out[kept], rtol=0, atol=1e-12)


def test_raw_counts_scaled_and_wrapped() -> None:
    cpr = 2**17
    stamps, th_in, th_out = ramp(1000, w=-W_IN, theta0=3.0)
    c_in = np.round(th_in / (2 * math.pi) * cpr)
    c_out = np.round(th_out / (2 * math.pi) * cpr)
    items = feed(JointStateAssembler(cfg(position_unit='counts', counts_per_rev_in=cpr,
                                         counts_per_rev_out=cpr, wrap_in=True,
                                         wrap_out=True)),
                 stamps, np.mod(c_in, cpr), np.mod(c_out, cpr))
    assert_allclose(cat(blocks_of(items), 'theta_in_rad'), c_in * 2 * math.pi / cpr,
                    rtol=0, atol=1e-12)
    assert_allclose(cat(blocks_of(items), 'theta_out_rad'), c_out * 2 * math.pi / cpr,
                    rtol=0, atol=1e-12)


def test_raw_counts_of_different_encoders_and_one_wrapped() -> None:
    """Multi-turn incremental input counter, single-turn 32-bit absolute output."""
    stamps, th_in, th_out = ramp(500, theta0=3.0)
    cpr_in, cpr_out = 36000 * 4, 2**32
    c_in = np.round(th_in / (2 * math.pi) * cpr_in)          # keeps counting
    c_out = np.round(th_out / (2 * math.pi) * cpr_out)
    items = feed(JointStateAssembler(cfg(position_unit='counts', counts_per_rev_in=cpr_in,
                                         counts_per_rev_out=cpr_out, wrap_out=True)),
                 stamps, c_in, np.mod(c_out, cpr_out))
    assert_allclose(cat(blocks_of(items), 'theta_in_rad'), c_in * 2 * math.pi / cpr_in,
                    rtol=0, atol=1e-12)
    assert_allclose(cat(blocks_of(items), 'theta_out_rad'), c_out * 2 * math.pi / cpr_out,
                    rtol=0, atol=1e-12)


def test_effort_scaled_to_output_torque() -> None:
    stamps, th_in, th_out = ramp(200)
    effort = np.linspace(-5.0, 5.0, 200)
    items = feed(JointStateAssembler(cfg(effort_scale=12.5)), stamps, th_in, th_out,
                 effort=effort)
    assert_allclose(cat(blocks_of(items), 'torque_out_nm'), effort * 12.5, rtol=1e-15)


@pytest.mark.parametrize('separate', [False, True])
def test_drive_joint_effort_is_the_input_torque(separate: bool) -> None:
    """Issue 38: the drive joint's effort x input_effort_scale is the input torque, sample
    for sample, whether both joints share a message or come in their own."""
    stamps, th_in, th_out = ramp(250)
    e_in = 0.3 + 1e-3 * np.arange(250)
    e_out = -np.linspace(0.0, 40.0, 250)
    asm = JointStateAssembler(cfg(effort_scale=-1.0, input_effort_scale=2.0,
                                  pairing_tolerance_s=100e-6))
    items: list[JointStateBlock | JointStateGap] = []
    for i in range(250):
        if separate:
            items.extend(asm.push(int(stamps[i]), ['input_joint'], [float(th_in[i])],
                                  [float(e_in[i])]))
            items.extend(asm.push(int(stamps[i]) + 50_000, ['output_joint'],
                                  [float(th_out[i])], [float(e_out[i])]))
        else:
            items.extend(asm.push(int(stamps[i]), ['input_joint', 'output_joint'],
                                  [float(th_in[i]), float(th_out[i])],
                                  [float(e_in[i]), float(e_out[i])]))
    items.extend(asm.finish())
    blocks = blocks_of(items)
    assert_array_equal(cat(blocks, 'torque_in_nm'), e_in * 2.0)
    assert_array_equal(cat(blocks, 'torque_out_nm'), -e_out)
    # without the scale there is no input torque (an empty array, as before)
    (b, *_) = blocks_of(feed(JointStateAssembler(cfg()), stamps, th_in, th_out))
    assert b.torque_in_nm.size == 0


def test_unrelated_messages_are_ignored() -> None:
    asm = JointStateAssembler(cfg())
    assert asm.push(T0_NS, ['gripper'], [0.3]) == ()
    assert asm.counters['ignored_messages'] == 1
    assert asm.finish() == ()


def test_malformed_message_is_a_missing_joint_not_an_exception() -> None:
    asm = JointStateAssembler(cfg())
    asm.push(T0_NS, ['input_joint', 'output_joint'], [0.0, 0.0])
    (first,) = asm.push(T0_NS + PERIOD_NS, ['input_joint', 'output_joint'], [])  # no positions
    assert isinstance(first, JointStateBlock)   # the problem closed the open block
    assert len(first.theta_in_rad) == 1
    asm.push(T0_NS + 2 * PERIOD_NS, ['input_joint', 'output_joint'], ['x', 0.0])
    items = asm.push(T0_NS + 3 * PERIOD_NS, ['input_joint', 'output_joint'], [0.1, 0.001])
    items += asm.finish()
    gaps = gaps_of(list(items))
    assert [(g.reason, g.samples_dropped) for g in gaps] == [('missing_joint', 2)]


def test_a_gap_reaches_the_te_core_as_a_seq_jump() -> None:
    """The adapter's contract with the TE node / analyze: no silent splice."""
    stamps, th_in, th_out = ramp(2000)
    items = feed(JointStateAssembler(cfg()), stamps, th_in, th_out, skip=set(range(900, 960)))
    analyzer = StreamingTeAnalyzer(TeAnalysisConfig(
        orders=OrderSet(gear_ratio=RATIO, crank_per_output=25.0), window_revolutions=1.0))
    kinds = [g.kind for b in blocks_of(items)
             for g in analyzer.push(b.to_encoder_block_data()).gaps]
    assert kinds == ['seq_jump']


@pytest.mark.parametrize(('kw', 'fragment'), [
    ({'input_joint': ''}, "input_joint must be a non-empty joint name, got ''"),
    ({'output_joint': 'input_joint'}, "both are 'input_joint'"),
    ({'sample_rate_hz': 0.0}, 'sample_rate_hz must be finite and > 0, got 0.0'),
    ({'sample_rate_hz': math.nan}, 'got nan'),
    ({'block_size': 0}, 'block_size must be an integer >= 1, got 0'),
    ({'position_unit': 'deg'}, "position_unit must be 'rad' or 'counts', got 'deg'"),
    ({'position_unit': 'counts', 'counts_per_rev_in': 4096.0},
     'counts_per_rev_out must be finite and > 0'),
    ({'counts_per_rev_in': 4096.0}, "with 'rad' it must be 0, got 4096.0"),
    ({'effort_scale': math.inf}, 'effort_scale must be finite, got inf'),
    ({'pairing_tolerance_s': 0.0005}, 'below half a sample period (0.0005 s at 1000 Hz), '
                                      'got 0.0005'),
    ({'max_unpaired': 0}, 'max_unpaired must be an integer >= 1, got 0'),
])
def test_bad_config_named(kw: dict[str, object], fragment: str) -> None:
    with pytest.raises(TeConfigError, match=None) as info:
        cfg(**kw)
    assert fragment in str(info.value)


@given(drops=st.sets(st.integers(1, 498), max_size=40),
       block_size=st.integers(1, 64), w=st.sampled_from([W_IN, -W_IN, 0.3]))
def test_property_blocks_keep_every_sample_and_each_gap_skips_one_seq(
        drops: set[int], block_size: int, w: float) -> None:
    stamps, th_in, th_out = ramp(500, w=w)
    items = feed(JointStateAssembler(cfg(block_size=block_size)), stamps, th_in, th_out,
                 skip=drops)
    kept = np.setdiff1d(np.arange(500), sorted(drops))
    blocks, gaps = blocks_of(items), gaps_of(items)
    runs = sum(1 for d in drops if d - 1 not in drops)   # each run of dropped samples
    assert len(gaps) == runs
    assert sum(g.samples_missing for g in gaps) == len(drops)
    assert_array_equal(cat(blocks, 'theta_in_rad'), th_in[kept])
    times = np.concatenate([b.stamp_ns + np.round(b.time_offset_s * 1e9).astype(np.int64)
                            for b in blocks])
    assert_array_equal(times, stamps[kept])
    seqs = np.array([b.seq for b in blocks])
    assert seqs[0] == 0
    assert int(np.sum(np.diff(seqs) - 1)) == runs
    assert all(len(b.theta_in_rad) <= block_size for b in blocks)
