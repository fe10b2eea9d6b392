"""Converted samples -> a rosbag2/MCAP bag of the suite's messages, written whole or not at all.

The bag holds what a live session records: ``/bench/info`` (``rv_te_msgs/BenchInfo``, offered
transient-local as the bench publishes it, written first) and ``/bench/encoders``
(``rv_te_msgs/EncoderBlock``: ``block_size`` samples per message, ``seq`` from 0, header
stamp = absolute time of the block's first sample, ``time_offset_s`` per sample). Messages
are serialised to CDR as the rosbags typestore does (:mod:`rv_te_bench.io._encoder_cdr_out`,
no rclpy) and written by
:class:`rv_te_bench.io.bag_writer.BagWriter`.

A drop-out in the file (:mod:`._convert`) ends the open block early and the next block's
``seq`` skips one number, as the live JointState adapter does: the TE node on replay,
``rv-te analyze``, ``identify`` and the report all see the gap (``seq_jump``, with its time
and length), and no window holding it counts as complete. A drop-out across which a
single-turn angle's turns are ambiguous (:mod:`._turns`) splits the record: the data after
it goes to a new bag, ``OUT_seg2`` (then ``_seg3``, ...) beside ``OUT``, from seq 0.

Nothing is left half-way: the bags are written in a hidden folder beside ``out`` and
renamed only once complete; on any error the hidden folder is removed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import math
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.core.plausibility import check_measured_ratio, check_sample_rate
from rv_te_bench.errors import BagExistsError, DataImportError
from rv_te_bench.io._encoder_cdr_out import EncoderBlocksLayout, encoder_block_cdr
from rv_te_bench.io.bag_writer import BagWriter, qos_profile_dict
from rv_te_bench.io.bench_record import bench_info_cdr
from rv_te_bench.io.importers._ahead import read_ahead
from rv_te_bench.io.importers._common import (
    COMPRESSIONS,
    DEFAULT_COMPRESSION,
    TIME_UNITS,
    angle_unit,
    time_unit,
)
from rv_te_bench.io.importers._convert import ChunkConverter, to_rad_factor
from rv_te_bench.io.importers._turns import TurnStitcher
from rv_te_bench.io.msgdefs import BENCH_CHANNELS, BENCH_INFO, ENCODER_BLOCK, own_typestore

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator

    from rosbags.typesys.store import Typestore

    from rv_te_bench.io.bench_description import BenchDescription
    from rv_te_bench.io.importers._common import ImportOptions, ImportReader
    from rv_te_bench.io.importers._turns import ImportGap, Piece
    from sim.bench import BenchInfoData

__all__ = ['ENCODER_TOPIC', 'INFO_TOPIC', 'ImportSummary', 'write_bag']

ENCODER_TOPIC = '/bench/encoders'
CHANNELS_TOPIC = '/bench/channels'
INFO_TOPIC = '/bench/info'
_NS = 1_000_000_000
#: Drop-outs named one by one in the notes (all are in the summary, up to MAX_GAPS_LISTED).
NOTED_GAPS = 10
MAX_GAPS_LISTED = 10_000
_NO_IDS = np.zeros(0, dtype=np.uint8)
_NO_VALUES = np.zeros(0)
#: Whole blocks of a piece are laid out all at once (False: block by block, as before
#: issue 41; the bags are the same byte for byte, tested).
BATCH_BLOCKS = True
#: A first time value at least this far from zero [s] is an absolute (epoch) time.
EPOCH_MIN_S = 1e9


@dataclass(frozen=True)
class ImportSummary:
    """What an import wrote (SI units)."""

    bag: str
    source: str
    samples: int
    blocks: int
    duration_s: float
    sample_rate_hz: float
    rate_from: str
    start_utc: str
    start_from: str
    unit_in: str
    unit_out: str
    wraps_in: int
    wraps_out: int
    torque: bool
    time_unit: str | None = None
    samples_dropped: int = 0
    gaps: tuple[ImportGap, ...] = ()
    gaps_total: int = 0
    segments: tuple[str, ...] = ()

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict (the drop-outs as ``gaps``, the bags as ``segments``)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out['gaps'] = [g.to_json_dict() for g in self.gaps]
        out['segments'] = list(self.segments)
        return out


def _unit(role: str, given: str | None, declared: dict[str, str | None], labels: dict[str, str],
          origin: str) -> str:
    if given is not None:
        return given
    text = declared.get(role)
    if not text:
        return 'rad'
    unit = angle_unit(text)
    if unit is None:
        msg = (f'{origin}: column {labels[role]!r}: unknown unit {text!r} (known: rad, deg, '
               'arcmin, arcsec, counts, rev; give --unit-in/--unit-out to override)')
        raise DataImportError(msg)
    return unit


#: What a ROS 2 stamp holds: builtin_interfaces/Time ``sec`` is int32 and a bag's log time
#: uint64 ns, so 1970-01-01T00:00:00Z .. 2038-01-19T03:14:07Z.
STAMP_MAX_NS = (2**31 - 1) * _NS + _NS - 1


def _utc(ns: int) -> str:
    try:
        return dt.datetime.fromtimestamp(ns / _NS, tz=dt.UTC).isoformat(timespec='milliseconds')
    except (OverflowError, OSError, ValueError):
        return f'{ns / _NS:.6g} s from 1970'


def _text(s: str) -> str:
    """A file name as UTF-8 text (bytes that are not UTF-8 shown as U+FFFD)."""
    return s.encode('utf-8', 'surrogateescape').decode('utf-8', 'replace')


def check_stamp(ns: int, what: str) -> None:
    """Refuse a time a ROS 2 stamp cannot hold, in one line naming where it came from.

    Raises:
        DataImportError: Before 1970-01-01 or after 2038-01-19T03:14:07Z.
    """
    if not 0 <= ns <= STAMP_MAX_NS:
        hint = '' if '--start-utc' in what else '; give --start-utc'
        msg = (f'{what} is {_utc(ns)}, outside what ROS 2 stamps hold (1970-01-01T00:00:00Z '
               f'.. 2038-01-19T03:14:07Z){hint}')
        raise DataImportError(msg)


def _time_unit(reader: ImportReader, options: ImportOptions) -> str | None:
    """The time column's unit: the format's, ``--time-unit``, the column name / channel
    unit; refused in one line naming the column when none says (never assumed)."""
    if not reader.has_time:
        return None
    if reader.time_unit is not None:
        return reader.time_unit
    if options.time_unit is not None:
        return options.time_unit
    text = reader.declared_units.get('time')
    unit = time_unit(text)
    if unit is None:
        label = reader.labels.get('time', 'time')
        said = f'its unit {text!r} is not a time unit' if text else \
            'neither its name nor the file states its unit'
        msg = (f'{reader.origin}: time column {label!r}: {said}; give --time-unit '
               f'({", ".join(TIME_UNITS)}) or name it like t_ms / "time [s]"')
        raise DataImportError(msg)
    return unit


class _Blocks:
    """Cuts pieces into EncoderBlocks and writes them to one segment's bag (a Python loop
    over blocks only)."""

    def __init__(self, writer: BagWriter, desc: BenchDescription, rate_hz: float,
                 start_ns: int) -> None:
        self.writer = writer
        self.bs = desc.block_size
        self.frame_id = desc.bench_id
        self.rate_hz = rate_hz
        self.start_ns = start_ns
        self.seq = 0
        self.written = 0      # blocks written (seq also counts the numbers skipped at gaps)
        self.samples = 0
        self.last_t_s = 0.0
        self.head_missing_blocks = 0   # blocks written without some of the output heads
        self._store: Typestore | None = None   # for BenchChannels (issue 38), when needed
        self._rest: tuple[np.ndarray, ...] | None = None

    def push(self, piece: Piece) -> None:
        """Write the piece's whole blocks; a drop-out before it ends the open block and
        skips one seq (every consumer sees the gap)."""
        extra = piece.theta_out_heads_rad
        heads = (np.vstack([piece.theta_out_rad[None, :], extra]) if extra is not None
                 else np.empty((0, piece.t_s.size)))
        loss = piece.loss if piece.loss is not None else np.empty((0, piece.t_s.size))
        arrays: tuple[np.ndarray, ...] = (piece.t_s, piece.theta_in_rad, piece.theta_out_rad,
                                          piece.torque_out_nm, heads, loss)
        if piece.gap is not None and self.samples + (0 if self._rest is None
                                                     else self._rest[0].size):
            self.finish()
            self.seq += 1
        if self._rest is not None:
            need = self.bs - self._rest[0].size
            if arrays[0].size >= need:   # the open block, completed: the rest is not copied
                head = tuple(np.concatenate([a, b[..., :need]], axis=-1)
                             for a, b in zip(self._rest, arrays, strict=True))
                self._rest = None
                self._write(head, 0, self.bs)
                arrays = tuple(a[..., need:] if a.size else a for a in arrays)
            else:
                arrays = tuple(np.concatenate([a, b], axis=-1)
                               for a, b in zip(self._rest, arrays, strict=True))
                self._rest = None
        n = arrays[0].size
        full = n - n % self.bs
        done = self._write_many(arrays, full) if full and BATCH_BLOCKS else 0
        for s in range(done, full, self.bs):
            self._write(arrays, s, s + self.bs)
        self._rest = None if full == n else tuple(a[..., full:] if a.size else a
                                                  for a in arrays)

    def finish(self) -> None:
        """Write the open (short) block."""
        if self._rest is not None and self._rest[0].size:
            self._write(self._rest, 0, self._rest[0].size)
        self._rest = None

    def _write_channels(self, loss: np.ndarray, stamp_ns: int) -> None:
        """The BenchChannels of the block about to be written (rows: input torque, case
        temperature; an all-NaN row is a channel not imported)."""
        if self._store is None:
            self._store = own_typestore(BENCH_CHANNELS)
        ty = self._store.types
        header = ty['std_msgs/msg/Header'](stamp=ty['builtin_interfaces/msg/Time'](
            sec=stamp_ns // _NS, nanosec=stamp_ns % _NS), frame_id=self.frame_id)
        rows = [np.ascontiguousarray(r) if np.any(np.isfinite(r)) else np.zeros(0)
                for r in loss]
        ch = ty[BENCH_CHANNELS](header=header, seq=self.seq, torque_in_nm=rows[0],
                                temp_case_degc=rows[1])
        self.writer.write(CHANNELS_TOPIC, stamp_ns, self._store.serialize_cdr(ch, BENCH_CHANNELS))

    def _write_many(self, c: tuple[np.ndarray, ...], full: int) -> int:
        """Write the first ``full`` samples as whole blocks laid out all at once (the bytes
        of ``_write`` block by block, tested); 0 (nothing written) where blocks differ in
        shape (a head missing a reading, the loss channels' messages between the blocks)
        or a stamp is out of range: ``_write`` handles and names those."""
        bs = self.bs
        k = full // bs
        heads = c[4]
        if c[5].shape[0] or (heads.shape[0] and not np.isfinite(heads[:, :full]).all()):
            return 0
        t = c[0][:full].reshape(k, bs)
        room = STAMP_MAX_NS - self.start_ns     # as _write's test: last * 1e9 < room
        room_f = float(room)
        if room_f > room:
            room_f = math.nextafter(room_f, -math.inf)
        if not bool(np.all(t[:, -1] * _NS < room_f)):
            return 0
        stamps = self.start_ns + np.rint(t[:, 0] * _NS).astype(np.int64)
        h = heads.shape[0]
        torque = c[3][:full].reshape(k, bs) if c[3].size else None
        heads_k = heads[:, :full].reshape(h, k, bs).transpose(1, 0, 2) if h else None
        th_in, th_out = c[1][:full].reshape(k, bs), c[2][:full].reshape(k, bs)
        layout = EncoderBlocksLayout(self.frame_id, bs, bs if torque is not None else 0,
                                     np.arange(h, dtype=np.uint8))
        seq0 = self.seq

        def fill(rows: np.ndarray, i: int, j: int) -> None:
            layout.fill(rows, stamps[i:j], seq0 + i, self.rate_hz, t[i:j], th_in[i:j],
                        th_out[i:j], None if torque is None else torque[i:j],
                        None if heads_k is None else heads_k[i:j])

        self.writer.write_batch(ENCODER_TOPIC, stamps, layout.size, fill)
        self.seq += k
        self.written += k
        self.samples += full
        self.last_t_s = float(t[-1, -1])
        return full

    def _write(self, c: tuple[np.ndarray, ...], a: int, b: int) -> None:
        t = c[0][a:b]
        last = float(t[-1]) * _NS
        if not last < STAMP_MAX_NS - self.start_ns:
            at = self.start_ns + int(last) if math.isfinite(last) else STAMP_MAX_NS + 1
            check_stamp(at, f'the time of the sample {float(t[-1]):.6g} s after the start '
                            f'({_utc(self.start_ns)})')
        stamp_ns = self.start_ns + round(float(t[0]) * _NS)
        torque = c[3][a:b] if c[3].size else np.zeros(0)
        heads = c[4][:, a:b]
        ids = _NO_IDS
        if heads.shape[0]:   # a head with a missing reading in this block is left out of it
            keep = np.flatnonzero(np.isfinite(heads).all(axis=1))
            ids = keep.astype(np.uint8)
            heads = heads[keep]
            self.head_missing_blocks += int(keep.size < c[4].shape[0])
        cdr = encoder_block_cdr(stamp_ns, self.frame_id, self.seq, self.rate_hz, t - t[0],
                                c[1][a:b], c[2][a:b], torque, _NO_IDS, _NO_VALUES, ids,
                                np.ascontiguousarray(heads).ravel())
        self.writer.write(ENCODER_TOPIC, stamp_ns, cdr)
        if c[5].shape[0]:   # the loss channels (issue 38), one BenchChannels per block
            self._write_channels(c[5][:, a:b], stamp_ns)
        self.seq += 1
        self.written += 1
        self.samples += b - a
        self.last_t_s = float(t[-1])


def _segment_path(out: Path, k: int) -> Path:
    """The bag of segment ``k`` (1: ``out`` itself)."""
    return out if k == 1 else out.with_name(f'{out.name}_seg{k}')


class _Segments:
    """The bags of one import in a hidden work folder: one per segment of the record."""

    def __init__(self, tmp_dir: Path, out: Path, desc: BenchDescription, info: BenchInfoData,
                 meta: dict[str, Any], rate_hz: float, start_ns: int, *,
                 channels: bool = False, compression: str = DEFAULT_COMPRESSION) -> None:
        self.compression = compression
        self.channels = channels     # loss columns: a bench/channels topic (issue 38)
        self.tmp_dir = tmp_dir
        self.out = out
        self.desc = desc
        self.info = info
        self.meta = meta
        self.rate_hz = rate_hz
        self.start_ns = start_ns
        self.done: list[tuple[Path, _Blocks]] = []
        self.writer: BagWriter | None = None
        self.blocks: _Blocks | None = None
        self._open(None)

    def _open(self, after: ImportGap | None) -> None:
        k = len(self.done) + 1
        meta = dict(self.meta)
        if after is not None:
            meta.update({'import_segment': str(k), 'import_segment_after': after.describe()})
        tmp_bag = self.tmp_dir / _segment_path(self.out, k).name
        compression, level = COMPRESSIONS[self.compression]
        self.writer = BagWriter(tmp_bag, session_metadata=meta, flush_interval_s=3600.0,
                                compression=compression, compression_level=level)
        self.writer.add_topic(INFO_TOPIC, BENCH_INFO, offered_qos_profiles=[
            qos_profile_dict(durability='transient_local', depth=1)])
        self.writer.add_topic(ENCODER_TOPIC, ENCODER_BLOCK,
                              offered_qos_profiles=[qos_profile_dict(depth=1000)])
        if self.channels:
            self.writer.add_topic(CHANNELS_TOPIC, BENCH_CHANNELS,
                                  offered_qos_profiles=[qos_profile_dict(depth=1000)])
        self.writer.write(INFO_TOPIC, self.start_ns, bench_info_cdr(self.info, self.start_ns))
        self.blocks = _Blocks(self.writer, self.desc, self.rate_hz, self.start_ns)
        self.done.append((tmp_bag, self.blocks))

    def push(self, piece: Piece) -> None:
        assert self.blocks is not None
        if piece.new_segment:
            self._close()
            self._open(piece.gap)
            assert self.blocks is not None
            piece = dataclasses.replace(piece, gap=None)
        self.blocks.push(piece)

    def _close(self) -> None:
        assert self.blocks is not None and self.writer is not None
        self.blocks.finish()
        writer, self.writer = self.writer, None
        writer.close()
        if writer.lost_messages:
            msg = f'{self.out}: {writer.lost_messages} messages could not be written (disk full?)'
            raise DataImportError(msg)

    def finish(self) -> list[Path]:
        """Close the last bag and move every bag into place (none if one exists already)."""
        self._close()
        targets = [_segment_path(self.out, k + 1) for k in range(len(self.done))]
        there = [t for t in targets if t.exists() or t.is_symlink()]
        if there:
            msg = (f'Output {there[0]} exists already, not overwriting (the record is split '
                   f'into {len(targets)} segments: {", ".join(t.name for t in targets)})')
            raise BagExistsError(msg)
        for (tmp_bag, _), target in zip(self.done, targets, strict=True):
            tmp_bag.rename(target)
        return targets

    def abort(self) -> None:
        if self.writer is not None:
            with contextlib.suppress(Exception):
                self.writer.close()


def write_bag(reader: ImportReader, desc: BenchDescription, options: ImportOptions,
              out: Path, *, fmt: str, on_note: Callable[[str], None] | None = None,
              ) -> ImportSummary:
    """Convert everything ``reader`` yields and write the bag ``out`` (see the module doc).

    Args:
        reader: An opened importer (``chunks()``, ``labels``, ``declared_units``, ...).
        desc: The bench description (BenchInfo, block size, torque scale, counts/rev).
        options: The import options.
        out: Bag folder to create; must not exist.
        fmt: Format name for the record (``csv``, ``tdms``, ``mdf``, ...).
        on_note: Called with one line for each assumption made (rate, start time) and
            each drop-out found.

    Raises:
        DataImportError: A bad value (file, column, row named); nothing is written.
        BagExistsError: ``out`` exists already.
    """
    chunks = read_ahead(reader.chunks())   # a helper thread reads ahead on a second core
    try:
        return _write_bag(reader, desc, options, Path(out), fmt, on_note, chunks)
    finally:
        chunks.close()


def _write_bag(reader: ImportReader, desc: BenchDescription, options: ImportOptions,
               out: Path, fmt: str, on_note: Callable[[str], None] | None,
               chunks: Iterator[Any]) -> ImportSummary:
    note = on_note or (lambda _line: None)
    try:
        out.name.encode('utf-8')
    except UnicodeEncodeError:
        shown = out.name.encode('utf-8', 'surrogateescape').decode('utf-8', 'replace')
        msg = (f'--out name {shown!r} is not UTF-8 text: rosbag2 keeps the bag and file '
               'names in metadata.yaml (UTF-8); choose a UTF-8 name')
        raise DataImportError(msg) from None
    if out.exists() or out.is_symlink():
        msg = f'Output {out} exists already, not overwriting.'
        raise BagExistsError(msg)
    _remove_killed_imports(out, note)
    origin = reader.origin
    labels = reader.labels
    _check_heads(reader, desc, note)
    unit_in = _unit('in', options.unit_in, reader.declared_units, labels, origin)
    unit_out = _unit('out', options.unit_out, reader.declared_units, labels, origin)
    t_unit = _time_unit(reader, options)
    if 'torque' in labels and not desc.torque_sensor.present:
        note(f'the bench description has no torque sensor; column {labels["torque"]!r} '
             'imported with its scale anyway')
    rate_hz: float | None = options.rate_hz
    rate_from = '--rate'
    if rate_hz is None and reader.declared_rate_hz:
        rate_hz, rate_from = float(reader.declared_rate_hz), 'the file'
    if not reader.has_time and rate_hz is None:
        rate_hz, rate_from = desc.sample_rate_hz, 'the bench description'
        note(f'no time column and no --rate: samples taken {1.0 / rate_hz:g} s apart '
             f'(sample_rate_hz of {desc.origin})')
    conv = ChunkConverter(
        origin=origin, labels=labels, locate=reader.locate,
        k_in=to_rad_factor(unit_in, options.counts_per_rev_in or desc.encoder_in.counts_per_rev,
                           f'{origin}: column {labels["in"]!r}'),
        k_out=to_rad_factor(unit_out,
                            options.counts_per_rev_out or desc.encoder_out.counts_per_rev,
                            f'{origin}: column {labels["out"]!r}'),
        time_scale_s=TIME_UNITS[t_unit] if t_unit is not None else None, rate_hz=rate_hz,
        torque_scale_nm=desc.torque_sensor.scale_nm_per_unit,
        torque_in_scale_nm=float(((desc.loss_channels or {}).get('torque_in') or {}).get(
            'scale_nm_per_unit', 1.0)))
    for role in ('torque_in', 'temperature'):
        if role in labels and role not in (desc.loss_channels or {}):
            note(f'the bench description states no loss_channels.{role}; column '
                 f'{labels[role]!r} imported as N m / degC, its class unknown')
    first_raw = next(chunks, None)
    if first_raw is None:
        msg = f'{origin}: no samples'
        raise DataImportError(msg)
    first = conv(first_raw)
    if rate_hz is None:
        rate_hz = conv.rate_hz or desc.sample_rate_hz
        conv.rate_hz = rate_hz
        rate_from = 'the time column (median step of the first chunk)'
        _check_rate(reader, options, t_unit, rate_hz, desc)
    if abs(rate_hz - desc.sample_rate_hz) > 0.01 * desc.sample_rate_hz:
        note(f'sample rate {rate_hz:g} Hz (from {rate_from}) differs from the bench '
             f'description\'s {desc.sample_rate_hz:g} Hz; {rate_hz:g} Hz recorded')
    start_ns, start_from = _start(options, reader, conv, note)
    info = dataclasses.replace(desc.bench_info(), sample_rate_hz=rate_hz)
    meta = desc.to_metadata()
    session = out.parent.name if out.name in {'bag', 'bag_0'} and out.parent.name else out.name
    meta.update({'session': session, 'started_utc': _utc(start_ns),
                 'imported_from': _text(str(reader.path)), 'import_format': fmt,
                 'import_utc': dt.datetime.now(dt.UTC).isoformat(timespec='seconds')})
    stitcher = TurnStitcher(turns_in=options.turns_in,  # type: ignore[arg-type]
                            turns_out=options.turns_out,  # type: ignore[arg-type]
                            rate_hz=rate_hz)
    tmp_dir = out.parent / f'.{out.name}.importing-{os.getpid()}-{time.monotonic_ns()}'
    try:
        tmp_dir.mkdir(parents=True)
    except OSError as exc:
        msg = f'Cannot create {tmp_dir}: {exc.strerror or exc}.'
        raise DataImportError(msg) from None
    segments: _Segments | None = None
    advance = _Advance()
    try:
        segments = _Segments(tmp_dir, out, desc, info, meta, rate_hz, start_ns,
                             channels=bool({'torque_in', 'temperature'} & set(labels)),
                             compression=options.compression)
        for piece in stitcher.push(first):
            advance.push(piece)
            segments.push(piece)
        for raw in chunks:
            for piece in stitcher.push(conv(raw)):
                advance.push(piece)
                segments.push(piece)
        for piece in stitcher.finish():
            advance.push(piece)
            segments.push(piece)
        wrong = check_measured_ratio(*advance.total(), desc.gear_ratio,
                                     names=(labels['in'], labels['out']))
        if wrong is not None:    # swapped columns: refused before any bag is in place
            msg = f'{origin}: {wrong}'
            raise DataImportError(msg)
        bags = segments.finish()
    except BaseException:
        if segments is not None:
            segments.abort()
        shutil.rmtree(tmp_dir, ignore_errors=True)
        raise
    shutil.rmtree(tmp_dir, ignore_errors=True)
    _note_dropouts(stitcher.gaps, conv, bags, note)
    for role, jumps in zip(('in', 'out'), stitcher.jumps, strict=True):
        if jumps:
            note(f'column {labels[role]!r}: {jumps} steps of more than half a turn between two '
                 f'samples, kept as recorded (multi-turn, --no-unwrap-{role}); if it is a '
                 f'single-turn encoder these are wraps: import with --unwrap-{role}')
    missing = sum(b.head_missing_blocks for _, b in segments.done)
    if missing:
        note(f'{missing} blocks lack one or more output heads (a missing value in a head '
             'column): those heads are left out of those blocks, the samples are kept')
    unpaired = getattr(reader, 'unpaired', 0)   # the joint-state bag reader's count
    if unpaired:
        note(f'{unpaired} joint positions had no partner at the same stamp: left out '
             '(the sample times in the bag show where)')
    wraps_in, wraps_out = stitcher.wraps
    last = segments.done[-1][1]
    return ImportSummary(
        bag=str(out), source=str(reader.path), samples=conv.samples,
        blocks=sum(b.written for _, b in segments.done), duration_s=last.last_t_s,
        sample_rate_hz=rate_hz, rate_from=rate_from, start_utc=_utc(start_ns),
        start_from=start_from, unit_in=unit_in, unit_out=unit_out, wraps_in=wraps_in,
        wraps_out=wraps_out, torque='torque' in labels, time_unit=t_unit,
        samples_dropped=conv.dropped, gaps=tuple(stitcher.gaps[:MAX_GAPS_LISTED]),
        gaps_total=len(stitcher.gaps), segments=tuple(str(b) for b in bags))


def _check_heads(reader: ImportReader, desc: BenchDescription,
                 note: Callable[[str], None]) -> None:
    """One column per output head, as many as the bench description's heads_deg."""
    given = 1 + sum(1 for role in reader.labels if role.startswith('out_h'))
    stated = len(desc.encoder_out.head_angles_rad)
    if given > 1 and given != stated:
        msg = (f'{reader.origin}: {given} output head columns given, but {desc.origin} '
               f'states {stated or 1} head(s) (encoders.output.heads_deg): give one column '
               'per head, head 0 first')
        raise DataImportError(msg)
    if stated > 1 and given == 1:
        note(f'{desc.origin} states {stated} output heads but one column was imported: the '
             'bag holds head 0 only (give --theta-out-heads for all of them)')


class _Advance:
    """How far each angle advanced over the record (unwrapped; a new segment, whose turns
    are ambiguous against the last, adds its own advance)."""

    def __init__(self) -> None:
        self._done = [0.0, 0.0]
        self._first: tuple[float, float] | None = None
        self._last: tuple[float, float] | None = None

    def push(self, piece: Piece) -> None:
        if not piece.theta_in_rad.size:
            return
        if piece.new_segment:
            self._close()
        if self._first is None:
            self._first = (float(piece.theta_in_rad[0]), float(piece.theta_out_rad[0]))
        self._last = (float(piece.theta_in_rad[-1]), float(piece.theta_out_rad[-1]))

    def _close(self) -> None:
        if self._first is not None and self._last is not None:
            for k in range(2):
                self._done[k] += self._last[k] - self._first[k]
        self._first = self._last = None

    def total(self) -> tuple[float, float]:
        """(input advance, output advance) [rad]."""
        self._close()
        return self._done[0], self._done[1]


def _check_rate(reader: ImportReader, options: ImportOptions, t_unit: str | None,
                rate_hz: float, desc: BenchDescription) -> None:
    """A rate from a time column whose unit the user or the column name gave, absurd for
    the bench (a wrong time unit): one line, nothing written. A unit the format states
    (TDMS / JointState stamps) is not doubted."""
    if reader.time_unit is not None:
        return
    source = ('--time-unit' if options.time_unit is not None else
              f'the column name {reader.labels.get("time", "time")!r}')
    wrong = check_sample_rate(rate_hz, desc.sample_rate_hz, time_unit=t_unit, source=source)
    if wrong is not None:
        msg = f'{reader.origin}: {wrong}'
        raise DataImportError(msg)


def _start(options: ImportOptions, reader: ImportReader, conv: ChunkConverter,
           note: Callable[[str], None]) -> tuple[int, str]:
    """(absolute time of the first sample [ns], where it came from), within what a ROS 2
    stamp holds (refused in one line naming the source otherwise)."""
    start_ns, start_from = _start_unchecked(options, reader, conv)
    check_stamp(start_ns, f'the start time from {start_from}')
    if start_from == 'the file modification time':
        note(f'the file states no start time: the file modification time {_utc(start_ns)} '
             'is used (give --start-utc)')
    return start_ns, start_from


def _start_unchecked(options: ImportOptions, reader: ImportReader,
                     conv: ChunkConverter) -> tuple[int, str]:
    if options.start_ns is not None:
        return options.start_ns, '--start-utc'
    if reader.start_ns is not None:
        return int(reader.start_ns), 'the file'
    if isinstance(conv.t0, int) and conv.time_scale_s is not None \
            and abs(conv.t0_s) >= EPOCH_MIN_S:     # integer epoch stamps: exact
        return int(conv.t0) * round(conv.time_scale_s * _NS), 'the time column (epoch)'
    if math.isfinite(conv.t0_s) and abs(conv.t0_s) >= EPOCH_MIN_S:
        return round(conv.t0_s * _NS), 'the time column (epoch)'
    return reader.path.stat().st_mtime_ns, 'the file modification time'


def _note_dropouts(gaps: list[ImportGap], conv: ChunkConverter, bags: list[Path],
                   note: Callable[[str], None]) -> None:
    """One note per drop-out (the first NOTED_GAPS), and the samples dropped at the ends."""
    for g in gaps[:NOTED_GAPS]:
        note(g.describe())
    if len(gaps) > NOTED_GAPS:
        note(f'... {len(gaps) - NOTED_GAPS} more drop-outs ({len(gaps)} in all; --json lists '
             'them)')
    if conv.leading_dropped:
        note(f'{conv.leading_dropped} samples before the first good one dropped (non-finite '
             'or time not increasing)')
    trailing = conv.finish()
    if trailing is not None:
        note(f'{trailing[0]} samples from {trailing[1]} to the end dropped (non-finite or '
             'time not increasing)')
    if len(bags) > 1:
        note(f'the record is split into {len(bags)} segments (turns ambiguous across a '
             f'drop-out): {", ".join(str(b) for b in bags)}')


def _remove_killed_imports(out: Path, note: Callable[[str], None]) -> None:
    """Remove the hidden work folders of earlier imports to ``out`` whose process is gone.

    An import writes ``.NAME.importing-PID-NS`` beside ``out`` and renames the bag into
    place at the end; Ctrl-C and errors remove the folder, but a SIGKILL (or SIGTERM, the
    OOM killer, a power cut) leaves it, as large as the part written. A folder whose process
    still runs (an import beside this one, or a recycled pid: kept to be safe) is left alone.
    """
    prefix = f'.{out.name}.importing-'
    try:
        siblings = list(out.parent.iterdir())
    except OSError:   # no parent yet: nothing left behind either
        return
    for path in siblings:
        pid_text = path.name[len(prefix):].split('-', 1)[0] if path.name.startswith(prefix) \
            else ''
        if not pid_text.isdigit() or not path.is_dir() or path.is_symlink():
            continue
        pid = int(pid_text)
        if pid == os.getpid():
            continue
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            pass          # gone: its folder is a leftover
        except OSError:   # alive (another user's process, PermissionError), or unknown
            continue
        else:
            continue      # alive
        size = sum(f.stat().st_size for f in path.rglob('*') if f.is_file())
        shutil.rmtree(path, ignore_errors=True)
        note(f'removed {path}: {size / 1e6:.1f} MB left by an earlier import to the same '
             f'bag whose process {pid} was killed')
