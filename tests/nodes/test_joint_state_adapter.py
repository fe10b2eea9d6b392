"""bench(JointState) -> joint_state_adapter -> TE node over the real middleware.

Own Context and domain id per test (conftest), every node destroyed, every test bounded.

The reference is the EncoderBlock path computed independently of the adapter: the same
simulated unit (same parameters and seed) run through :class:`sim.bench.BenchSimulator`
block by block and analysed by :func:`rv_te_bench.core.offline.analyze_blocks`, which is what
the TE node computes live on the bench's EncoderBlocks (tests/nodes/test_pipeline.py checks
live == offline). The JointState path carries the same float64 encoder readings (quantised
by the simulated RON 886 encoders, resolution 2 pi / 36e6 rad = 1.7e-7 rad), so the window
statistics and spectral lines agree to rounding; asserted within 1e-3 of one encoder
increment (1.7e-10 rad), far inside the quantisation. A wrapped (single-turn) encoder adds
the unwrap's float error, ~1e-13 rad over the session's turns.
"""

from __future__ import annotations

import itertools
import math
import time

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from builtin_interfaces.msg import Time  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import BenchInfo, EncoderBlock, TeSpectrum, TransmissionError  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from rv_te_bench.core.offline import analyze_blocks  # noqa: E402
from rv_te_bench.core.orders import OrderSet  # noqa: E402
from rv_te_bench.core.stream_records import TeAnalysisConfig  # noqa: E402
from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.bench_node import BenchNode, bench_config_from_params  # noqa: E402
from rv_te_bench.nodes.joint_state_adapter import JointStateAdapterNode  # noqa: E402
from rv_te_bench.nodes.te_node import TeNode  # noqa: E402
from tests.nodes.rosutil import spin_for, spin_until, spin_while_progress  # noqa: E402

SPEED_RPM = 2950.0   # 1606.8 samples per output revolution: no window boundary on a sample
RATE_HZ = 1000.0
BLOCK = 100
RESOLUTION_RAD = 2.0 * math.pi / 36e6   # heidenhain-ron886 (sim.encoders)

DESCRIPTION = """\
bench_id: sim-js
preset: wang2020-2kv
sample_rate_hz: 1000.0
block_size: 100
encoders:       # the simulated encoders read the model's shafts: their zeros are 0
  input: {model: heidenhain-ron886, zero_offset_deg: 0.0}
  output: {model: heidenhain-ron886, zero_offset_deg: 0.0}
torque_sensor: {present: true, scale_nm_per_unit: 1.0}
joints: {input: input_joint, output: output_joint}
"""


def bench_values(**extra: object) -> dict[str, object]:
    return {'preset': 'wang2020-2kv', 'te_mode': 'nlte', 'speed_rpm': SPEED_RPM,
            'sample_rate_hz': RATE_HZ, 'block_size': BLOCK, 'duration_output_revs': 2.3,
            'time_mode': 'fast', 'speed_factor': 4.0, 'seed': 7, 'load_nm': 30.0, **extra}



def reference_windows(values: dict[str, object]) -> list:
    """The EncoderBlock path, offline: the same simulated unit's blocks -> windows."""
    from rv_te_bench.nodes.params.bench import BenchParams
    from rv_te_bench.params import params_record
    from sim.bench import BenchSimulator

    sim = BenchSimulator(bench_config_from_params(params_record(BenchParams, values)))
    n_blocks = math.ceil(2.3 * 79.0 / (SPEED_RPM / 60.0) * RATE_HZ / BLOCK) + 1
    data = [_as_data(sim.next_block()) for _ in range(n_blocks)]
    orders = OrderSet.from_bench_info(sim.info)
    return [w for w in analyze_blocks(data, TeAnalysisConfig(orders=orders)).windows
            if w.complete]


def _as_data(b):
    from rv_te_bench.core.stream_records import EncoderBlockData

    return EncoderBlockData(b.seq, b.t0_s, RATE_HZ, b.time_offset_s, b.theta_in_rad,
                            b.theta_out_rad, b.torque_out_nm)


@pytest.mark.timeout(300)   # a backstop: the waits below end when progress stops
@pytest.mark.parametrize(('layout', 'wrap'), [('one_message', False), ('separate', False),
                                              ('one_message', True)])
def test_joint_state_path_equals_encoder_block_path(graph, tmp_path, layout: str,
                                                    wrap: bool) -> None:
    ctx, ex, add = graph
    desc = tmp_path / 'bench.yaml'
    desc.write_text(DESCRIPTION)
    probe = add(rclpy.create_node('probe', context=ctx))
    windows: list[TransmissionError] = []
    spectra: list[TeSpectrum] = []
    blocks: list[EncoderBlock] = []
    infos: list[BenchInfo] = []
    probe.create_subscription(TransmissionError, 'te/statistics', windows.append,
                              qos.LATCHED_QOS)
    probe.create_subscription(TeSpectrum, 'te/spectrum', spectra.append, qos.LATCHED_QOS)
    probe.create_subscription(EncoderBlock, 'bench/encoders', blocks.append, qos.ENCODER_QOS)
    probe.create_subscription(BenchInfo, 'bench/info', infos.append, qos.LATCHED_QOS)
    te = add(TeNode(context=ctx))
    adapter = add(JointStateAdapterNode(context=ctx, parameter_overrides=[
        Parameter('bench_description', value=str(desc)),
        Parameter('wrap', value='both' if wrap else 'none'),
        Parameter('idle_flush_s', value=0.2)]))
    spin_for(ex, 0.5)
    values = bench_values(output='joint_state', joint_state_layout=layout,
                          joint_state_wrap=wrap)
    # The bench, the adapter and the TE node share this thread, where on a real bench they
    # have their own processes and cores: the bench spins on its own executor, and every
    # JointState it sent is taken before it spins again. So its bursts (at most one
    # JointState queue's depth per tick: bench_node's catch-up bound) never meet a backlog,
    # however slowly this machine runs the test; a busy machine once lost 2,101 of 7,400
    # messages here when a 5000-message queue overflowed (tests/nodes/test_qos.py).
    bench = BenchNode(context=ctx, parameter_overrides=[
        Parameter(k, value=v) for k, v in values.items()])
    bench_ex = SingleThreadedExecutor(context=ctx)
    bench_ex.add_node(bench)
    per_sample = 2 if layout == 'separate' else 1
    try:
        end = time.monotonic() + 90.0
        while not bench.finished and time.monotonic() < end:
            sent = bench.joint_states_published * per_sample
            while adapter.assembler.counters['messages'] < sent and time.monotonic() < end:
                ex.spin_once(timeout_sec=0.01)
            bench_ex.spin_once(timeout_sec=0.01)
        assert bench.finished, 'bench did not finish'
    finally:
        bench_ex.shutdown()
        bench.destroy_node()
    n_samples = bench.joint_states_published
    assert spin_while_progress(
        ex, lambda: sum(len(b.theta_in_rad) for b in blocks) == n_samples,
        lambda: (adapter.assembler.counters['messages'], len(blocks)), idle_s=30.0), (
        adapter.assembler.counters, n_samples)
    assert spin_until(ex, lambda: sum(w.window_complete for w in windows) >= 2, 10.0)
    spin_for(ex, 0.3)

    assert adapter.assembler.counters['gaps'] == 0
    assert adapter.drops.total == 0
    assert [b.seq for b in blocks] == list(range(len(blocks)))
    assert te.drops.total == 0
    assert te._gaps_total == 0
    assert len(infos) == 1
    assert infos[0].gear_ratio == pytest.approx(79.0, rel=1e-12)
    # effort -> output torque (the bench's 30 N m load)
    assert np.asarray(blocks[0].torque_out_nm) == pytest.approx(30.0, abs=1e-9)

    ref = reference_windows(bench_values())
    live = [w for w in windows if w.window_complete]
    assert len(live) == len(ref) == 2
    tol = 1e-3 * RESOLUTION_RAD
    for lw, rw in zip(live, ref, strict=True):
        assert lw.window.n_samples == rw.stats.n_samples
        for name in ('pp_rad', 'mean_rad', 'amplitude_rad', 'std_rad'):
            assert getattr(lw.window, name) == pytest.approx(getattr(rw.stats, name),
                                                             abs=tol), name
    assert len(spectra) >= 2
    ref_lines = {ln.label: ln for ln in ref[0].spectrum.lines}
    for ln in spectra[0].lines:
        assert ln.amplitude_rad == pytest.approx(ref_lines[ln.label].amplitude_rad, abs=tol)
    # a real unit with real quantisation: the statistics are not trivially zero
    assert ref[0].stats.pp_rad > 100 * RESOLUTION_RAD


# -- injected faults through a hand-made JointState publisher ------------------------------

def _ramp(n: int, t0_ns: int = 1_700_000_000_000_000_000) -> tuple[list[int], np.ndarray,
                                                                     np.ndarray]:
    k = np.arange(n)
    th_in = 1.0 + 2.0 * math.pi * 5.0 * k / RATE_HZ    # 300 rpm: 0.0314 rad per sample
    return [t0_ns + i * 1_000_000 for i in range(n)], th_in, th_in / 79.0 + 1e-4


def _js(t_ns: int, names: list[str], pos: list[float]) -> JointState:
    m = JointState()
    m.header.stamp = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
    m.name = names
    m.position = pos
    return m


@pytest.mark.timeout(60)
def test_injected_faults_are_reported_gaps_and_nothing_crashes(graph) -> None:
    ctx, ex, add = graph
    probe = add(rclpy.create_node('fault_source', context=ctx))
    pub = probe.create_publisher(JointState, 'joint_states', qos.JOINT_STATE_QOS)
    blocks: list[EncoderBlock] = []
    probe.create_subscription(EncoderBlock, 'bench/encoders', blocks.append, qos.ENCODER_QOS)
    te = add(TeNode(context=ctx, parameter_overrides=[
        Parameter('gear_ratio', value=79.0), Parameter('crank_per_output', value=25.0)]))
    adapter = add(JointStateAdapterNode(context=ctx, parameter_overrides=[
        Parameter('sample_rate_hz', value=RATE_HZ), Parameter('block_size', value=BLOCK),
        Parameter('wrap', value='input'), Parameter('idle_flush_s', value=0.2),
        Parameter('diagnostics_period_s', value=0.2)]))
    from diagnostic_msgs.msg import DiagnosticArray

    diags: list[dict[str, str]] = []
    probe.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: diags.extend({kv.key: kv.value for kv in st.values} for st in m.status
                               if st.hardware_id == 'joint_state_adapter'),
        qos.DIAGNOSTICS_QOS)
    assert spin_until(ex, lambda: pub.get_subscription_count() >= 1, 10.0)

    n = 1000
    stamps, th_in, th_out = _ramp(n)
    wrapped_in = np.mod(th_in, 2.0 * math.pi)   # single-turn absolute input encoder
    names = ['input_joint', 'output_joint']
    skip = set(range(150, 155))                  # stamp jump: 5 samples never sent
    expected = [('stamp_jump', stamps[149], stamps[155]),
                ('missing_joint', stamps[299], stamps[301]),
                ('non_finite', stamps[449], stamps[451]),
                ('stamp_backwards', stamps[599], stamps[600] - 20_000_000),
                ('missing_joint', stamps[749] - 20_000_000, stamps[751] - 20_000_000)]
    kept = []
    for i in range(n):
        if i in skip:
            continue
        t = stamps[i] if i < 600 else stamps[i] - 20_000_000   # the clock steps back 20 ms
        if i == 300:
            msg = _js(t, ['input_joint'], [float(wrapped_in[i])])          # output missing
        elif i == 450:
            msg = _js(t, names, [float(wrapped_in[i]), math.nan])          # NaN position
        elif i == 750:
            msg = _js(t, names, [float(wrapped_in[i])])                    # malformed: short
        else:
            msg = _js(t, names, [float(wrapped_in[i]), float(th_out[i])])
            kept.append(i)
        pub.publish(msg)
        if i % 100 == 99:
            ex.spin_once(timeout_sec=0.0)
    assert spin_until(ex, lambda: sum(len(b.theta_in_rad) for b in blocks) == len(kept)
                      and te._blocks == len(blocks), 20.0), adapter.assembler.counters

    got = [(g.reason, g.stamp_before_ns, g.stamp_after_ns) for g in adapter.recent_gaps]
    assert got == expected
    seqs = [b.seq for b in blocks]
    assert seqs[0] == 0
    assert sum(b - a - 1 for a, b in itertools.pairwise(seqs)) == len(expected)  # one skip per gap
    # the TE node saw every one of them as a seq jump (the stepped-back clock also as time
    # going backwards), and dropped nothing as malformed
    counters = te.analyzer.counters
    assert (counters['seq_jumps'], counters['time_backwards']) == (len(expected), 1)
    assert counters['malformed'] == counters['non_finite'] == 0
    assert te.drops.total == 0
    assert adapter.drops.total == 0
    # the wrapped input encoder came out unwrapped, continuous across the gaps
    th = np.concatenate([np.asarray(b.theta_in_rad) for b in blocks])
    np.testing.assert_allclose(th, th_in[kept], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.concatenate([np.asarray(b.theta_out_rad) for b in blocks]),
                               th_out[kept], rtol=0, atol=0)
    # the adapter's diagnostics carry the gaps by reason
    assert spin_until(ex, lambda: bool(diags) and diags[-1].get('gaps') == '5', 5.0), diags[-1:]
    assert (diags[-1]['stamp_jump'], diags[-1]['missing_joint'], diags[-1]['non_finite'],
            diags[-1]['stamp_backwards']) == ('1', '2', '1', '1')
    assert diags[-1]['last_gap_reason'] == 'missing_joint'
    # the node keeps running after all of it
    more = _js(stamps[-1] + 1_000_000 - 20_000_000, names, [0.0, 0.0])
    pub.publish(more)
    spin_for(ex, 0.2)
    assert adapter.assembler.counters['messages'] == n - len(skip) + 1


@pytest.mark.timeout(30)
@pytest.mark.parametrize(('name', 'value', 'needle'), [
    ('wrap', 'sometimes', 'wrap'),
    ('block_size', -1, 'block_size'),
    ('position_unit', 'deg', 'position_unit'),
])
def test_bad_adapter_parameter_stops_start_up(ros_context, name: str, value: object,
                                              needle: str) -> None:
    from rclpy.exceptions import InvalidParameterValueException

    with pytest.raises(InvalidParameterValueException, match=needle):
        JointStateAdapterNode(context=ros_context, parameter_overrides=[
            Parameter('sample_rate_hz', value=RATE_HZ), Parameter(name, value=value)])


@pytest.mark.timeout(30)
@pytest.mark.parametrize(('overrides', 'needle'), [
    ({}, 'sample_rate_hz is 0 and no bench_description gives it'),
    ({'sample_rate_hz': RATE_HZ, 'position_unit': 'counts'},
     'position_unit counts needs counts_per_rev_in > 0'),
    ({'sample_rate_hz': RATE_HZ, 'pairing_tolerance_s': 0.001}, 'pairing_tolerance_s'),
    ({'bench_description': '/nonexistent/bench.yaml'}, '/nonexistent/bench.yaml'),
])
def test_bad_adapter_combination_is_one_clear_error(ros_context, overrides: dict[str, object],
                                                    needle: str) -> None:
    from rv_te_bench.errors import RvTeError

    with pytest.raises(RvTeError) as info:
        JointStateAdapterNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in overrides.items()])
    assert needle in str(info.value)
    assert '\n' not in str(info.value)


@pytest.mark.timeout(300)   # a backstop: the waits below end when progress stops
def test_joint_states_to_recorded_bag_analysed_with_the_gap(graph, tmp_path) -> None:
    """JointState -> adapter -> TE node + recorder -> bag -> rv-te analyze's core: the
    injected stamp jump is a seq_jump in the bag's analysis, not a splice."""
    from rv_te_bench.nodes.recorder import RecorderNode
    from rv_te_bench.report.analysis import analyze_bag

    ctx, ex, add = graph
    desc = tmp_path / 'bench.yaml'
    desc.write_text(DESCRIPTION)
    src = add(rclpy.create_node('js_source', context=ctx))
    pub = src.create_publisher(JointState, 'joint_states', qos.JOINT_STATE_QOS)
    stats: list[TransmissionError] = []
    src.create_subscription(TransmissionError, 'te/statistics', stats.append, qos.LATCHED_QOS)
    te = add(TeNode(context=ctx))
    adapter = add(JointStateAdapterNode(context=ctx, parameter_overrides=[
        Parameter('bench_description', value=str(desc)), Parameter('idle_flush_s', value=0.2)]))
    recorder = RecorderNode(context=ctx, parameter_overrides=[
        Parameter('output_dir', value=str(tmp_path)), Parameter('bag_name', value='bag'),
        Parameter('discovery_period_s', value=0.1),
        Parameter('topics', value=['bench/encoders', 'bench/info', 'te/statistics'])])
    ex.add_node(recorder)
    try:
        assert spin_until(ex, lambda: pub.get_subscription_count() >= 1
                          and adapter.pub_blocks.get_subscription_count() >= 2, 15.0)
        spin_for(ex, 0.5)
        n = 4000                                     # 2.5 output revolutions at 300 rpm in
        stamps, th_in, th_out = _ramp(n)
        th_in, th_out = th_in * 10.0, th_out * 10.0   # 3000 rpm: 1580 samples per rev
        skip = set(range(2000, 2003))
        for i in range(n):
            if i not in skip:
                pub.publish(_js(stamps[i], ['input_joint', 'output_joint'],
                                [float(th_in[i]), float(th_out[i])]))
            if i % 50 == 49:
                ex.spin_once(timeout_sec=0.0)
        assert spin_while_progress(
            ex, lambda: adapter.assembler.counters['samples'] == n - len(skip)
            and te._blocks == adapter.blocks_published,
            lambda: (adapter.assembler.counters['messages'], te._blocks), idle_s=20.0), \
            adapter.assembler.counters
        spin_for(ex, 1.5)   # the recorder flushes
    finally:
        ex.remove_node(recorder)
        recorder.destroy_node()
    assert [g.reason for g in adapter.recent_gaps] == ['stamp_jump']
    assert te.analyzer.counters['seq_jumps'] == 1
    result = analyze_bag(tmp_path / 'bag', with_advice=False)
    assert [g.kind for g in result.gaps] == ['seq_jump']
    assert result.counters['samples'] == n - len(skip)
    assert result.counters['seq_jumps'] == 1


@pytest.mark.timeout(60)
def test_first_blocks_held_until_the_session_subscribers_are_up(graph) -> None:
    ctx, ex, add = graph
    src = add(rclpy.create_node('js_source', context=ctx))
    pub = src.create_publisher(JointState, 'joint_states', qos.JOINT_STATE_QOS)
    adapter = add(JointStateAdapterNode(context=ctx, parameter_overrides=[
        Parameter('sample_rate_hz', value=RATE_HZ), Parameter('block_size', value=BLOCK),
        Parameter('wait_for_nodes', value=['late_te'])]))
    assert spin_until(ex, lambda: pub.get_subscription_count() >= 1, 10.0)
    stamps, th_in, th_out = _ramp(350)
    for i in range(350):
        pub.publish(_js(stamps[i], ['input_joint', 'output_joint'],
                        [float(th_in[i]), float(th_out[i])]))
    assert spin_until(ex, lambda: adapter.assembler.counters['blocks'] == 3, 10.0)
    assert adapter.blocks_published == 0          # held: nobody of the session listens yet
    blocks: list[EncoderBlock] = []
    late = add(rclpy.create_node('late_te', context=ctx))
    late.create_subscription(EncoderBlock, 'bench/encoders', blocks.append, qos.ENCODER_QOS)
    assert spin_until(ex, lambda: len(blocks) >= 3, 10.0)
    assert [b.seq for b in blocks[:3]] == [0, 1, 2]


@pytest.mark.timeout(60)
def test_first_blocks_held_until_the_recorder_takes_the_channels(graph, tmp_path) -> None:
    """With loss channels, the adapter holds its first blocks until the session's recorder
    has bench/channels too (it subscribes to each topic as it finds it): every block the
    recorder gets has its channels. Before, the blocks left once the recorder had
    bench/encoders, and a bag lacked the first 24 blocks' channels (rv-te unit-report then
    found no temperature rise that the live test had measured)."""
    from rv_te_msgs.msg import BenchChannels

    from tests.nodes.real_bench import LOSS_DESCRIPTION

    desc = tmp_path / 'bench.yaml'
    desc.write_text(LOSS_DESCRIPTION, encoding='utf-8')
    ctx, ex, add = graph
    src = add(rclpy.create_node('js_source', context=ctx))
    pub = src.create_publisher(JointState, 'joint_states', qos.JOINT_STATE_QOS)
    adapter = add(JointStateAdapterNode(context=ctx, parameter_overrides=[
        Parameter('bench_description', value=str(desc)),
        Parameter('wait_for_nodes', value=['recorder'])]))
    assert adapter.pub_channels is not None
    assert spin_until(ex, lambda: pub.get_subscription_count() >= 1, 10.0)
    rate = adapter.config.sample_rate_hz
    n = 3 * adapter.config.block_size + 50
    stamps = [1_700_000_000_000_000_000 + round(i * 1e9 / rate) for i in range(n)]
    for i in range(n):
        pub.publish(_js(stamps[i], ['input_joint', 'output_joint'], [1e-3 * i, 1e-5 * i]))
    assert spin_until(ex, lambda: adapter.assembler.counters['blocks'] == 3, 10.0)
    rec = add(rclpy.create_node('recorder', context=ctx))
    blocks: list[EncoderBlock] = []
    chans: list[BenchChannels] = []
    rec.create_subscription(EncoderBlock, 'bench/encoders', blocks.append, qos.ENCODER_QOS)
    spin_for(ex, 1.5)     # the recorder has bench/encoders only: still held
    assert adapter.blocks_published == 0 and not blocks
    assert adapter.busy   # (a stop now waits for the recorder: run_node's work under way)
    rec.create_subscription(BenchChannels, 'bench/channels', chans.append, qos.ENCODER_QOS)
    assert spin_until(ex, lambda: len(blocks) >= 3 and len(chans) >= 3, 10.0)
    assert [b.seq for b in blocks[:3]] == [c.seq for c in chans[:3]] == [0, 1, 2]
    assert not adapter.busy


@pytest.mark.timeout(30)
@pytest.mark.parametrize(('name', 'value', 'needle'), [
    ('output', 'joint_states', 'output'),
    ('joint_state_names', ['input_joint', 'input_joint'], 'two different non-empty joint names'),
    ('joint_state_layout', 'split', 'joint_state_layout'),
])
def test_bad_bench_joint_state_parameter_stops_start_up(ros_context, name: str,
                                                        value: object, needle: str) -> None:
    from rclpy.exceptions import InvalidParameterValueException

    with pytest.raises(InvalidParameterValueException, match=needle):
        BenchNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])
