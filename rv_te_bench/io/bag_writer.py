"""rosbag2 (MCAP storage) writer for raw CDR messages, crash-tolerant, without rclpy.

Why not ``rosbags.rosbag2.Writer`` or ``mcap.writer.Writer``: rosbags closes chunks only by
size (1 MiB) and writes the footer and metadata.yaml only at close, so a killed recorder
leaves an unreadable bag; ``mcap.writer.Writer`` (1.6) can flush a chunk, but puts schema
and channel records inside the next chunk and never writes a footer before ``finish()``.
This writer builds records with ``mcap.records`` (and ``struct`` on the hot path) and keeps
the file valid at every flush:

* messages collect in an in-memory chunk; a chunk is written when it exceeds
  ``chunk_size_bytes`` or when ``flush_interval_s`` has passed since the last flush;
* after every chunk a minimal trailer (Data End + Footer without summary + magic) is written
  in the same ``write()`` call, and the next chunk overwrites it; readers that need the end
  magic (rosbags) or scan the records (mcap's stream reader) both read the file;
* ``metadata.yaml`` is written at open and replaced atomically (tmp file + ``os.replace``)
  with the counts on disk at least every ``flush_interval_s`` while messages arrive, so a
  SIGKILLed recorder loses at most the messages of the last ``flush_interval_s`` and the
  bag opens with any rosbag2 reader (its counts may trail the .mcap by one interval);
* ``close()`` writes the full summary (schemas, channels, statistics, chunk and metadata
  indexes, summary offsets, CRC) and the final ``metadata.yaml``.
"""

from __future__ import annotations

import os
import struct
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import yaml
from mcap.data_stream import RecordBuilder
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from rv_te_bench.errors import BagError
from rv_te_bench.io.msgdefs import full_msgdef, type_hash

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping, Sequence
    from types import TracebackType

__all__ = ['SESSION_METADATA_NAME', 'BagWriter', 'Compression', 'qos_profile_dict']

Compression = Literal['zstd', 'lz4', 'none']

MAGIC = b'\x89MCAP0\r\n'
SESSION_METADATA_NAME = 'rv_te_session'
_MSG_HEADER = struct.Struct('<BQHIQQ')  # opcode, length, channel, sequence, log, publish
_CHUNK_HEADER = struct.Struct('<QQQI')  # start, end, uncompressed size, crc
_OP_MESSAGE = 0x05
_OP_CHUNK = 0x06
_OP_MESSAGE_INDEX = 0x07
_OP_FOOTER = 0x02
_MAX_TIME_NS = 2**63 - 1
# Data End (no CRC) + Footer without summary + magic: keeps the file valid between chunks.
_TRAILER = (struct.pack('<BQI', 0x0F, 4, 0) + struct.pack('<BQQQI', 0x02, 20, 0, 0, 0)
            + MAGIC)
_YamlDumper = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)  # libyaml: ~20x faster


def qos_profile_dict(
    *,
    reliability: str = 'reliable',
    durability: str = 'volatile',
    history: str = 'keep_last',
    depth: int = 10,
) -> dict[str, Any]:
    """One offered QoS profile in the rosbag2 (metadata version 9) form.

    Args:
        reliability: ``reliable`` or ``best_effort``.
        durability: ``volatile`` or ``transient_local``.
        history: ``keep_last`` or ``keep_all``.
        depth: History depth [messages].

    Returns:
        The dict rosbag2 writes under ``offered_qos_profiles``.
    """
    default = {'sec': 0, 'nsec': 0}  # 0 = the RMW default (infinite)
    return {
        'history': history,
        'depth': int(depth),
        'reliability': reliability,
        'durability': durability,
        'deadline': dict(default),
        'lifespan': dict(default),
        'liveliness': 'automatic',
        'liveliness_lease_duration': dict(default),
        'avoid_ros_namespace_conventions': False,
    }


def _record_bytes(*records: Any) -> bytes:  # noqa: ANN401 - mcap.records types
    builder = RecordBuilder()
    for record in records:
        record.write(builder)
    return builder.end()


def _compressor(compression: Compression) -> tuple[str, Callable[[bytes], bytes]]:
    if compression == 'zstd':
        import zstandard  # noqa: PLC0415 - optional at import time

        ctx = zstandard.ZstdCompressor(level=1)
        return 'zstd', ctx.compress
    if compression == 'lz4':
        import lz4.frame  # noqa: PLC0415

        return 'lz4', lz4.frame.compress
    if compression == 'none':
        return '', bytes
    msg = f"compression must be 'zstd', 'lz4' or 'none', got {compression!r}"
    raise BagError(msg)


@dataclass(slots=True)
class _Topic:
    name: str
    msgtype: str
    msgdef: str
    digest: str
    qos_yaml: str
    qos_list: list[dict[str, Any]] | str
    channel_id: int
    schema_id: int
    count: int = 0          # messages flushed to disk
    pending: int = 0        # messages in the open chunk


@dataclass(slots=True)
class _File:
    path: Path
    fd: Any
    data_end: int = 0
    chunk_indexes: list[ChunkIndex] = field(default_factory=list)
    metadata_indexes: list[MetadataIndex] = field(default_factory=list)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int = _MAX_TIME_NS
    end_ns: int = 0
    schemas: set[int] = field(default_factory=set)

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())


class BagWriter:
    """Write a rosbag2 bag folder (``metadata.yaml`` + ``.mcap`` files) from raw CDR bytes.

    Use as a context manager, or call ``close()``. Not thread-safe: call from one thread.

    Args:
        path: Bag folder to create; must not exist.
        compression: Chunk compression, ``'zstd'``, ``'lz4'`` or ``'none'``.
        chunk_size_bytes: Uncompressed chunk size that triggers a chunk write [bytes].
        flush_interval_s: Longest time a message stays in memory [s] (checked on ``write``
            and ``flush_if_due``; call the latter from a timer when messages can stop).
        split_size_bytes: Start a new ``.mcap`` file past this size [bytes]; None: never.
        split_duration_s: Start a new file when its messages span this long [s]; None: never.
        session_metadata: Written as the MCAP metadata record ``rv_te_session`` and into
            ``custom_data`` of metadata.yaml; values that are not strings are YAML-dumped.

    Raises:
        BagError: ``path`` exists already, or a setting is invalid.
    """

    def __init__(  # noqa: PLR0913
        self,
        path: str | os.PathLike[str],
        *,
        compression: Compression = 'zstd',
        chunk_size_bytes: int = 1 << 20,
        flush_interval_s: float = 1.0,
        split_size_bytes: int | None = None,
        split_duration_s: float | None = None,
        session_metadata: Mapping[str, Any] | None = None,
    ) -> None:
        self.path = Path(path)
        if not chunk_size_bytes > 0:
            msg = f'chunk_size_bytes must be > 0, got {chunk_size_bytes!r}'
            raise BagError(msg)
        if not flush_interval_s > 0:
            msg = f'flush_interval_s must be > 0, got {flush_interval_s!r}'
            raise BagError(msg)
        if split_size_bytes is not None and not split_size_bytes > 0:
            msg = f'split_size_bytes must be > 0 or None, got {split_size_bytes!r}'
            raise BagError(msg)
        if split_duration_s is not None and not split_duration_s > 0:
            msg = f'split_duration_s must be > 0 or None, got {split_duration_s!r}'
            raise BagError(msg)
        self._compression_name, self._compress = _compressor(compression)
        self.compression: Compression = compression
        self.chunk_size_bytes = int(chunk_size_bytes)
        self.flush_interval_s = float(flush_interval_s)
        self.split_size_bytes = split_size_bytes
        self.split_duration_ns = (
            None if split_duration_s is None else int(split_duration_s * 1e9))
        self.session_metadata = {
            str(k): v if isinstance(v, str) else _dump_yaml(v).strip()
            for k, v in (session_metadata or {}).items()
        }
        try:
            self.path.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            msg = f'Bag {self.path} exists already, not overwriting.'
            raise BagError(msg) from None
        except OSError as exc:
            msg = f'Cannot create bag folder {self.path}: {exc}.'
            raise BagError(msg) from None

        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, int] = {}
        self._files: list[_File] = []
        self._closed_files: list[_File] = []
        self._file: _File | None = None
        self._chunk = bytearray()
        self._index: dict[int, list[int]] = {}
        self._chunk_start_ns = _MAX_TIME_NS
        self._chunk_end_ns = 0
        self._last_flush_mono = time.monotonic()
        self._last_yaml_mono = self._last_flush_mono
        self._yaml_dirty = False
        self._closed = False
        self._open_file()
        self._write_metadata_yaml(state='recording')

    # ----------------------------------------------------------------- public API
    @property
    def counts(self) -> dict[str, int]:
        """Messages per topic written so far (flushed or pending)."""
        return {t.name: t.count + t.pending for t in self._topics.values()}

    @property
    def files(self) -> list[Path]:
        """The ``.mcap`` files of the bag so far."""
        return [f.path for f in self._files]

    def add_topic(
        self,
        name: str,
        msgtype: str,
        *,
        offered_qos_profiles: Sequence[Mapping[str, Any]] | str = (),
        msgdef: str | None = None,
        digest: str | None = None,
    ) -> None:
        """Register a topic; call once per topic before writing to it.

        Args:
            name: Absolute topic name (``/ns/bench/encoders``).
            msgtype: ``pkg/msg/Name``.
            offered_qos_profiles: QoS profiles as rosbag2 dicts (see ``qos_profile_dict``)
                or an already serialised YAML string.
            msgdef: Full ros2msg definition; None: built from the known ``.msg`` files.
            digest: RIHS01 type hash; None: computed from the typestore when known.

        Raises:
            BagError: The writer is closed, the topic exists, or the type is unknown and no
                ``msgdef`` was given.
        """
        self._check_open()
        if name in self._topics:
            msg = f'Topic {name!r} was added to bag {self.path} already.'
            raise BagError(msg)
        if msgdef is None:
            msgdef = full_msgdef(msgtype)
        if digest is None:
            try:
                digest = type_hash(msgtype)
            except BagError:
                digest = ''
        if isinstance(offered_qos_profiles, str):
            qos_yaml = offered_qos_profiles
            qos_list: list[dict[str, Any]] | str = offered_qos_profiles
        else:
            qos_list = [dict(q) for q in offered_qos_profiles]
            qos_yaml = _dump_yaml(qos_list).strip() if qos_list else ''
        if msgtype not in self._schemas:
            self._schemas[msgtype] = len(self._schemas) + 1
        topic = _Topic(name=name, msgtype=msgtype, msgdef=msgdef, digest=digest,
                       qos_yaml=qos_yaml, qos_list=qos_list,
                       channel_id=len(self._topics) + 1, schema_id=self._schemas[msgtype])
        self._topics[name] = topic
        self._index[topic.channel_id] = []
        assert self._file is not None
        self._append(self._topic_records(topic, self._file))
        self._write_metadata_yaml(state='recording')

    def write(self, topic: str, timestamp_ns: int, cdr_bytes: bytes | memoryview) -> None:
        """Append one serialised message (CDR with its 4-byte encapsulation header).

        Args:
            topic: A topic added with ``add_topic``.
            timestamp_ns: Receive time [ns since epoch]; log and publish time of the record.
            cdr_bytes: The message as it travelled on the wire.

        Raises:
            BagError: Unknown topic or writer closed.
        """
        try:
            info = self._topics[topic]
        except KeyError:
            msg = f'Topic {topic!r} was not added to bag {self.path}.'
            raise BagError(msg) from None
        if self._closed:
            self._check_open()
        file = self._file
        assert file is not None
        if self.split_duration_ns is not None and file.start_ns != _MAX_TIME_NS and (
                timestamp_ns - file.start_ns >= self.split_duration_ns):
            self._split()
            file = self._file
            assert file is not None
        chunk = self._chunk
        cid = info.channel_id
        index = self._index[cid]
        index.append(timestamp_ns)
        index.append(len(chunk))
        chunk += _MSG_HEADER.pack(_OP_MESSAGE, 22 + len(cdr_bytes), cid, 0,
                                  timestamp_ns, timestamp_ns)
        chunk += cdr_bytes
        info.pending += 1
        self._chunk_start_ns = min(self._chunk_start_ns, timestamp_ns)
        self._chunk_end_ns = max(self._chunk_end_ns, timestamp_ns)
        if file.start_ns == _MAX_TIME_NS:
            file.start_ns = timestamp_ns
        if len(chunk) >= self.chunk_size_bytes:
            self._flush(update_yaml=False)
        elif time.monotonic() - self._last_flush_mono >= self.flush_interval_s:
            self._flush(update_yaml=True)

    def flush_if_due(self) -> bool:
        """Flush when ``flush_interval_s`` has passed since the last flush.

        Returns:
            True if a flush happened.
        """
        if self._closed or time.monotonic() - self._last_flush_mono < self.flush_interval_s:
            return False
        self.flush()
        return True

    def flush(self) -> None:
        """Write the open chunk, a valid trailer and an updated metadata.yaml."""
        self._flush(update_yaml=True)

    def _flush(self, *, update_yaml: bool) -> None:
        """Write the open chunk; rewrite metadata.yaml when asked or when it is older than
        ``flush_interval_s`` (a rename costs milliseconds on some file systems, so chunks
        closed for size do not each rewrite it; readers scan the .mcap, not the counts)."""
        self._check_open()
        now = time.monotonic()
        self._last_flush_mono = now
        if self._chunk:
            self._write_chunk()
        if self._yaml_dirty and (
                update_yaml or now - self._last_yaml_mono >= self.flush_interval_s):
            self._write_metadata_yaml(state='recording')
        file = self._file
        assert file is not None
        if self.split_size_bytes is not None and file.data_end >= self.split_size_bytes:
            self._split()

    def close(self) -> None:
        """Write the last chunk, the MCAP summary and the final metadata.yaml (idempotent)."""
        if self._closed:
            return
        try:
            if self._chunk:
                self._write_chunk()
            self._finish_file()
        finally:
            self._closed = True
        self._write_metadata_yaml(state='closed')

    def __enter__(self) -> BagWriter:
        """Return self; the bag is already open."""
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Close the bag (also on error, so that what was written stays readable)."""
        self.close()

    # ----------------------------------------------------------------- internals
    def _check_open(self) -> None:
        if self._closed:
            msg = f'Bag {self.path} is closed.'
            raise BagError(msg)

    def _topic_records(self, topic: _Topic, file: _File) -> bytes:
        records: list[Any] = []
        if topic.schema_id not in file.schemas:
            records.append(Schema(id=topic.schema_id, name=topic.msgtype, encoding='ros2msg',
                                  data=topic.msgdef.encode()))
            file.schemas.add(topic.schema_id)
        records.append(Channel(id=topic.channel_id, topic=topic.name, message_encoding='cdr',
                               schema_id=topic.schema_id, metadata=self._channel_metadata(topic)))
        file.counts.setdefault(topic.channel_id, 0)
        return _record_bytes(*records)

    @staticmethod
    def _channel_metadata(topic: _Topic) -> dict[str, str]:
        meta = {'offered_qos_profiles': topic.qos_yaml}
        if topic.digest:
            meta['topic_type_hash'] = topic.digest
        return meta

    def _open_file(self) -> None:
        index = len(self._files)
        path = self.path / f'{self.path.name}_{index}.mcap'
        try:
            fd = path.open('xb', buffering=0)
        except OSError as exc:
            msg = f'Cannot create {path}: {exc}.'
            raise BagError(msg) from None
        file = _File(path=path, fd=fd)
        self._files.append(file)
        self._file = file
        head = MAGIC + _record_bytes(Header(profile='ros2', library=_library_id()))
        file.data_end = 0
        self._raw_append(file, head)
        if self.session_metadata:
            offset = file.data_end
            rec = _record_bytes(Metadata(name=SESSION_METADATA_NAME,
                                         metadata=dict(self.session_metadata)))
            file.metadata_indexes.append(
                MetadataIndex(offset=offset, length=len(rec), name=SESSION_METADATA_NAME))
            self._raw_append(file, rec)
        out = b''.join(self._topic_records(t, file) for t in self._topics.values())
        if out:
            self._append(out)

    def _append(self, payload: bytes) -> None:
        """Write payload at the data end, followed by a valid trailer, in one write."""
        assert self._file is not None
        self._raw_append(self._file, payload)

    def _raw_append(self, file: _File, *parts: bytes | bytearray) -> None:
        """Write parts at the data end, then a valid trailer, in one vectored write."""
        size = sum(len(p) for p in parts)
        fd = file.fd.fileno()
        try:
            written = os.pwritev(fd, [*parts, _TRAILER], file.data_end)
            if written < size + len(_TRAILER):  # short write (rare): finish it plainly
                rest = b''.join([*parts, _TRAILER])[written:]
                while rest:
                    n = os.pwrite(fd, rest, file.data_end + written)
                    written += n
                    rest = rest[n:]
        except OSError as exc:
            msg = f'Cannot write {file.path}: {exc}.'
            raise BagError(msg) from None
        file.data_end += size

    def _write_chunk(self) -> None:
        file = self._file
        assert file is not None
        raw = self._chunk
        compressed = raw if self.compression == 'none' else self._compress(raw)
        comp = self._compression_name.encode()
        body_len = _CHUNK_HEADER.size + 4 + len(comp) + 8 + len(compressed)
        head = b''.join((
            struct.pack('<BQ', _OP_CHUNK, body_len),
            _CHUNK_HEADER.pack(self._chunk_start_ns, self._chunk_end_ns, len(raw),
                               zlib.crc32(raw)),
            struct.pack('<I', len(comp)), comp, struct.pack('<Q', len(compressed))))
        chunk_len = len(head) + len(compressed)
        chunk_start = file.data_end
        index = bytearray()
        index_offsets: dict[int, int] = {}
        for cid, flat in self._index.items():
            if not flat:
                continue
            index_offsets[cid] = chunk_start + chunk_len + len(index)
            pairs = struct.pack(f'<{len(flat)}Q', *flat)
            index += struct.pack('<BQHI', _OP_MESSAGE_INDEX, 2 + 4 + len(pairs), cid, len(pairs))
            index += pairs
        file.chunk_indexes.append(ChunkIndex(
            message_start_time=self._chunk_start_ns, message_end_time=self._chunk_end_ns,
            chunk_start_offset=chunk_start, chunk_length=chunk_len,
            message_index_offsets=index_offsets, message_index_length=len(index),
            compression=self._compression_name, compressed_size=len(compressed),
            uncompressed_size=len(raw)))
        self._raw_append(file, head, compressed, index)
        self._yaml_dirty = True
        # Only now, with the chunk on disk, do the counts include it.
        for topic in self._topics.values():
            if topic.pending:
                file.counts[topic.channel_id] = file.counts.get(topic.channel_id, 0) + topic.pending
                topic.count += topic.pending
                topic.pending = 0
        file.start_ns = min(file.start_ns, self._chunk_start_ns)
        file.end_ns = max(file.end_ns, self._chunk_end_ns)
        self._chunk = bytearray()
        for flat in self._index.values():
            flat.clear()
        self._chunk_start_ns = _MAX_TIME_NS
        self._chunk_end_ns = 0

    def _split(self) -> None:
        if self._chunk:
            self._write_chunk()
        self._finish_file()
        self._open_file()
        self._write_metadata_yaml(state='recording')

    def _finish_file(self) -> None:
        file = self._file
        assert file is not None
        # rosbag2 writes its bag information as a metadata record named 'rosbag2'.
        info = _dump_yaml(self._bag_info(state='closed'))
        rec = _record_bytes(Metadata(name='rosbag2', metadata={'serialized_metadata': info}))
        file.metadata_indexes.append(
            MetadataIndex(offset=file.data_end, length=len(rec), name='rosbag2'))
        self._raw_append(file, rec)
        data_end = _record_bytes(DataEnd(data_section_crc=0))
        summary_start = file.data_end + len(data_end)
        groups: list[tuple[int, bytes]] = []
        in_file = [t for t in self._topics.values() if t.channel_id in file.counts]
        schema_ids: dict[int, _Topic] = {}
        for t in in_file:
            schema_ids.setdefault(t.schema_id, t)
        groups.append((0x03, _record_bytes(*[
            Schema(id=sid, name=t.msgtype, encoding='ros2msg', data=t.msgdef.encode())
            for sid, t in schema_ids.items()])))
        groups.append((0x04, _record_bytes(*[
            Channel(id=t.channel_id, topic=t.name, message_encoding='cdr',
                    schema_id=t.schema_id, metadata=self._channel_metadata(t))
            for t in in_file])))
        has_msgs = file.message_count > 0
        groups.append((0x0B, _record_bytes(Statistics(
            message_count=file.message_count, schema_count=len(schema_ids),
            channel_count=len(in_file), attachment_count=0,
            metadata_count=len(file.metadata_indexes), chunk_count=len(file.chunk_indexes),
            message_start_time=file.start_ns if has_msgs else 0,
            message_end_time=file.end_ns if has_msgs else 0,
            channel_message_counts=dict(file.counts)))))
        groups.append((0x0D, _record_bytes(*file.metadata_indexes)))
        groups.append((0x08, _record_bytes(*file.chunk_indexes)))
        summary = bytearray()
        offsets: list[SummaryOffset] = []
        for opcode, blob in groups:
            if blob:
                offsets.append(SummaryOffset(group_opcode=opcode,
                                             group_start=summary_start + len(summary),
                                             group_length=len(blob)))
                summary += blob
        summary_offset_start = summary_start + len(summary)
        summary += _record_bytes(*offsets)
        footer_head = struct.pack('<BQQQ', _OP_FOOTER, 20, summary_start, summary_offset_start)
        crc = zlib.crc32(bytes(summary) + footer_head)
        tail = data_end + bytes(summary) + footer_head + struct.pack('<I', crc) + MAGIC
        try:
            os.pwrite(file.fd.fileno(), tail, file.data_end)
            os.ftruncate(file.fd.fileno(), file.data_end + len(tail))
            file.fd.close()
        except OSError as exc:
            msg = f'Cannot finish {file.path}: {exc}.'
            raise BagError(msg) from None
        file.data_end += len(tail)
        self._closed_files.append(file)

    def _bag_info(self, *, state: str) -> dict[str, Any]:
        files = self._files
        starts = [f.start_ns for f in files if f.message_count]
        ends = [f.end_ns for f in files if f.message_count]
        start = min(starts) if starts else 0
        duration = (max(ends) - start) if ends else 0
        return {
            'version': 9,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': sum(f.message_count for f in files),
            'topics_with_message_count': [
                {
                    'topic_metadata': {
                        'name': t.name,
                        'type': t.msgtype,
                        'serialization_format': 'cdr',
                        'offered_qos_profiles': t.qos_list if t.qos_list else [],
                        'type_description_hash': t.digest,
                    },
                    'message_count': t.count,
                }
                for t in self._topics.values()
            ],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [f.path.name for f in files],
            'files': [
                {
                    'path': f.path.name,
                    'starting_time': {
                        'nanoseconds_since_epoch': f.start_ns if f.message_count else 0},
                    'duration': {'nanoseconds': (f.end_ns - f.start_ns) if f.message_count else 0},
                    'message_count': f.message_count,
                }
                for f in files
            ],
            'custom_data': {**self.session_metadata, 'rv_te_bench.writer_state': state},
            'ros_distro': 'jazzy',
        }

    def _write_metadata_yaml(self, *, state: str) -> None:
        self._yaml_dirty = False
        self._last_yaml_mono = time.monotonic()
        text = _dump_yaml({'rosbag2_bagfile_information': self._bag_info(state=state)})
        target = self.path / 'metadata.yaml'
        tmp = self.path / '.metadata.yaml.tmp'
        try:
            tmp.write_text(text, encoding='utf-8')
            os.replace(tmp, target)
        except OSError as exc:
            msg = f'Cannot write {target}: {exc}.'
            raise BagError(msg) from None


def _dump_yaml(data: Any) -> str:  # noqa: ANN401
    return yaml.dump(data, Dumper=_YamlDumper, sort_keys=False)


def _library_id() -> str:
    try:
        from importlib.metadata import version  # noqa: PLC0415

        return f'rv_te_bench {version("rv-te-bench")} (BagWriter)'
    except Exception:  # noqa: BLE001 - metadata absent in a source checkout
        return 'rv_te_bench (BagWriter)'
