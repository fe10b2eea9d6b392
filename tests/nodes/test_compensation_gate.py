"""Issue 33 s.4, live: the compensation node gives advice only where the data holds it, gated
as ``rv-te analyze`` gates it (one function, core.advice_gate).

An RV bench (the simulated hu2020-rv's own BenchInfo: its crank and mesh orders) and a TE whose
spectrum is dominated by the crank line (1 f_w: crankshaft eccentricity) gets no tooth-profile
change (Hu 2020 Eq. 27 assigns the whole TE p-p to the cycloid-pin mesh): the advice is
published as withheld, naming the line and the crankshaft. The same TE with a mesh line on top
gets the pin-radius change. The node before this change published the profile change for both.
Real nodes over the middleware.
"""

from __future__ import annotations

import math

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import (  # noqa: E402
    CompensationAdvice,
    SpectrumLine,
    TeSpectrum,
    TransmissionError,
)

from rv_te_bench.nodes import convert, qos  # noqa: E402
from rv_te_bench.nodes.compensation_node import CompensationNode  # noqa: E402
from sim.units import arcmin_to_rad  # noqa: E402
from tests.nodes.rosutil import spin_until  # noqa: E402


def rv_bench_info():
    """The BenchInfo the simulated hu2020-rv bench publishes (its orders, not ours)."""
    from rv_te_bench.nodes.bench_node import bench_config_from_params
    from rv_te_bench.nodes.params.bench import BenchParams
    from rv_te_bench.params import params_record
    from sim.bench import BenchSimulator

    return BenchSimulator(bench_config_from_params(params_record(
        BenchParams, {'preset': 'hu2020-rv', 'te_mode': 'geometric'}))).info


def _line(order: float, amplitude_arcmin: float, label: str) -> SpectrumLine:
    ln = SpectrumLine()
    ln.output_order = float(order)
    ln.amplitude_rad = float(arcmin_to_rad(amplitude_arcmin))
    ln.label = label
    return ln


def _advice_for(graph, lines_of_window) -> CompensationAdvice:
    ctx, ex, add = graph
    info = rv_bench_info()
    crank = abs(info.crank_per_input) * info.gear_ratio         # crank revs per output rev
    assert len(info.mesh_orders) >= 1 and crank > 1.0
    src = add(rclpy.create_node('te_source', context=ctx))
    got: list[CompensationAdvice] = []
    src.create_subscription(CompensationAdvice, 'compensation/advice', got.append,
                            qos.LATCHED_QOS)
    pub_info = src.create_publisher(type(convert.make_bench_info(info, src.get_clock().now()
                                                                 .to_msg())),
                                    'bench/info', qos.LATCHED_QOS)
    pub_stats = src.create_publisher(TransmissionError, 'te/statistics', qos.LATCHED_QOS)
    pub_spec = src.create_publisher(TeSpectrum, 'te/spectrum', qos.LATCHED_QOS)
    node = add(CompensationNode(context=ctx, parameter_overrides=[
        Parameter('optimize_phases', value=False)]))
    pub_info.publish(convert.make_bench_info(info, src.get_clock().now().to_msg()))
    assert spin_until(ex, lambda: node.preset is not None, 20.0)
    assert spin_until(ex, lambda: pub_stats.get_subscription_count() >= 1, 10.0)
    stats = TransmissionError()
    stats.window_index = 0
    stats.window_complete = True
    stats.window.pp_rad = float(arcmin_to_rad(1.2))
    stats.window.amplitude_rad = float(arcmin_to_rad(0.6))
    stats.window.revolutions_covered = 1.0
    pub_stats.publish(stats)       # (the TE node publishes the statistics first)
    spec = TeSpectrum()
    spec.window_index = 0
    spec.revolutions_covered = 1.0
    spec.lines = lines_of_window(crank, float(info.mesh_orders[0]))
    pub_spec.publish(spec)
    assert spin_until(ex, lambda: got, 30.0), node.errors
    return got[-1]


@pytest.mark.timeout(90)
def test_tooth_profile_withheld_when_the_crank_line_dominates(graph) -> None:
    advice = _advice_for(graph, lambda crank, mesh: [
        _line(1.0, 0.05, 'f_out'), _line(crank, 0.6, '1 f_w'), _line(mesh, 0.1, 'mesh')])
    assert advice.method == 'tooth-profile'
    assert advice.summary.startswith('tooth-profile advice withheld'), advice.summary
    assert '1 f_w (0.6 arcmin)' in advice.summary
    assert 'crankshaft' in advice.summary          # the diagnosis of 1 f_w on an RV
    assert list(advice.modifications) == []
    assert math.isnan(advice.te_after_rad)


@pytest.mark.timeout(90)
def test_tooth_profile_given_when_a_mesh_line_dominates(graph) -> None:
    advice = _advice_for(graph, lambda crank, mesh: [
        _line(1.0, 0.05, 'f_out'), _line(crank, 0.1, '1 f_w'), _line(mesh, 0.5, 'mesh')])
    assert advice.method == 'tooth-profile'
    assert 'withheld' not in advice.summary, advice.summary
    assert len(advice.modifications) >= 1
    assert math.isfinite(advice.te_after_rad)
