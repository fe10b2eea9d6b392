"""A DAQ file with drop-outs, imported and replayed through the live TE node (issue #32
s.1): the node reports every drop-out as a gap (the ``gaps`` count of te/statistics, the
latest one's time and length in its diagnostics) and no window holding one is complete.
The file is written by pandas (tests/io/dropout_files.py: 1500 rpm, a multi-turn input
counter beside a single-turn output encoder, drop-outs of 25 ms to 10 s)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import pytest

from tests.io import dropout_files as df

if TYPE_CHECKING:
    from pathlib import Path

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('pandas')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import TransmissionError  # noqa: E402

from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.replay import ReplayNode  # noqa: E402
from rv_te_bench.nodes.te_node import TeNode  # noqa: E402
from tests.nodes.rosutil import spin_for, spin_until  # noqa: E402


def test_imported_dropouts_are_gaps_on_replay(ros_context, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from rv_te_bench.cli.main import main

    r = df.record(duration_s=50.0)
    csv = df.write_pandas_csv(tmp_path / 'run.csv', r)
    bag = tmp_path / 'bag'
    assert main(['import', str(csv), '--bench', str(df.bench_yaml(tmp_path / 'b.yaml')),
                 '--out', str(bag), '--time', 't_s', '--theta-in', 'theta_in_rad',
                 '--theta-out', 'theta_out_rad', '--start-utc', '2026-11-24T09:30:00Z',
                 '--json']) == 0
    blocks = json.loads(capsys.readouterr().out)['blocks']
    ex = SingleThreadedExecutor(context=ros_context)
    te = TeNode(context=ros_context)
    probe = rclpy.create_node('probe', context=ros_context)
    stats: list[TransmissionError] = []
    probe.create_subscription(TransmissionError, 'te/statistics', stats.append,
                              qos.LATCHED_QOS)
    nodes = [te, probe]
    for n in nodes:
        ex.add_node(n)
    try:
        spin_for(ex, 0.5)
        replay = ReplayNode(context=ros_context, parameter_overrides=[
            Parameter('bag', value=str(bag)), Parameter('rate', value=25.0),
            Parameter('wait_for_subscribers_s', value=5.0)])
        nodes.append(replay)
        ex.add_node(replay)
        want = len(df.DROPOUTS)
        assert spin_until(ex, lambda: te._gaps_total >= want and te._blocks >= blocks, 60.0)
        spin_for(ex, 0.5)
    finally:
        ex.shutdown()
        for n in nodes:
            n.destroy_node()
    assert te._gaps_total == len(df.DROPOUTS)
    assert max(s.gaps for s in stats) == len(df.DROPOUTS)
    assert te.last_gap.startswith('seq_jump') and 'no data for 10 s after 35.9995 s' in \
        te.last_gap
    pp = df.true_pp_rad()
    complete = [s for s in stats if s.window_complete]
    assert len(complete) >= 10
    for s in complete:   # a window holding a drop-out would be off by orders of magnitude
        assert s.window.pp_rad == pytest.approx(pp, rel=5e-3)
