"""Several read heads over the real middleware: bench -> TE node -> recorder -> analyze.

The bench's output scale is mounted 5 um off centre on 100 mm (+-20.6" at once per output
revolution) and read by 2 or 4 heads. Expected values are the test's own: the same bench
simulated here (same seed) gives the model's true TE, whose order-1 line the test takes by
its own FFT over whole revolutions; the live TE node, the recorded bag (read by ``rv-te
analyze``'s code) and the JointState route must all give that line, and head 0 alone must
not (it carries the scale's eccentricity).
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import EncoderBlock, TeSpectrum, TransmissionError  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from rv_te_bench.core.encoder_calibration import (  # noqa: E402
    CalibrationHarmonic,
    EncoderCalibration,
)
from rv_te_bench.io.bag_reader import iter_messages, read_encoder_blocks  # noqa: E402
from rv_te_bench.io.calibration_file import write_encoder_calibration  # noqa: E402
from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.bench_node import BenchNode, bench_config_from_params  # noqa: E402
from rv_te_bench.nodes.joint_state_adapter import JointStateAdapterNode  # noqa: E402
from rv_te_bench.nodes.recorder import RecorderNode  # noqa: E402
from rv_te_bench.nodes.te_node import PARAMS as TE_PARAMS  # noqa: E402
from rv_te_bench.nodes.te_node import TeNode  # noqa: E402
from rv_te_bench.report.analysis import analyze_bag  # noqa: E402
from sim.bench import BenchSimulator  # noqa: E402
from tests.nodes.rosutil import spin_for, spin_until  # noqa: E402
from tests.scale_reference import ARCSEC_RAD, whole_revolutions_fft  # noqa: E402

if TYPE_CHECKING:
    from pathlib import Path

RATE_HZ = 2000.0
BLOCK = 100
HEADS = {2: [0.0, 180.0], 4: [0.0, 90.0, 180.0, 270.0]}
ERROR_LEVEL = b'\x02'   # diagnostic_msgs/DiagnosticStatus.ERROR


def bench_values(n_heads: int, **extra: object) -> dict[str, object]:
    return {'preset': 'wang2020-2kv', 'te_mode': 'nlte', 'speed_rpm': 3000.0,
            'encoder_in': 'ideal', 'encoder_out': 'heidenhain-ron886',
            'encoder_out_heads_deg': HEADS[n_heads], 'encoder_out_scale_eccentricity_um': 5.0,
            'encoder_out_scale_diameter_mm': 100.0, 'encoder_out_scale_serial': 'RING-9',
            'sample_rate_hz': RATE_HZ, 'block_size': BLOCK, 'duration_output_revs': 2.3,
            'time_mode': 'fast', 'speed_factor': 10.0, 'seed': 5, **extra}


def _true_line1_rad(values: dict[str, object]) -> float:
    """The model's order-1 TE amplitude: the same bench simulated here, the test's FFT."""
    from rv_te_bench.nodes.params.bench import BenchParams
    from rv_te_bench.params import params_record

    sim = BenchSimulator(bench_config_from_params(params_record(BenchParams, values)))
    te, th = [], []
    for _ in range(int(2.3 * 79 / 50.0 * RATE_HZ / BLOCK)):
        b = sim.next_block()
        te.append(b.te_true_rad)
        th.append(b.theta_out_true_rad)
    return float(abs(whole_revolutions_fft(np.concatenate(th), np.concatenate(te), 1)[0]))


def _line1(spectra: list[TeSpectrum]) -> float:
    vals = [ln.amplitude_rad for s in spectra for ln in s.lines if ln.label == 'f_out']
    return float(np.mean(vals))


@pytest.mark.timeout(180)
@pytest.mark.parametrize('n_heads', [2, 4])
def test_heads_through_te_node_recorder_and_analyze(graph, tmp_path: Path,
                                                    n_heads: int) -> None:
    ctx, ex, add = graph
    probe = add(rclpy.create_node('probe', context=ctx))
    spectra: list[TeSpectrum] = []
    heads_msgs: list[String] = []
    probe.create_subscription(TeSpectrum, 'te/spectrum', spectra.append, qos.LATCHED_QOS)
    probe.create_subscription(String, 'te/encoder_heads', heads_msgs.append, qos.LATCHED_QOS)
    recorder = add(RecorderNode(context=ctx, parameter_overrides=[
        Parameter('output_dir', value=str(tmp_path)), Parameter('bag_name', value='bag'),
        Parameter('discovery_period_s', value=0.1), Parameter('flush_interval_s', value=0.2)]))
    add(TeNode(context=ctx))
    spin_for(ex, 1.0)
    values = bench_values(n_heads)
    bench = add(BenchNode(context=ctx, parameter_overrides=[
        Parameter(k, value=v) for k, v in values.items()]))
    assert spin_until(ex, lambda: bench.finished, 90.0), 'bench did not finish'
    assert spin_until(ex, lambda: len(spectra) >= 2 and heads_msgs, 30.0)
    spin_for(ex, 1.0)
    recorder.destroy_node()        # closes the bag (the fixture destroys it again: no-op)

    truth = _true_line1_rad(values)
    assert truth / ARCSEC_RAD > 5.0
    live = _line1(spectra)
    assert abs(live - truth) / ARCSEC_RAD < 0.3, (live / ARCSEC_RAD, truth / ARCSEC_RAD)
    assert f'{n_heads} heads equally spaced' in heads_msgs[-1].data

    bag = tmp_path / 'bag'
    blocks = list(read_encoder_blocks(bag))
    assert blocks[0].out_head_ids == tuple(range(n_heads))
    assert blocks[0].theta_out_heads_rad.shape == (n_heads, BLOCK)
    recorded = [d for t, _, _, d in iter_messages(bag, ['/te/encoder_heads'])]
    assert recorded, 'te/encoder_heads not in the bag'
    res = analyze_bag(bag, with_advice=False)
    line = next(ln.amplitude_rad for ln in res.spectrum.lines if ln.label == 'f_out')
    assert abs(line - truth) / ARCSEC_RAD < 0.3
    one = analyze_bag(bag, with_advice=False, heads_mode='head0')
    line0 = next(ln.amplitude_rad for ln in one.spectrum.lines if ln.label == 'f_out')
    assert abs(line0 - truth) / ARCSEC_RAD > 3.0       # head 0 carries the scale's 20.6"
    assert res.encoder['once_per_rev']['separated']
    assert not one.encoder['once_per_rev']['separated']


@pytest.mark.timeout(120)
def test_calibration_of_another_scale_is_reported_and_the_te_goes_on(graph,
                                                                     tmp_path: Path) -> None:
    ctx, ex, add = graph
    cal = write_encoder_calibration(tmp_path / 'other.yaml', EncoderCalibration(
        scale_serial='RING-8', date='2026-11-01', method='reversal',
        harmonics=(CalibrationHarmonic(1, 1e-4, 0.3, 1e-7),)))
    probe = add(rclpy.create_node('probe', context=ctx))
    windows: list[TransmissionError] = []
    diags: list[DiagnosticArray] = []
    probe.create_subscription(TransmissionError, 'te/statistics', windows.append,
                              qos.LATCHED_QOS)
    probe.create_subscription(DiagnosticArray, '/diagnostics', diags.append,
                              qos.DIAGNOSTICS_QOS)
    te = add(TeNode(context=ctx, parameter_overrides=[
        Parameter('encoder_out_calibration', value=str(cal)),
        Parameter('diagnostics_period_s', value=0.2)]))
    spin_for(ex, 0.5)
    bench = add(BenchNode(context=ctx, parameter_overrides=[
        Parameter(k, value=v) for k, v in bench_values(2).items()]))
    assert spin_until(ex, lambda: bench.finished, 90.0)
    assert spin_until(ex, lambda: sum(w.window_complete for w in windows) >= 2, 30.0)
    spin_for(ex, 0.5)
    assert "for scale 'RING-8', the bench reports scale 'RING-9'" in te.heads_problem
    status = [s for d in diags for s in d.status if s.name.endswith('te analysis')]
    assert status and status[-1].level == ERROR_LEVEL   # diagnostics say so: ERROR
    assert any(kv.key == 'heads_problem' and 'RING-8' in kv.value
               for s in status for kv in s.values)
    assert te.drops.total == 0          # every block analysed (averaged, uncalibrated)


@pytest.mark.timeout(180)
def test_a_one_head_bench_with_its_scales_calibration_gives_the_reducers_line(
        graph, tmp_path: Path) -> None:
    """The workflow of issue 36 over the middleware: the scale is self-calibrated from its
    4 heads (the same simulated scale: same seed, offline, the suite's self-calibration),
    then a one-head session of it runs with that file applied live. The TE node's order-1
    line is the reducer's (the test's FFT of the model's TE) within 0.3"; the bag records
    what was applied (te/encoder_heads) and rv-te analyze of it applies the same and gives
    the same line; without it head 0 is the scale's 20.6" off."""
    from rv_te_bench.core.encoder_calibration import calibration_from_estimate
    from rv_te_bench.core.heads import HeadLayout
    from rv_te_bench.core.selfcal import HeadSelfCalibration
    from rv_te_bench.nodes.params.bench import BenchParams
    from rv_te_bench.params import params_record

    four = params_record(BenchParams, bench_values(4))
    sim = BenchSimulator(bench_config_from_params(four))
    selfcal = HeadSelfCalibration(HeadLayout.of(np.radians(HEADS[4])))
    for _ in range(int(2.3 * 79 / 50.0 * RATE_HZ / BLOCK)):
        selfcal.add(sim.next_block().theta_out_heads_rad)
    cal_file = write_encoder_calibration(tmp_path / 'RING-9.yaml', calibration_from_estimate(
        selfcal.result(), scale_serial='RING-9', source='4-head self-calibration'))

    ctx, ex, add = graph
    probe = add(rclpy.create_node('probe', context=ctx))
    spectra: list[TeSpectrum] = []
    probe.create_subscription(TeSpectrum, 'te/spectrum', spectra.append, qos.LATCHED_QOS)
    recorder = add(RecorderNode(context=ctx, parameter_overrides=[
        Parameter('output_dir', value=str(tmp_path)), Parameter('bag_name', value='bag'),
        Parameter('discovery_period_s', value=0.1), Parameter('flush_interval_s', value=0.2)]))
    te = add(TeNode(context=ctx, parameter_overrides=[
        Parameter('encoder_out_calibration', value=str(cal_file))]))
    spin_for(ex, 1.0)
    one = {k: v for k, v in bench_values(4).items() if k != 'encoder_out_heads_deg'}
    bench = add(BenchNode(context=ctx, parameter_overrides=[
        Parameter(k, value=v) for k, v in one.items()]))
    assert spin_until(ex, lambda: bench.finished, 90.0), 'bench did not finish'
    assert spin_until(ex, lambda: len(spectra) >= 2, 30.0)
    spin_for(ex, 1.0)
    recorder.destroy_node()
    assert te.heads_problem == ''

    truth = _true_line1_rad(one)
    assert abs(_line1(spectra) - truth) / ARCSEC_RAD < 0.3, (
        _line1(spectra) / ARCSEC_RAD, truth / ARCSEC_RAD)
    res = analyze_bag(tmp_path / 'bag', with_advice=False)
    line = next(ln.amplitude_rad for ln in res.spectrum.lines if ln.label == 'f_out')
    assert res.encoder['calibration_source'] == 'session'
    assert abs(line - truth) / ARCSEC_RAD < 0.3
    raw = analyze_bag(tmp_path / 'bag', with_advice=False, session_calibration=False)
    line0 = next(ln.amplitude_rad for ln in raw.spectrum.lines if ln.label == 'f_out')
    assert abs(line0 - truth) / ARCSEC_RAD > 3.0


def test_a_bad_calibration_file_stops_the_te_node_at_start(ros_context, tmp_path: Path) -> None:
    bad = tmp_path / 'bad.yaml'
    bad.write_text('format: rv-te encoder calibration 1\nscale_serial: X\n')
    with pytest.raises(Exception, match='date is required'):
        TeNode(context=ros_context, parameter_overrides=[
            Parameter('encoder_out_calibration', value=str(bad))])
    assert {s.name for s in TE_PARAMS} >= {'heads_mode', 'encoder_out_calibration'}


DESCRIPTION = """\
bench_id: js-heads
preset: wang2020-2kv
sample_rate_hz: 2000.0
block_size: 100
encoders:
  input: {model: ideal}
  output:
    model: heidenhain-ron886
    serial: RING-9
    heads_deg: [0, 90, 180, 270]
    scale: {diameter_mm: 100.0, eccentricity_um: 5.0}
joints: {input: input_joint, output: output_joint,
         output_heads: [output_joint, output_joint_head1, output_joint_head2,
                        output_joint_head3]}
"""


@pytest.mark.timeout(180)
def test_joint_state_route_one_joint_per_head(graph, tmp_path: Path) -> None:
    """The bench publishes JointStates with one joint per head; the adapter (heads from the
    bench description) makes EncoderBlocks with 4 heads; the TE node averages them."""
    ctx, ex, add = graph
    desc = tmp_path / 'bench.yaml'
    desc.write_text(DESCRIPTION)
    probe = add(rclpy.create_node('probe', context=ctx))
    spectra: list[TeSpectrum] = []
    blocks: list[EncoderBlock] = []
    probe.create_subscription(TeSpectrum, 'te/spectrum', spectra.append, qos.LATCHED_QOS)
    probe.create_subscription(EncoderBlock, 'bench/encoders', blocks.append, qos.ENCODER_QOS)
    add(TeNode(context=ctx))
    adapter = add(JointStateAdapterNode(context=ctx, parameter_overrides=[
        Parameter('bench_description', value=str(desc)), Parameter('idle_flush_s', value=0.2)]))
    spin_for(ex, 0.5)
    values = bench_values(4, output='joint_state', speed_factor=5.0)
    bench = BenchNode(context=ctx, parameter_overrides=[
        Parameter(k, value=v) for k, v in values.items()])
    bench_ex = SingleThreadedExecutor(context=ctx)
    bench_ex.add_node(bench)
    try:   # every JointState taken before the bench spins again (see test_joint_state_adapter)
        end = time.monotonic() + 120.0
        while not bench.finished and time.monotonic() < end:
            while adapter.assembler.counters['messages'] < bench.joint_states_published \
                    and time.monotonic() < end:
                ex.spin_once(timeout_sec=0.01)
            bench_ex.spin_once(timeout_sec=0.01)
        assert bench.finished
    finally:
        bench_ex.shutdown()
        bench.destroy_node()
    assert spin_until(ex, lambda: len(spectra) >= 2, 30.0)
    spin_for(ex, 0.3)
    assert adapter.assembler.counters['gaps'] == 0
    assert bytes(blocks[0].out_head_ids) == bytes([0, 1, 2, 3])
    assert len(blocks[0].theta_out_heads_rad) == 4 * len(blocks[0].theta_out_rad)
    truth = _true_line1_rad(bench_values(4))
    assert abs(_line1(spectra) - truth) / ARCSEC_RAD < 0.3
    assert math.isfinite(truth)
