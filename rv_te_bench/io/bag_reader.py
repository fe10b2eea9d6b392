"""Read rosbag2 (MCAP storage) bags without rclpy: summary, raw messages, encoder blocks.

The reader scans the MCAP records itself (no summary needed) so that bags whose recorder
was killed, or whose last file was cut short, still yield every sound message; what could
not be read is reported. ``EncoderBlock`` messages are decoded straight from their CDR
layout into read-only numpy arrays (``np.frombuffer``), which is several times faster than
generic deserialisation; ``decode_encoder_block_rosbags`` is the slower cross-check.

This module is the public face of the reading side: the readers, on top of a layout as
rosbags' (``rosbag2/reader.py`` on ``storage_mcap.py`` / ``storage_sqlite3.py``, types
below): the record types (:class:`Bag`, :class:`MessageStream`) in :mod:`._bag_types`;
the opener choosing the storage (:func:`open_bag`) in :mod:`._bag_open`; the storages in
:mod:`._storage_mcap` (on the MCAP record walk, summary and read-ahead of
:mod:`._mcap_scan`) and :mod:`._storage_sqlite3`; the EncoderBlock CDR decoders in
:mod:`._encoder_cdr`. The BenchInfo reader is :mod:`.bench_record`; :func:`read_bench_info`,
the types, the opener and the decoders are re-exported here, the module users import.

Partial results: every reader returns a ``MessageStream``. With ``strict=True`` (default)
it raises ``BagError`` after the last sound message when part of the bag was unreadable
(truncated file, corrupt chunk, malformed message), naming the file and the problem; with
``strict=False`` it stops quietly and ``stream.partial`` / ``stream.problems`` say so.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import BagError
from rv_te_bench.io._bag_open import messages, open_bag, scan_topics, topic_types, unit_columns
from rv_te_bench.io._bag_types import (
    PROBLEMS_SHOWN,
    Bag,
    MessageStream,
    RawMessage,
    summarize_problems,
)
from rv_te_bench.io._encoder_cdr import (
    BatchArena,
    _encoder_items,
    decode_encoder_block,
    decode_encoder_block_rosbags,
    encoder_block_seq,
)
from rv_te_bench.io._mcap_scan import PREFETCH_CHUNKS, READ_AHEAD_ENV, helper_threads_allowed
from rv_te_bench.io._storage_mcap import mcap_counts
from rv_te_bench.io.bench_record import read_bench_info
from rv_te_bench.io.msgdefs import ENCODER_BLOCK, rv_te_typestore

if TYPE_CHECKING:
    from collections.abc import Collection, Iterator
    from concurrent.futures import Executor
    from pathlib import Path

    from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData

__all__ = [
    'PREFETCH_CHUNKS',
    'PROBLEMS_SHOWN',
    'READ_AHEAD_ENV',
    'Bag',
    'MessageStream',
    'RawMessage',
    'bag_summary',
    'bag_topics',
    'decode_encoder_block',
    'decode_encoder_block_rosbags',
    'encoder_block_seq',
    'helper_threads_allowed',
    'iter_messages',
    'open_bag',
    'read_bench_info',
    'read_encoder_batches',
    'read_encoder_blocks',
    'summarize_problems',
]


# ----------------------------------------------------------------------------- public
def iter_messages(
    path: str | Path, topics: Collection[str] | None = None, *, strict: bool = True,
) -> MessageStream[RawMessage]:
    """Every message of a bag, raw, in recording order (file by file, as logged).

    Args:
        path: Bag folder or ``.mcap`` file.
        topics: Topic names to keep; None keeps all.
        strict: Raise ``BagError`` after the last sound message if part was unreadable.

    Returns:
        Stream of ``(topic, msgtype, timestamp_ns, cdr_bytes)``; ``cdr_bytes`` is a
        read-only memoryview into the decompressed chunk (``bytes()`` makes a copy).

    Raises:
        BagError: Bad layout (at call) or unreadable parts (at the end, when strict).
    """
    bag = open_bag(path)
    return MessageStream(lambda s: messages(bag, s, topics), strict=strict)


def _encoder_topic(bag: Bag, topic: str | None) -> str:
    types = topic_types(bag)
    if topic is not None:
        if topic not in types:
            msg = f'Bag {bag.path} has no topic {topic!r}; topics: {sorted(types)}.'
            raise BagError(msg)
        if types[topic] != ENCODER_BLOCK:
            msg = (f'Bag {bag.path}: topic {topic!r} has type {types[topic]!r}, '
                   f'expected {ENCODER_BLOCK}.')
            raise BagError(msg)
        return topic
    found = sorted(t for t, ty in types.items() if ty == ENCODER_BLOCK)
    if not found:
        msg = f'Bag {bag.path} has no topic of type {ENCODER_BLOCK}; topics: {types}.'
        raise BagError(msg)
    if len(found) > 1:
        msg = f'Bag {bag.path} has several {ENCODER_BLOCK} topics {found}; choose one.'
        raise BagError(msg)
    return found[0]


def bag_topics(path: str | Path) -> dict[str, dict[str, Any]]:
    """Topics of a bag with their type and recorded offered QoS profiles.

    From metadata.yaml for a bag folder; from the MCAP channels (their rosbag2
    ``offered_qos_profiles`` metadata) for a lone ``.mcap`` file, read from the summary
    when the file has one.

    Returns:
        ``{topic: {'type': 'pkg/msg/Type', 'offered_qos_profiles': YAML text, a list, or
        None}}``.

    Raises:
        BagError: Bad layout.
    """
    bag = open_bag(path)
    if bag.info:
        return {str(t['topic_metadata']['name']): {
            'type': str(t['topic_metadata']['type']),
            'offered_qos_profiles': t['topic_metadata'].get('offered_qos_profiles')}
            for t in bag.info.get('topics_with_message_count') or []}
    return scan_topics(bag)


def _check_encoder_definition(bag: Bag, topic: str) -> None:
    """Refuse a bag whose EncoderBlock definition differs from ours (decode would lie);
    the definition before issue 36 (no head fields) is read as well."""
    from rv_te_bench.io._legacy_msgs import LEGACY_HASHES

    for entry in bag.info.get('topics_with_message_count') or []:
        meta = entry.get('topic_metadata', {})
        if meta.get('name') == topic:
            digest = meta.get('type_description_hash') or ''
            ours = rv_te_typestore().hash_rihs01(ENCODER_BLOCK)
            if digest and digest != ours and digest not in LEGACY_HASHES[ENCODER_BLOCK]:
                msg = (f'Bag {bag.path}: {ENCODER_BLOCK} on {topic!r} has type hash {digest}, '
                       f'this software reads {ours}: the definition changed.')
                raise BagError(msg)


def read_encoder_blocks(
    path: str | Path, topic: str | None = None, *, strict: bool = True,
) -> MessageStream[EncoderBlockData]:
    """Encoder blocks of a bag decoded into ``EncoderBlockData`` (read-only arrays).

    Args:
        path: Bag folder or ``.mcap`` file.
        topic: The EncoderBlock topic; None: the single topic of that type.
        strict: Raise ``BagError`` after the last sound block if part was unreadable or a
            message was malformed (malformed messages are skipped either way).

    Returns:
        Stream of blocks in recording order.

    Raises:
        BagError: Bad layout, no or several encoder topics, wrong type on ``topic``;
            unreadable parts at the end when strict.
    """
    bag = open_bag(path)
    name = _encoder_topic(bag, topic)
    _check_encoder_definition(bag, name)

    def produce(stream: MessageStream[EncoderBlockData]) -> Iterator[EncoderBlockData]:
        for index, (_, msgtype, log_time, data) in enumerate(messages(bag, stream, [name])):
            if msgtype != ENCODER_BLOCK:
                stream.report_problem(f'Bag {bag.path}: topic {name!r} message {index} is stored '
                                f'as {msgtype!r}, expected {ENCODER_BLOCK}; skipped')
                continue
            try:
                yield decode_encoder_block(data)
            except BagError as exc:
                stream.report_problem(
                    f'{bag.path}: {name} message {index} at {log_time} ns: {exc}; skipped')

    return MessageStream(produce, strict=strict)


def read_encoder_batches(
    path: str | Path, topic: str | None = None, *, strict: bool = True,
    executor: Executor | None = None, read_ahead: bool = True, merge: bool = False,
) -> MessageStream[EncoderBatch | EncoderBlockData]:
    """Encoder blocks of a bag, a whole MCAP chunk at a time (the fast offline path).

    Well-formed consecutive blocks of a chunk come as one
    :class:`~rv_te_bench.core.stream.EncoderBatch` (decoded side by side, no per-message
    Python work beyond the record walk); a block that does not fit a batch (big-endian
    CDR, arrays of unequal length, no sample) comes as an ``EncoderBlockData`` of its
    own, exactly as :func:`read_encoder_blocks` decodes it, so the TE core reports it the
    same way. Undecodable messages are reported and skipped as there.

    Args:
        path: Bag folder or ``.mcap`` file.
        topic: The EncoderBlock topic; None: the single topic of that type.
        strict: Raise ``BagError`` after the last sound block if part was unreadable.
        executor: Decompress the chunks ahead on this executor's (one) worker thread,
            shared with other work of the caller (``analyze_bag`` computes window spectra
            on it too); None: on a thread of the reader's own. Either way not under
            ``RV_TE_READ_AHEAD=0``.
        read_ahead: False: no chunk read ahead, no thread (the one-core path).
        merge: Hand on the batches of consecutive chunks as one batch of about
            :data:`MERGE_SAMPLES` samples (decoded side by side, not copied again): less
            work per batch for a consumer of the whole bag (the offline analysis), but
            the first batch comes only after several chunks.

    Returns:
        Stream of batches and single blocks in recording order.

    Raises:
        BagError: As :func:`read_encoder_blocks`.
    """
    bag = open_bag(path)
    name = _encoder_topic(bag, topic)
    _check_encoder_definition(bag, name)

    from rv_te_bench.core.stream_records import EncoderBatch

    def produce(stream: MessageStream[Any]) -> Iterator[EncoderBatch | EncoderBlockData]:
        if not merge:
            yield from _units(stream, None)
            return
        arena = BatchArena(MERGE_SAMPLES)
        # batches side by side in the arena's arrays since ``begin``, not handed on yet
        pending: list[EncoderBatch] = []
        gen, begin = 0, 0
        arena_arrays = arena.arrays
        for item in _units(stream, arena):
            if isinstance(item, EncoderBatch) and item.theta_in_heads_rad.size == 0 \
                    and item.theta_out_heads_rad.size == 0:   # (decoded into the arena)
                if pending and arena.generation != gen:   # not next to the pending ones
                    yield _merged(pending, arena_arrays, begin)
                    pending = []
                if not pending:
                    gen, begin = arena.generation, arena.last[0]
                    arena_arrays = arena.arrays
                pending.append(item)
                if arena.last[1] - begin >= MERGE_SAMPLES:
                    yield _merged(pending, arena_arrays, begin)
                    pending = []
                continue
            if pending:                                   # (the order is kept)
                yield _merged(pending, arena_arrays, begin)
                pending = []
            yield item
        if pending:
            yield _merged(pending, arena_arrays, begin)

    def _units(stream: MessageStream[Any],
               arena: BatchArena | None) -> Iterator[EncoderBatch | EncoderBlockData]:
        index = 0   # of the message on the topic (as read_encoder_blocks counts)
        for unit in unit_columns(bag, stream, [name], executor, read_ahead=read_ahead):
            m = unit.start.size
            typed = [msgtype == ENCODER_BLOCK for _, msgtype in unit.targets]
            sel = None   # the EncoderBlocks of the unit: all of them
            starts, ends = unit.start, unit.end
            if not all(typed):
                good = np.array(typed)[unit.kind]
                for i in np.flatnonzero(~good).tolist():
                    stream.report_problem(
                        f'Bag {bag.path}: topic {name!r} message {index + i} is stored as '
                        f'{unit.targets[int(unit.kind[i])][1]!r}, expected {ENCODER_BLOCK}; '
                        'skipped')
                sel = np.flatnonzero(good)
                starts, ends = starts[sel], ends[sel]
            if starts.size:
                for item in _encoder_items(unit.buf, starts, ends, arena):
                    if not isinstance(item, int):
                        yield item
                        continue
                    i = item if sel is None else int(sel[item])
                    start, end = int(unit.start[i]), int(unit.end[i])
                    try:
                        yield decode_encoder_block(unit.buf[start:end])
                    except BagError as exc:
                        stream.report_problem(
                            f'{bag.path}: {name} message {index + i} at '
                            f'{int(unit.log_time[i])} ns: {exc}; skipped')
            index += m

    return MessageStream(produce, strict=strict)


#: Samples of consecutive chunks handed on as one batch by :func:`read_encoder_batches`
#: (about four 1 MiB chunks: issue 41, the analysis's work per batch).
MERGE_SAMPLES = 1 << 17


def _merged(batches: list[EncoderBatch], arrays: Any, begin: int) -> EncoderBatch:
    """Batches decoded side by side into ``arrays`` (time, in, out) from sample ``begin``
    on, as one batch: views of those arrays, nothing copied but the per-block fields."""
    from rv_te_bench.core.stream_records import EncoderBatch

    if len(batches) == 1:
        return batches[0]
    sizes = [b.n_samples for b in batches]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    blocks = np.cumsum([b.n_blocks for b in batches])[:-1]
    end = begin + int(offsets[-1])
    time_s, theta_in, theta_out = arrays
    return EncoderBatch(
        seq=np.concatenate([b.seq for b in batches]),
        stamp_s=np.concatenate([b.stamp_s for b in batches]),
        sample_rate_hz=np.concatenate([b.sample_rate_hz for b in batches]),
        starts=np.concatenate([*(np.asarray(b.starts[:-1], dtype=np.int64) + off
                                 for b, off in zip(batches, offsets.tolist(), strict=False)),
                               offsets[-1:]]),
        time_offset_s=time_s[begin:end], theta_in_rad=theta_in[begin:end],
        theta_out_rad=theta_out[begin:end], parts=tuple(int(k) for k in blocks))


def bag_summary(path: str | Path) -> dict[str, Any]:
    """Scan a whole bag and summarise it.

    Returns:
        ``{'path', 'files', 'finalized', 'topics': {name: {'type', 'count',
        'count_metadata_yaml'}}, 'message_count', 'start_ns', 'end_ns', 'duration_s',
        'session', 'metadata': {record name: dict}, 'partial', 'problems', 'notes'}``, where
        ``session`` is the rv_te_session metadata record; damage found while scanning is
        reported in ``partial`` / ``problems``, not raised.

    Raises:
        BagError: Bad layout.
    """
    bag = open_bag(path)
    stream: MessageStream[Any] = MessageStream(lambda s: iter(()), strict=False)
    types: dict[str, str] = dict(bag.topic_types)
    counts, start, stop, meta = mcap_counts(bag, stream.report_problem, types)
    yaml_counts = {
        str(t['topic_metadata']['name']): int(t.get('message_count', 0))
        for t in bag.info.get('topics_with_message_count') or []
    }
    topics = {
        name: {'type': types.get(name, ''), 'count': counts.get(name, 0),
               'count_metadata_yaml': yaml_counts.get(name)}
        for name in sorted(set(types) | set(counts))
    }
    return {
        'path': str(bag.path),
        'files': [str(f) for f in bag.files],
        'finalized': bag.finalized,
        'topics': topics,
        'message_count': sum(counts.values()),
        'start_ns': start,
        'end_ns': stop,
        'duration_s': 0.0 if start is None or stop is None else (stop - start) * 1e-9,
        'session': meta.get('rv_te_session', {}),
        'metadata': {k: v for k, v in meta.items() if k != 'rosbag2'},
        'partial': stream.partial,
        'problems': list(stream.problems),
        'notes': list(bag.notes),
    }
