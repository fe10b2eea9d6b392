"""Recordings for the viewers (Foxglove, PlotJuggler): a fast (sim-time) session is recorded
at the session's clock, as ``ros2 bag record --use-sim-time`` does, so that a viewer shows it
at its true duration; te/plot carries flat scalars a plot panel takes as they are.

The bag is read with the ``mcap`` library (not our reader); the expected span comes from the
Wang 2020 2K-V kinematics: i = 79 at 300 rpm input is one output revolution in
60 * 79 / 300 = 15.8 s.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
import yaml

from tests.launch.conftest import read_decoded

pytestmark = pytest.mark.ros

pytest.importorskip('rclpy')

OUTPUT_REV_S = 60.0 * 79 / 300.0     # 15.8 s: Wang 2020 Tables 1-2, 300 rpm input
BLOCK_S = 100 / 1000.0               # blocks of 100 samples at 1 kHz


@pytest.fixture(scope='module')
def fast_session(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, float]:
    """One output revolution of the default session (fast, speed_factor 20): (bag, wall s)."""
    from rv_te_bench.cli.launch import default_session_file
    from rv_te_bench.launch.session import build_session, run_session

    out = tmp_path_factory.mktemp('fast')
    spec = build_session([default_session_file()], nodes=['bench', 'te_node', 'recorder'],
                         overrides=['bench.duration_output_revs=1.0',
                                    'bench.speed_factor=20.0',
                                    f'recorder.output_dir={out}', 'recorder.bag_name=bag'])
    t0 = time.monotonic()
    assert run_session(spec, log=lambda _s: None) == 0
    return out / 'bag', time.monotonic() - t0


def test_fast_session_bag_spans_the_simulated_duration(
        fast_session: tuple[Path, float]) -> None:
    bag, wall_s = fast_session
    blocks = read_decoded(bag, ['/bench/encoders'])
    log_ns = [t for _, t, _ in blocks]
    stamp_ns = [m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
                for _, _, m in blocks]
    # one revolution and the sample at exactly one revolution (it closes the window):
    # 158 blocks + 1, whose starts span 158 blocks = one revolution of simulated time
    assert len(log_ns) == round(OUTPUT_REV_S / BLOCK_S) + 1
    span_s = (max(log_ns) - min(log_ns)) * 1e-9
    assert span_s == pytest.approx(OUTPUT_REV_S, abs=2 * BLOCK_S)
    assert wall_s < span_s                             # it did run faster than real time
    # each block is logged at the session clock of its own time: the bench publishes /clock
    # at the start and after every block (measured: exact; one block allowed for a recorder
    # that falls behind under load and takes a later /clock first)
    worst = max(abs(a - b) for a, b in zip(log_ns, stamp_ns, strict=True)) * 1e-9
    assert worst <= BLOCK_S + 1e-6

    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    custom = meta['rosbag2_bagfile_information']['custom_data']
    assert custom['log_time'].startswith('sim: the session clock from /clock')
    duration_s = meta['rosbag2_bagfile_information']['duration']['nanoseconds'] * 1e-9
    assert duration_s >= OUTPUT_REV_S - 2 * BLOCK_S


def test_realtime_session_states_system_log_time() -> None:
    from rv_te_bench.launch.session import build_session, node_parameters

    fast = build_session([], overrides=['bench.time_mode=fast'])
    real = build_session([], overrides=['bench.time_mode=realtime'])
    alone = build_session([], nodes=['te_node', 'recorder'])
    assert node_parameters(fast, 'recorder')['use_sim_time'] is True
    assert 'use_sim_time' not in node_parameters(real, 'recorder')
    assert 'use_sim_time' not in node_parameters(alone, 'recorder')
    assert 'use_sim_time' not in node_parameters(fast, 'bench')   # the /clock source


def test_te_plot_scalars_match_the_statistics_and_spectrum(
        fast_session: tuple[Path, float]) -> None:
    """te/plot: no array anywhere in its schema (a plot panel takes every field), one message
    per encoder block at the default 20 Hz > 10 blocks/s, values equal to te/statistics and
    te/spectrum converted here (1 rad = 10800/pi arcmin)."""
    from mcap.reader import make_reader

    bag, _ = fast_session
    with next(bag.glob('*.mcap')).open('rb') as stream:
        summary = make_reader(stream).get_summary()
    schema = next(s for s in summary.schemas.values() if s.name == 'rv_te_msgs/msg/TePlot')
    fields = [ln.split('#')[0].split() for ln in schema.data.decode().splitlines()]
    fields = [f for f in fields if f and not f[0].startswith(('=', 'MSG:'))]
    assert fields and not [f for f in fields if '[' in f[0]], fields

    arcmin = 10800.0 / math.pi
    rows = read_decoded(bag, ['/te/plot', '/te/statistics', '/te/spectrum', '/te/samples'])
    plot = [m for t, _, m in rows if t == '/te/plot']
    stats = [m for t, _, m in rows if t == '/te/statistics' and m.window_complete]
    spectra = [m for t, _, m in rows if t == '/te/spectrum']
    assert len(plot) == len([1 for t, _, _ in rows if t == '/te/samples'])
    assert len(stats) == len(spectra) == 1
    before = [m for m in plot if m.window_index == 0 and math.isnan(m.window_pp_arcmin)]
    after = [m for m in plot if not math.isnan(m.window_pp_arcmin)]
    assert before and after and len(before) + len(after) == len(plot)
    last = after[-1]
    w = stats[0].window
    assert last.window_pp_arcmin == pytest.approx(w.pp_rad * arcmin, rel=1e-12)
    assert last.window_amplitude_arcmin == pytest.approx(w.amplitude_rad * arcmin, rel=1e-12)
    assert last.window_mean_arcmin == pytest.approx(w.mean_rad * arcmin, rel=1e-12)
    assert last.window_revolutions == pytest.approx(w.revolutions_covered, rel=1e-12)
    lines = {ln.label: ln.amplitude_rad * arcmin for ln in spectra[0].lines}
    assert last.f_w_amplitude_arcmin == pytest.approx(lines['1 f_w'], rel=1e-12)
    assert last.f_w2_amplitude_arcmin == pytest.approx(lines['2 f_w'], rel=1e-12)
    assert last.f_out_amplitude_arcmin == pytest.approx(lines['f_out'], rel=1e-12)
    assert last.crank_hz == pytest.approx(25 * 300 / 60 / 79, rel=1e-3)   # f_w = 25 f_out
    # the live trace: TE within the window's range, angle wrapped, cumulative p-p grows
    te = [m.te_arcmin for m in plot]
    assert max(te) - min(te) <= last.cumulative_pp_arcmin + 1e-9
    assert all(0.0 <= m.theta_out_deg < 360.0 for m in plot)
    assert last.gaps == 0


def test_foxglove_layout_paths_have_data_in_the_recording(
        fast_session: tuple[Path, float]) -> None:
    """Every te/* path of docs/foxglove_te_session.json yields finite numbers from the
    recorded session (compensation/advice and /diagnostics are checked by definition only,
    tests/package/test_foxglove_layout.py; this session has no compensation node)."""
    from tests.package.conftest import layout_paths

    bag, _ = fast_session
    paths = sorted({p for _, p in layout_paths() if p.startswith('/te/')})
    assert paths
    msgs: dict[str, list[object]] = {}
    for topic, _, msg in read_decoded(bag, sorted({p.split('.')[0] for p in paths})):
        msgs.setdefault(topic, []).append(msg)

    def values(obj: object, parts: list[str]) -> list[object]:
        if not parts:
            return [obj]
        name = parts[0].removesuffix('[:]')
        child = getattr(obj, name)
        items = list(child) if parts[0].endswith('[:]') else [child]
        return [v for item in items for v in values(item, parts[1:])]

    for path in paths:
        topic, *parts = path.split('.')
        got = [v for m in msgs.get(topic, []) for v in values(m, parts)]
        assert got, path
        if all(isinstance(v, (int, float)) for v in got):   # a plotted series
            assert any(math.isfinite(float(v)) for v in got), path
