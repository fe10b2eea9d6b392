"""Sessions launched as one process per node: two namespaces side by side, clean stop."""

from __future__ import annotations

import time

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rv_te_msgs.msg import EncoderBlock, TeSpectrum  # noqa: E402

from rv_te_bench.launch.session import Session, build_session  # noqa: E402
from rv_te_bench.nodes import qos  # noqa: E402
from tests.nodes.rosutil import spin_until  # noqa: E402


def _spec(ns: str, bench_id: str, rpm: float, revs: float):  # noqa: ANN202
    # each bench starts its clock once its TE node and the test's probe in its namespace
    # subscribe (a bench that starts up fast must not finish before the probe matched it)
    return build_session([], namespace=ns, nodes=['bench', 'te_node'], overrides=[
        f'bench.bench_id={bench_id}', f'bench.speed_rpm={rpm}', 'bench.te_mode=nlte',
        'bench.sample_rate_hz=1000.0', 'bench.time_mode=fast', 'bench.speed_factor=1.0',
        f'bench.duration_output_revs={revs}', 'bench.wait_for_nodes=[te_node, probe]'])


def test_two_namespaced_sessions_do_not_cross(ros_context) -> None:  # noqa: ANN001
    ctx = ros_context
    got: dict[str, list[EncoderBlock]] = {'a': [], 'b': []}
    spectra: dict[str, list[TeSpectrum]] = {'a': [], 'b': []}
    ex = SingleThreadedExecutor(context=ctx)
    probes = []
    for ns in ('a', 'b'):
        probe = rclpy.create_node('probe', namespace=ns, context=ctx)
        probe.create_subscription(EncoderBlock, f'/{ns}/bench/encoders', got[ns].append,
                                  qos.ENCODER_QOS)
        probe.create_subscription(TeSpectrum, f'/{ns}/te/spectrum', spectra[ns].append,
                                  qos.LATCHED_QOS)
        ex.add_node(probe)
        probes.append(probe)
    sa = Session(_spec('a', 'benchA', 3000.0, 1.5))
    sb = Session(_spec('b', 'benchB', 6000.0, 3.0))
    try:
        sa.start()
        sb.start()
        assert spin_until(ex, lambda: sa.bench_done() and sb.bench_done(), 90.0), \
            (sa.poll(), sb.poll())
        assert spin_until(ex, lambda: spectra['a'] and spectra['b'], 20.0)
        time.sleep(0.5)
    finally:
        codes_a = sa.stop()
        codes_b = sb.stop()
        ex.shutdown()
        for probe in probes:
            probe.destroy_node()
    assert got['a'] and got['b']
    assert {m.header.frame_id for m in got['a']} == {'benchA'}
    assert {m.header.frame_id for m in got['b']} == {'benchB'}
    for ns in ('a', 'b'):  # the bench waited for the probe: every block, from seq 0
        seqs = [m.seq for m in got[ns]]
        assert seqs == list(range(len(seqs)))
    # each TE node analysed its own bench: crank frequency f_w = 25 n_in / 79
    assert spectra['a'][0].crank_hz == pytest.approx(25 * 3000 / 60 / 79, rel=1e-3)
    assert spectra['b'][0].crank_hz == pytest.approx(25 * 6000 / 60 / 79, rel=1e-3)
    assert all(c == 0 for c in codes_a.values()), codes_a
    assert all(c == 0 for c in codes_b.values()), codes_b
    assert not sa.failures and not sb.failures


def test_crashing_node_is_reported(ros_context) -> None:  # noqa: ANN001
    # an unknown preset makes the bench exit 1 at start-up: the session reports it
    # (build_session refuses it, as --check does: set it after the checks, as a crash)
    spec = build_session([], nodes=['bench', 'te_node'])
    spec.parameters['bench']['preset'] = 'no-such-reducer'
    s = Session(spec)
    try:
        s.start()
        end = time.monotonic() + 30.0
        while time.monotonic() < end and not s.failures:
            s.poll()
            time.sleep(0.1)
    finally:
        s.stop()
    assert any("'bench'" in f and 'code 1' in f for f in s.failures), s.failures
