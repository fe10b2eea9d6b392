"""A fast (sim-time) session is recorded at the session's clock, as ``ros2 bag record
--use-sim-time`` does, so that Foxglove / PlotJuggler show it at its true duration.

The bag is read with the ``mcap`` library (not our reader); the expected span comes from the
Wang 2020 2K-V kinematics: i = 79 at 300 rpm input is one output revolution in
60 * 79 / 300 = 15.8 s.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.ros

pytest.importorskip('rclpy')

OUTPUT_REV_S = 60.0 * 79 / 300.0     # 15.8 s: Wang 2020 Tables 1-2, 300 rpm input
BLOCK_S = 100 / 1000.0               # blocks of 100 samples at 1 kHz


def test_fast_session_bag_spans_the_simulated_duration(tmp_path: Path) -> None:
    from mcap.reader import make_reader  # noqa: PLC0415
    from mcap_ros2.decoder import DecoderFactory  # noqa: PLC0415

    from rv_te_bench.cli.launch import default_session_file  # noqa: PLC0415
    from rv_te_bench.launch.session import build_session, run_session  # noqa: PLC0415

    spec = build_session([default_session_file()], nodes=['bench', 'te_node', 'recorder'],
                         overrides=['bench.duration_output_revs=1.0',
                                    'bench.speed_factor=20.0',
                                    f'recorder.output_dir={tmp_path}',
                                    'recorder.bag_name=bag'])
    t0 = time.monotonic()
    assert run_session(spec, log=lambda _s: None) == 0
    wall_s = time.monotonic() - t0

    log_ns: list[int] = []
    stamp_ns: list[int] = []
    files = sorted((tmp_path / 'bag').glob('*.mcap'))
    assert files
    for f in files:
        with f.open('rb') as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            for _s, channel, message, msg in reader.iter_decoded_messages(
                    topics=['/bench/encoders']):
                log_ns.append(message.log_time)
                stamp_ns.append(msg.header.stamp.sec * 1_000_000_000
                                + msg.header.stamp.nanosec)
    # one revolution and the sample at exactly one revolution (it closes the window):
    # 158 blocks + 1, whose starts span 158 blocks = one revolution of simulated time
    assert len(log_ns) == round(OUTPUT_REV_S / BLOCK_S) + 1
    span_s = (max(log_ns) - min(log_ns)) * 1e-9
    assert span_s == pytest.approx(OUTPUT_REV_S, abs=2 * BLOCK_S)
    assert wall_s < span_s                             # it did run faster than real time
    # each block is logged at the session clock of its own time (the /clock that came with
    # the block before it; the two topics may cross: within two blocks)
    worst = max(abs(a - b) for a, b in zip(log_ns, stamp_ns, strict=True)) * 1e-9
    assert worst <= 2 * BLOCK_S

    meta = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())
    custom = meta['rosbag2_bagfile_information']['custom_data']
    assert custom['log_time'].startswith('sim: the session clock from /clock')
    duration_s = meta['rosbag2_bagfile_information']['duration']['nanoseconds'] * 1e-9
    assert duration_s >= OUTPUT_REV_S - 2 * BLOCK_S


def test_realtime_session_states_system_log_time() -> None:
    from rv_te_bench.launch.session import build_session, node_parameters  # noqa: PLC0415

    fast = build_session([], overrides=['bench.time_mode=fast'])
    real = build_session([], overrides=['bench.time_mode=realtime'])
    alone = build_session([], nodes=['te_node', 'recorder'])
    assert node_parameters(fast, 'recorder')['use_sim_time'] is True
    assert 'use_sim_time' not in node_parameters(real, 'recorder')
    assert 'use_sim_time' not in node_parameters(alone, 'recorder')
    assert 'use_sim_time' not in node_parameters(fast, 'bench')   # the /clock source
