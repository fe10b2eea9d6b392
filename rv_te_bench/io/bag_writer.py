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

A full disk (any failed write) does not corrupt the bag:

* a chunk enters the chunk index and the counts only once it is on disk; a failed write is
  cut back (``ftruncate``) to the end of the last complete chunk, where the trailer goes;
* a reserve file in the bag folder (``.rv_te_reserve``, sized to the summary and
  metadata.yaml still to come) is given back, and the file is closed with its summary, so
  rosbags and mcap read it; metadata.yaml says what was lost;
* messages keep arriving: up to ``stall_buffer_bytes`` are held in memory, the rest are
  counted as lost (per topic, with the range of their log times: a ``WriteGap``);
* every ``flush_interval_s`` the writer checks the free space; once the reserve, the held
  messages and a chunk fit, recording resumes into a new split file (which starts with an
  ``rv_te_write_gap`` metadata record) and the held messages are written first;
* ``counts`` are the messages on disk, ``lost`` the messages lost; ``on_event`` is told
  (one line) when writing stops and resumes.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import BagError, BagExistsError
from rv_te_bench.io._mcap_file import (
    MAX_TIME_NS,
    MSG_HEADER,
    OP_MESSAGE,
    Chunk,
    Compression,
    McapFile,
    TopicInfo,
    compressor,
)
from rv_te_bench.io._metadata_yaml import (
    bag_info,
    dump_yaml,
    metadata_yaml_bytes,
    qos_profile_dict,
    replace_metadata_yaml,
)
from rv_te_bench.io._reserve import Reserve, reserve_need
from rv_te_bench.io._storage import Storage
from rv_te_bench.io._write_loss import WRITE_GAP_RECORD, WriteGap, utc_now
from rv_te_bench.io._write_stall import WriteStall
from rv_te_bench.io.msgdefs import full_msgdef, type_hash

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping, Sequence
    from types import TracebackType

__all__ = ['RESERVE_NAME', 'SESSION_METADATA_NAME', 'BagWriter', 'Compression', 'Storage',
           'WriteGap', 'qos_profile_dict']

SESSION_METADATA_NAME = 'rv_te_session'
RESERVE_NAME = '.rv_te_reserve'
_log = logging.getLogger(__name__)


class BagWriter:
    """Write a rosbag2 bag folder (``metadata.yaml`` + ``.mcap`` files) from raw CDR bytes.

    Use as a context manager, or call ``close()``. Not thread-safe: call from one thread.

    Args:
        path: Bag folder to create; must not exist.
        compression: Chunk compression, ``'zstd'``, ``'lz4'`` or ``'none'``.
        compression_level: The zstd level (None: 1, as rosbag2's default; a negative
            level is one of zstd's fast ones).
        chunk_size_bytes: Uncompressed chunk size that triggers a chunk write [bytes].
        flush_interval_s: Longest time a message stays in memory [s] (checked on ``write``
            and ``flush_if_due``; call the latter from a timer when messages can stop); also
            how often a writer whose disk is full checks whether space has returned.
        split_size_bytes: Start a new ``.mcap`` file past this size [bytes]; None: never.
        split_duration_s: Start a new file when its messages span this long [s]; None: never.
        session_metadata: Written as the MCAP metadata record ``rv_te_session`` and into
            ``custom_data`` of metadata.yaml; values that are not strings are YAML-dumped.
        stall_buffer_bytes: Messages held in memory while the disk is full [bytes]; what
            does not fit is lost (``lost``, ``write_gaps``, metadata.yaml).
        storage: The file operations (a ``Storage``); tests pass one that injects faults.
        on_event: Called with one line when writing fails and when it resumes; default:
            a warning on this module's ``logging`` logger.

    Raises:
        BagError: ``path`` exists already, a setting is invalid, or the bag cannot be
            started (no space for its first file and reserve).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        compression: Compression = 'zstd',
        compression_level: int | None = None,
        chunk_size_bytes: int = 1 << 20,
        flush_interval_s: float = 1.0,
        split_size_bytes: int | None = None,
        split_duration_s: float | None = None,
        session_metadata: Mapping[str, Any] | None = None,
        stall_buffer_bytes: int = 64 << 20,
        storage: Storage | None = None,
        on_event: Callable[[str], None] | None = None,
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
        if not stall_buffer_bytes >= 0:
            msg = f'stall_buffer_bytes must be >= 0, got {stall_buffer_bytes!r}'
            raise BagError(msg)
        try:
            self._compression_name, self._compress = compressor(compression, compression_level)
        except ValueError as exc:
            raise BagError(str(exc)) from None
        self.compression: Compression = compression
        self.chunk_size_bytes = int(chunk_size_bytes)
        self.flush_interval_s = float(flush_interval_s)
        self.split_size_bytes = split_size_bytes
        self.split_duration_ns = (
            None if split_duration_s is None else int(split_duration_s * 1e9))
        self.stall_buffer_bytes = int(stall_buffer_bytes)
        self.session_metadata = {
            str(k): v if isinstance(v, str) else dump_yaml(v).strip()
            for k, v in (session_metadata or {}).items()
        }
        self._storage = storage if storage is not None else Storage()
        self._on_event = on_event if on_event is not None else _log.warning
        try:
            self.path.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            msg = f'Bag {self.path} exists already, not overwriting.'
            raise BagExistsError(msg) from None
        except OSError as exc:
            msg = f'Cannot create bag folder {self.path}: {exc}.'
            raise BagError(msg) from None

        self._topics: dict[str, TopicInfo] = {}
        self._by_cid: dict[int, TopicInfo] = {}
        self._schemas: dict[str, int] = {}
        self._files: list[McapFile] = []
        self._file: McapFile | None = None
        self._open = Chunk()           # collecting messages
        self._stall = WriteStall(self.stall_buffer_bytes)   # the disk is full: held, lost
        self._reserve = Reserve(self._storage, self.path / RESERVE_NAME)
        self._yaml_size = 4096
        self._last_flush_mono = time.monotonic()
        self._last_yaml_mono = self._last_flush_mono
        self._yaml_dirty = False
        self._closed = False
        try:
            self._open_file()
            self._write_metadata_yaml(state='recording')
            self._ensure_reserve()
        except OSError as exc:
            self._abandon()
            msg = f'Cannot start bag {self.path}: {exc.strerror or exc}.'
            raise BagError(msg) from None

    # ----------------------------------------------------------------- public API
    @property
    def counts(self) -> dict[str, int]:
        """Messages per topic on disk (in complete chunks): what a reader finds."""
        return {t.name: t.count for t in self._topics.values()}

    @property
    def pending(self) -> dict[str, int]:
        """Messages per topic accepted but not on disk yet (open chunk, held ones)."""
        out = dict.fromkeys(self._topics, 0)
        for chunk in (*self._stall.held, self._open):
            for cid, n in chunk.message_counts().items():
                out[self._by_cid[cid].name] += n
        return out

    @property
    def lost(self) -> dict[str, int]:
        """Messages per topic that could not be written (the disk was full)."""
        return {t.name: t.lost for t in self._topics.values()}

    @property
    def lost_messages(self) -> int:
        """Messages lost, all topics."""
        return sum(t.lost for t in self._topics.values())

    @property
    def write_gaps(self) -> list[WriteGap]:
        """Every period in which the bag could not be written, in order."""
        return list(self._stall.gaps)

    @property
    def stalled(self) -> bool:
        """True while the disk is full (messages are held or lost)."""
        return self._stall.gap is not None

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
            qos_yaml = dump_yaml(qos_list).strip() if qos_list else ''
        if msgtype not in self._schemas:
            self._schemas[msgtype] = len(self._schemas) + 1
        topic = TopicInfo(name=name, msgtype=msgtype, msgdef=msgdef, digest=digest,
                       qos_yaml=qos_yaml, qos_list=qos_list,
                       channel_id=len(self._topics) + 1, schema_id=self._schemas[msgtype])
        self._topics[name] = topic
        self._by_cid[topic.channel_id] = topic
        file = self._file
        if file is not None:   # (while the disk is full, the next file gets the records)
            try:
                file.append(file.topic_records(topic))
                self._ensure_reserve()
            except OSError as exc:
                self._start_gap(exc)
        self._write_yaml_or_gap()

    def write(self, topic: str, timestamp_ns: int, cdr_bytes: bytes | memoryview) -> None:
        """Append one serialised message (CDR with its 4-byte encapsulation header).

        A message that cannot be stored because the disk is full (and the memory held
        meanwhile is used up) is counted in ``lost``; this does not raise.

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
        if self._stall.gap is not None and self._drop_while_stalled(info, timestamp_ns,
                                                                    len(cdr_bytes)):
            return
        file = self._file
        if self.split_duration_ns is not None and file is not None and (
                file.first_ns != MAX_TIME_NS
                and timestamp_ns - file.first_ns >= self.split_duration_ns):
            self._split()
            file = self._file
        chunk = self._open
        data = chunk.data
        cid = info.channel_id
        index = chunk.index.get(cid)
        if index is None:
            index = chunk.index[cid] = []
        index.append(timestamp_ns)
        index.append(len(data))
        data += MSG_HEADER.pack(OP_MESSAGE, 22 + len(cdr_bytes), cid, 0,
                                 timestamp_ns, timestamp_ns)
        data += cdr_bytes
        chunk.start_ns = min(chunk.start_ns, timestamp_ns)
        chunk.end_ns = max(chunk.end_ns, timestamp_ns)
        if file is not None and file.first_ns == MAX_TIME_NS:
            file.first_ns = timestamp_ns
        if len(data) >= self.chunk_size_bytes:
            self._flush(update_yaml=False)
        elif time.monotonic() - self._last_flush_mono >= self.flush_interval_s:
            self._flush(update_yaml=True)

    def write_batch(self, topic: str, timestamps_ns: np.ndarray, size: int,
                    fill: Callable[[np.ndarray, int, int], None]) -> None:
        """Append ``len(timestamps_ns)`` messages of ``size`` bytes each, laid out in place.

        The same records, chunks and index as ``write`` called once per message (tested
        byte for byte), without a Python step per message: the MCAP record headers are
        written for all the messages of a chunk at once and ``fill(rows, i, j)`` lays out
        messages ``i..j-1`` (CDR, encapsulation header included) into ``rows``, a
        ``(j - i, size)`` uint8 array inside the chunk (zeros on entry; keep no reference
        to it). The time-based flush is checked once per batch. While the disk is full or
        with ``split_duration_s`` the messages go through ``write`` one by one.

        Raises:
            BagError: Unknown topic or writer closed.
        """
        try:
            info = self._topics[topic]
        except KeyError:
            msg = f'Topic {topic!r} was not added to bag {self.path}.'
            raise BagError(msg) from None
        self._check_open()
        stamps = np.asarray(timestamps_ns, dtype=np.int64)
        n = stamps.size
        rec = MSG_HEADER.size + size
        head = np.frombuffer(MSG_HEADER.pack(OP_MESSAGE, 22 + size, info.channel_id, 0, 0, 0),
                             dtype=np.uint8)
        i = 0
        while i < n:
            if self._stall.gap is not None or self.split_duration_ns is not None:
                rows = np.zeros((n - i, size), dtype=np.uint8)
                fill(rows, i, n)
                for k in range(n - i):
                    self.write(topic, int(stamps[i + k]), rows[k].data)
                break
            chunk = self._open
            old = len(chunk.data)
            # write() flushes after the message that brings the chunk to chunk_size_bytes
            m = min(n - i, max(1, -(-(self.chunk_size_bytes - old) // rec)))
            if old:
                chunk.data += bytes(m * rec)
            else:
                chunk.data = bytearray(m * rec)
            ts = stamps[i:i + m]
            view = np.frombuffer(chunk.data, dtype=np.uint8, count=m * rec,
                                 offset=old).reshape(m, rec)
            view[:, :head.size] = head
            stamp_bytes = ts.astype('<u8').view(np.uint8).reshape(m, 8)
            view[:, 15:23] = stamp_bytes
            view[:, 23:31] = stamp_bytes
            fill(view[:, MSG_HEADER.size:], i, i + m)
            del view
            flat = np.empty(2 * m, dtype=np.int64)
            flat[0::2] = ts
            flat[1::2] = old + rec * np.arange(m, dtype=np.int64)
            chunk.index.setdefault(info.channel_id, []).extend(flat.tolist())
            chunk.start_ns = min(chunk.start_ns, int(ts.min()))
            chunk.end_ns = max(chunk.end_ns, int(ts.max()))
            file = self._file
            if file is not None and file.first_ns == MAX_TIME_NS:
                file.first_ns = int(ts[0])
            i += m
            if len(chunk.data) >= self.chunk_size_bytes:
                self._flush(update_yaml=False)
        if self._open.data and time.monotonic() - self._last_flush_mono >= self.flush_interval_s:
            self._flush(update_yaml=True)

    def flush_if_due(self) -> bool:
        """Flush (or, while the disk is full, look for space) every ``flush_interval_s``.

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

    def close(self) -> None:
        """Write the last chunk, the MCAP summary and the final metadata.yaml (idempotent).

        If the disk is still full, what is held in memory is counted as lost; the files
        on disk are closed readable either way.

        Raises:
            BagError: The final metadata.yaml could not be written (the .mcap files are
                complete; metadata.yaml is then the one of the last flush).
        """
        if self._closed:
            return
        try:
            if self._stall.gap is None and self._open.data:
                self._write_open()
            if self._stall.gap is not None and self._try_resume() and self._open.data:
                self._write_open()
            if self._stall.gap is not None:
                self._stall.lose_all(self._open, self._by_cid)
                self._open = Chunk()
            file = self._file
            if file is not None and not file.closed:
                self._reserve.release()
                try:
                    self._finish_file(file)
                except OSError as exc:
                    file.close_without_summary()
                    self._on_event(f'bag {self.path}: no room for the summary of '
                                   f'{file.path.name} ({exc.strerror}); left without one '
                                   '(readers scan it)')
        finally:
            self._closed = True
            self._reserve.release()
        try:
            self._write_metadata_yaml(state='closed')
        except OSError as exc:
            msg = (f'Cannot write {self.path / "metadata.yaml"}: {exc.strerror or exc}; the '
                   '.mcap files are complete, metadata.yaml is the one of the last flush.')
            raise BagError(msg) from None

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

    # ----------------------------------------------------------------- writing
    def _check_open(self) -> None:
        if self._closed:
            msg = f'Bag {self.path} is closed.'
            raise BagError(msg)

    def _flush(self, *, update_yaml: bool) -> None:
        """Write the open chunk; rewrite metadata.yaml when asked or when it is older than
        ``flush_interval_s`` (a rename costs milliseconds on some file systems, so chunks
        closed for size do not each rewrite it; readers scan the .mcap, not the counts)."""
        self._check_open()
        now = time.monotonic()
        self._last_flush_mono = now
        if self._stall.gap is not None:
            if len(self._open.data) >= self.chunk_size_bytes:
                self._stall.hold(self._open)
                self._open = Chunk()
            if now < self._stall.next_retry_mono or not self._try_resume():
                return
        if self._open.data:
            self._write_open()
            if self._stall.gap is not None:
                return
        if self._yaml_dirty and (
                update_yaml or now - self._last_yaml_mono >= self.flush_interval_s):
            self._write_yaml_or_gap()
        file = self._file
        if (file is not None and self.split_size_bytes is not None
                and file.data_end >= self.split_size_bytes):
            self._split()

    def _write_open(self) -> None:
        """Write the open chunk; a failure starts a gap that holds it."""
        chunk, self._open = self._open, Chunk()
        try:
            self._write_chunk(chunk)
        except OSError as exc:
            self._start_gap(exc, [chunk])
            return
        try:
            self._ensure_reserve()
        except OSError as exc:
            self._start_gap(exc)

    def _write_chunk(self, chunk: Chunk) -> None:
        """Write one chunk to the open file and count its messages as on disk.

        Raises:
            OSError: The write failed (the file is cut back, nothing was counted).
        """
        file = self._file
        assert file is not None
        counts = file.write_chunk(chunk, compression=self._compression_name,
                                  compress=self._compress)
        for cid, n in counts.items():
            self._by_cid[cid].count += n
        self._yaml_dirty = True

    def _split(self) -> None:
        if self._open.data:
            self._write_open()
            if self._stall.gap is not None:
                return
        file = self._file
        assert file is not None
        try:
            self._finish_file(file)
        except OSError as exc:
            self._start_gap(exc)
            return
        self._file = None
        try:
            self._open_file()
        except OSError as exc:
            self._start_gap(exc)
            return
        self._write_yaml_or_gap()

    # ----------------------------------------------------------------- a full disk
    def _start_gap(self, exc: OSError, held: Sequence[Chunk] = ()) -> None:
        """Writing failed: close the file at its last complete chunk, hold or lose."""
        file = self._file
        stall = self._stall
        if stall.begin(exc, file.path.name if file is not None else '', held, self._open,
                       self._by_cid):
            self._open = Chunk()   # newer than what was lost: lost too
        gap = stall.gap
        assert gap is not None
        self._reserve.shrink(3 * self._yaml_size + (16 << 10))   # room for metadata.yaml
        if file is not None and not file.closed:
            self._close_after_failure(file, exc)
        self._file = None
        stall.next_retry_mono = time.monotonic() + self.flush_interval_s
        retry = f'retrying every {self.flush_interval_s:g} s' if stall.retrying else 'not retrying'
        self._on_event(
            f'bag {self.path}: cannot write ({gap.error}); {gap.file_before or "the bag"} '
            f'closed at its last complete chunk ({sum(self.counts.values())} messages on '
            f'disk); holding up to {self.stall_buffer_bytes / 2**20:.3g} MiB of messages in '
            f'memory, {retry}')
        try:
            self._write_metadata_yaml(state='recording')
        except OSError as exc2:
            self._on_event(f'bag {self.path}: metadata.yaml not updated ({exc2.strerror})')

    def _close_after_failure(self, file: McapFile, exc: OSError) -> None:
        """Close ``file`` with its summary; if even that fails, with the trailer only."""
        try:
            self._finish_file(file)
        except OSError as exc2:
            file.close_without_summary()
            self._on_event(f'bag {self.path}: no room for the summary of {file.path.name} '
                           f'({exc2.strerror or exc}); left without one (readers scan it)')

    def _drop_while_stalled(self, info: TopicInfo, t_ns: int, size: int) -> bool:
        """While the disk is full: try to resume when due. True: the message is counted
        lost (do not store it); False: store it (held in memory until space returns)."""
        if time.monotonic() >= self._stall.next_retry_mono and self._try_resume():
            return False
        return not self._stall.admits(info, t_ns, size, len(self._open.data))

    def _try_resume(self) -> bool:
        """Resume into a new file if the space has returned; True when writing again."""
        stall = self._stall
        gap = stall.gap
        if gap is None:
            return True
        stall.next_retry_mono = time.monotonic() + self.flush_interval_s
        if not stall.retrying:
            return False
        pending = stall.held_bytes + len(self._open.data)
        free = self._storage.free_bytes(self.path)
        if free is not None and free < 2 * self._reserve_need() + pending + self.chunk_size_bytes:
            return False
        try:
            self._ensure_reserve()
        except OSError:
            return False
        gap.resumed_utc = utc_now()
        gap.file_after = f'{self.path.name}_{len(self._files)}.mcap'
        gap.held = sum(sum(c.message_counts().values()) for c in (*stall.held, self._open))
        try:
            self._open_file(gap)
        except OSError:
            gap.resumed_utc = gap.file_after = None
            gap.held = 0
            return False
        stall.gap = None
        # metadata.yaml lists the new file before messages go into it (readers ignore
        # unlisted files); no room even for that: still full, a new gap keeps the held ones
        self._write_yaml_or_gap()
        if stall.gap is not None:
            gap.held = 0
            return False
        held = stall.take_held()
        for i, chunk in enumerate(held):
            try:
                self._write_chunk(chunk)
            except OSError as exc:
                gap.held -= sum(sum(c.message_counts().values()) for c in (*held[i:], self._open))
                self._start_gap(exc, held[i:])
                return False
        self._on_event(f'bag {self.path}: writing again: {gap.describe()}')
        self._yaml_dirty = True   # the counts of the held messages, at the next flush
        return True

    def _reserve_need(self) -> int:
        return reserve_need(self._file, self._topics.values(), self._yaml_size)

    def _ensure_reserve(self) -> None:
        """Grow the reserve file to twice the need once the need passes it (rarely)."""
        self._reserve.ensure(self._reserve_need())

    # ----------------------------------------------------------------- files
    def _open_file(self, gap: WriteGap | None = None) -> None:
        """Create the next ``<bag>_<n>.mcap`` (after a gap: with its ``rv_te_write_gap``).

        Raises:
            OSError: It could not be created or written (nothing of it is left).
        """
        meta: list[tuple[str, dict[str, str]]] = []
        if self.session_metadata:
            meta.append((SESSION_METADATA_NAME, dict(self.session_metadata)))
        if gap is not None:
            meta.append((WRITE_GAP_RECORD, {k: v if isinstance(v, str) else dump_yaml(v).strip()
                                            for k, v in gap.as_dict().items()}))
        self._file = McapFile.create(
            self._storage, self.path / f'{self.path.name}_{len(self._files)}.mcap',
            library=_library_id(), metadata=meta, topics=self._topics.values())
        self._files.append(self._file)

    def _finish_file(self, file: McapFile) -> None:
        """Close ``file`` with the rosbag2 metadata record and the summary.

        Raises:
            OSError: No room for it (the file is cut back, still open).
        """
        file.finish(dump_yaml(self._bag_info(state='closed')), self._topics.values())

    def _abandon(self) -> None:
        """Undo a start that failed: close and remove what was created."""
        for file in self._files:
            try:
                self._storage.close(file.fd)
            except OSError:
                pass
        for extra in (*self.files, self.path / 'metadata.yaml', self._reserve.path):
            try:
                self._storage.unlink(extra)
            except OSError:
                pass
        try:
            self.path.rmdir()
        except OSError:
            pass
        self._closed = True

    # ----------------------------------------------------------------- metadata.yaml
    def _bag_info(self, *, state: str) -> dict[str, Any]:
        custom = {**self.session_metadata, 'rv_te_bench.writer_state': state}
        if self._stall.gaps:
            custom['rv_te_bench.lost_messages'] = str(self.lost_messages)
            custom['rv_te_bench.write_gaps'] = dump_yaml(
                [g.as_dict() for g in self._stall.gaps]).strip()
        return bag_info(self._files, self._topics.values(), custom)

    def _write_metadata_yaml(self, *, state: str) -> None:
        """Replace metadata.yaml atomically (temporary file + rename).

        Raises:
            OSError: It could not be written (the old one stays; the temporary is removed).
        """
        self._yaml_dirty = False
        self._last_yaml_mono = time.monotonic()
        data = metadata_yaml_bytes(self._bag_info(state=state))
        self._yaml_size = len(data)
        try:
            replace_metadata_yaml(self._storage, self.path, data)
        except OSError:
            self._yaml_dirty = True
            raise

    def _write_yaml_or_gap(self) -> None:
        """Rewrite metadata.yaml; no space for it means the disk is full: start a gap."""
        try:
            self._write_metadata_yaml(state='recording')
        except OSError as exc:
            if self._stall.gap is None and self._file is not None:
                self._start_gap(exc)
            else:
                self._on_event(f'bag {self.path}: metadata.yaml not updated ({exc.strerror})')


def _library_id() -> str:
    try:
        from importlib.metadata import version

        return f'rv_te_bench {version("rv-te-bench")} (BagWriter)'
    except Exception:  # noqa: BLE001 - metadata absent in a source checkout
        return 'rv_te_bench (BagWriter)'
