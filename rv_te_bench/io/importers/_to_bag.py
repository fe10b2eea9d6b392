"""Converted samples -> a rosbag2/MCAP bag of the suite's messages, written whole or not at all.

The bag holds what a live session records: ``/bench/info`` (``rv_te_msgs/BenchInfo``, offered
transient-local as the bench publishes it, written first) and ``/bench/encoders``
(``rv_te_msgs/EncoderBlock``: ``block_size`` samples per message, ``seq`` contiguous from 0,
header stamp = absolute time of the block's first sample, ``time_offset_s`` per sample; the
last block may be shorter). Messages are serialised to CDR by the rosbags typestore (no
rclpy) and written by :class:`rv_te_bench.io.bag_writer.BagWriter`.

Nothing is left half-way: the bag is written in a hidden folder beside ``out`` and renamed
to ``out`` only once complete; on any error the hidden folder is removed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import BagExistsError, DataImportError
from rv_te_bench.io.bag_writer import BagWriter, qos_profile_dict
from rv_te_bench.io.importers._common import TIME_UNITS, ChunkConverter, SiChunk, angle_unit
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, rv_te_typestore

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator

    from rv_te_bench.core.bench_description import BenchDescription
    from rv_te_bench.io.importers._common import ImportOptions, ImportReader
    from sim.bench import BenchInfoData

__all__ = ['ENCODER_TOPIC', 'INFO_TOPIC', 'ImportSummary', 'write_bag']

ENCODER_TOPIC = '/bench/encoders'
INFO_TOPIC = '/bench/info'
_NS = 1_000_000_000


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

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict."""
        return dataclasses.asdict(self)


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


def _utc(ns: int) -> str:
    return dt.datetime.fromtimestamp(ns / _NS, tz=dt.UTC).isoformat(timespec='milliseconds')


class _Blocks:
    """Cuts SiChunks into EncoderBlocks and writes them (a Python loop over blocks only)."""

    def __init__(self, writer: BagWriter, desc: BenchDescription, rate_hz: float,
                 start_ns: int) -> None:
        self.writer = writer
        self.bs = desc.block_size
        self.frame_id = desc.bench_id
        self.rate_hz = rate_hz
        self.start_ns = start_ns
        self.store = rv_te_typestore()
        self.types = self.store.types
        self.seq = 0
        self.samples = 0
        self.last_t_s = 0.0
        self._rest: SiChunk | None = None

    def push(self, chunk: SiChunk) -> None:
        if self._rest is not None:
            r = self._rest
            chunk = SiChunk(*(np.concatenate([a, b]) for a, b in zip(
                (r.t_s, r.theta_in_rad, r.theta_out_rad, r.torque_out_nm),
                (chunk.t_s, chunk.theta_in_rad, chunk.theta_out_rad, chunk.torque_out_nm),
                strict=True)))
        n = chunk.t_s.size
        full = n - n % self.bs
        for s in range(0, full, self.bs):
            self._write(chunk, s, s + self.bs)
        self._rest = None if full == n else SiChunk(
            chunk.t_s[full:], chunk.theta_in_rad[full:], chunk.theta_out_rad[full:],
            chunk.torque_out_nm[full:] if chunk.torque_out_nm.size else chunk.torque_out_nm)

    def finish(self) -> None:
        if self._rest is not None and self._rest.t_s.size:
            self._write(self._rest, 0, self._rest.t_s.size)
        self._rest = None

    def _write(self, c: SiChunk, a: int, b: int) -> None:
        t = c.t_s[a:b]
        stamp_ns = self.start_ns + round(float(t[0]) * _NS)
        torque = c.torque_out_nm[a:b] if c.torque_out_nm.size else np.zeros(0)
        msg = self.types[ENCODER_BLOCK](
            header=self.types['std_msgs/msg/Header'](
                stamp=self.types['builtin_interfaces/msg/Time'](
                    sec=stamp_ns // _NS, nanosec=stamp_ns % _NS),
                frame_id=self.frame_id),
            seq=self.seq, sample_rate_hz=self.rate_hz, time_offset_s=t - t[0],
            theta_in_rad=np.ascontiguousarray(c.theta_in_rad[a:b]),
            theta_out_rad=np.ascontiguousarray(c.theta_out_rad[a:b]),
            torque_out_nm=np.ascontiguousarray(torque))
        self.writer.write(ENCODER_TOPIC, stamp_ns, self.store.serialize_cdr(msg, ENCODER_BLOCK))
        self.seq += 1
        self.samples += b - a
        self.last_t_s = float(t[-1])


def _estimate_rate_hz(chunk: SiChunk) -> float | None:
    if chunk.t_s.size < 2:
        return None
    return 1.0 / float(np.median(np.diff(chunk.t_s)))


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
        on_note: Called with one line for each assumption made (rate, start time).

    Raises:
        DataImportError: A bad value (file, column, row named); nothing is written.
        BagExistsError: ``out`` exists already.
    """
    note = on_note or (lambda _line: None)
    out = Path(out)
    if out.exists() or out.is_symlink():
        msg = f'Output {out} exists already, not overwriting.'
        raise BagExistsError(msg)
    _remove_killed_imports(out, note)
    origin = reader.origin
    labels = reader.labels
    unit_in = _unit('in', options.unit_in, reader.declared_units, labels, origin)
    unit_out = _unit('out', options.unit_out, reader.declared_units, labels, origin)
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
        origin=origin, labels=labels, locate=reader.locate, unit_in=unit_in, unit_out=unit_out,
        counts_per_rev_in=options.counts_per_rev_in or desc.encoder_in.counts_per_rev,
        counts_per_rev_out=options.counts_per_rev_out or desc.encoder_out.counts_per_rev,
        time_scale_s=TIME_UNITS[reader.time_unit] if reader.has_time else None,
        rate_hz=None if reader.has_time else rate_hz,
        torque_scale_nm=desc.torque_sensor.scale_nm_per_unit, unwrap=options.unwrap)
    chunks: Iterator[Any] = iter(reader.chunks())
    first_raw = next(chunks, None)
    if first_raw is None:
        msg = f'{origin}: no samples'
        raise DataImportError(msg)
    first = conv(first_raw)
    if rate_hz is None:
        rate_hz = _estimate_rate_hz(first) or desc.sample_rate_hz
        rate_from = 'the time column (median step of the first chunk)'
    if abs(rate_hz - desc.sample_rate_hz) > 0.01 * desc.sample_rate_hz:
        note(f'sample rate {rate_hz:g} Hz (from {rate_from}) differs from the bench '
             f'description\'s {desc.sample_rate_hz:g} Hz; {rate_hz:g} Hz recorded')
    start_ns, start_from = options.start_ns, '--start-utc'
    if start_ns is None and reader.start_ns is not None:
        start_ns, start_from = int(reader.start_ns), 'the file'
    if start_ns is None:
        start_ns, start_from = reader.path.stat().st_mtime_ns, 'the file modification time'
        note(f'the file states no start time: the file modification time {_utc(start_ns)} '
             'is used (give --start-utc)')
    info = dataclasses.replace(desc.bench_info(), sample_rate_hz=rate_hz)
    meta = desc.to_metadata()
    session = out.parent.name if out.name in {'bag', 'bag_0'} and out.parent.name else out.name
    meta.update({'session': session, 'started_utc': _utc(start_ns),
                 'imported_from': str(reader.path), 'import_format': fmt,
                 'import_utc': dt.datetime.now(dt.UTC).isoformat(timespec='seconds')})
    tmp_dir = out.parent / f'.{out.name}.importing-{os.getpid()}-{time.monotonic_ns()}'
    try:
        tmp_dir.mkdir(parents=True)
    except OSError as exc:
        msg = f'Cannot create {tmp_dir}: {exc.strerror or exc}.'
        raise DataImportError(msg) from None
    tmp_bag = tmp_dir / out.name
    writer: BagWriter | None = None
    try:
        writer = BagWriter(tmp_bag, session_metadata=meta, flush_interval_s=3600.0)
        writer.add_topic(INFO_TOPIC, BENCH_INFO, offered_qos_profiles=[
            qos_profile_dict(durability='transient_local', depth=1)])
        writer.add_topic(ENCODER_TOPIC, ENCODER_BLOCK,
                         offered_qos_profiles=[qos_profile_dict(depth=1000)])
        writer.write(INFO_TOPIC, start_ns, _bench_info_cdr(info, start_ns))
        blocks = _Blocks(writer, desc, rate_hz, start_ns)
        blocks.push(first)
        for raw in chunks:
            blocks.push(conv(raw))
        blocks.finish()
        writer.close()
        if writer.lost_messages:
            msg = f'{out}: {writer.lost_messages} messages could not be written (disk full?)'
            raise DataImportError(msg)
        tmp_bag.rename(out)
    except BaseException:
        if writer is not None:
            with contextlib.suppress(Exception):
                writer.close()
        shutil.rmtree(tmp_dir, ignore_errors=True)
        raise
    shutil.rmtree(tmp_dir, ignore_errors=True)
    if getattr(reader, 'unpaired', 0):
        note(f'{reader.unpaired} joint positions had no partner at the same stamp: left out '
             '(the sample times in the bag show where)')
    return ImportSummary(
        bag=str(out), source=str(reader.path), samples=blocks.samples, blocks=blocks.seq,
        duration_s=blocks.last_t_s, sample_rate_hz=rate_hz, rate_from=rate_from,
        start_utc=_utc(start_ns), start_from=start_from, unit_in=unit_in, unit_out=unit_out,
        wraps_in=conv.unwrap_in.wraps, wraps_out=conv.unwrap_out.wraps,
        torque='torque' in labels)


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


def _bench_info_cdr(info: BenchInfoData, stamp_ns: int) -> bytes:
    store = rv_te_typestore()
    types = store.types
    msg = types[BENCH_INFO](
        header=types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=stamp_ns // _NS,
                                                       nanosec=stamp_ns % _NS),
            frame_id=info.bench_id),
        bench_id=info.bench_id, preset=info.preset, reducer_type=info.reducer_type,
        gear_ratio=float(info.gear_ratio), crank_per_input=float(info.crank_per_input),
        crank_rel_per_input=float(info.crank_rel_per_input),
        mesh_orders=np.asarray(info.mesh_orders, dtype=np.float64),
        mesh_labels=list(info.mesh_labels), encoder_in_model=info.encoder_in_model,
        encoder_out_model=info.encoder_out_model,
        encoder_in_resolution_rad=float(info.encoder_in_resolution_rad),
        encoder_out_resolution_rad=float(info.encoder_out_resolution_rad),
        sample_rate_hz=float(info.sample_rate_hz), block_size=int(info.block_size),
        parameters_yaml=info.parameters_yaml)
    return bytes(store.serialize_cdr(msg, BENCH_INFO))
