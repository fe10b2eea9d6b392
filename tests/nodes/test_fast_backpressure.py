"""A fast session loses no block to a slow reader (bench back-pressure, issue 41 point 5).

In fast mode the bench publishes as fast as it can; a recorder further behind than the
encoder queue (1000 blocks) lost the oldest (5,714 of 6,000 blocks in a 10-minute bag beside
load 10-15). The bench now holds back while a waited-for reader acknowledges less than
``ACK_WINDOW_BLOCKS`` behind its newest block. Real nodes over the middleware: the bench
spins in its own thread, the recorder (slowed: every block's write waits 4 ms, ~250
blocks/s, far below the bench's speed) on the test's; the bag is read back by rosbags.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import EncoderBlock  # noqa: E402

from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.backpressure import ACK_WINDOW_BLOCKS, BlockAcks  # noqa: E402
from rv_te_bench.nodes.bench_node import BenchNode  # noqa: E402
from rv_te_bench.nodes.recorder import RecorderNode  # noqa: E402
from tests.nodes.rosutil import spin_for, spin_until, spin_while_progress  # noqa: E402

BLOCKS = 3000          # 30 s at 10 kHz in blocks of 100: three encoder queues
#: The sessions without a slow reader: three windows (ACK_WINDOW_BLOCKS, 500), so a bench
#: held by a reader that took 200 blocks has to wait for it, and one nobody holds shows it
#: ran free (1.5 s of CPU less per test than BLOCKS: ~1 ms of rclpy per block).
FREE_BLOCKS = 1500
WRITE_DELAY_S = 0.004  # the slowed recorder: ~250 blocks/s


def _bench(ctx: Any, ns: str, waits: list[str], **extra: Any) -> BenchNode:
    params = {'preset': 'wang2020-2kv', 'te_mode': 'nlte', 'sample_rate_hz': 10000.0,
              'block_size': 100, 'duration_s': BLOCKS * 100 / 10000.0, 'time_mode': 'fast',
              'speed_factor': 0.0, 'wait_for_nodes': waits, 'wait_timeout_s': 3.0 if not
              waits else 30.0, **extra}
    return BenchNode(context=ctx, namespace=ns,
                     parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])


def _spin_in_thread(ex: SingleThreadedExecutor, stop: threading.Event) -> threading.Thread:
    def run() -> None:
        while not stop.is_set():
            ex.spin_once(timeout_sec=0.05)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t


def _seqs(bag: Path, topic: str) -> list[int]:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [int(reader.deserialize(raw, c.msgtype).seq)
                for c, _, raw in reader.messages(connections=conns)]


@pytest.mark.timeout(180)
def test_slow_recorder_records_every_block(ros_context: Any, tmp_path: Path) -> None:
    ns = f'/bp_{os.getpid()}_{time.monotonic_ns() % 10**6}'
    topic = f'{ns}/bench/encoders'
    recorder = RecorderNode(context=ros_context, namespace=ns, parameter_overrides=[
        Parameter('output_dir', value=str(tmp_path)), Parameter('bag_name', value='bag'),
        Parameter('topics', value=['bench/encoders', 'bench/info'])])
    write = recorder._writer.write

    def slow_write(name: str, t_ns: int, data: bytes) -> None:
        if name == topic:
            time.sleep(WRITE_DELAY_S)
        write(name, t_ns, data)

    recorder._writer.write = slow_write   # type: ignore[method-assign]
    bench = _bench(ros_context, ns, ['recorder'])
    ex_rec, ex_bench = SingleThreadedExecutor(context=ros_context), \
        SingleThreadedExecutor(context=ros_context)
    ex_rec.add_node(recorder)
    ex_bench.add_node(bench)
    stop = threading.Event()
    thread = _spin_in_thread(ex_bench, stop)
    try:
        assert spin_until(ex_rec, lambda: bench.finished, 150.0), 'the bench never finished'
        spin_until(ex_rec, lambda: recorder.counts.get(topic, 0) >= BLOCKS, 30.0)
        stop.set()
        thread.join()
        recorder.close()
        assert recorder.gaps[topic] == (0, 0)
        seqs = _seqs(tmp_path / 'bag', topic)
        assert seqs == list(range(BLOCKS)), (
            f'{len(seqs)} of {BLOCKS} blocks on disk, {len(set(range(BLOCKS)) - set(seqs))} '
            'missing')
        assert bench.gate is not None and bench.gate.held_s > 0   # it did hold back
    finally:
        stop.set()
        ex_rec.shutdown()
        ex_bench.shutdown()
        bench.destroy_node()
        recorder.destroy_node()


@pytest.mark.timeout(120)
def test_bench_without_reader_is_not_held(ros_context: Any) -> None:
    """No recorder there (the wait times out): nobody holds the bench, it runs free."""
    ns = f'/bpnone_{os.getpid()}_{time.monotonic_ns() % 10**6}'
    bench = _bench(ros_context, ns, ['recorder'], wait_timeout_s=1.0,
                   duration_s=FREE_BLOCKS * 100 / 10000.0)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(bench)
    try:
        assert spin_until(ex, lambda: bench.finished, 100.0)
        assert bench.blocks_published == FREE_BLOCKS
        assert bench.gate is not None
        assert bench.gate.held_s == 0.0 and bench.gate.released == []
    finally:
        ex.shutdown()
        bench.destroy_node()


@pytest.mark.timeout(120)
def test_reader_that_dies_does_not_hang_the_bench(ros_context: Any) -> None:
    """A te_node that acknowledges 200 blocks and then is gone: the bench waits
    ``ack_timeout_s`` for it, lets it go (named in the diagnostics), and finishes."""
    ns = f'/bpdead_{os.getpid()}_{time.monotonic_ns() % 10**6}'
    seen: list[int] = []
    reader = rclpy.create_node('te_node', namespace=ns, context=ros_context)

    def on_block(m: EncoderBlock) -> None:
        if len(seen) < 200:
            seen.append(int(m.seq))

    reader.create_subscription(EncoderBlock, 'bench/encoders', on_block, qos.ENCODER_QOS)
    BlockAcks(reader, lambda: seen[-1] if seen else None)
    bench = _bench(ros_context, ns, ['te_node'], ack_timeout_s=1.0,
                   duration_s=FREE_BLOCKS * 100 / 10000.0)
    assert FREE_BLOCKS > 200 + ACK_WINDOW_BLOCKS    # the gate must hold for the dead reader
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(bench)
    ex.add_node(reader)
    try:
        assert spin_until(ex, lambda: len(seen) >= 200, 60.0)
        ex.remove_node(reader)
        reader.destroy_node()       # died mid-session
        t0 = time.monotonic()
        assert spin_until(ex, lambda: bench.finished, 60.0), 'the bench hung on a dead reader'
        assert bench.gate is not None and bench.gate.released == ['te_node']
        assert bench.blocks_published == FREE_BLOCKS
        assert time.monotonic() - t0 < 60.0
    finally:
        ex.shutdown()
        bench.destroy_node()


def _run_program(ex: SingleThreadedExecutor, client: Any, blocks: int) -> Any:
    """Ask the bench (bench/run_program, as the sequencer does) for a drive of ``blocks``."""
    import yaml
    from rv_te_msgs.srv import RunBenchProgram

    program = [{'kind': 'drive', 'speed_rpm': 1000.0, 'duration_s': blocks * 100 / 10000.0}]
    future = client.call_async(RunBenchProgram.Request(program_yaml=yaml.safe_dump(program)))
    assert spin_until(ex, future.done, 30.0), 'bench/run_program did not answer'
    resp = future.result()
    assert resp.accepted, resp.reason
    assert resp.block_count == blocks
    return resp


@pytest.mark.timeout(240)
def test_program_bench_waits_for_a_slow_recorder(ros_context: Any, tmp_path: Path) -> None:
    """A bench running programs (commanded, the sequencer's whole-reducer route) in fast
    mode waits for its recorder too: two programs, the second once the recorder has taken
    the first (its seq starts where the first ended: the gate starts over from there, not
    from seq 0), the recorder slowed to ~250 blocks/s. Every block of both programs is in
    the bag, in order, and the recorder was never let go."""
    from rv_te_msgs.srv import RunBenchProgram

    first, second = 2000, 1500     # the first alone is twice the encoder queue
    ns = f'/bpprog_{os.getpid()}_{time.monotonic_ns() % 10**6}'
    topic = f'{ns}/bench/encoders'
    recorder = RecorderNode(context=ros_context, namespace=ns, parameter_overrides=[
        Parameter('output_dir', value=str(tmp_path)), Parameter('bag_name', value='bag'),
        Parameter('topics', value=['bench/encoders', 'bench/info'])])
    write = recorder._writer.write

    def slow_write(name: str, t_ns: int, data: bytes) -> None:
        if name == topic:
            time.sleep(WRITE_DELAY_S)
        write(name, t_ns, data)

    recorder._writer.write = slow_write   # type: ignore[method-assign]
    bench = _bench(ros_context, ns, ['recorder'], commanded=True, duration_s=0.0)
    caller = rclpy.create_node('caller', namespace=ns, context=ros_context)
    client = caller.create_client(RunBenchProgram, 'bench/run_program')
    ex_rec, ex_bench = SingleThreadedExecutor(context=ros_context), \
        SingleThreadedExecutor(context=ros_context)
    ex_rec.add_node(recorder)
    ex_rec.add_node(caller)
    ex_bench.add_node(bench)
    stop = threading.Event()
    thread = _spin_in_thread(ex_bench, stop)
    try:
        assert client.wait_for_service(timeout_sec=30.0)
        assert spin_until(ex_rec, lambda: bench.get_subscriptions_info_by_topic(topic)
                          and bench.count_publishers(f'{ns}/bench/acked/recorder') >= 1
                          and bench.pub_blocks.get_subscription_count() >= 1, 30.0)
        assert _run_program(ex_rec, client, first).first_seq == 0
        assert spin_until(ex_rec, lambda: not bench.program.running, 150.0), \
            'the first program never ended'
        # the recorder has taken all of it and said so: the second program starts from a
        # reader that acknowledges nothing before its first block
        assert spin_while_progress(ex_rec, lambda: recorder.counts.get(topic, 0) >= first,
                                   lambda: recorder.counts.get(topic, 0), idle_s=10.0)
        spin_for(ex_rec, 0.3)
        assert _run_program(ex_rec, client, second).first_seq == first
        assert spin_until(ex_rec, lambda: not bench.program.running, 150.0), \
            'the second program never ended'
        spin_while_progress(ex_rec, lambda: recorder.counts.get(topic, 0) >= first + second,
                            lambda: recorder.counts.get(topic, 0), idle_s=10.0)
        stop.set()
        thread.join()
        recorder.close()
        seqs = _seqs(tmp_path / 'bag', topic)
        total = first + second
        assert seqs == list(range(total)), (
            f'{len(seqs)} of {total} blocks on disk, {len(set(range(total)) - set(seqs))} '
            'missing')
        assert recorder.gaps[topic] == (0, 0)
        assert bench.gate is not None and bench.gate.held_s > 0   # it did hold back
        assert bench.gate.released == []
    finally:
        stop.set()
        ex_rec.shutdown()
        ex_bench.shutdown()
        caller.destroy_node()
        bench.destroy_node()
        recorder.destroy_node()


@pytest.mark.timeout(60)
def test_first_block_waits_for_each_reader_to_take_it(ros_context: Any) -> None:
    """A reader's side of the match can come after the bench's: the bench sends its first
    block, then waits until every holding reader has acknowledged it (blocks sent before
    reached a sim-time recorder late, logged at a later clock). A reader that has not
    taken block 0 keeps the bench at one block; once it acknowledges, the bench runs."""
    ns = f'/bpfirst_{os.getpid()}_{time.monotonic_ns() % 10**6}'
    seen: list[int] = []
    taking = threading.Event()
    reader = rclpy.create_node('te_node', namespace=ns, context=ros_context)

    reader.create_subscription(EncoderBlock, 'bench/encoders',
                               lambda m: seen.append(int(m.seq)), qos.ENCODER_QOS)
    # it acknowledges what it took only once `taking` is set (a reader not matched yet)
    BlockAcks(reader, lambda: seen[-1] if seen and taking.is_set() else None)
    bench = _bench(ros_context, ns, ['te_node'], ack_timeout_s=30.0,
                   duration_s=FREE_BLOCKS * 100 / 10000.0)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(bench)
    ex.add_node(reader)
    try:
        assert spin_until(ex, lambda: bench.blocks_published >= 1, 30.0)
        spin_for(ex, 1.0)
        assert bench.blocks_published == 1, 'ran on before its reader took the first block'
        taking.set()
        assert spin_until(ex, lambda: bench.finished, 25.0), 'still held after the ack'
        assert bench.blocks_published == FREE_BLOCKS
        assert bench.gate is not None and bench.gate.released == []   # (not by the timeout)
    finally:
        ex.shutdown()
        reader.destroy_node()
        bench.destroy_node()


@pytest.mark.timeout(60)
def test_an_acknowledgement_that_stands_is_said_again(ros_context: Any) -> None:
    """An acknowledgement sent before the bench's reader matched is lost; one that does not
    move is said again every ACK_REPEAT_PERIODS periods (0.5 s), so a bench held at its
    first block does not wait for its ack timeout."""
    from std_msgs.msg import UInt64

    from rv_te_bench.nodes.backpressure import ACK_PERIOD_S, ACK_QOS, ACK_REPEAT_PERIODS

    ns = f'/bprepeat_{os.getpid()}_{time.monotonic_ns() % 10**6}'
    reader = rclpy.create_node('te_node', namespace=ns, context=ros_context)
    BlockAcks(reader, lambda: 0)                      # took block 0, and nothing since
    got: list[int] = []
    bench = rclpy.create_node('bench', namespace=ns, context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(reader)
    ex.add_node(bench)
    try:
        spin_for(ex, 1.0)                             # the first ack went before we listened
        bench.create_subscription(UInt64, 'bench/acked/te_node',
                                  lambda m: got.append(int(m.data)), ACK_QOS)
        assert spin_until(ex, lambda: bool(got), 20 * ACK_REPEAT_PERIODS * ACK_PERIOD_S)
        assert got[0] == 0
    finally:
        ex.shutdown()
        reader.destroy_node()
        bench.destroy_node()
