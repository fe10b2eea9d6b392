"""Bench node -> TE node over the real middleware (own context, own domain id).

Expected values are independent of the nodes: the test collects the very blocks the bench
published and runs the core offline on them, and checks Eq. 22 against the model's TE.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import BenchInfo, EncoderBlock, TeSpectrum, TransmissionError  # noqa: E402

from rv_te_bench.core.offline import analyze_blocks  # noqa: E402
from rv_te_bench.core.orders import OrderSet  # noqa: E402
from rv_te_bench.core.stream_records import TeAnalysisConfig  # noqa: E402
from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.bench_node import BenchNode  # noqa: E402
from rv_te_bench.nodes.convert import encoder_block_to_data  # noqa: E402
from rv_te_bench.nodes.te_node import TeNode  # noqa: E402
from sim.bench_info import BenchInfoData  # noqa: E402
from tests.nodes.rosutil import spin_for, spin_until  # noqa: E402

SPEED_RPM = 3000.0          # one output revolution of wang2020-2kv = 1.58 s simulated
RATE_HZ = 2000.0
BLOCK = 100


def bench_params(**extra: object) -> list[Parameter]:
    values = {'preset': 'wang2020-2kv', 'te_mode': 'nlte', 'speed_rpm': SPEED_RPM,
              'encoder_in': 'ideal', 'encoder_out': 'ideal', 'sample_rate_hz': RATE_HZ,
              'block_size': BLOCK, 'duration_output_revs': 2.3, 'time_mode': 'fast',
              'speed_factor': 10.0, 'seed': 3, **extra}
    return [Parameter(k, value=v) for k, v in values.items()]



def test_bench_to_te_node_live_equals_offline(graph) -> None:
    ctx, ex, add = graph
    probe = add(rclpy.create_node('probe', context=ctx))
    blocks: list[EncoderBlock] = []
    windows: list[TransmissionError] = []
    spectra: list[TeSpectrum] = []
    probe.create_subscription(EncoderBlock, 'bench/encoders', blocks.append, qos.ENCODER_QOS)
    probe.create_subscription(TransmissionError, 'te/statistics', windows.append,
                              qos.LATCHED_QOS)
    probe.create_subscription(TeSpectrum, 'te/spectrum', spectra.append, qos.LATCHED_QOS)
    te = add(TeNode(context=ctx))
    spin_for(ex, 0.5)
    bench = add(BenchNode(context=ctx, parameter_overrides=bench_params()))
    assert spin_until(ex, lambda: bench.finished, 60.0), 'bench did not finish'
    assert spin_until(ex, lambda: len(blocks) == bench.blocks_published
                      and len(windows) >= 2, 30.0)
    spin_for(ex, 0.5)

    # contiguous sequence, monotonic time
    assert [b.seq for b in blocks] == list(range(len(blocks)))
    t = np.concatenate([b.header.stamp.sec + b.header.stamp.nanosec * 1e-9
                        + np.asarray(b.time_offset_s) for b in blocks])
    assert np.all(np.diff(t) > 0)

    # BenchInfo reaches a subscriber that joins late (transient-local)
    infos: list[BenchInfo] = []
    late = add(rclpy.create_node('late_joiner', context=ctx))
    late.create_subscription(BenchInfo, 'bench/info', infos.append, qos.LATCHED_QOS)
    assert spin_until(ex, lambda: len(infos) == 1, 10.0)
    info = infos[0]
    assert info.gear_ratio == pytest.approx(79.0, rel=1e-12)
    assert abs(info.crank_per_input) * info.gear_ratio == pytest.approx(25.0, rel=1e-12)

    # ideal encoders: Eq. 22 on the published angles equals the model TE (recomputed here)
    data = [encoder_block_to_data(b) for b in blocks]
    th_in = np.concatenate([d.theta_in_rad for d in data])
    th_out = np.concatenate([d.theta_out_rad for d in data])
    from sim.presets import load_preset
    from sim.wang2020 import Wang2kvParams, nlte_rad
    params = Wang2kvParams.from_preset(load_preset('wang2020-2kv'))
    te_model = nlte_rad(th_in / 79.0, params)
    np.testing.assert_allclose(th_out - th_in / 79.0, te_model, rtol=0, atol=1e-9)

    # live windows equal the offline computation on the same blocks
    orders = OrderSet.from_bench_info(BenchInfoData.from_message(info))
    offline = analyze_blocks(data, TeAnalysisConfig(orders=orders))
    live_complete = [w for w in windows if w.window_complete]
    off_complete = [w for w in offline.windows if w.complete]
    assert len(live_complete) == len(off_complete) == 2
    for lw, ow in zip(live_complete, off_complete, strict=True):
        assert lw.window.pp_rad == pytest.approx(ow.stats.pp_rad, rel=1e-9)
        assert lw.window.mean_rad == pytest.approx(ow.stats.mean_rad, rel=1e-9)
        assert lw.window.amplitude_rad == pytest.approx(ow.stats.amplitude_rad, rel=1e-9)
    # the live spectrum's largest line is at f_w and equals the offline one
    assert len(spectra) >= 2
    live_lines = spectra[0].lines
    top = max(live_lines, key=lambda ln: ln.amplitude_rad)
    assert top.output_order == pytest.approx(25.0)
    off_lines = {ln.label: ln for ln in off_complete[0].spectrum.lines}
    for ln in live_lines:
        assert ln.amplitude_rad == pytest.approx(off_lines[ln.label].amplitude_rad, rel=1e-9,
                                                 abs=1e-15)
    f_w = 25.0 * SPEED_RPM / 60.0 / 79.0
    assert spectra[0].crank_hz == pytest.approx(f_w, rel=1e-3)
    assert te.drops.total == 0


@pytest.mark.parametrize(('name', 'value', 'needle'), [
    ('sample_rate_hz', 0.0, 'sample_rate_hz'),
    ('block_size', 0, 'block_size'),
    ('time_mode', 'warp', 'time_mode'),
])
def test_bad_bench_parameter_stops_start_up(ros_context, name: str, value: object,
                                            needle: str) -> None:
    from rclpy.exceptions import InvalidParameterValueException

    with pytest.raises(InvalidParameterValueException, match=needle):
        BenchNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])


def test_unknown_preset_and_nonsense_drive_stop_start_up(ros_context) -> None:
    from sim.errors import SimError

    with pytest.raises(SimError, match='unknown preset'):
        BenchNode(context=ros_context,
                  parameter_overrides=[Parameter('preset', value='no-such-reducer')])
    with pytest.raises(SimError, match='speed_rpm'):
        BenchNode(context=ros_context, parameter_overrides=[Parameter('speed_rpm', value=0.0)])


def test_invalid_runtime_change_is_rejected(ros_context) -> None:
    te = TeNode(context=ros_context)
    try:
        res = te.set_parameters([Parameter('decimated_rate_hz', value=-3.0)])[0]
        assert not res.successful
        assert 'decimated_rate_hz' in res.reason
        assert te.get_parameter('decimated_rate_hz').value == 50.0
        res = te.set_parameters([Parameter('decimated_rate_hz', value=20.0)])[0]
        assert res.successful
        assert te.p.decimated_rate_hz == 20.0
    finally:
        te.destroy_node()


def test_te_node_crank_per_output_and_deprecated_alias(graph, capfd) -> None:
    """crank_per_output (as rv-te analyze --crank-per-output) sets the crank order; the old
    crank_per_input still works, converted with the ratio, and warns (issue #15)."""
    ctx, _, add = graph
    te = add(TeNode(context=ctx, parameter_overrides=[
        Parameter('gear_ratio', value=79.0), Parameter('crank_per_output', value=25.0)]))
    assert te.analyzer is not None
    assert te.analyzer.config.orders.crank_per_output == 25.0
    old = TeNode(context=ctx, parameter_overrides=[
        Parameter('gear_ratio', value=79.0), Parameter('crank_per_input', value=-25.0 / 79.0)])
    try:
        assert old.analyzer is not None
        assert old.analyzer.config.orders.crank_per_output == pytest.approx(25.0, rel=1e-12)
    finally:
        old.destroy_node()
    assert "parameter 'crank_per_input' is deprecated: use crank_per_output" in \
        capfd.readouterr().err


def test_te_node_survives_malformed_blocks(graph) -> None:
    ctx, ex, add = graph
    te = add(TeNode(context=ctx, parameter_overrides=[
        Parameter('gear_ratio', value=79.0), Parameter('crank_per_output', value=25.0)]))
    pub_node = add(rclpy.create_node('bad_publisher', context=ctx))
    pub = pub_node.create_publisher(EncoderBlock, 'bench/encoders', qos.ENCODER_QOS)
    windows: list[TransmissionError] = []
    pub_node.create_subscription(TransmissionError, 'te/statistics', windows.append,
                                 qos.LATCHED_QOS)
    spin_until(ex, lambda: pub.get_subscription_count() > 0, 10.0)

    rate = 1000.0
    n = 100
    omega_in = 2 * math.pi * 3000 / 60   # 1 output rev = 1.58 s
    amp = 1e-4

    def block(seq: int, t0: float) -> EncoderBlock:
        msg = EncoderBlock()
        msg.seq = seq
        msg.sample_rate_hz = rate
        s = int(t0)
        msg.header.stamp.sec = s
        msg.header.stamp.nanosec = round((t0 - s) * 1e9)
        off = np.arange(n) / rate
        th_in = omega_in * (t0 + off)
        msg.time_offset_s = off
        msg.theta_in_rad = th_in
        msg.theta_out_rad = th_in / 79.0 + amp * np.cos(25 * th_in / 79.0)
        return msg

    t0 = 100.0
    sent = [block(0, t0)]                       # clean: the reference for what follows
    m = block(1, t0 + 0.1)
    m.theta_in_rad = np.full(n, np.nan)         # non-finite -> dropped
    sent.append(m)
    m = block(2, t0 + 0.2)
    m.theta_out_rad = np.zeros(n - 3)           # lengths differ -> malformed
    sent.append(m)
    sent.append(block(3, t0 - 50.0))            # clean data, stamp going backwards
    empty = EncoderBlock()
    empty.seq = 4                               # empty -> malformed
    sent.append(empty)
    for m in sent:
        pub.publish(m)
        spin_for(ex, 0.02)
    first_clean = 10                            # 3 -> 10: a sequence jump
    for k in range(45):  # 4.5 s of clean data: at least two whole output revolutions
        pub.publish(block(first_clean + k, t0 + 10 + k * n / rate))
        spin_for(ex, 0.01)
    spin_until(ex, lambda: any(w.window_complete for w in windows), 10.0)
    assert te.analyzer is not None
    # every block taken (the first window completes before the last blocks are: under load
    # the node was still 23 blocks behind when it came)
    spin_until(ex, lambda: te.analyzer.counters['blocks'] >= len(sent) + 45, 10.0)
    counters = te.analyzer.counters
    assert counters['non_finite'] == 1
    assert counters['malformed'] == 2
    assert counters['time_backwards'] == 1
    assert counters['seq_jumps'] == 1
    assert counters['blocks'] == len(sent) + 45
    assert counters['samples'] == (2 + 45) * n  # the clean blocks: 0, 3 and 10..54
    complete = [w for w in windows if w.window_complete]
    assert complete, 'no clean window after the bad blocks'
    # closed form: amp*cos(25 phi) over whole revolutions: p-p 2 amp, mean 0, std amp/sqrt2;
    # with no encoder zeros declared the TE is referred to the first clean sample (issue 33
    # s.1: block 0, sample 0, at phi = omega_in t0 / 79), so the mean is minus its TE
    te_first = amp * math.cos(25 * omega_in * t0 / 79.0)
    w = complete[0].window
    assert w.pp_rad == pytest.approx(2 * amp, rel=1e-3)
    assert w.mean_rad == pytest.approx(-te_first, abs=1e-3 * amp)
    assert w.std_rad == pytest.approx(amp / math.sqrt(2), rel=1e-3)


def test_blocks_before_bench_info_are_kept_and_analysed(graph) -> None:
    """bench/info may land after the first blocks: they wait, nothing is dropped."""
    ctx, ex, add = graph
    te = add(TeNode(context=ctx))
    pub_node = add(rclpy.create_node('early_publisher', context=ctx))
    pub = pub_node.create_publisher(EncoderBlock, 'bench/encoders', qos.ENCODER_QOS)
    info_pub = pub_node.create_publisher(BenchInfo, 'bench/info', qos.LATCHED_QOS)
    spin_until(ex, lambda: pub.get_subscription_count() > 0, 10.0)
    n, rate = 100, 1000.0
    omega = 2 * math.pi * 3000 / 60
    for seq in range(20):
        m = EncoderBlock()
        m.seq = seq
        m.sample_rate_hz = rate
        m.header.stamp.sec = 10
        m.header.stamp.nanosec = seq * 100_000_000
        off = np.arange(n) / rate
        th = omega * (10 + seq * n / rate + off)
        m.time_offset_s = off
        m.theta_in_rad = th
        m.theta_out_rad = th / 79.0
        pub.publish(m)
    assert spin_until(ex, lambda: len(te._pending) == 20, 10.0)
    assert te.analyzer is None
    info = BenchInfo()
    info.gear_ratio = 79.0
    info.crank_per_input = -25.0 / 79.0
    info_pub.publish(info)
    assert spin_until(ex, lambda: te.analyzer is not None, 10.0)
    assert te.analyzer.counters['blocks'] == 20
    assert te.drops.total == 0
    assert te._gaps_total == 0


def test_compensation_node_bad_preset_stops_start_up(ros_context) -> None:
    from rv_te_bench.nodes.compensation_node import CompensationNode
    from sim.errors import PresetError

    with pytest.raises(PresetError, match="unknown preset 'nope'"):
        CompensationNode(context=ros_context, parameter_overrides=[
            Parameter('preset', value='nope')])


def test_compensation_node_aborts_a_running_search_on_shutdown(ros_context) -> None:
    import time

    from rv_te_bench.nodes.compensation_node import CompensationNode

    node = CompensationNode(context=ros_context, parameter_overrides=[
        Parameter('preset', value='wang2020-2kv'), Parameter('step_deg', value=5.0)])
    # the 73^4 grid runs for a while; destroying the node must not wait for it
    end = time.monotonic() + 10.0
    while node.progress.get('assembly-phases', 0.0) <= 0.0 and time.monotonic() < end:
        time.sleep(0.05)
    t0 = time.monotonic()
    node.destroy_node()
    assert time.monotonic() - t0 < 5.0
    assert node.published == {}


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='per-thread nice is Linux')
@pytest.mark.parametrize('in_worker', [True, False], ids=['process', 'thread'])
def test_compensation_search_runs_niced(ros_context, in_worker: bool) -> None:
    """The searches yield the cores to the benches' data path (issue #23 item 1): the worker
    process (or, with search_process false, thread) runs at the node's niceness +
    search_nice; the node's own thread is unchanged."""
    import os

    from rv_te_bench.nodes.compensation_node import CompensationNode
    from rv_te_bench.nodes.search_process import SearchJob, current_nice

    base = current_nice()
    for nice, want in ((5, min(19, base + 5)), (0, base)):
        node = CompensationNode(context=ros_context, parameter_overrides=[
            Parameter('preset', value='hu2020-rv'), Parameter('search_nice', value=nice),
            Parameter('search_process', value=in_worker)])
        try:
            seen = node.searches.submit(SearchJob('tooth-profile', current_nice,
                                                  progress=False)).result(60)
            pid = node.searches.submit(SearchJob('tooth-profile', os.getpid,
                                                 progress=False)).result(60)
            assert seen == want
            assert node.search_nice == (want if nice else None)
            assert (pid != os.getpid()) is in_worker
            assert current_nice() == base
        finally:
            node.destroy_node()


def test_realtime_bench_reports_a_late_tick_as_lag(graph) -> None:
    """A bench whose process stalls (here: the executor does not spin for 0.3 s) publishes
    the blocks that fell due in one catch-up tick; the first of them leaves ~0.3 s after the
    end of its samples, and that is the lag the diagnostics report (the largest lag since
    the previous diagnostics message too). Before, the lag was taken after the catch-up
    only, so a stall of any length under 100 blocks showed as no lag at all."""
    import time

    from diagnostic_msgs.msg import DiagnosticArray

    ctx, ex, add = graph
    diags: list[dict[str, str]] = []
    probe = add(rclpy.create_node('probe', context=ctx))
    probe.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: diags.extend({kv.key: kv.value for kv in s.values} for s in m.status
                               if s.name.endswith('bench: bench')), qos.DIAGNOSTICS_QOS)
    bench = add(BenchNode(context=ctx, parameter_overrides=bench_params(
        time_mode='realtime', sample_rate_hz=1000.0, block_size=10,
        duration_output_revs=0.0, diagnostics_period_s=0.2)))
    assert spin_until(ex, lambda: bench.blocks_published >= 20, 20.0)
    spin_for(ex, 0.5)
    steady = max(float(d['lag_period_max_s']) for d in diags)
    time.sleep(0.3)                       # the stall: no timer callback runs
    n = len(diags)
    assert spin_until(ex, lambda: any(float(d['lag_period_max_s']) > 0.2 for d in diags[n:]),
                      5.0), f'no lag reported after a 0.3 s stall (steady {steady:.4f} s)'
    assert float(diags[-1]['lag_max_s']) >= 0.2
    assert steady < 0.2, 'the bench lagged before the stall (machine too busy to tell)'
