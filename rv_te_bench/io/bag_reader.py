"""Read rosbag2 (MCAP storage) bags without rclpy: summary, raw messages, encoder blocks.

The reader scans the MCAP records itself (no summary needed) so that bags whose recorder
was killed, or whose last file was cut short, still yield every sound message; what could
not be read is reported. ``EncoderBlock`` messages are decoded straight from their CDR
layout into read-only numpy arrays (``np.frombuffer``), which is several times faster than
generic deserialisation; ``decode_encoder_block_rosbags`` is the slower cross-check.

Partial results: every reader returns a ``MessageStream``. With ``strict=True`` (default)
it raises ``BagError`` after the last sound message when part of the bag was unreadable
(truncated file, corrupt chunk, malformed message), naming the file and the problem; with
``strict=False`` it stops quietly and ``stream.partial`` / ``stream.problems`` say so.
"""

from __future__ import annotations

import collections
import contextlib
import mmap
import os
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import numpy as np

from rv_te_bench.errors import BagError, YamlInputError
from rv_te_bench.io._bag_folder import entry_problem, layout_notes, listed_files
from rv_te_bench.io.bench_record import bench_info_values
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, rv_te_typestore
from rv_te_bench.safe_yaml import BAG_METADATA_LIMITS, read_yaml_file

if TYPE_CHECKING:
    from collections.abc import Callable, Collection, Iterator

    from rv_te_bench.core.stream import EncoderBatch, EncoderBlockData

__all__ = [
    'Bag',
    'MessageStream',
    'RawMessage',
    'bag_summary',
    'bag_topics',
    'decode_encoder_block',
    'decode_encoder_block_rosbags',
    'iter_messages',
    'open_bag',
    'read_bench_info',
    'read_encoder_batches',
    'read_encoder_blocks',
    'summarize_problems',
]

MAGIC = b'\x89MCAP0\r\n'
_U16 = struct.Struct('<H')
_U32 = struct.Struct('<I')
_U64 = struct.Struct('<Q')
_REC = struct.Struct('<BQ')
_MSG = struct.Struct('<HIQQ')
_CHUNK = struct.Struct('<QQQI')
_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = 1, 2, 3, 4, 5, 6
_OP_METADATA, _OP_DATA_END = 0x0C, 0x0F

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
    """  # noqa: D205
    shown = '; '.join(problems[:PROBLEMS_SHOWN])
    if len(problems) > PROBLEMS_SHOWN:
        shown += f'; ... and {len(problems) - PROBLEMS_SHOWN} more problems'
    return shown


class _CorruptError(Exception):
    """A record cannot be parsed (internal; turned into a problem or BagError)."""


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
    if storage != 'mcap':
        msg = f'Bag {path} uses storage {storage!r}; only mcap is supported.'
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


# ----------------------------------------------------------------------------- MCAP scan
@dataclass(slots=True)
class _ScanState:
    schemas: dict[int, tuple[str, str]] = field(default_factory=dict)   # id -> (name, text)
    channels: dict[int, tuple[str, int]] = field(default_factory=dict)  # id -> (topic, schema)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    channel_meta: dict[int, dict[str, str]] = field(default_factory=dict)  # id -> metadata


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise _CorruptError('string runs past its record')
    return bytes(buf[pos + 4:end]).decode('utf-8'), end


def _map(buf: memoryview, pos: int) -> tuple[dict[str, str], int]:
    (n,) = _U32.unpack_from(buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise _CorruptError('map runs past its record')
    out: dict[str, str] = {}
    pos += 4
    while pos < end:
        key, pos = _string(buf, pos)
        val, pos = _string(buf, pos)
        out[key] = val
    return out, end


def _parse_meta_record(op: int, body: memoryview, state: _ScanState) -> None:
    if op == _OP_SCHEMA:
        (sid,) = _U16.unpack_from(body, 0)
        name, pos = _string(body, 2)
        _, pos = _string(body, pos)
        (n,) = _U32.unpack_from(body, pos)
        if pos + 4 + n > len(body):
            raise _CorruptError('schema data runs past its record')
        state.schemas[sid] = (name, bytes(body[pos + 4:pos + 4 + n]).decode('utf-8'))
    elif op == _OP_CHANNEL:
        cid, sid = struct.unpack_from('<HH', body, 0)
        topic, pos = _string(body, 4)
        state.channels[cid] = (topic, sid)
        _, pos = _string(body, pos)   # message encoding
        state.channel_meta[cid], _ = _map(body, pos)
    elif op == _OP_METADATA:
        name, pos = _string(body, 0)
        state.metadata[name], _ = _map(body, pos)


_MAX_CHUNK_BYTES = 1 << 32  # a larger uncompressed size is a corrupt header, not data


def _decompress(compression: str, data: memoryview, size: int) -> bytes:
    if size > _MAX_CHUNK_BYTES:
        raise _CorruptError(f'chunk claims {size} uncompressed bytes')
    if compression == '':
        return bytes(data)
    try:
        if compression == 'zstd':
            import zstandard  # noqa: PLC0415

            return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        if compression == 'lz4':
            import lz4.frame  # noqa: PLC0415

            return lz4.frame.decompress(bytes(data))
    except MemoryError:
        raise _CorruptError(f'{compression} chunk does not fit in memory') from None
    except Exception as exc:  # noqa: BLE001 - codecs raise assorted errors on bad input
        raise _CorruptError(f'{compression} chunk does not decompress ({exc})') from None
    raise _CorruptError(f'unsupported chunk compression {compression!r}')


def _chunk_records(body: memoryview) -> memoryview:
    start, end, usize, crc = _CHUNK.unpack_from(body, 0)
    _ = start, end
    compression, pos = _string(body, _CHUNK.size)
    (csize,) = _U64.unpack_from(body, pos)
    if pos + 8 + csize > len(body):
        raise _CorruptError('chunk data runs past its record')
    raw = _decompress(compression, body[pos + 8:pos + 8 + csize], usize)
    if len(raw) != usize:
        raise _CorruptError(f'chunk holds {len(raw)} bytes, header says {usize}')
    if crc and zlib.crc32(raw) != crc:
        raise _CorruptError('chunk CRC mismatch')
    return memoryview(raw)


def _iter_records(buf: memoryview, start: int) -> Iterator[tuple[int, int, memoryview]]:
    """Yield (offset, opcode, body); raise _CorruptError at a record past the end."""
    pos, n = start, len(buf)
    while pos < n:
        if pos + 9 > n:
            raise _CorruptError(f'{n - pos} stray bytes at byte {pos} (truncated)')
        op, length = _REC.unpack_from(buf, pos)
        end = pos + 9 + length
        if end > n:
            raise _CorruptError(
                f'record (opcode 0x{op:02x}) at byte {pos} claims {length} bytes, past the '
                f'end at {n} (truncated or corrupt)')
        yield pos, op, buf[pos + 9:end]
        pos = end


_Unit = tuple[memoryview, list[tuple[int, int, int, int]]]
"""A decompressed chunk (or one loose message) and its messages as
(channel_id, log_time_ns, data_start, data_end) byte positions in it."""

#: Environment switch: ``0`` turns the read-ahead thread off (a Dask worker of a fleet run
#: on a machine whose cores are all workers: parallel bags use the cores better).
READ_AHEAD_ENV = 'RV_TE_READ_AHEAD'
#: Chunks decompressed ahead of the one being consumed (by one worker thread: zstd, lz4 and
#: crc32 release the GIL, so reading overlaps with the analysis on a second core).
PREFETCH_CHUNKS = 2
_AHEAD_RECORDS = 64


def _walk_chunk(inner: memoryview, state: _ScanState,
                out: list[tuple[int, int, int, int]]) -> None:
    """Collect the messages of a decompressed chunk into ``out``, parse its other records.

    Raises:
        _CorruptError, struct.error, UnicodeDecodeError, ValueError: A record is damaged
            (the messages before it are in ``out``).
    """
    pos, n = 0, len(inner)
    rec, msg, op_message = _REC.unpack_from, _MSG.unpack_from, _OP_MESSAGE
    head = 9 + _MSG.size
    while pos < n:
        if pos + 9 > n:
            raise _CorruptError(f'{n - pos} stray bytes at byte {pos} (truncated)')
        op, length = rec(inner, pos)
        end = pos + 9 + length
        if end > n:
            raise _CorruptError(
                f'record (opcode 0x{op:02x}) at byte {pos} claims {length} bytes, past the '
                f'end at {n} (truncated or corrupt)')
        if op == op_message:
            if length < _MSG.size:
                raise _CorruptError(f'message record at byte {pos} is {length} bytes long')
            cid, _, log_time, _ = msg(inner, pos + 9)
            out.append((cid, log_time, pos + head, end))
        else:
            _parse_meta_record(op, inner[pos + 9:end], state)
        pos = end


def _scan_units(  # noqa: C901, PLR0912, PLR0915
    file: Path,
    state: _ScanState,
    report: Callable[[str], None],
    *,
    messages: bool = True,
    prefetch: bool = True,
) -> Iterator[_Unit]:
    """Yield every sound message of one MCAP file, grouped by chunk (see ``_Unit``).

    With ``prefetch`` the next chunks are decompressed and CRC-checked by a worker thread
    while the caller works on the current one.
    """
    try:
        with file.open('rb') as fh:
            size = fh.seek(0, 2)
            if size == 0:
                report(f'{file} is empty (0 bytes)')
                return
            mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
    except (OSError, ValueError) as exc:
        report(f'cannot read {file}: {exc}')
        return
    buf = memoryview(mm)
    ended = False
    pool = None
    if prefetch and messages and os.environ.get(READ_AHEAD_ENV, '1') != '0':
        from concurrent.futures import ThreadPoolExecutor  # noqa: PLC0415

        pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix='mcap-read')
    ahead: collections.deque[tuple[int, int, memoryview, Any]] = collections.deque()
    try:
        if bytes(buf[:8]) != MAGIC:
            report(f'{file} is not an MCAP file (bad magic)')
            return
        records = _iter_records(buf, 8)
        exhausted = False
        while True:
            # read records ahead until PREFETCH_CHUNKS chunks are being decompressed (loose
            # records are cheap views of the map; at most _AHEAD_RECORDS of them are held)
            while not exhausted and (not ahead or (
                    pool is not None and len(ahead) < _AHEAD_RECORDS
                    and sum(1 for r in ahead if r[1] == _OP_CHUNK) <= PREFETCH_CHUNKS)):
                try:
                    item = next(records, None)
                except _CorruptError as exc:
                    ahead.append((-1, -1, memoryview(b''), str(exc)))
                    exhausted = True
                    break
                if item is None:
                    exhausted = True
                    break
                offset, op, body = item
                job = None
                if op == _OP_CHUNK and messages and pool is not None:
                    job = pool.submit(_chunk_records, body)
                ahead.append((offset, op, body, job))
                if op in (_OP_DATA_END, _OP_FOOTER):
                    exhausted = True
            if not ahead:
                break
            offset, op, body, job = ahead.popleft()
            if offset < 0:   # the record walk itself failed
                report(f'{file}: {job}')
                return
            try:
                if op == _OP_MESSAGE:
                    if messages:
                        if len(body) < _MSG.size:
                            raise _CorruptError(f'message record is {len(body)} bytes long')
                        cid, _, log_time, _ = _MSG.unpack_from(body, 0)
                        yield memoryview(bytes(body)), [(cid, log_time, _MSG.size, len(body))]
                elif op == _OP_CHUNK:
                    # (a metadata-only scan decompresses too: schemas and channels live there)
                    inner = _chunk_records(body) if job is None else job.result()
                    found: list[tuple[int, int, int, int]] = []
                    damage = None
                    try:
                        _walk_chunk(inner, state, found)
                    except (_CorruptError, struct.error, UnicodeDecodeError, ValueError) as exc:
                        damage = exc   # the messages before the damaged record are sound
                    if found and messages:
                        yield inner, found
                    if damage is not None:
                        raise damage
                elif op in (_OP_DATA_END, _OP_FOOTER):
                    ended = True
                    break
                else:
                    _parse_meta_record(op, body, state)
            except (_CorruptError, struct.error, UnicodeDecodeError, ValueError) as exc:
                report(f'{file}: corrupt record (opcode 0x{op:02x}) at byte {offset}: {exc}; '
                       'skipped')
        if not ended:
            report(f'{file} ends without a Data End record at byte {len(buf)}: the file was '
                   'truncated')
    finally:
        if pool is not None:
            for *_, job in ahead:
                if job is not None:
                    job.cancel()
            pool.shutdown(wait=True)
        ahead.clear()
        # Views handed out are copies or slices of decompressed chunks, never of the map;
        # a consumer holding a record body only delays the unmapping to garbage collection.
        with contextlib.suppress(BufferError):
            buf.release()
            mm.close()


def _scan_file(
    file: Path,
    state: _ScanState,
    report: Callable[[str], None],
    *,
    messages: bool = True,
) -> Iterator[tuple[int, int, memoryview]]:
    """Yield (channel_id, log_time_ns, data) of every sound message of one MCAP file."""
    for inner, found in _scan_units(file, state, report, messages=messages):
        for cid, log_time, start, end in found:
            yield cid, log_time, inner[start:end]


def _units(
    bag: Bag, stream: MessageStream[Any], topics: Collection[str] | None,
) -> Iterator[tuple[memoryview, list[tuple[str, str, int, int, int]]]]:
    """Per chunk: the buffer and its wanted messages (topic, msgtype, log_time, start, end)."""
    wanted = None if topics is None else set(topics)
    for file in bag.files:
        state = _ScanState()
        resolved: dict[int, tuple[str, str] | None] = {}
        for inner, found in _scan_units(file, state, stream.report_problem):
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


def _file_channels(file: Path) -> _ScanState:
    """Schemas and channels of one MCAP file: from its summary, else by a scan."""
    state = _summary(file)
    if state is None:
        state = _ScanState()
        for _ in _scan_file(file, state, lambda _t: None, messages=False):
            pass
    else:
        state = state[0]
    return state


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


_ALIGN4, _ALIGN8 = 3, 7


def _seq_offset(buf: bytes | memoryview, end: str) -> int:
    """Offset (after the 4-byte encapsulation) of EncoderBlock.seq: header.stamp (8 B),
    frame_id (length + bytes), padding to 8."""
    (flen,) = struct.unpack_from(end + 'I', buf, 12)
    return (12 + flen + _ALIGN8) & ~_ALIGN8


def encoder_block_seq(data: bytes | memoryview) -> int:
    """``seq`` of a serialised EncoderBlock, without decoding the arrays (recorder hot path).

    Raises:
        struct.error, IndexError: The bytes are too short to hold it.
    """
    end = '<' if data[1] == 1 else '>'
    return struct.unpack_from(end + 'Q', data, 4 + _seq_offset(data, end))[0]


@dataclass(frozen=True, slots=True)
class _Layout:
    """Where the fields of one serialised EncoderBlock lie (byte offsets from its start,
    the 4-byte encapsulation included)."""  # noqa: D205, D209

    order: str                          # struct byte order: '<' or '>'
    seq_at: int                         # seq (uint64), then sample_rate_hz (float64)
    count_at: tuple[int, ...]           # element count of each of the four arrays
    counts: tuple[int, ...]
    data_at: tuple[int, ...]            # first element of each array
    length: int                         # bytes the message uses


def _layout(buf: bytes | memoryview) -> _Layout:
    """Walk the CDR layout of one EncoderBlock (header, seq, rate, four float64 arrays).

    Raises:
        BagError: Not a CDR EncoderBlock, truncated, or an array runs past the end.
    """
    size = len(buf)
    if size < 4 + 12 or buf[0] != 0 or buf[1] not in (0, 1):
        msg = f'not a CDR EncoderBlock ({size} bytes, header {bytes(buf[:4]).hex()})'
        raise BagError(msg)
    order = '<' if buf[1] == 1 else '>'
    try:
        off = _seq_offset(buf, order)
        seq_at = 4 + off
        off += 16
        count_at, counts, data_at = [], [], []
        for _ in range(4):
            off = (off + _ALIGN4) & ~_ALIGN4
            (count,) = struct.unpack_from(order + 'I', buf, 4 + off)
            count_at.append(4 + off)
            off += 4
            if count:
                off = (off + _ALIGN8) & ~_ALIGN8
            if 4 + off + 8 * count > size:
                msg = f'array of {count} float64 runs past the message end ({size} bytes)'
                raise BagError(msg)
            counts.append(count)
            data_at.append(4 + off)
            off += 8 * count
    except struct.error as exc:
        msg = f'EncoderBlock CDR truncated ({size} bytes): {exc}'
        raise BagError(msg) from None
    return _Layout(order, seq_at, tuple(count_at), tuple(counts), tuple(data_at), 4 + off)


def decode_encoder_block(data: bytes | memoryview) -> EncoderBlockData:
    """Decode one EncoderBlock CDR message (with encapsulation header) into numpy arrays.

    Args:
        data: Serialised message as stored in a bag or received raw.

    Returns:
        The block; arrays are float64 views of a private copy of ``data``, read-only.

    Raises:
        BagError: The bytes do not hold a well-formed EncoderBlock.
    """
    from rv_te_bench.core.stream import EncoderBlockData  # noqa: PLC0415

    buf = bytes(data)
    lay = _layout(buf)
    sec, nsec = struct.unpack_from(lay.order + 'iI', buf, 4)
    seq, rate = struct.unpack_from(lay.order + 'Qd', buf, lay.seq_at)
    dtype = np.dtype(lay.order + 'f8')
    arrays = [np.frombuffer(buf, dtype, n, at) for n, at in zip(lay.counts, lay.data_at,
                                                                  strict=True)]
    if lay.order == '>':
        arrays = [a.astype(np.float64) for a in arrays]
        for a in arrays:
            a.setflags(write=False)
    try:
        return EncoderBlockData(seq=int(seq), stamp_s=sec + nsec * 1e-9,
                                sample_rate_hz=float(rate), time_offset_s=arrays[0],
                                theta_in_rad=arrays[1], theta_out_rad=arrays[2],
                                torque_out_nm=arrays[3])
    except (ValueError, TypeError) as exc:
        msg = f'EncoderBlock content invalid: {exc}'
        raise BagError(msg) from None


def _gather_le(u8: np.ndarray, pos: np.ndarray, dtype: str) -> np.ndarray:
    """Little-endian values of ``dtype`` at byte positions ``pos`` (any alignment)."""
    width = np.dtype(dtype).itemsize
    return u8[pos[:, None] + np.arange(width)].view(dtype).ravel()


@dataclass(frozen=True, slots=True)
class _ParsedBlocks:
    """Header fields and array positions of EncoderBlock messages parsed side by side."""

    ok: np.ndarray          # bool: well-formed little-endian, batchable (equal lengths, n > 0)
    seq: np.ndarray         # uint64
    stamp_s: np.ndarray
    rate_hz: np.ndarray
    count: np.ndarray       # samples per block
    data: tuple[np.ndarray, np.ndarray, np.ndarray]  # byte position of time/in/out arrays


def _parse_same_layout(u8: np.ndarray, starts: np.ndarray,
                       ends: np.ndarray) -> _ParsedBlocks | None:
    """Fast path of :func:`_parse_encoder_blocks`: every message laid out like the first
    (same frame_id length and array lengths, the usual case), checked with one gather of
    the bytes that decide the layout. None when they differ."""  # noqa: D205, D209
    try:
        first = _layout(u8[int(starts[0]):int(ends[0])].data)
    except BagError:
        return None
    n = first.counts[1]
    if first.order != '<' or not (n > 0 and first.counts[0] == n == first.counts[2]
                                  and first.counts[3] in (0, n)):
        return None   # not batchable: the general parse sorts the messages out
    seq_at, count_at, data_at = first.seq_at, first.count_at, first.data_at
    if not ((ends - starts) >= first.length).all():
        return None
    deciding = np.array([0, 1, 12, 13, 14, 15,
                         *(c + k for c in count_at for k in range(4))], dtype=np.int64)
    rows = u8[starts[:, None] + deciding]
    if not (rows == rows[0]).all():
        return None
    head = u8[starts[:, None] + np.arange(4, 12)].view('<u4')
    tail = u8[starts[:, None] + np.arange(seq_at, seq_at + 16)]
    seq = tail[:, :8].copy().view('<u8').ravel()
    if not (seq < np.uint64(1 << 63)).all():
        return None
    stamp = head[:, 0].view('<i4').astype(np.float64) + head[:, 1].astype(np.float64) * 1e-9
    return _ParsedBlocks(
        ok=np.ones(starts.size, dtype=bool), seq=seq, stamp_s=stamp,
        rate_hz=tail[:, 8:].copy().view('<f8').ravel(),
        count=np.full(starts.size, n, dtype=np.int64),
        data=(starts + data_at[0], starts + data_at[1], starts + data_at[2]))


def _parse_encoder_blocks(u8: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> _ParsedBlocks:
    """Parse the EncoderBlock CDR of messages [starts, ends) of one buffer, vectorised.

    The layout is the one :func:`decode_encoder_block` walks. A message that is big-endian,
    runs short, has arrays of unequal length, no sample or a torque array of another
    length gets ``ok`` False: the caller decodes it on its own (and so reports it exactly
    as the single-message path does).
    """
    same = _parse_same_layout(u8, starts, ends)
    if same is not None:
        return same
    size = ends - starts
    ok = size >= 4 + 12 + 4  # noqa: PLR2004 - encapsulation, stamp, frame_id length

    def at(pos: np.ndarray, dtype: str) -> np.ndarray:
        nonlocal ok
        ok &= pos + np.dtype(dtype).itemsize <= ends
        return _gather_le(u8, np.where(ok, pos, 0), dtype)

    head = _gather_le(u8, np.where(ok, starts, 0), '<u2')
    ok &= head == 0x0100   # bytes 00 01: CDR little-endian
    p = starts + 4
    sec = at(p, '<i4')
    nsec = at(p + 4, '<u4')
    off = (12 + at(p + 8, '<u4').astype(np.int64) + _ALIGN8) & ~_ALIGN8
    seq = at(p + off, '<u8')
    rate = at(p + off + 8, '<f8')
    off += 16
    counts, data = [], []
    for _ in range(4):
        off = (off + _ALIGN4) & ~_ALIGN4
        c = at(p + off, '<u4').astype(np.int64)
        off = off + 4
        off = np.where(c > 0, (off + _ALIGN8) & ~_ALIGN8, off)
        data.append(p + off)
        counts.append(c)
        off = off + 8 * c
        ok &= p + off <= ends
    n = counts[1]
    ok &= (counts[0] == n) & (counts[2] == n) & (n > 0) & ((counts[3] == 0) | (counts[3] == n))
    ok &= seq < np.uint64(1 << 63)
    stamp = sec.astype(np.float64) + nsec.astype(np.float64) * 1e-9
    return _ParsedBlocks(ok, seq, stamp, rate, n, (data[0], data[1], data[2]))


def _concat_f64(u8: np.ndarray, pos: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Concatenate little-endian float64 arrays of ``counts[k]`` values at byte ``pos[k]``.

    The bytes are copied message by message (one slice each, any alignment) and viewed as
    float64 once: faster than an element gather when the sources are not 8-byte aligned.
    """
    ends = pos + 8 * counts
    return np.concatenate([u8[a:b] for a, b in zip(pos.tolist(), ends.tolist(),
                                                     strict=True)]).view('<f8')


def _encoder_items(buf: memoryview, starts: np.ndarray,
                   ends: np.ndarray) -> Iterator[EncoderBatch | int]:
    """Runs of well-formed messages as EncoderBatch, other messages by their index."""
    from rv_te_bench.core.stream import EncoderBatch  # noqa: PLC0415

    u8 = np.frombuffer(buf, np.uint8)
    parsed = _parse_encoder_blocks(u8, starts, ends)
    ok = parsed.ok
    # cut into runs of ok messages; a bad one is handed over by index
    edges = np.flatnonzero(np.diff(np.concatenate([[False], ok, [False]]).astype(np.int8)))
    bad = np.flatnonzero(~ok).tolist()
    runs = list(zip(edges[0::2].tolist(), edges[1::2].tolist(), strict=True))
    bi = 0
    for a, b in runs:
        while bi < len(bad) and bad[bi] < a:
            yield bad[bi]
            bi += 1
        n = parsed.count[a:b]
        arrays = [_concat_f64(u8, d[a:b], n) for d in parsed.data]
        yield EncoderBatch(seq=parsed.seq[a:b].astype(np.int64), stamp_s=parsed.stamp_s[a:b],
                           sample_rate_hz=parsed.rate_hz[a:b],
                           starts=np.concatenate([[0], np.cumsum(n)]).astype(np.int64),
                           time_offset_s=arrays[0], theta_in_rad=arrays[1],
                           theta_out_rad=arrays[2])
    yield from bad[bi:]


def read_encoder_batches(
    path: str | Path, topic: str | None = None, *, strict: bool = True,
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
        for buf, found in _units(bag, stream, [name]):
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


def decode_encoder_block_rosbags(data: bytes | memoryview) -> EncoderBlockData:
    """Decode one EncoderBlock with the rosbags typestore (slower; cross-check/fallback).

    Raises:
        BagError: The bytes do not deserialise as EncoderBlock.
    """
    from rv_te_bench.core.stream import EncoderBlockData  # noqa: PLC0415

    try:
        msg = rv_te_typestore().deserialize_cdr(bytes(data), ENCODER_BLOCK)
    except Exception as exc:  # noqa: BLE001 - rosbags raises assorted errors on bad bytes
        text = f'EncoderBlock does not deserialise: {exc}'
        raise BagError(text) from None
    stamp = msg.header.stamp
    return EncoderBlockData(
        seq=int(msg.seq), stamp_s=stamp.sec + stamp.nanosec * 1e-9,
        sample_rate_hz=float(msg.sample_rate_hz),
        time_offset_s=np.asarray(msg.time_offset_s, np.float64),
        theta_in_rad=np.asarray(msg.theta_in_rad, np.float64),
        theta_out_rad=np.asarray(msg.theta_out_rad, np.float64),
        torque_out_nm=np.asarray(msg.torque_out_nm, np.float64))


_OP_CHUNK_INDEX = 0x08
_FOOTER_TAIL = 1 + 8 + 20 + 8   # footer record (opcode, length, 8 + 8 + 4) and magic


@contextlib.contextmanager
def _mapped(file: Path) -> Iterator[memoryview | None]:
    """The file mapped read-only, or None when it cannot be (missing, empty, unreadable)."""
    try:
        with file.open('rb') as fh:
            mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
    except (OSError, ValueError):
        yield None
        return
    buf = memoryview(mm)
    try:
        yield buf
    finally:
        with contextlib.suppress(BufferError):
            buf.release()
            mm.close()


def _summary_in(buf: memoryview) -> tuple[_ScanState, list[tuple[int, set[int]]]] | None:
    """Schemas, channels and chunk index (offset, channel ids) from an MCAP file's summary.

    None when the file has no usable summary (a recorder that was killed writes none; a
    summary whose CRC does not match is not trusted; a summary without channels or chunk
    indexes cannot answer for the file) and the caller must scan it.
    """
    size = len(buf)
    if size < 8 + _FOOTER_TAIL:
        return None
    foot = size - _FOOTER_TAIL
    try:
        if bytes(buf[size - 8:]) != MAGIC or buf[foot] != _OP_FOOTER:
            return None
        summary_start, _, crc = struct.unpack_from('<QQI', buf, foot + 9)
        if not 8 < summary_start < foot:
            return None
        if crc and zlib.crc32(buf[summary_start:foot + 9 + 16]) != crc:
            return None
        state = _ScanState()
        chunks: list[tuple[int, set[int]]] = []
        for _, op, body in _iter_records(buf[:foot], summary_start):
            if op == _OP_CHUNK_INDEX:
                (offset,) = _U64.unpack_from(body, 16)
                index, _ = _map_u16_u64(body, 32)
                chunks.append((offset, set(index)))
            else:
                _parse_meta_record(op, body, state)
    except (_CorruptError, struct.error, UnicodeDecodeError, ValueError):
        return None
    if not chunks or not state.channels:
        return None
    return state, chunks


def _summary(file: Path) -> tuple[_ScanState, list[tuple[int, set[int]]]] | None:
    """:func:`_summary_in` of a file (None also when it cannot be mapped)."""
    with _mapped(file) as buf:
        return None if buf is None else _summary_in(buf)


def _indexed_messages(file: Path, topics: Collection[str]) -> list[tuple[str, bytes]] | None:
    """Messages of ``topics`` in one MCAP file, found through its summary's chunk indexes.

    Only the chunks that hold those channels are decompressed (a BenchInfo is one small
    message in a long bag). Returns ``(schema name, cdr bytes)`` in file order, or None
    when the file has no usable summary (see :func:`_summary_in`) and the caller must scan
    it.
    """
    with _mapped(file) as buf:
        found_summary = None if buf is None else _summary_in(buf)
        if buf is None or found_summary is None:
            return None
        state, chunks = found_summary
        wanted = {cid for cid, (topic, _) in state.channels.items() if topic in topics}
        out: list[tuple[str, bytes]] = []
        try:
            for offset, cids in chunks:
                if not cids & wanted:
                    continue
                op, length = _REC.unpack_from(buf, offset)
                if op != _OP_CHUNK or offset + 9 + length > len(buf):
                    return None
                inner = _chunk_records(buf[offset + 9:offset + 9 + length])
                found: list[tuple[int, int, int, int]] = []
                _walk_chunk(inner, state, found)
                for cid, _, start, end in found:
                    if cid in wanted:
                        sid = state.channels[cid][1]
                        out.append((state.schemas.get(sid, ('', ''))[0],
                                    bytes(inner[start:end])))
        except (_CorruptError, struct.error, UnicodeDecodeError, ValueError, KeyError):
            return None   # damaged: the full scan decides what is readable
        return out


def _map_u16_u64(buf: memoryview, pos: int) -> tuple[dict[int, int], int]:
    """An MCAP map<uint16, uint64> (message index offsets by channel id)."""
    (n,) = _U32.unpack_from(buf, pos)
    end = pos + 4 + n
    if end > len(buf) or n % 10:
        raise _CorruptError('chunk index map runs past its record')
    return {cid: off for cid, off in struct.iter_unpack('<HQ', buf[pos + 4:end])}, end


def read_bench_info(path: str | Path, topic: str | None = None) -> dict[str, Any] | None:
    """The last BenchInfo message of a bag as a dict of its fields, or None if there is none.

    Args:
        path: Bag folder or ``.mcap`` file.
        topic: BenchInfo topic; None: every topic of type BenchInfo.

    Raises:
        BagError: Bad layout, or the message does not deserialise.
    """
    bag = open_bag(path)
    types = bag.topic_types or _scan_topic_types(bag)
    names = [topic] if topic is not None else [t for t, ty in types.items() if ty == BENCH_INFO]
    if not names:
        return None
    last: bytes | None = None
    stream: MessageStream[Any] = MessageStream(lambda s: iter(()), strict=False)
    for file in bag.files:
        # the summary's chunk index finds the few chunks that hold the topic; without a
        # summary (killed recorder) the file is scanned
        indexed = _indexed_messages(file, names)
        if indexed is None:
            one = Bag(path=bag.path, files=(file,), info=bag.info, topic_types=bag.topic_types)
            indexed = [(msgtype, bytes(data))
                       for _, msgtype, _, data in _messages(one, stream, names)]
        for msgtype, data in indexed:
            if msgtype == BENCH_INFO:
                last = data
    if last is None:
        if stream.partial:   # the BenchInfo may be in the part that cannot be read
            text = (f'Bag {bag.path}: no readable BenchInfo; the bag is damaged: '
                    f'{summarize_problems(stream.problems)}')
            raise BagError(text)
        return None
    try:
        msg = rv_te_typestore().deserialize_cdr(last, BENCH_INFO)
    except Exception as exc:  # noqa: BLE001
        text = f'Bag {bag.path}: BenchInfo does not deserialise: {exc}.'
        raise BagError(text) from None
    stamp = msg.header.stamp
    return {'stamp_s': stamp.sec + stamp.nanosec * 1e-9, 'frame_id': msg.header.frame_id,
            **bench_info_values(msg)}


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
