"""Read rosbag2 (MCAP storage) bags without rclpy: summary, raw messages, encoder blocks.

The reader scans the MCAP records itself (no summary needed) so that bags whose recorder
was killed, or whose last file was cut short, still yield every sound message; what could
not be read is reported. ``EncoderBlock`` messages are decoded straight from their CDR
layout into read-only numpy arrays (``np.frombuffer``), which is several times faster than
generic deserialisation; ``decode_encoder_block_rosbags`` is the slower cross-check.

This module is the rosbag2 side (the bag folder, metadata.yaml, topics, the public readers);
the pieces live beside it, as rosbags splits ``rosbag2/reader.py``, ``storage_mcap.py`` and
``serde/``: the MCAP record walk, summary and read-ahead in :mod:`._mcap_scan`, the
EncoderBlock CDR decoders in :mod:`._encoder_cdr`, the BenchInfo lookup in
:mod:`.bench_record` (:func:`read_bench_info`, re-exported here with the decoders).

Partial results: every reader returns a ``MessageStream``. With ``strict=True`` (default)
it raises ``BagError`` after the last sound message when part of the bag was unreadable
(truncated file, corrupt chunk, malformed message), naming the file and the problem; with
``strict=False`` it stops quietly and ``stream.partial`` / ``stream.problems`` say so.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import numpy as np

from rv_te_bench.errors import BagError, YamlInputError
from rv_te_bench.io import _sqlite_bag as _sqlite
from rv_te_bench.io._bag_folder import entry_problem, layout_notes, listed_files
from rv_te_bench.io._encoder_cdr import (
    _encoder_items,
    decode_encoder_block,
    decode_encoder_block_rosbags,
    encoder_block_seq,
)
from rv_te_bench.io._mcap_file import MAGIC
from rv_te_bench.io._mcap_scan import (
    PREFETCH_CHUNKS,
    READ_AHEAD_ENV,
    _file_channels,
    _scan_file,
    _scan_units,
    _ScanState,
    helper_threads_allowed,
)
from rv_te_bench.io.bench_record import read_bench_info
from rv_te_bench.io.msgdefs import ENCODER_BLOCK, rv_te_typestore
from rv_te_bench.safe_yaml import BAG_METADATA_LIMITS, read_yaml_file

if TYPE_CHECKING:
    from collections.abc import Callable, Collection, Iterator
    from concurrent.futures import Executor

    from rv_te_bench.core.stream import EncoderBatch, EncoderBlockData

__all__ = [
    'PREFETCH_CHUNKS',
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

T = TypeVar('T')
RawMessage = tuple[str, str, int, memoryview]
"""(topic, msgtype, timestamp_ns, cdr_bytes): one message as stored."""


#: Problems named one by one in a one-line message; the rest are counted.
PROBLEMS_SHOWN = 3


def summarize_problems(problems: list[str] | tuple[str, ...]) -> str:
    """The problems as one line: the first few, then how many more (a bag damaged all
    through has one problem per chunk, hundreds of them).

    Examples:
        >>> summarize_problems(['a', 'b'])
        'a; b'
        >>> summarize_problems([f'chunk {i} bad' for i in range(10)])
        'chunk 0 bad; chunk 1 bad; chunk 2 bad; ... and 7 more problems'
    """
    shown = '; '.join(problems[:PROBLEMS_SHOWN])
    if len(problems) > PROBLEMS_SHOWN:
        shown += f'; ... and {len(problems) - PROBLEMS_SHOWN} more problems'
    return shown


@dataclass(frozen=True, slots=True)
class Bag:
    """A validated bag layout.

    Attributes:
        path: The bag folder (or the lone ``.mcap`` file).
        files: The ``.mcap`` files in recording order.
        info: ``rosbag2_bagfile_information`` from metadata.yaml (empty for a lone file).
        topic_types: Topic name -> type from metadata.yaml (empty for a lone file).
        notes: What a reader should know but that does not stop reading: unlisted .mcap
            files (ignored), messages the recorder could not write (a full disk).
    """

    path: Path
    files: tuple[Path, ...]
    info: dict[str, Any]
    topic_types: dict[str, str]
    notes: tuple[str, ...] = ()

    @property
    def finalized(self) -> bool | None:
        """True when the writer closed the bag, False when it did not, None if unknown."""
        state = (self.info.get('custom_data') or {}).get('rv_te_bench.writer_state')
        return None if state is None else state == 'closed'


class MessageStream(Generic[T]):
    """Iterator over a bag's messages that records whether the result is partial.

    Attributes:
        partial: True once a problem made part of the bag unreadable.
        problems: One message per problem, each naming the file.
    """

    def __init__(self, producer: Callable[[MessageStream[T]], Iterator[T]], *,
                 strict: bool) -> None:
        self.partial = False
        self.problems: list[str] = []
        self._strict = strict
        self._it = producer(self)
        self._done = False

    def __iter__(self) -> MessageStream[T]:
        return self

    def __next__(self) -> T:
        if self._done:
            raise StopIteration
        try:
            return next(self._it)
        except StopIteration:
            self._done = True
            if self._strict and self.problems:
                msg = (summarize_problems(self.problems)
                       + ' (the messages before were read: partial)')
                raise BagError(msg) from None
            raise

    def report_problem(self, text: str) -> None:
        """Mark the result partial and record why (used by the producers)."""
        self.partial = True
        self.problems.append(text)


# ----------------------------------------------------------------------------- layout
def open_bag(path: str | Path) -> Bag:
    """Validate a bag's layout and read its metadata.yaml.

    Args:
        path: A rosbag2 bag folder (metadata.yaml + .mcap files) or a single ``.mcap`` file.

    Returns:
        The bag's layout.

    Raises:
        BagError: Missing path or metadata, unreadable YAML, storage other than MCAP,
            files missing, or a file that is not MCAP.
    """
    path = Path(path)
    if path.is_file():
        _check_magic(path)
        return Bag(path=path, files=(path,), info={}, topic_types={})
    if not path.is_dir():
        what = entry_problem(path)
        msg = (f'Bag {path} does not exist.' if what == 'missing' else
               f'Bag {path} is not a bag folder or .mcap file: {what}.')
        raise BagError(msg)
    meta_path = path / 'metadata.yaml'
    if not meta_path.is_file():
        msg = f'Bag {path} has no metadata.yaml: not a rosbag2 bag folder.'
        raise BagError(msg)
    try:
        # bounded: a ~1 KB alias bomb once expanded to gigabytes here (issue #16)
        doc = read_yaml_file(meta_path, what='bag metadata', limits=BAG_METADATA_LIMITS)
        info = doc['rosbag2_bagfile_information']
        storage = info['storage_identifier']
        listed = listed_files(path, info['relative_file_paths'], where=meta_path)
        topics = {
            str(t['topic_metadata']['name']): str(t['topic_metadata']['type'])
            for t in info.get('topics_with_message_count') or []
        }
    except YamlInputError as exc:
        msg = f'Cannot read {exc}.'
        raise BagError(msg) from None
    except (KeyError, TypeError, AttributeError) as exc:
        msg = f'{meta_path} is not rosbag2 metadata (missing or bad key {exc}).'
        raise BagError(msg) from None
    if storage == 'sqlite3':   # read through rosbags (issue #19 s.4)
        return _sqlite.sqlite_bag(path, info, topics, listed)
    if storage != 'mcap':
        msg = f'Bag {path} uses storage {storage!r}; only mcap and sqlite3 are supported.'
        raise BagError(msg)
    problems = {p: entry_problem(p) for p in listed}
    if missing := [str(p) for p, what in problems.items() if what == 'missing']:
        # bounded: a 4 MiB metadata.yaml can list ~100,000 files (a 10 MB one-line error)
        shown = ', '.join(Path(m).name for m in missing[:3])
        more = f' and {len(missing) - 3} more' if len(missing) > 3 else ''
        msg = (f'Bag {path}: {len(missing)} file(s) listed in metadata.yaml are missing: '
               f'{shown}{more}.')
        raise BagError(msg)
    if odd := [f'{p.name} is {what}' for p, what in problems.items() if what]:
        msg = f'Bag {path}: listed in metadata.yaml but {"; ".join(odd)}.'
        raise BagError(msg)
    if not listed:
        msg = f'Bag {path} has no .mcap files.'
        raise BagError(msg)
    for file in listed:
        _check_magic(file)
    # unlisted .mcap files (another session's, or a split a killed recorder had not listed
    # yet, which holds no message: BagWriter lists a file before writing messages to it)
    # are ignored, as rosbags ignores them, with a note
    notes = tuple(layout_notes(path, listed, info))
    return Bag(path=path, files=tuple(listed), info=info, topic_types=topics, notes=notes)


def _check_magic(file: Path) -> None:
    try:
        with file.open('rb') as fh:
            head = fh.read(8)
    except OSError as exc:
        msg = f'Cannot open {file}: {exc}.'
        raise BagError(msg) from None
    if not head:
        msg = f'{file} is empty (0 bytes).'
        raise BagError(msg)
    if head != MAGIC:
        msg = f'{file} is not an MCAP file (bad magic {head[:8]!r}).'
        raise BagError(msg)


def _units(
    bag: Bag, stream: MessageStream[Any], topics: Collection[str] | None,
    executor: Executor | None = None,
) -> Iterator[tuple[memoryview, list[tuple[str, str, int, int, int]]]]:
    """Per chunk: the buffer and its wanted messages (topic, msgtype, log_time, start, end).

    ``executor``: the thread that reads MCAP chunks ahead (None: one of the scan's own).
    """
    wanted = None if topics is None else set(topics)
    if _sqlite.is_sqlite(bag):   # issue #19 s.4
        yield from _sqlite.sqlite_units(bag, stream.report_problem, wanted)
        return
    for file in bag.files:
        state = _ScanState()
        resolved: dict[int, tuple[str, str] | None] = {}
        for inner, found in _scan_units(file, state, stream.report_problem, executor=executor):
            out = []
            for cid, log_time, start, end in found:
                target = resolved.get(cid, False)
                if target is False:
                    chan = state.channels.get(cid)
                    if chan is None:
                        stream.report_problem(f'{file}: message on unknown channel {cid}; skipped')
                        continue
                    topic, sid = chan
                    msgtype = state.schemas.get(sid, ('', ''))[0] or bag.topic_types.get(topic, '')
                    target = (topic, msgtype) if wanted is None or topic in wanted else None
                    resolved[cid] = target
                if target is not None:
                    out.append((target[0], target[1], log_time, start, end))
            if out:
                yield inner, out


def _messages(
    bag: Bag, stream: MessageStream[Any], topics: Collection[str] | None,
) -> Iterator[tuple[str, str, int, memoryview]]:
    for inner, found in _units(bag, stream, topics):
        for topic, msgtype, log_time, start, end in found:
            yield topic, msgtype, log_time, inner[start:end]


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
    return MessageStream(lambda s: _messages(bag, s, topics), strict=strict)


def _encoder_topic(bag: Bag, topic: str | None) -> str:
    types = bag.topic_types or _scan_topic_types(bag)
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


def _scan_topic_types(bag: Bag) -> dict[str, str]:
    return {topic: info['type'] for topic, info in _mcap_topics(bag).items()}


def _mcap_topics(bag: Bag) -> dict[str, dict[str, Any]]:
    """Topic -> {'type', 'offered_qos_profiles'} from the MCAP channels of every file."""
    out: dict[str, dict[str, Any]] = {}
    for file in bag.files:
        state = _file_channels(file)
        for cid, (topic, sid) in state.channels.items():
            meta = state.channel_meta.get(cid, {})
            out.setdefault(topic, {'type': state.schemas.get(sid, ('', ''))[0],
                                   'offered_qos_profiles': meta.get('offered_qos_profiles')})
    return out


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
    return _mcap_topics(bag)


def _check_encoder_definition(bag: Bag, topic: str) -> None:
    """Refuse a bag whose EncoderBlock definition differs from ours (decode would lie)."""
    for entry in bag.info.get('topics_with_message_count') or []:
        meta = entry.get('topic_metadata', {})
        if meta.get('name') == topic:
            digest = meta.get('type_description_hash') or ''
            ours = rv_te_typestore().hash_rihs01(ENCODER_BLOCK)
            if digest and digest != ours:
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
        for index, (_, msgtype, log_time, data) in enumerate(_messages(bag, stream, [name])):
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
    executor: Executor | None = None,
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

    Returns:
        Stream of batches and single blocks in recording order.

    Raises:
        BagError: As :func:`read_encoder_blocks`.
    """
    bag = open_bag(path)
    name = _encoder_topic(bag, topic)
    _check_encoder_definition(bag, name)

    def produce(stream: MessageStream[Any]) -> Iterator[EncoderBatch | EncoderBlockData]:
        index = 0
        for buf, found in _units(bag, stream, [name], executor):
            typed = []
            for _, msgtype, log_time, start, end in found:
                if msgtype != ENCODER_BLOCK:
                    stream.report_problem(
                        f'Bag {bag.path}: topic {name!r} message {index} is stored as '
                        f'{msgtype!r}, expected {ENCODER_BLOCK}; skipped')
                else:
                    typed.append((index, log_time, start, end))
                index += 1
            if not typed:
                continue
            starts = np.array([t[2] for t in typed], dtype=np.int64)
            ends = np.array([t[3] for t in typed], dtype=np.int64)
            for item in _encoder_items(buf, starts, ends):
                if not isinstance(item, int):
                    yield item
                    continue
                k, log_time, start, end = typed[item]
                try:
                    yield decode_encoder_block(buf[start:end])
                except BagError as exc:
                    stream.report_problem(
                        f'{bag.path}: {name} message {k} at {log_time} ns: {exc}; skipped')

    return MessageStream(produce, strict=strict)


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
    counts: dict[str, int] = {}
    types: dict[str, str] = dict(bag.topic_types)
    meta: dict[str, dict[str, str]] = {}
    start, stop = None, None
    for file in bag.files:
        state = _ScanState()
        per_cid: dict[int, int] = {}
        times: list[int] = []
        for cid, log_time, _ in _scan_file(file, state, stream.report_problem):
            per_cid[cid] = per_cid.get(cid, 0) + 1
            times.append(log_time)
        for cid, n in per_cid.items():
            topic, sid = state.channels.get(cid, (f'<unknown channel {cid}>', 0))
            counts[topic] = counts.get(topic, 0) + n
        for topic, sid in state.channels.values():
            types.setdefault(topic, state.schemas.get(sid, ('', ''))[0])
        meta.update(state.metadata)
        if times:
            lo, hi = min(times), max(times)
            start = lo if start is None else min(start, lo)
            stop = hi if stop is None else max(stop, hi)
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
