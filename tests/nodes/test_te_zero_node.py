"""The TE node refers the TE to the same zero as rv-te analyze (issue 33 s.1).

Bags written by rosbags (tests.unit_bags) with the output encoder 123.4 deg and 359.998 deg
off, replayed into a TE node: each window's mean and amplitude equal those of a zeroed output
encoder, computed here from the arrays (TE referred to its first sample, windows of whole
output revolutions of theta_in / i from 0).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pytest

from tests import wang2020_reference as ref
from tests.unit_bags import write_unit_bag

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import TransmissionError  # noqa: E402

from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.replay import ReplayNode  # noqa: E402
from rv_te_bench.nodes.te_node import TeNode  # noqa: E402
from tests.nodes.rosutil import spin_for, spin_while_progress  # noqa: E402

if TYPE_CHECKING:
    from pathlib import Path

RATE_HZ = 1000.0
REVS = 2.05
N = round(REVS * 60.0 / 300.0 * ref.RATIO * RATE_HZ)


@pytest.mark.parametrize('offset_deg', [123.4, 359.998])
def test_te_node_mean_does_not_depend_on_the_encoder_zero(ros_context, tmp_path: Path,
                                                          offset_deg: float) -> None:
    rng = np.random.default_rng(7)
    th_in, th_out = ref.encoder_record(ref.table2_unit(), rng, n_samples=N, revolutions=REVS,
                                       noise_arcsec=0.2, theta_in_start_rad=0.0)
    te = th_out - th_in / ref.RATIO
    te = te - te[0]
    rev = np.floor(th_in / ref.RATIO / (2 * math.pi)).astype(int)
    expect = [(te[rev == k].mean(), np.abs(te[rev == k]).max()) for k in (0, 1)]
    bag = write_unit_bag(tmp_path / 'bag', th_in, th_out + math.radians(offset_deg),
                         rate_hz=RATE_HZ)

    ex = SingleThreadedExecutor(context=ros_context)
    te_node = TeNode(context=ros_context)
    probe = rclpy.create_node('probe', context=ros_context)
    stats: list[TransmissionError] = []
    probe.create_subscription(TransmissionError, 'te/statistics', stats.append,
                              qos.LATCHED_QOS)
    nodes = [te_node, probe]
    for n in nodes:
        ex.add_node(n)
    try:
        spin_for(ex, 0.3)
        replay = ReplayNode(context=ros_context, parameter_overrides=[
            Parameter('bag', value=str(bag)), Parameter('rate', value=20.0),
            Parameter('wait_for_subscribers_s', value=5.0)])
        nodes.append(replay)
        ex.add_node(replay)
        assert spin_while_progress(ex, lambda: sum(s.window_complete for s in stats) >= 2,
                                   lambda: te_node._blocks, idle_s=20.0)
    finally:
        ex.shutdown()
        for n in nodes:
            n.destroy_node()
    live = [s.window for s in stats if s.window_complete][:2]
    for w, (mean, amp) in zip(live, expect, strict=True):
        assert w.mean_rad == pytest.approx(mean, abs=1e-9)
        assert w.amplitude_rad == pytest.approx(amp, abs=1e-9)
    assert te_node.zero.reference.method == 'first-sample'
    assert te_node.zero.reference.whole_turns == (1 if offset_deg > 180 else 0)
