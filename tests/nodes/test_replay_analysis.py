"""Replay -> live TE node gives the statistics of analysing the bag directly; the bench node
runs the RV presets like the 2K-V one."""

from __future__ import annotations

from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import BenchInfo, EncoderBlock, TransmissionError  # noqa: E402

from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.bench_node import BenchNode  # noqa: E402
from rv_te_bench.nodes.replay import ReplayNode  # noqa: E402
from rv_te_bench.nodes.te_node import TeNode  # noqa: E402
from tests.nodes.rosutil import spin_for, spin_until  # noqa: E402

SAMPLE = Path(__file__).resolve().parents[2] / 'bags' / 'sample'


def test_replay_then_live_analysis_equals_offline_analysis(ros_context) -> None:
    from rv_te_bench.report.analysis import analyze_bag

    offline = analyze_bag(SAMPLE, with_advice=False)
    off_windows = [w for w in offline.windows if w.complete]
    assert len(off_windows) == 2
    ctx = ros_context
    ex = SingleThreadedExecutor(context=ctx)
    te = TeNode(context=ctx)
    probe = rclpy.create_node('probe', context=ctx)
    stats: list[TransmissionError] = []
    probe.create_subscription(TransmissionError, 'te/statistics', stats.append,
                              qos.LATCHED_QOS)
    nodes = [te, probe]
    for n in nodes:
        ex.add_node(n)
    try:
        spin_for(ex, 0.5)
        replay = ReplayNode(context=ctx, parameter_overrides=[
            Parameter('bag', value=str(SAMPLE)), Parameter('rate', value=8.0),
            Parameter('wait_for_subscribers_s', value=5.0)])
        nodes.append(replay)
        ex.add_node(replay)
        assert spin_until(ex, lambda: sum(s.window_complete for s in stats) >= 2, 60.0)
        spin_for(ex, 0.3)
    finally:
        ex.shutdown()
        for n in nodes:
            n.destroy_node()
    live = [s for s in stats if s.window_complete]
    assert te.drops.total == 0
    for lw, ow in zip(live, off_windows, strict=False):
        assert lw.window.pp_rad == pytest.approx(ow.stats.pp_rad, rel=1e-9)
        assert lw.window.amplitude_rad == pytest.approx(ow.stats.amplitude_rad, rel=1e-9)
        assert lw.window.mean_rad == pytest.approx(ow.stats.mean_rad, rel=1e-9)
        assert lw.window.std_rad == pytest.approx(ow.stats.std_rad, rel=1e-9)


@pytest.mark.parametrize(('preset', 'mode', 'ratio'), [
    ('hu2020-rv', 'geometric', 1 + 60 / 22 * 40),   # Hu 2020 Table 3: 110.09
    ('rv-80e-101', 'geometric', 101.0),
    ('li2023-rv', 'dte', 121.0),                    # Li 2023: 1 + 3 * 40
])
def test_bench_node_runs_rv_presets(ros_context, preset: str, mode: str,
                                    ratio: float) -> None:
    ctx = ros_context
    ex = SingleThreadedExecutor(context=ctx)
    probe = rclpy.create_node('probe', context=ctx)
    blocks: list[EncoderBlock] = []
    infos: list[BenchInfo] = []
    probe.create_subscription(EncoderBlock, 'bench/encoders', blocks.append, qos.ENCODER_QOS)
    probe.create_subscription(BenchInfo, 'bench/info', infos.append, qos.LATCHED_QOS)
    bench = BenchNode(context=ctx, parameter_overrides=[Parameter(k, value=v) for k, v in {
        'preset': preset, 'te_mode': mode, 'speed_rpm': 1500.0, 'sample_rate_hz': 1000.0,
        'block_size': 100, 'duration_s': 0.5, 'time_mode': 'fast', 'speed_factor': 2.0,
        'load_nm': 100.0, 'wait_for_nodes': ['probe']}.items()])
    for n in (probe, bench):
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: bench.finished, 60.0)
        assert spin_until(ex, lambda: len(blocks) == bench.blocks_published and infos, 10.0)
    finally:
        ex.shutdown()
        bench.destroy_node()
        probe.destroy_node()
    assert infos[0].reducer_type == 'rv'
    assert infos[0].gear_ratio == pytest.approx(ratio, rel=1e-9)
    assert [b.seq for b in blocks] == list(range(len(blocks)))
    assert len(blocks) >= 5


def test_replay_with_start_offset_still_gives_the_latched_bench_info(ros_context) -> None:
    ctx = ros_context
    ex = SingleThreadedExecutor(context=ctx)
    probe = rclpy.create_node('probe', context=ctx)
    infos: list[BenchInfo] = []
    blocks: list[EncoderBlock] = []
    probe.create_subscription(BenchInfo, 'bench/info', infos.append, qos.LATCHED_QOS)
    probe.create_subscription(EncoderBlock, 'bench/encoders', blocks.append, qos.ENCODER_QOS)
    ex.add_node(probe)
    replay = ReplayNode(context=ctx, parameter_overrides=[
        Parameter('bag', value=str(SAMPLE)), Parameter('rate', value=20.0),
        Parameter('start_offset_s', value=30.0), Parameter('wait_for_subscribers_s', value=5.0)])
    ex.add_node(replay)
    try:
        assert spin_until(ex, lambda: replay.finished, 30.0)
        spin_for(ex, 0.3)
    finally:
        ex.shutdown()
        replay.destroy_node()
        probe.destroy_node()
    assert len(infos) == 1              # recorded at the start, before the offset
    assert blocks and blocks[0].seq >= 290   # 30 s into a 1 kHz, 100-sample session
