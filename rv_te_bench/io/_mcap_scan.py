"""The MCAP record walk of the bag reader: records, chunks, summary, read-ahead.

The reader scans the records itself (no summary needed) so that files whose recorder was
killed, or that were cut short, still yield every sound message; what could not be read is
reported through a callback. A file's summary (when it has a sound one) answers the
questions that do not need the data: schemas, channels, and which chunks hold a topic.

The opcodes and the magic are ``mcap``'s (:class:`mcap.opcode.Opcode`, via
:mod:`rv_te_bench.io._mcap_file`), bound to plain ints here: the walks compare the opcode
of every record, and an ``IntEnum`` comparison costs more than an ``int`` one.
"""

from __future__ import annotations

import collections
import contextlib
import mmap
import os
import struct
import threading
import zlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from mcap.opcode import Opcode

from rv_te_bench.io._cores import READ_AHEAD_ENV, helper_threads_allowed, read_ahead_setting
from rv_te_bench.io._mcap_file import MAGIC

if TYPE_CHECKING:
    from collections.abc import Callable, Collection, Iterator
    from concurrent.futures import Executor
    from pathlib import Path

__all__ = ['CHUNK_CRC_ENV', 'PREFETCH_CHUNKS', 'READ_AHEAD_ENV', 'chunk_crc_checked',
           'helper_threads_allowed']

_U16 = struct.Struct('<H')
_U32 = struct.Struct('<I')
_U64 = struct.Struct('<Q')
_REC = struct.Struct('<BQ')
_MSG = struct.Struct('<HIQQ')
_CHUNK = struct.Struct('<QQQI')
_OP_FOOTER = int(Opcode.FOOTER)
_OP_SCHEMA = int(Opcode.SCHEMA)
_OP_CHANNEL = int(Opcode.CHANNEL)
_OP_MESSAGE = int(Opcode.MESSAGE)
_OP_CHUNK = int(Opcode.CHUNK)
_OP_CHUNK_INDEX = int(Opcode.CHUNK_INDEX)
_OP_METADATA = int(Opcode.METADATA)
_OP_DATA_END = int(Opcode.DATA_END)


class _CorruptError(Exception):
    """A record cannot be parsed (internal; turned into a problem or BagError)."""


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
            import zstandard

            return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        if compression == 'lz4':
            import lz4.frame

            out: bytes = lz4.frame.decompress(bytes(data))
            return out
    except MemoryError:
        raise _CorruptError(f'{compression} chunk does not fit in memory') from None
    except Exception as exc:  # noqa: BLE001 - codecs raise assorted errors on bad input
        raise _CorruptError(f'{compression} chunk does not decompress ({exc})') from None
    raise _CorruptError(f'unsupported chunk compression {compression!r}')


try:   # ISA-L's CRC-32 (carry-less multiply): ~15x zlib's; the same checksum (tested)
    from isal.isal_zlib import crc32 as _crc32
except ImportError:   # pragma: no cover - a platform without an isal wheel
    _crc32 = zlib.crc32


#: Environment switch: ``0`` skips the CRC-32 of the decompressed chunks (unset or ``1``:
#: checked). The rosbags reader does not check it; here it is on by default because it is
#: the only check of the measured values themselves (the writers' zstd frames carry no
#: checksum of their own: a flipped bit in a chunk that still decompresses would otherwise
#: change a TE value unseen). It costs 1-3 % of an analysis's CPU time (issue 41,
#: benchmarks/README.md); switch it off only for data whose storage is checked otherwise.
CHUNK_CRC_ENV = 'RV_TE_CHUNK_CRC'


def chunk_crc_checked() -> bool:
    """False when ``RV_TE_CHUNK_CRC=0`` (see :data:`CHUNK_CRC_ENV`), else True."""
    return os.environ.get(CHUNK_CRC_ENV, '1').strip() != '0'


def _chunk_records(body: memoryview, check_crc: bool = True) -> memoryview:
    start, end, usize, crc = _CHUNK.unpack_from(body, 0)
    _ = start, end
    compression, pos = _string(body, _CHUNK.size)
    (csize,) = _U64.unpack_from(body, pos)
    if pos + 8 + csize > len(body):
        raise _CorruptError('chunk data runs past its record')
    raw = _decompress(compression, body[pos + 8:pos + 8 + csize], usize)
    if len(raw) != usize:
        raise _CorruptError(f'chunk holds {len(raw)} bytes, header says {usize}')
    if crc and check_crc and _crc32(raw) != crc:
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


class _Columns(NamedTuple):
    """The messages of a decompressed chunk (or one loose message), one array per field:
    channel id, log time [ns] (uint64), and the byte positions of each message's data in
    the chunk (``start``, ``end``)."""

    cid: np.ndarray
    log_time: np.ndarray
    start: np.ndarray
    end: np.ndarray

    def rows(self) -> Iterator[tuple[int, int, int, int]]:
        """(cid, log_time, start, end) message by message, as Python ints."""
        return zip(*(a.tolist() for a in self), strict=True)


_Unit = tuple[memoryview, _Columns]
"""A decompressed chunk (or one loose message) and its messages (see ``_Columns``)."""


#: Environment switch: ``0`` turns the helper threads of one bag's analysis off, the
#: read-ahead here and the spectra thread of ``analyze_bag`` (a Dask worker of a fleet run on
#: a machine whose cores are all workers: parallel bags use the cores better).
def _read_ahead_on() -> bool:
    return read_ahead_setting() != '0'


#: Chunks decompressed ahead of the one being consumed (by one worker thread: zstd, lz4 and
#: crc32 release the GIL, so reading overlaps with the analysis on a second core). Eight
#: rather than two smooth out the hand-over with the spectra thread (issue 23: 1.17x ->
#: 1.08x the rosbags read with blocks of 10000); at most eight decompressed chunks are held.
PREFETCH_CHUNKS = 8
_AHEAD_RECORDS = 64

#: The map's pages behind the record walk are handed back every this many bytes: a mapped
#: page, once read, counts in the process's resident memory until it is unmapped, so without
#: this a 5 GB bag (10 h at 10 kHz) would hold 5 GB "resident" at the end of its read
#: (issue 41 s.5). The pages stay in the page cache; a view still read re-reads them there.
RELEASE_STEP_BYTES = 32 << 20


class _Releaser:
    """Drops the map's pages before a byte offset from this process (``MADV_DONTNEED``:
    the file's pages, not its data), in steps of ``RELEASE_STEP_BYTES``."""

    def __init__(self, mm: mmap.mmap) -> None:
        self.mm = mm
        self.done = 0   # pages before this offset are released
        self.on = hasattr(mmap, 'MADV_DONTNEED')   # (Linux, macOS; not Windows)

    def before(self, offset: int) -> None:
        """Release the whole pages before ``offset`` (every record there is consumed)."""
        if not self.on or offset - self.done < RELEASE_STEP_BYTES:
            return
        end = offset - offset % mmap.PAGESIZE
        try:
            self.mm.madvise(mmap.MADV_DONTNEED, self.done, end - self.done)
        except (OSError, ValueError):
            self.on = False    # not supported here: memory as before, nothing else changes
            return
        self.done = end


#: Message records of one length in a row from which the walk parses them as one array
#: (issue 41): a chunk of EncoderBlocks is a few to a few hundred records of one length.
_RUN_MIN = 8


class _Found:
    """The messages a chunk walk has found: rows one by one, runs as arrays."""

    __slots__ = ('_pieces', '_rows')

    def __init__(self) -> None:
        self._rows: list[tuple[int, int, int, int]] = []
        self._pieces: list[tuple[np.ndarray, ...]] = []

    def __bool__(self) -> bool:
        return bool(self._rows or self._pieces)

    def _flush(self) -> None:
        if self._rows:
            cid, log_time, start, end = zip(*self._rows, strict=True)
            self._pieces.append((np.array(cid, np.int64), np.array(log_time, np.uint64),
                                 np.array(start, np.int64), np.array(end, np.int64)))
            self._rows.clear()

    def run(self, *arrays: np.ndarray) -> None:
        self._flush()
        self._pieces.append(arrays)

    def columns(self) -> _Columns:
        self._flush()
        if len(self._pieces) == 1:
            return _Columns(*self._pieces[0])
        return _Columns(*(np.concatenate(parts) for parts in zip(*self._pieces, strict=True)))


def _message_run(u8: np.ndarray, pos: int, length: int, found: _Found) -> int:
    """Parse the run of message records of ``length`` bytes from ``pos`` as arrays (one
    numpy pass over their headers, none per message); the bytes after it, or ``pos`` when
    fewer than :data:`_RUN_MIN` records of that length follow."""
    rec = 9 + length
    k = (u8.size - pos) // rec
    if k < _RUN_MIN:
        return pos
    rows = u8[pos:pos + k * rec].reshape(k, rec)
    same = (rows[:, :9] == rows[0, :9]).all(axis=1)   # opcode and length as the first's
    run = k if same.all() else int(same.argmin())
    if run < _RUN_MIN:
        return pos
    rows = rows[:run]
    first = pos + 9 + _MSG.size
    start = np.arange(first, first + run * rec, rec, dtype=np.int64)
    found.run(rows[:, 9:11].copy().view('<u2').ravel().astype(np.int64),
              rows[:, 15:23].copy().view('<u8').ravel(), start, start + (length - _MSG.size))
    return pos + run * rec


def _walk_chunk(inner: memoryview, state: _ScanState, found: _Found) -> None:
    """Collect the messages of a decompressed chunk into ``found``, parse its other records.

    Runs of message records of one length (the EncoderBlocks of a bench) are parsed as
    arrays, checked record by record as the plain walk checks them (opcode, length).

    Raises:
        _CorruptError, struct.error, UnicodeDecodeError, ValueError: A record is damaged
            (the messages before it are in ``found``).
    """
    pos, n = 0, len(inner)
    rec, msg, op_message = _REC.unpack_from, _MSG.unpack_from, _OP_MESSAGE
    head = 9 + _MSG.size
    rows = found._rows   # the walk appends to its accumulator directly
    u8: np.ndarray | None = None
    last_length = -1
    runs = True   # off once a run came out short (records of varying lengths)
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
            if runs and length == last_length:   # a second of one length: try a run
                if u8 is None:
                    u8 = np.frombuffer(inner, np.uint8)
                after = _message_run(u8, pos, length, found)
                if after > pos:
                    pos = after
                    continue
                runs = False
            last_length = length
            cid, _, log_time, _ = msg(inner, pos + 9)
            rows.append((cid, log_time, pos + head, end))
        else:
            _parse_meta_record(op, inner[pos + 9:end], state)
        pos = end


def _scan_units(
    file: Path,
    state: _ScanState,
    report: Callable[[str], None],
    *,
    messages: bool = True,
    prefetch: bool = True,
    executor: Executor | None = None,
) -> Iterator[_Unit]:
    """Yield every sound message of one MCAP file, grouped by chunk (see ``_Unit``).

    With ``prefetch`` the next chunks are decompressed and CRC-checked by a worker thread
    while the caller works on the current one: the one of ``executor`` when given (shared
    with the caller's other jobs; left running), else a thread of its own.
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
    release = _Releaser(mm)
    ended = False
    check_crc = chunk_crc_checked()
    reader_thread = threading.get_ident()
    pool: Executor | None = None
    if prefetch and messages and _read_ahead_on():
        from concurrent.futures import ThreadPoolExecutor

        pool = executor if executor is not None else ThreadPoolExecutor(
            max_workers=1, thread_name_prefix='mcap-read')
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
                    job = pool.submit(_chunk_records, body, check_crc)
                ahead.append((offset, op, body, job))
                if op in (_OP_DATA_END, _OP_FOOTER):
                    exhausted = True
            if not ahead:
                break
            offset, op, body, job = ahead.popleft()
            if offset < 0:   # the record walk itself failed
                report(f'{file}: {job}')
                return
            release.before(offset)   # the records before this one are all consumed
            try:
                if op == _OP_MESSAGE:
                    if messages:
                        if len(body) < _MSG.size:
                            raise _CorruptError(f'message record is {len(body)} bytes long')
                        cid, _, log_time, _ = _MSG.unpack_from(body, 0)
                        yield memoryview(bytes(body)), _Columns(
                            np.array([cid], np.int64), np.array([log_time], np.uint64),
                            np.array([_MSG.size], np.int64), np.array([len(body)], np.int64))
                elif op == _OP_CHUNK:
                    # (a metadata-only scan decompresses too: schemas and channels live there)
                    # a chunk the helper has not started yet (busy, or not given a core by
                    # a loaded machine) is decompressed here rather than waited for
                    inner = _chunk_records(body, check_crc) \
                        if job is None or job.cancel() else job.result()
                    found = _Found()
                    damage = None
                    try:
                        _walk_chunk(inner, state, found)
                    except (_CorruptError, struct.error, UnicodeDecodeError, ValueError) as exc:
                        damage = exc   # the messages before the damaged record are sound
                    if found and messages:
                        yield inner, found.columns()
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
            # a job still reading the map is waited for before the map is closed
            running = [job for *_, job in ahead if job is not None and not job.cancel()]
            if pool is not executor:
                pool.shutdown(wait=True)
            elif threading.get_ident() == reader_thread:
                from concurrent.futures import wait

                wait(running)
            # (an abandoned reader closed by the garbage collector on another thread, maybe
            # the executor's own, does not wait on it: the map's views keep it open instead)
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
        for cid, log_time, start, end in found.rows():
            yield cid, log_time, inner[start:end]


def _file_channels(file: Path) -> _ScanState:
    """Schemas and channels of one MCAP file: from its summary, else by a scan."""
    summary = _summary(file)
    if summary is not None:
        return summary[0]
    state = _ScanState()
    for _ in _scan_file(file, state, lambda _t: None, messages=False):
        pass
    return state


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
                found = _Found()
                _walk_chunk(inner, state, found)
                for cid, _, start, end in found.columns().rows():
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
    return dict(struct.iter_unpack('<HQ', buf[pos + 4:end])), end
