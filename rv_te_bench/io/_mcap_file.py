"""One ``.mcap`` file of a bag as ``BagWriter`` writes it: records, chunks, trailer, summary.

The file stays valid after every write: the data section is followed by a trailer (Data End
+ Footer without summary + magic) written in the same vectored write, which the next write
overwrites. A write that fails is cut back (``ftruncate``) to the end of the last complete
record and the trailer is put back, so a failed chunk never enters the file's chunk index
or counts. ``finish`` writes the rosbag2 metadata record and the full summary.
"""

from __future__ import annotations

import errno
import os
import struct
import zlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.writer import MCAP0_MAGIC

try:   # the chunk CRC at ISA-L speed (several times zlib's); zlib's gives the same value
    from isal.isal_zlib import crc32 as _chunk_crc32
except ImportError:   # pragma: no cover - a platform without an isal wheel
    _chunk_crc32 = zlib.crc32

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Sequence
    from pathlib import Path

    from mcap.records import McapRecord

    from rv_te_bench.io._storage import Storage

__all__ = ['MAGIC', 'MAX_TIME_NS', 'MSG_HEADER', 'OP_MESSAGE', 'TRAILER', 'Chunk',
           'Compression', 'McapFile', 'TopicInfo', 'compressor', 'record_bytes']

Compression = Literal['zstd', 'lz4', 'none']

#: The MCAP magic (``mcap``'s own), at the start and the end of every file.
MAGIC: bytes = MCAP0_MAGIC
MSG_HEADER = struct.Struct('<BQHIQQ')  # opcode, length, channel, sequence, log, publish
# mcap's opcodes as plain ints (struct.pack and the readers' hot loops take ints)
OP_MESSAGE = int(Opcode.MESSAGE)
MAX_TIME_NS = 2**63 - 1
_CHUNK_HEADER = struct.Struct('<QQQI')  # start, end, uncompressed size, crc
_OP_CHUNK = int(Opcode.CHUNK)
_OP_MESSAGE_INDEX = int(Opcode.MESSAGE_INDEX)
_OP_FOOTER = int(Opcode.FOOTER)
_OP_DATA_END = int(Opcode.DATA_END)
# Data End (no CRC) + Footer without summary + magic: keeps the file valid between chunks.
TRAILER = (struct.pack('<BQI', _OP_DATA_END, 4, 0)
           + struct.pack('<BQQQI', _OP_FOOTER, 20, 0, 0, 0) + MAGIC)


def record_bytes(*records: McapRecord) -> bytes:
    """The serialised records, in order."""
    builder = RecordBuilder()
    for record in records:
        record.write(builder)
    out: bytes = builder.end()
    return out


def compressor(compression: Compression, level: int | None = None,
               ) -> tuple[str, Callable[[bytes | bytearray], bytes]]:
    """(MCAP compression name, function) for a ``compression`` setting.

    Args:
        compression: ``zstd``, ``lz4`` or ``none``.
        level: The zstd level (None: 1; negative levels are zstd's fast ones).

    Raises:
        ValueError: Unknown compression, or a level given for another than zstd.
    """
    if level is not None and compression != 'zstd':
        msg = f'a compression level is a zstd setting, not one of {compression!r}'
        raise ValueError(msg)
    if compression == 'zstd':
        import zstandard

        ctx = zstandard.ZstdCompressor(level=1 if level is None else int(level))
        return 'zstd', ctx.compress
    if compression == 'lz4':
        import lz4.frame

        return 'lz4', lz4.frame.compress
    if compression == 'none':
        return '', bytes
    msg = f"compression must be 'zstd', 'lz4' or 'none', got {compression!r}"
    raise ValueError(msg)


@dataclass(slots=True)
class TopicInfo:
    """A topic of the bag: what its Schema and Channel records hold, and its counts."""

    name: str
    msgtype: str
    msgdef: str
    digest: str
    qos_yaml: str
    qos_list: list[dict[str, Any]] | str
    channel_id: int
    schema_id: int
    count: int = 0          # messages on disk
    lost: int = 0           # messages lost (disk full)

    def schema(self) -> Schema:
        return Schema(id=self.schema_id, name=self.msgtype, encoding='ros2msg',
                      data=self.msgdef.encode())

    def channel(self) -> Channel:
        meta = {'offered_qos_profiles': self.qos_yaml}
        if self.digest:
            meta['topic_type_hash'] = self.digest
        return Channel(id=self.channel_id, topic=self.name, message_encoding='cdr',
                       schema_id=self.schema_id, metadata=meta)


@dataclass(slots=True)
class Chunk:
    """Messages not on disk yet: their records and, per channel, flat (log time, offset)."""

    data: bytearray = field(default_factory=bytearray)
    index: dict[int, list[int]] = field(default_factory=dict)
    start_ns: int = MAX_TIME_NS
    end_ns: int = 0

    def message_counts(self) -> dict[int, int]:
        """Messages per channel id."""
        return {cid: len(flat) // 2 for cid, flat in self.index.items() if flat}

    @property
    def message_count(self) -> int:
        """Messages, all channels."""
        return sum(len(flat) for flat in self.index.values()) // 2

    def split(self, max_bytes: int) -> tuple[Chunk, Chunk]:
        """(the first messages, within ``max_bytes`` of records; the rest), in order."""
        starts = sorted(off for flat in self.index.values() for off in flat[1::2])
        starts.append(len(self.data))
        cut = max((s for s in starts if s <= max_bytes), default=0)
        parts = (Chunk(self.data[:cut]), Chunk(self.data[cut:]))
        for cid, flat in self.index.items():
            for t_ns, off in zip(flat[0::2], flat[1::2], strict=True):
                part, off2 = (parts[0], off) if off < cut else (parts[1], off - cut)
                part.index.setdefault(cid, []).extend((t_ns, off2))
                part.start_ns = min(part.start_ns, t_ns)
                part.end_ns = max(part.end_ns, t_ns)
        return parts


class McapFile:
    """An open ``.mcap`` file: data end, chunk and metadata indexes, counts per channel.

    Every method that writes raises ``OSError`` when the write fails, after cutting the
    file back to its last complete record; nothing it indexes or counts changes then.
    """

    def __init__(self, storage: Storage, path: Path, fd: int) -> None:
        self.storage = storage
        self.path = path
        self.fd = fd
        self.data_end = 0
        self.chunk_indexes: list[ChunkIndex] = []
        self.metadata_indexes: list[MetadataIndex] = []
        self.counts: dict[int, int] = {}
        self.channels: set[int] = set()
        self.schemas: set[int] = set()
        self.start_ns = MAX_TIME_NS    # log times of the messages on disk
        self.end_ns = 0
        self.first_ns = MAX_TIME_NS    # of the first message given to this file (splits)
        self.closed = False

    @classmethod
    def create(cls, storage: Storage, path: Path, *, library: str,
               metadata: Sequence[tuple[str, dict[str, str]]],
               topics: Iterable[TopicInfo]) -> McapFile:
        """Create ``path`` with magic, header, metadata records and the topics' records.

        Raises:
            OSError: It could not be created or written (nothing of it is left).
        """
        fd = storage.create(path)
        file = cls(storage, path, fd)
        head = bytearray(MAGIC + record_bytes(Header(profile='ros2', library=library)))
        for name, values in metadata:
            rec = record_bytes(Metadata(name=name, metadata=values))
            file.metadata_indexes.append(MetadataIndex(offset=len(head), length=len(rec),
                                                       name=name))
            head += rec
        for t in topics:
            head += file.topic_records(t)
        try:
            file.append(head)
        except OSError:
            undos: tuple[Callable[[], None], ...] = (lambda: storage.close(fd),
                                                     lambda: storage.unlink(path))
            for undo in undos:
                try:
                    undo()
                except OSError:
                    pass
            raise
        return file

    @property
    def message_count(self) -> int:
        """Messages on disk in this file."""
        return sum(self.counts.values())

    def topic_records(self, topic: TopicInfo) -> bytes:
        """Schema (first time in this file) and Channel record of ``topic``."""
        records: list[Any] = []
        if topic.schema_id not in self.schemas:
            records.append(topic.schema())
            self.schemas.add(topic.schema_id)
        records.append(topic.channel())
        self.channels.add(topic.channel_id)
        return record_bytes(*records)

    def append(self, *parts: bytes | bytearray) -> None:
        """Write parts at the data end, then the trailer, in one vectored write.

        Raises:
            OSError: The write failed; the file was cut back to its data end (+ trailer).
        """
        size = sum(len(p) for p in parts)
        try:
            self._write_at(self.data_end, [*parts, TRAILER], size + len(TRAILER))
        except OSError:
            self.cut_back()
            raise
        self.data_end += size

    def _write_at(self, offset: int, parts: list[bytes | bytearray | memoryview],
                  total: int) -> None:
        written = self.storage.pwritev(self.fd, parts, offset)
        if written < total:   # short write (a disk filling up): finish it or fail
            rest = memoryview(b''.join(parts))[written:]
            while rest:
                n = self.storage.pwritev(self.fd, [rest], offset + written)
                if n <= 0:
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                written += n
                rest = rest[n:]

    def cut_back(self) -> None:
        """Drop whatever a failed write left past the data end; put the trailer back."""
        try:
            self.storage.truncate(self.fd, self.data_end)
            self.storage.pwritev(self.fd, [TRAILER], self.data_end)
        except OSError:
            pass   # finish() or close_without_summary() tries again

    def write_chunk(self, chunk: Chunk, *, compression: str,
                    compress: Callable[[bytes | bytearray], bytes]) -> dict[int, int]:
        """Write one chunk and its message indexes; index and count it once on disk.

        Returns:
            Messages written per channel id.

        Raises:
            OSError: The write failed (the file is cut back, nothing was recorded).
        """
        raw = chunk.data
        compressed = compress(raw) if compression else raw
        comp = compression.encode()
        body_len = _CHUNK_HEADER.size + 4 + len(comp) + 8 + len(compressed)
        head = b''.join((
            struct.pack('<BQ', _OP_CHUNK, body_len),
            _CHUNK_HEADER.pack(chunk.start_ns, chunk.end_ns, len(raw), _chunk_crc32(raw)),
            struct.pack('<I', len(comp)), comp, struct.pack('<Q', len(compressed))))
        chunk_len = len(head) + len(compressed)
        chunk_start = self.data_end
        index = bytearray()
        index_offsets: dict[int, int] = {}
        for cid, flat in chunk.index.items():
            if not flat:
                continue
            index_offsets[cid] = chunk_start + chunk_len + len(index)
            pairs = struct.pack(f'<{len(flat)}Q', *flat)
            index += struct.pack('<BQHI', _OP_MESSAGE_INDEX, 2 + 4 + len(pairs), cid, len(pairs))
            index += pairs
        self.append(head, compressed, index)
        # Only now, with the chunk on disk, do the index and the counts include it.
        self.chunk_indexes.append(ChunkIndex(
            message_start_time=chunk.start_ns, message_end_time=chunk.end_ns,
            chunk_start_offset=chunk_start, chunk_length=chunk_len,
            message_index_offsets=index_offsets, message_index_length=len(index),
            compression=compression, compressed_size=len(compressed),
            uncompressed_size=len(raw)))
        counts = chunk.message_counts()
        for cid, n in counts.items():
            self.counts[cid] = self.counts.get(cid, 0) + n
        self.start_ns = min(self.start_ns, chunk.start_ns)
        self.end_ns = max(self.end_ns, chunk.end_ns)
        return counts

    def finish(self, bag_info_yaml: str, topics: Iterable[TopicInfo]) -> None:
        """Write the rosbag2 metadata record and the summary, then close the file.

        Raises:
            OSError: The tail could not be written (the file is cut back, still open).
        """
        # rosbag2 writes its bag information as a metadata record named 'rosbag2'.
        rec = record_bytes(Metadata(name='rosbag2',
                                    metadata={'serialized_metadata': bag_info_yaml}))
        meta_indexes = [*self.metadata_indexes,
                        MetadataIndex(offset=self.data_end, length=len(rec), name='rosbag2')]
        in_file = [t for t in topics if t.channel_id in self.channels]
        schemas: dict[int, TopicInfo] = {}
        for t in in_file:
            schemas.setdefault(t.schema_id, t)
        has_msgs = self.message_count > 0
        statistics = Statistics(
            message_count=self.message_count, schema_count=len(schemas),
            channel_count=len(in_file), attachment_count=0,
            metadata_count=len(meta_indexes), chunk_count=len(self.chunk_indexes),
            message_start_time=self.start_ns if has_msgs else 0,
            message_end_time=self.end_ns if has_msgs else 0,
            channel_message_counts={t.channel_id: self.counts.get(t.channel_id, 0)
                                    for t in in_file})
        tail = rec + _summary_tail(self.data_end + len(rec), [
            (Opcode.SCHEMA, [t.schema() for t in schemas.values()]),
            (Opcode.CHANNEL, [t.channel() for t in in_file]),
            (Opcode.STATISTICS, [statistics]),
            (Opcode.METADATA_INDEX, meta_indexes),
            (Opcode.CHUNK_INDEX, self.chunk_indexes)])
        try:
            self._write_at(self.data_end, [tail], len(tail))
            self.storage.truncate(self.fd, self.data_end + len(tail))
        except OSError:
            self.cut_back()
            raise
        self.storage.close(self.fd)
        self.metadata_indexes = meta_indexes
        self.data_end += len(tail)
        self.closed = True

    def close_without_summary(self) -> None:
        """Close with the trailer only (no room for the summary): readers scan the file."""
        self.cut_back()
        try:
            self.storage.close(self.fd)
        except OSError:
            pass
        self.closed = True


def _summary_tail(data_end: int, groups: Sequence[tuple[int, Sequence[Any]]]) -> bytes:
    """Data End, the summary groups, summary offsets, footer (with CRC) and magic."""
    data_end_rec = record_bytes(DataEnd(data_section_crc=0))
    summary_start = data_end + len(data_end_rec)
    summary = bytearray()
    offsets: list[SummaryOffset] = []
    for opcode, records in groups:
        blob = record_bytes(*records)
        if blob:
            offsets.append(SummaryOffset(group_opcode=opcode,
                                         group_start=summary_start + len(summary),
                                         group_length=len(blob)))
            summary += blob
    summary_offset_start = summary_start + len(summary)
    summary += record_bytes(*offsets)
    footer_head = struct.pack('<BQQQ', _OP_FOOTER, 20, summary_start, summary_offset_start)
    crc = zlib.crc32(bytes(summary) + footer_head)
    return data_end_rec + bytes(summary) + footer_head + struct.pack('<I', crc) + MAGIC
