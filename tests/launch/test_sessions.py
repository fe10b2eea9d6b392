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


def _spec(ns: str, bench_id: str, rpm: float, revs: float):
    # each bench starts its clock once its TE node and the test's probe in its namespace
    # subscribe (a bench that starts up fast must not finish before the probe matched it)
    return build_session([], namespace=ns, nodes=['bench', 'te_node'], overrides=[
        f'bench.bench_id={bench_id}', f'bench.speed_rpm={rpm}', 'bench.te_mode=nlte',
        'bench.sample_rate_hz=1000.0', 'bench.time_mode=fast', 'bench.speed_factor=1.0',
        f'bench.duration_output_revs={revs}', 'bench.wait_for_nodes=[te_node, probe]'])


def test_two_namespaced_sessions_do_not_cross(ros_context) -> None:
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


def test_crashing_node_is_reported(ros_context) -> None:
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


def _bag_times(bag) -> tuple[dict[str, list[int]], list[int], list[int]]:
    """(clock values by clock topic [ns], encoder log times [ns], encoder header stamps [ns]),
    read with the mcap library (not our reader)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    clocks: dict[str, list[int]] = {}
    log_ns: list[int] = []
    stamp_ns: list[int] = []
    for f in sorted(bag.glob('*.mcap')):
        with f.open('rb') as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            for _s, channel, message, msg in reader.iter_decoded_messages():
                if channel.topic.endswith('/clock'):
                    clocks.setdefault(channel.topic, []).append(
                        msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)
                elif channel.topic.endswith('/bench/encoders'):
                    log_ns.append(message.log_time)
                    stamp_ns.append(msg.header.stamp.sec * 1_000_000_000
                                    + msg.header.stamp.nanosec)
    return clocks, log_ns, stamp_ns


@pytest.mark.timeout(180)
def test_two_namespaced_fast_sessions_keep_their_own_clock(tmp_path) -> None:
    """Issue #22: two fast (sim-time) sessions in namespaces a and b shared /clock; each
    recorder kept the largest /clock it saw, so a bag logged its blocks at the other
    session's clock. A namespaced sim-time session now runs on <ns>/clock: every encoder
    block is logged at its own header stamp, and each bag holds its own clock only."""
    sessions = {}
    for ns, rpm, revs in (('a', 3000.0, 3.0), ('b', 6000.0, 6.0)):
        sessions[ns] = Session(build_session([], namespace=ns,
                                             nodes=['bench', 'te_node', 'recorder'], overrides=[
            f'bench.bench_id=bench_{ns}', f'bench.speed_rpm={rpm}', 'bench.te_mode=nlte',
            'bench.sample_rate_hz=1000.0', 'bench.time_mode=fast', 'bench.speed_factor=1.0',
            f'bench.duration_output_revs={revs}', f'recorder.output_dir={tmp_path}',
            f'recorder.bag_name={ns}']))
    try:
        for s in sessions.values():
            s.start()
        end = time.monotonic() + 120.0
        while time.monotonic() < end and not all(s.bench_done() for s in sessions.values()):
            for s in sessions.values():
                s.poll()
            time.sleep(0.1)
        assert all(s.bench_done() for s in sessions.values()), [s.poll() for s in
                                                                 sessions.values()]
        time.sleep(1.0)
    finally:
        codes = {ns: s.stop() for ns, s in sessions.items()}
    assert all(c == 0 for cs in codes.values() for c in cs.values()), codes
    block_ns = 100_000_000   # blocks of 100 samples at 1 kHz
    read = {ns: _bag_times(tmp_path / ns) for ns in ('a', 'b')}
    for ns, (_clocks, log_ns, stamp_ns) in read.items():
        diffs = [a - b for a, b in zip(log_ns, stamp_ns, strict=True)]
        print(f'{ns}: {len(diffs)} blocks, {sum(d == 0 for d in diffs)} logged exactly at '
              f'their stamp, worst {max(map(abs, diffs), default=0) * 1e-9:.3f} s')
    for ns, (clocks, log_ns, stamp_ns) in read.items():
        assert log_ns and len(log_ns) == len(stamp_ns)
        diffs = [a - b for a, b in zip(log_ns, stamp_ns, strict=True)]
        assert all(d == 0 for d in diffs), (ns, sorted(set(diffs))[-3:])
        assert list(clocks) == [f'/{ns}/clock'], list(clocks)   # its own clock only
        own = clocks[f'/{ns}/clock']
        assert min(stamp_ns) <= min(own) and max(own) <= max(stamp_ns) + block_ns + 1000


def test_node_processes_get_one_blas_thread_unless_set(monkeypatch) -> None:
    """Issue #23 item 1: every node process has one BLAS / OpenMP thread by default (16 node
    processes of four benches on 2 cores: OpenBLAS's spinning pool doubled the compensation
    node's CPU); a value the user set is kept."""
    from rv_te_bench.launch.session import NODE_THREAD_ENV, child_env

    for var in NODE_THREAD_ENV:
        monkeypatch.delenv(var, raising=False)
    env = child_env()
    assert all(env[v] == '1' for v in NODE_THREAD_ENV)
    monkeypatch.setenv('OPENBLAS_NUM_THREADS', '2')
    assert child_env()['OPENBLAS_NUM_THREADS'] == '2'
