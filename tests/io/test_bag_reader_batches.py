"""read_encoder_batches (the fast offline path) gives exactly the blocks read_encoder_blocks
gives; read_bench_info through the summary index equals a full scan; prefetching changes
nothing but the speed."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData
from rv_te_bench.errors import BagError
from rv_te_bench.io import _mcap_scan, bag_reader
from rv_te_bench.io.bag_reader import (
    open_bag,
    read_bench_info,
    read_encoder_batches,
    read_encoder_blocks,
)
from rv_te_bench.io.bag_writer import BagWriter
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, rv_te_typestore
from tests.io.bag_fixtures import (
    ENCODER_TOPIC,
    INFO_TOPIC,
    T0_NS,
    bench_info_cdr,
    encoder_cdr,
    write_sample_bag,
)

FIELDS = ('time_offset_s', 'theta_in_rad', 'theta_out_rad')


def _flatten(items: list[EncoderBatch | EncoderBlockData]) -> list[EncoderBlockData]:
    out: list[EncoderBlockData] = []
    for item in items:
        if isinstance(item, EncoderBatch):
            out += [item.block(k) for k in range(item.n_blocks)]
        else:
            out.append(item)
    return out


def _assert_same_blocks(got: list[EncoderBlockData], ref: list[EncoderBlockData]) -> None:
    assert len(got) == len(ref)
    for a, b in zip(got, ref, strict=True):
        assert (a.seq, a.stamp_s, a.sample_rate_hz) == (b.seq, b.stamp_s, b.sample_rate_hz)
        for name in FIELDS:
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def _big_endian(seq: int, n: int) -> bytes:
    store = rv_te_typestore()
    msg = store.deserialize_cdr(encoder_cdr(seq, n), ENCODER_BLOCK)
    return bytes(store.serialize_cdr(msg, ENCODER_BLOCK, little_endian=False))


def _mixed_bag(path: Path) -> None:
    """Encoder blocks of many sizes (records at every byte alignment), other topics in
    between, and messages that cannot be batched or decoded."""
    with BagWriter(path, chunk_size_bytes=6000) as w:
        w.add_topic(INFO_TOPIC, BENCH_INFO)
        w.add_topic(ENCODER_TOPIC, ENCODER_BLOCK)
        w.add_topic('/other', 'std_msgs/msg/String')
        store = rv_te_typestore()
        text = store.types['std_msgs/msg/String']
        w.write(INFO_TOPIC, T0_NS, bench_info_cdr())
        t = T0_NS
        for seq in range(60):
            t += 1000
            n = 1 + (seq * 37) % 90
            if seq == 13:
                data = _big_endian(seq, n)                  # decoded alone
            elif seq == 21:
                data = encoder_cdr(seq, n)[:40]             # cut short: reported, skipped
            elif seq == 34:
                data = encoder_cdr(seq, n, torque=False)    # no torque: still batchable
            else:
                data = encoder_cdr(seq, n, frame_id='b' * (seq % 9))
            w.write(ENCODER_TOPIC, t, data)
            if seq % 4 == 0:
                w.write('/other', t, bytes(store.serialize_cdr(text(data='x' * seq),
                                                               'std_msgs/msg/String')))


@pytest.mark.parametrize('merge', [False, True])
@pytest.mark.parametrize('read_ahead', ['own thread', 'shared executor', 'none'])
def test_batches_equal_blocks_on_a_mixed_bag(tmp_path: Path, read_ahead: str, merge: bool,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """The batches (merged across chunks or not) hold exactly the blocks read one by one,
    in order, around the blocks that go alone (big-endian, cut short)."""
    monkeypatch.setitem(_mcap_scan._scan_units.__kwdefaults__, 'prefetch',
                        read_ahead != 'none')
    monkeypatch.setattr(bag_reader, 'MERGE_SAMPLES', 400)   # ~8 chunks of this bag
    bag = tmp_path / 'mixed'
    _mixed_bag(bag)
    ref_stream = read_encoder_blocks(bag, strict=False)
    ref = list(ref_stream)
    with ThreadPoolExecutor(max_workers=1) as helper:
        stream = read_encoder_batches(
            bag, strict=False, executor=helper if read_ahead == 'shared executor' else None,
            merge=merge)
        items = list(stream)
    assert any(isinstance(i, EncoderBatch) and i.n_blocks > 1 for i in items)
    if merge:   # batches span chunks: fewer of them than chunk by chunk, none empty
        chunkwise = list(read_encoder_batches(bag, strict=False))
        assert len(items) < len(chunkwise)
        assert max(i.n_samples for i in items if isinstance(i, EncoderBatch)) > max(
            i.n_samples for i in chunkwise if isinstance(i, EncoderBatch))
    _assert_same_blocks(_flatten(items), ref)
    assert [b.seq for b in ref] == [s for s in range(60) if s != 21]
    assert stream.problems == ref_stream.problems
    assert len(stream.problems) == 1
    assert 'message 21' in stream.problems[0]
    assert stream.partial


def test_batches_stop_at_truncation_like_blocks(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=30, compression='zstd', chunk_size_bytes=4096)
    (file,) = bag.glob('*.mcap')
    data = file.read_bytes()
    file.write_bytes(data[: len(data) // 2])
    ref = read_encoder_blocks(bag, strict=False)
    got = read_encoder_batches(bag, strict=False)
    _assert_same_blocks(_flatten(list(got)), list(ref))
    assert got.problems == ref.problems
    assert got.partial
    with pytest.raises(BagError, match='truncated'):
        list(read_encoder_batches(bag))


def test_abandoned_read_leaves_no_worker_thread(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=40, compression='zstd', chunk_size_bytes=2048)
    before = {t.name for t in threading.enumerate()}
    stream = read_encoder_batches(bag)
    next(stream)
    stream._it.close()
    assert not {t.name for t in threading.enumerate()
                if t.name.startswith('mcap-read')} - before


def test_abandoned_read_leaves_a_shared_executor_running_and_idle(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A read that stops early with a caller's executor (analyze_bag's helper thread): the
    chunks queued ahead are cancelled, the one being decompressed is waited for (the file's
    map is closed after it), and the executor is not shut down."""
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=40, compression='zstd', chunk_size_bytes=2048)
    real = _mcap_scan._chunk_records
    decompressed: list[str] = []

    def counted(body: memoryview, *check: bool) -> memoryview:
        decompressed.append(threading.current_thread().name)
        time.sleep(0.002)   # the read-ahead queue is still full when the read stops
        return real(body, *check)

    monkeypatch.setattr(_mcap_scan, '_chunk_records', counted)
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix='shared') as helper:
        stream = read_encoder_batches(bag, executor=helper)
        next(stream)
        stream._it.close()
        at_close = len(decompressed)
        assert helper.submit(lambda: 42).result() == 42   # still running; runs after them
        assert len(decompressed) == at_close               # nothing queued was left to run
    assert set(decompressed) == {'shared_0'}
    assert at_close < 20


def test_a_reader_closed_on_the_shared_executors_thread_does_not_wait_for_itself(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The garbage collector may finalise an abandoned reader on any thread, also inside a
    job of the shared executor: the reader then must not wait for its jobs (one of them is
    the job it runs in), or the executor's only thread would wait for itself forever."""
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=40, compression='zstd', chunk_size_bytes=2048)
    real = _mcap_scan._chunk_records
    calls: list[int] = []
    caller_out, closed = threading.Event(), threading.Event()
    box: dict[str, object] = {}

    def closing_in_the_second_job(body: memoryview, *check: bool) -> memoryview:
        calls.append(1)
        if len(calls) == 2:
            assert caller_out.wait(5.0)
            box['stream']._it.close()
            closed.set()
        return real(body, *check)

    monkeypatch.setattr(_mcap_scan, '_chunk_records', closing_in_the_second_job)
    helper = ThreadPoolExecutor(max_workers=1)
    try:
        box['stream'] = stream = read_encoder_batches(bag, executor=helper)
        next(stream)
        caller_out.set()
        assert closed.wait(10.0), 'the reader waited for the job it was closed in'
        assert helper.submit(lambda: 42).result(timeout=10.0) == 42
    finally:
        helper.shutdown(wait=False, cancel_futures=True)   # (a deadlocked one: report it)


def test_bench_info_from_the_summary_equals_a_scan(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=30, compression='zstd', chunk_size_bytes=4096)
    (file,) = open_bag(bag).files
    indexed = _mcap_scan._indexed_messages(file, [INFO_TOPIC])
    assert indexed == [(BENCH_INFO, bench_info_cdr())]
    fast = read_bench_info(bag)
    # a damaged summary (CRC mismatch) is not trusted: the reader scans the file instead
    data = bytearray(file.read_bytes())
    data[-8 - 37 + 9 + 16] ^= 0xFF   # the footer's summary CRC
    file.write_bytes(bytes(data))
    assert _mcap_scan._indexed_messages(file, [INFO_TOPIC]) is None
    assert read_bench_info(bag) == fast
    assert fast is not None
    assert fast.preset == 'wang2020-2kv'


def test_bench_info_of_a_killed_recording(tmp_path: Path) -> None:
    """No summary (the recorder never closed the file): found by scanning."""
    bag = tmp_path / 'bag'
    writer = write_sample_bag(bag, n_blocks=10, close=False, chunk_size_bytes=2048)
    writer.flush()
    (file,) = open_bag(bag).files
    assert _mcap_scan._indexed_messages(file, [INFO_TOPIC]) is None
    info = read_bench_info(bag)
    assert info is not None
    assert info.gear_ratio == 79.0
    writer.close()


@pytest.mark.parametrize('odd', ['first_big_endian', 'other_length', 'no_torque', 'short'])
def test_one_message_off_the_common_layout(tmp_path: Path, odd: str) -> None:
    """Messages laid out alike take the fast path; one that differs sends the chunk through
    the general parse, with the same blocks and problems as the one-by-one reader."""
    bag = tmp_path / 'bag'
    with BagWriter(bag, chunk_size_bytes=1 << 20) as w:
        w.add_topic(ENCODER_TOPIC, ENCODER_BLOCK)
        for seq in range(12):
            data = encoder_cdr(seq, 50)
            if seq == 5 and odd == 'other_length':
                data = encoder_cdr(seq, 49)
            elif seq == 5 and odd == 'no_torque':
                data = encoder_cdr(seq, 50, torque=False)
            elif seq == 5 and odd == 'short':
                data = data[:60]
            elif seq == 0 and odd == 'first_big_endian':
                data = _big_endian(seq, 50)
            w.write(ENCODER_TOPIC, T0_NS + seq, data)
    ref = read_encoder_blocks(bag, strict=False)
    ref_blocks = list(ref)
    got = read_encoder_batches(bag, strict=False)
    _assert_same_blocks(_flatten(list(got)), ref_blocks)
    assert got.problems == ref.problems
    assert len(ref_blocks) == (11 if odd == 'short' else 12)


def test_bench_info_in_the_first_of_split_files(tmp_path: Path) -> None:
    """A later split file without BenchInfo is answered from its summary (no scan)."""
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=200, compression='zstd', chunk_size_bytes=4096,
                     split_size_bytes=20_000)
    files = open_bag(bag).files
    assert len(files) > 1
    assert _mcap_scan._indexed_messages(files[0], [INFO_TOPIC]) == [
        (BENCH_INFO, bench_info_cdr())]
    assert _mcap_scan._indexed_messages(files[-1], [INFO_TOPIC]) == []
    info = read_bench_info(bag)
    assert info is not None
    assert info.preset == 'wang2020-2kv'


def test_bag_topics_of_a_folder_and_of_its_lone_file(tmp_path: Path) -> None:
    """A lone .mcap file answers with the types and offered QoS its channels carry, the
    same as metadata.yaml; from the summary, and by a scan when there is none."""
    import yaml

    from rv_te_bench.io.bag_reader import bag_topics

    def parsed(topics: dict) -> dict:
        return {t: (v['type'], yaml.safe_load(v['offered_qos_profiles'])
                    if isinstance(v['offered_qos_profiles'], str) else v['offered_qos_profiles'])
                for t, v in topics.items()}

    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=5, chunk_size_bytes=2048)
    (file,) = open_bag(bag).files
    folder = parsed(bag_topics(bag))
    assert set(folder) == {ENCODER_TOPIC, INFO_TOPIC}
    assert folder[INFO_TOPIC][1][0]['durability'] == 'transient_local'
    assert parsed(bag_topics(file)) == folder
    killed = tmp_path / 'killed'
    writer = write_sample_bag(killed, n_blocks=5, close=False, chunk_size_bytes=2048)
    writer.flush()
    (kfile,) = open_bag(killed).files
    assert _mcap_scan._summary(kfile) is None
    assert parsed(bag_topics(kfile)) == folder
    writer.close()


def test_a_bag_damaged_all_through_gives_one_readable_line(tmp_path: Path) -> None:
    """Every chunk corrupt: the error names the first problems and counts the rest; the
    analysis keeps the full list for the JSON."""
    from rv_te_bench.report.analysis import analyze_bag

    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=40, compression='none', chunk_size_bytes=2048)
    (file,) = bag.glob('*.mcap')
    data = bytearray(file.read_bytes())
    for seq in range(40):   # flip a byte inside every block's theta_in_rad
        at = data.find(encoder_cdr(seq, 100)[1000:1040])
        data[at + 5] ^= 0xFF
    file.write_bytes(bytes(data))
    with pytest.raises(BagError) as err:
        list(read_encoder_batches(bag))
    text = str(err.value)
    assert text.count('CRC mismatch') == 3
    assert '... and ' in text
    assert len(text) < 1000
    with pytest.raises(BagError, match=r'damaged: .*; \.\.\. and 37 more problems; pass --ratio '
                                         r'and --crank-per-output to analyse the rest'):
        analyze_bag(bag, with_advice=False)


def test_partial_analysis_keeps_every_read_problem(tmp_path: Path) -> None:
    from rv_te_bench.report.analysis import analyze_bag

    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=40, compression='none', chunk_size_bytes=2048)
    (file,) = bag.glob('*.mcap')
    data = bytearray(file.read_bytes())
    for seq in range(20, 40):
        at = data.find(encoder_cdr(seq, 100)[1000:1040])
        data[at + 5] ^= 0xFF
    file.write_bytes(bytes(data))
    res = analyze_bag(bag, with_advice=False, gear_ratio=79.0, crank_per_output=25.0)
    assert res.partial
    n_bad = len(res.read_problems)
    assert n_bad >= 10   # one per damaged chunk
    assert all('CRC mismatch' in p for p in res.read_problems)
    assert res.problems[0].endswith(f'... and {n_bad - 3} more problems')
    assert res.to_json_dict()['read_problems'] == list(res.read_problems)
    assert res.blocks_read == 20


@pytest.mark.parametrize(('env', 'thread'), [(None, True), ('1', True), ('0', False)])
def test_read_ahead_switch(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                           env: str | None, thread: bool) -> None:
    """RV_TE_READ_AHEAD=0 (set in the workers of a fleet run with a worker per core) reads
    without the read-ahead thread; the blocks are the same."""
    if env is None:
        monkeypatch.delenv(bag_reader.READ_AHEAD_ENV, raising=False)
    else:
        monkeypatch.setenv(bag_reader.READ_AHEAD_ENV, env)
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=30, compression='zstd', chunk_size_bytes=4096)
    seen = set()
    items = []
    for item in read_encoder_batches(bag):
        seen |= {t.name for t in threading.enumerate()}
        items.append(item)
    assert any(n.startswith('mcap-read') for n in seen) is thread
    assert [b.seq for b in _flatten(items)] == list(range(30))


@pytest.mark.parametrize('layout', ['equal_steps', 'unequal_steps', 'unequal_counts', 'one'])
def test_concat_f64_copies_every_array_whatever_the_layout(layout: str) -> None:
    """The strided one-copy path (equal lengths at equal steps, any alignment) and the
    per-message path give the arrays' bytes, checked against a struct read of each."""
    import struct

    from rv_te_bench.io._encoder_cdr import _concat_f64

    rng = np.random.default_rng(5)
    buf = bytearray(rng.integers(0, 256, 20_000, dtype=np.uint8).tobytes())
    counts = {'equal_steps': [40] * 6, 'unequal_steps': [40] * 6,
              'unequal_counts': [40, 41, 40, 39, 40, 40], 'one': [40]}[layout]
    step = 333                                    # odd: the arrays are not 8-byte aligned
    pos = [7 + k * step + (k * k * 3 if layout == 'unequal_steps' else 0)
           for k in range(len(counts))]
    want = []
    for p, c in zip(pos, counts, strict=True):
        values = rng.normal(size=c)
        buf[p:p + 8 * c] = struct.pack(f'<{c}d', *values)
        want.extend(struct.unpack_from(f'<{c}d', buf, p))
    got = _concat_f64(np.frombuffer(bytes(buf), np.uint8), np.array(pos), np.array(counts))
    np.testing.assert_array_equal(got, np.array(want))
