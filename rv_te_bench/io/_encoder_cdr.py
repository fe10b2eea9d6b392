"""EncoderBlock CDR decoders of the bag reader: one message, and a chunk's worth side by side.

``EncoderBlock`` messages are decoded straight from their CDR layout into read-only numpy
arrays (``np.frombuffer``), which is several times faster than generic deserialisation;
:func:`decode_encoder_block_rosbags` is the slower cross-check. The batch decoder parses the
blocks of one MCAP chunk together (one numpy pass over their headers).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import BagError
from rv_te_bench.io.msgdefs import ENCODER_BLOCK, rv_te_typestore

if TYPE_CHECKING:
    from collections.abc import Iterator

    from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData

__all__ = ['decode_encoder_block', 'decode_encoder_block_rosbags', 'encoder_block_frame_id',
           'encoder_block_seq']


_ALIGN4, _ALIGN8 = 3, 7


def _seq_offset(buf: bytes | memoryview, end: str) -> int:
    """Offset (after the 4-byte encapsulation) of EncoderBlock.seq: header.stamp (8 B),
    frame_id (length + bytes), padding to 8."""
    flen: int = struct.unpack_from(end + 'I', buf, 12)[0]
    return (12 + flen + _ALIGN8) & ~_ALIGN8


def encoder_block_seq(data: bytes | memoryview) -> int:
    """``seq`` of a serialised EncoderBlock, without decoding the arrays (recorder hot path).

    Raises:
        struct.error, IndexError: The bytes are too short to hold it.
    """
    end = '<' if data[1] == 1 else '>'
    seq: int = struct.unpack_from(end + 'Q', data, 4 + _seq_offset(data, end))[0]
    return seq


def encoder_block_frame_id(data: bytes | memoryview) -> str:
    """``header.frame_id`` of a serialised EncoderBlock (the bench id; invalid UTF-8 is
    replaced, as a reader that only shows it would).

    Raises:
        struct.error, IndexError: The bytes are too short to hold it.
    """
    end = '<' if data[1] == 1 else '>'
    flen: int = struct.unpack_from(end + 'I', data, 12)[0]
    if flen == 0 or 16 + flen > len(data):
        msg = f'frame_id of {flen} bytes in a message of {len(data)}'
        raise IndexError(msg)
    return bytes(data[16:16 + flen - 1]).decode('utf-8', 'replace')


#: Bytes the four head sequences take at least (their counts): fewer after the torque
#: array is the end padding of a message without them (the definition before issue 36;
#: serialisers pad the end by up to 7 bytes).
_HEAD_FIELDS_MIN = 16


@dataclass(frozen=True, slots=True)
class _Layout:
    """Where the fields of one serialised EncoderBlock lie (byte offsets from its start,
    the 4-byte encapsulation included)."""

    order: str                          # struct byte order: '<' or '>'
    seq_at: int                         # seq (uint64), then sample_rate_hz (float64)
    count_at: tuple[int, ...]           # element count of each of the four arrays
    counts: tuple[int, ...]
    data_at: tuple[int, ...]            # first element of each array
    length: int                         # bytes the message uses
    # the head fields (issue 36): in ids, in readings, out ids, out readings; () when the
    # message has none (the older definition)
    head_count_at: tuple[int, ...] = ()
    head_counts: tuple[int, ...] = ()
    head_data_at: tuple[int, ...] = ()

    @property
    def has_heads(self) -> bool:
        """Some head field holds data."""
        return any(self.head_counts)


def _head_layout(buf: bytes | memoryview, order: str, off: int, size: int,
                 ) -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...], int]:
    """(count positions, counts, data positions, end offset) of the four head fields from
    payload offset ``off``; empty when the message ends there (the older definition)."""
    if size - (4 + off) < _HEAD_FIELDS_MIN:
        return (), (), (), off
    count_at, counts, data_at = [], [], []
    for width in (1, 8, 1, 8):
        off = (off + _ALIGN4) & ~_ALIGN4
        (count,) = struct.unpack_from(order + 'I', buf, 4 + off)
        count_at.append(4 + off)
        off += 4
        if count and width == 8:
            off = (off + _ALIGN8) & ~_ALIGN8
        if 4 + off + width * count > size:
            msg = (f'head field of {count} x {width} bytes runs past the message end '
                   f'({size} bytes)')
            raise BagError(msg)
        counts.append(count)
        data_at.append(4 + off)
        off += width * count
    return tuple(count_at), tuple(counts), tuple(data_at), off


def _layout(buf: bytes | memoryview) -> _Layout:
    """Walk the CDR layout of one EncoderBlock (header, seq, rate, four float64 arrays,
    the head fields when present).

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
        h_at, h_counts, h_data, off = _head_layout(buf, order, off, size)
    except struct.error as exc:
        msg = f'EncoderBlock CDR truncated ({size} bytes): {exc}'
        raise BagError(msg) from None
    return _Layout(order, seq_at, tuple(count_at), tuple(counts), tuple(data_at), 4 + off,
                   h_at, h_counts, h_data)


def _heads_of(buf: bytes, lay: _Layout, n: int) -> dict[str, object]:
    """The EncoderBlockData head fields of a decoded message (ids, (heads, n) readings).

    Raises:
        BagError: Readings that do not fit the ids and the block's length.
    """
    out: dict[str, object] = {}
    if not lay.has_heads:
        return out
    dtype = np.dtype(lay.order + 'f8')
    for k, side in ((0, 'in'), (2, 'out')):
        n_ids, n_vals = lay.head_counts[k], lay.head_counts[k + 1]
        if n_ids == 0 and n_vals == 0:
            continue
        if n_vals != n_ids * n:
            msg = (f'{side}_head_ids names {n_ids} heads but theta_{side}_heads_rad holds '
                   f'{n_vals} values for {n} samples')
            raise BagError(msg)
        ids = tuple(buf[lay.head_data_at[k]:lay.head_data_at[k] + n_ids])
        vals = np.frombuffer(buf, dtype, n_vals, lay.head_data_at[k + 1]).reshape(n_ids, n)
        if lay.order == '>':
            vals = vals.astype(np.float64)
            vals.setflags(write=False)
        out[f'{side}_head_ids'] = ids
        out[f'theta_{side}_heads_rad'] = vals
    return out


def decode_encoder_block(data: bytes | memoryview) -> EncoderBlockData:
    """Decode one EncoderBlock CDR message (with encapsulation header) into numpy arrays.

    Args:
        data: Serialised message as stored in a bag or received raw.

    Returns:
        The block; arrays are float64 views of a private copy of ``data``, read-only.

    Raises:
        BagError: The bytes do not hold a well-formed EncoderBlock.
    """
    from rv_te_bench.core.stream_records import EncoderBlockData

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
    heads = _heads_of(buf, lay, lay.counts[1])
    try:
        return EncoderBlockData(seq=int(seq), stamp_s=sec + nsec * 1e-9,
                                sample_rate_hz=float(rate), time_offset_s=arrays[0],
                                theta_in_rad=arrays[1], theta_out_rad=arrays[2],
                                torque_out_nm=arrays[3], **heads)  # type: ignore[arg-type]
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
    # per side with heads (fast path only): side -> (head ids, byte position of the readings)
    heads: tuple[tuple[str, tuple[int, ...], np.ndarray], ...] = ()


def _parse_same_layout(u8: np.ndarray, starts: np.ndarray,
                       ends: np.ndarray) -> _ParsedBlocks | None:
    """Fast path of :func:`_parse_encoder_blocks`: every message laid out like the first
    (same frame_id length and array lengths, the usual case), checked with one gather of
    the bytes that decide the layout. None when they differ."""
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
    heads: list[tuple[str, tuple[int, ...], np.ndarray]] = []
    extra: list[int] = []
    if first.head_counts:       # today's layout: the head counts (and ids) decide too
        extra = [c + k for c in first.head_count_at for k in range(4)]
        for k, side in ((0, 'in'), (2, 'out')):
            n_ids, n_vals = first.head_counts[k], first.head_counts[k + 1]
            if n_vals != n_ids * n:
                return None
            if n_ids:
                at = first.head_data_at[k]
                extra.extend(range(at, at + n_ids))
                ids = tuple(int(x) for x in u8[int(starts[0]) + at:int(starts[0]) + at + n_ids])
                heads.append((side, ids, starts + first.head_data_at[k + 1]))
    deciding = np.array([0, 1, 12, 13, 14, 15,
                         *(c + k for c in count_at for k in range(4)), *extra], dtype=np.int64)
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
        data=(starts + data_at[0], starts + data_at[1], starts + data_at[2]),
        heads=tuple(heads))


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
    ok = size >= 4 + 12 + 4

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
    # head fields (issue 36): a message that carries heads is decoded on its own (off is
    # 4-aligned here, and its four counts follow one another while they are 0)
    has = ok & (ends - (p + off) >= _HEAD_FIELDS_MIN)
    if has.any():
        q = np.where(has, p + off, starts)
        for k in range(4):
            c = _gather_le(u8, q + 4 * k, '<u4')
            ok &= ~has | (c == 0)
            has &= c == 0
    stamp = sec.astype(np.float64) + nsec.astype(np.float64) * 1e-9
    return _ParsedBlocks(ok, seq, stamp, rate, n, (data[0], data[1], data[2]))


def _concat_f64(u8: np.ndarray, pos: np.ndarray, counts: np.ndarray,
                out: np.ndarray | None = None) -> np.ndarray:
    """Concatenate little-endian float64 arrays of ``counts[k]`` values at byte ``pos[k]``.

    The bytes are copied message by message (one slice each, any alignment) and viewed as
    float64 once: faster than an element gather when the sources are not 8-byte aligned.
    Arrays of equal length at equal steps (the usual chunk) are copied in one strided copy.
    ``out``: a contiguous float64 array of ``counts.sum()`` values to write into (returned).
    """
    m = pos.size
    if m > 1:
        step = int(pos[1] - pos[0])
        n = int(counts[0])
        # messages of one layout lie at equal steps in a chunk: one strided copy of all
        # (a view of rows of 8 n bytes, ``step`` apart), no per-message Python work
        if step >= 8 * n and int(pos[-1]) + 8 * n <= u8.size \
                and (counts == n).all() and (pos[1:] - pos[:-1] == step).all():
            # (np.ndarray over the buffer: as_strided's wrapper cost ~10 us per call)
            rows = np.ndarray((m, 8 * n), np.uint8, buffer=u8, offset=int(pos[0]),
                              strides=(step, 1))
            # copied straight into the float64 array's bytes (a copy, then a view of it,
            # took 15-20 % longer: issue 41)
            if out is None:
                out = np.empty(m * n, dtype='<f8')
            np.copyto(out.view(np.uint8).reshape(m, 8 * n), rows)
            return out
    ends = pos + 8 * counts
    parts = [u8[a:b] for a, b in zip(pos.tolist(), ends.tolist(), strict=True)]
    if out is None:
        return np.concatenate(parts).view('<f8')
    np.concatenate(parts, out=out.view(np.uint8))
    return out


class BatchArena:
    """Fresh float64 arrays that the batches of consecutive chunks are decoded into side by
    side, so that a reader can hand them on as one batch without copying them again.

    Issue 41: the analysis's work per batch (the checks, Eq. 22, the window search, the
    plot trace, each a few numpy calls) was ~15 % of its CPU time with one batch per 1 MiB
    chunk. Arrays are never reused: a batch handed on keeps its memory.
    """

    def __init__(self, samples: int) -> None:
        self.samples = samples
        self.arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._pos = 0
        self.generation = 0   # arrays handed out since: ``take`` started new ones
        self.last = (0, 0)    # [start, stop) of the last ``take`` in ``arrays``

    def take(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Room for ``k`` samples of the three arrays (time, in, out), after the last."""
        if self.arrays is None or self._pos + k > self.arrays[0].size:
            size = max(self.samples, k)
            self.arrays = (np.empty(size), np.empty(size), np.empty(size))
            self._pos = 0
            self.generation += 1
        a = self._pos
        self._pos += k
        self.last = (a, a + k)
        t, i, o = self.arrays
        return t[a:a + k], i[a:a + k], o[a:a + k]


def _encoder_items(buf: memoryview, starts: np.ndarray, ends: np.ndarray,
                   arena: BatchArena | None = None) -> Iterator[EncoderBatch | int]:
    """Runs of well-formed messages as EncoderBatch, other messages by their index; with
    ``arena`` the arrays of batches without read heads are decoded into its arrays."""
    from rv_te_bench.core.stream_records import EncoderBatch

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
        slots = (None, None, None) if arena is None or parsed.heads \
            else arena.take(int(n.sum()))
        arrays = [_concat_f64(u8, d[a:b], n, out) for d, out in zip(parsed.data, slots,
                                                                        strict=True)]
        heads: dict[str, object] = {}
        for side, ids, pos in parsed.heads:
            h = len(ids)
            vals = _concat_f64(u8, pos[a:b], n * h)           # block by block, (h, n) each
            heads[f'{side}_head_ids'] = ids
            heads[f'theta_{side}_heads_rad'] = (
                vals.reshape(b - a, h, int(n[0])).transpose(1, 0, 2).reshape(h, -1))
        yield EncoderBatch(seq=parsed.seq[a:b].astype(np.int64), stamp_s=parsed.stamp_s[a:b],
                           sample_rate_hz=parsed.rate_hz[a:b],
                           starts=np.concatenate([[0], np.cumsum(n)]).astype(np.int64),
                           time_offset_s=arrays[0], theta_in_rad=arrays[1],
                           theta_out_rad=arrays[2], **heads)  # type: ignore[arg-type]
    yield from bad[bi:]


def decode_encoder_block_rosbags(data: bytes | memoryview) -> EncoderBlockData:
    """Decode one EncoderBlock with the rosbags typestore (slower; cross-check/fallback).

    Raises:
        BagError: The bytes do not deserialise as EncoderBlock.
    """
    from rv_te_bench.core.stream_records import EncoderBlockData
    from rv_te_bench.io._legacy_msgs import upgrade_cdr

    try:
        # a class the typestore generates at run time: no static type
        msg: Any = rv_te_typestore().deserialize_cdr(upgrade_cdr(ENCODER_BLOCK, data),
                                                     ENCODER_BLOCK)
    except Exception as exc:  # noqa: BLE001 - rosbags raises assorted errors on bad bytes
        text = f'EncoderBlock does not deserialise: {exc}'
        raise BagError(text) from None
    stamp = msg.header.stamp
    n = len(msg.theta_in_rad)
    heads: dict[str, object] = {}
    for side in ('in', 'out'):
        ids = tuple(int(i) for i in getattr(msg, f'{side}_head_ids'))
        vals = np.asarray(getattr(msg, f'theta_{side}_heads_rad'), np.float64)
        if ids:
            if vals.size != len(ids) * n:
                text = (f'{side}_head_ids names {len(ids)} heads but theta_{side}_heads_rad '
                        f'holds {vals.size} values for {n} samples')
                raise BagError(text)
            heads[f'{side}_head_ids'] = ids
            heads[f'theta_{side}_heads_rad'] = vals.reshape(len(ids), n)
    return EncoderBlockData(
        seq=int(msg.seq), stamp_s=stamp.sec + stamp.nanosec * 1e-9,
        sample_rate_hz=float(msg.sample_rate_hz),
        time_offset_s=np.asarray(msg.time_offset_s, np.float64),
        theta_in_rad=np.asarray(msg.theta_in_rad, np.float64),
        theta_out_rad=np.asarray(msg.theta_out_rad, np.float64),
        torque_out_nm=np.asarray(msg.torque_out_nm, np.float64), **heads)  # type: ignore[arg-type]
