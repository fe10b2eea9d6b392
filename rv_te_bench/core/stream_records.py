"""The record types of the TE stream: blocks in, windows, gaps and updates out.

The lowest floor of the streaming analysis: what a node or a bag reader hands to it
(:class:`EncoderBlockData`, :class:`EncoderBatch`), its settings (:class:`TeAnalysisConfig`)
and what it gives back (:class:`WindowResult`, :class:`GapEvent`, :class:`StreamUpdate`,
:class:`BatchUpdate`, :class:`OfflineResult`), with the one check of a block
(:func:`check_block`, which never raises). The analyzer is :mod:`rv_te_bench.core.stream`,
the offline runner :mod:`rv_te_bench.core.offline`; readers and nodes that only build or
read these records import them from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from rv_te_bench.core.orders import OrderSet
from rv_te_bench.errors import TeConfigError, TeInputError

if TYPE_CHECKING:
    from collections.abc import Iterable

    from rv_te_bench.core.spectrum import OrderSpectrum
    from rv_te_bench.core.te import TeStats

__all__ = ['MAX_WINDOW_REVOLUTIONS', 'MIN_WINDOW_SAMPLES', 'BatchUpdate', 'BlockProblem',
           'CleanBlock', 'CloseReason', 'EncoderBatch', 'EncoderBlockData', 'GapEvent',
           'GapKind', 'OfflineResult',
           'StreamUpdate', 'TeAnalysisConfig', 'WindowResult', 'check_block', 'seq_jump_event']

#: Longest analysis window [whole output revolutions] (TE node parameter, CLI, library).
MAX_WINDOW_REVOLUTIONS = 1000
GapKind = Literal['seq_jump', 'time_backwards', 'non_finite', 'malformed', 'leading_loss']
CloseReason = Literal['complete', 'gap', 'overflow', 'flush', 'reconfigure', 'heads']

#: Smallest window buffer (samples).
MIN_WINDOW_SAMPLES = 16
_EMPTY = np.empty(0, dtype=np.float64)
_EMPTY.setflags(write=False)
_OFFS_BOUND = 1e300
_OFFS_SUM_SAFE_N = 10**8


def _empty_array() -> np.ndarray:
    return _EMPTY


_NO_HEADS = np.empty((0, 0), dtype=np.float64)
_NO_HEADS.setflags(write=False)


def _no_heads() -> np.ndarray:
    return _NO_HEADS


@dataclass(frozen=True)
class EncoderBlockData:
    """One block of encoder samples, as a node hands it over from an ``EncoderBlock``.

    Construction does not check anything (so that :meth:`StreamingTeAnalyzer.push` can
    count bad blocks instead of failing); use :meth:`checked` or :meth:`validate` at a
    boundary that should raise.

    Attributes:
        seq: Block sequence number (consecutive blocks differ by 1).
        stamp_s: Time of the block's reference instant [s].
        sample_rate_hz: Nominal sampling rate [Hz] (> 0).
        time_offset_s: Sample times relative to ``stamp_s`` [s], strictly increasing.
        theta_in_rad: Unwrapped input-shaft angle per sample [rad].
        theta_out_rad: Unwrapped output-shaft angle per sample [rad].
        torque_out_nm: Output torque per sample [N m], or empty.
        in_head_ids: Numbers of the input scale's read heads in ``theta_in_heads_rad``
            (empty: one head; issue 36).
        theta_in_heads_rad: Their readings, shape (heads, n) [rad].
        out_head_ids: The same for the output scale.
        theta_out_heads_rad: Their readings, shape (heads, n) [rad]. The TE core reads
            ``theta_*_rad`` only: :class:`~rv_te_bench.core.head_combine.HeadCombiner`
            forms those from the heads before a block is pushed.
    """

    seq: int
    stamp_s: float
    sample_rate_hz: float
    time_offset_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_out_nm: np.ndarray = field(default_factory=_empty_array)
    in_head_ids: tuple[int, ...] = ()
    theta_in_heads_rad: np.ndarray = field(default_factory=_no_heads)
    out_head_ids: tuple[int, ...] = ()
    theta_out_heads_rad: np.ndarray = field(default_factory=_no_heads)

    @classmethod
    def checked(cls, *, seq: int, stamp_s: float, sample_rate_hz: float,
                time_offset_s: Any, theta_in_rad: Any, theta_out_rad: Any,
                torque_out_nm: Any = ()) -> EncoderBlockData:
        """Build a block with float64 arrays and validate it.

        Raises:
            TeInputError: The block is malformed (see :meth:`validate`).

        Examples:
            >>> b = EncoderBlockData.checked(seq=0, stamp_s=0.0, sample_rate_hz=1000.0,
            ...     time_offset_s=[0.0, 0.001], theta_in_rad=[0.0, 0.1],
            ...     theta_out_rad=[0.0, 0.001])
            >>> b.theta_in_rad.dtype.name
            'float64'
            >>> EncoderBlockData.checked(seq=0, stamp_s=0.0, sample_rate_hz=1000.0,
            ...     time_offset_s=[0.0], theta_in_rad=[0.0, 0.1], theta_out_rad=[0.0, 0.0])
            Traceback (most recent call last):
            ...
            rv_te_bench.errors.TeInputError: block seq 0: array lengths differ: \
time_offset_s 1, theta_in_rad 2, theta_out_rad 2
        """
        try:
            arrays = [np.asarray(a, dtype=np.float64)
                      for a in (time_offset_s, theta_in_rad, theta_out_rad, torque_out_nm)]
        except (TypeError, ValueError) as exc:
            msg = f'block seq {seq}: arrays not convertible to float64 ({exc})'
            raise TeInputError(msg) from None
        t, th_in, th_out, torque = arrays
        block = cls(seq, stamp_s, sample_rate_hz, t, th_in, th_out, torque)
        block.validate()
        return block

    def validate(self) -> None:
        """Check the block.

        Raises:
            TeInputError: Naming the problem: empty block, arrays of different lengths or not
                1-D, non-finite values, time offsets not strictly increasing, sample rate
                <= 0, bad stamp or sequence number.
        """
        out = check_block(self)
        if isinstance(out, BlockProblem):
            raise TeInputError(out.detail)


@dataclass(frozen=True)
class BlockProblem:
    """What is wrong with a block (:func:`check_block`): the gap kind and one line."""

    kind: GapKind
    detail: str


CleanBlock = tuple[int, np.ndarray, np.ndarray, np.ndarray, float]
"""A clean block from :func:`check_block`: (seq, sample times t_s, theta_in_rad,
theta_out_rad, sample_rate_hz); a plain tuple, built once per pushed block."""


@dataclass(frozen=True)
class EncoderBatch:
    """Consecutive encoder blocks with their samples concatenated (offline reading).

    A bag reader hands over all the blocks of one MCAP chunk at once, so that checks,
    Wang 2020 Eq. 22 and statistics run over long arrays instead of block by block.
    :meth:`StreamingTeAnalyzer.push_batch` gives the same windows, gaps, statistics and
    counters as pushing :meth:`block` 0, 1, ... one by one (it only skips the decimated
    display TE). Only structure is checked on construction (values are the analyzer's job,
    as for :class:`EncoderBlockData`); the torque is not carried (TE does not use it).

    Attributes:
        seq: Sequence number per block, int64, shape (B,).
        stamp_s: Reference time per block [s], shape (B,).
        sample_rate_hz: Nominal rate per block [Hz], shape (B,).
        starts: Sample index where each block starts, plus the total: int64, shape (B + 1,),
            starts[0] = 0, strictly increasing (no empty block).
        time_offset_s: Sample times relative to their block's stamp [s], shape (N,).
        theta_in_rad: Input-shaft angles [rad], shape (N,).
        theta_out_rad: Output-shaft angles [rad], shape (N,).
        in_head_ids: The input scale's heads, the same in every block of the batch.
        theta_in_heads_rad: Their readings, shape (heads, N) [rad].
        out_head_ids: The output scale's heads, the same in every block.
        theta_out_heads_rad: Their readings, shape (heads, N) [rad].
        parts: Blocks (indices, ascending, > 0) where a batch a reader merged from the
            batches of consecutive chunks begins another chunk's (``read_encoder_batches(
            merge=True)``); a consumer whose result depends on where the record was cut
            cuts there too, so that merging changes nothing (the angle fold: its noise
            estimate starts with each piece it is given). Not checked.

    Raises:
        TeInputError: The arrays do not fit together (names the sizes).
    """

    seq: np.ndarray
    stamp_s: np.ndarray
    sample_rate_hz: np.ndarray
    starts: np.ndarray
    time_offset_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    in_head_ids: tuple[int, ...] = ()
    theta_in_heads_rad: np.ndarray = field(default_factory=_no_heads)
    out_head_ids: tuple[int, ...] = ()
    theta_out_heads_rad: np.ndarray = field(default_factory=_no_heads)
    parts: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        """Check the structure."""
        n_blocks = np.size(self.seq)
        n = np.size(self.theta_in_rad)
        # the shapes compared one by one (a batch per chunk of a 10-minute bag: the dict of
        # names was 2/3 of this check's time, issue 41); the dict only for the message
        per_block, per_sample = (n_blocks,), (n,)
        if n_blocks == 0 or np.shape(self.seq) != per_block \
                or np.shape(self.stamp_s) != per_block \
                or np.shape(self.sample_rate_hz) != per_block \
                or np.shape(self.starts) != (n_blocks + 1,) \
                or np.shape(self.time_offset_s) != per_sample \
                or np.shape(self.theta_in_rad) != per_sample \
                or np.shape(self.theta_out_rad) != per_sample:
            shapes = {name: np.shape(getattr(self, name)) for name in (
                'seq', 'stamp_s', 'sample_rate_hz', 'starts', 'time_offset_s', 'theta_in_rad',
                'theta_out_rad')}
            msg = f'EncoderBatch arrays do not fit together: shapes {shapes}'
            raise TeInputError(msg)
        starts = np.asarray(self.starts)
        if starts[0] != 0 or starts[-1] != n or not (starts[1:] > starts[:-1]).all():
            msg = (f'EncoderBatch starts must run from 0 to {n} in strictly increasing steps, '
                   f'got {starts[:5].tolist()}...{starts[-2:].tolist()}')
            raise TeInputError(msg)
        for side in ('in', 'out'):
            ids = getattr(self, f'{side}_head_ids')
            heads = np.shape(getattr(self, f'theta_{side}_heads_rad'))
            if ids and heads != (len(ids), n):
                msg = (f'EncoderBatch {side}put heads: {len(ids)} heads need readings of shape '
                       f'({len(ids)}, {n}), got {heads}')
                raise TeInputError(msg)

    @property
    def n_blocks(self) -> int:
        """Number of blocks B."""
        return int(np.size(self.seq))

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(np.size(self.theta_in_rad))

    def block(self, k: int) -> EncoderBlockData:
        """Block ``k`` as an :class:`EncoderBlockData` (views, no copy)."""
        a, b = int(self.starts[k]), int(self.starts[k + 1])
        heads: dict[str, Any] = {}
        for side in ('in', 'out'):
            if ids := getattr(self, f'{side}_head_ids'):
                heads[f'{side}_head_ids'] = ids
                heads[f'theta_{side}_heads_rad'] = getattr(self, f'theta_{side}_heads_rad')[:, a:b]
        return EncoderBlockData(int(self.seq[k]), float(self.stamp_s[k]),
                                float(self.sample_rate_hz[k]), self.time_offset_s[a:b],
                                self.theta_in_rad[a:b], self.theta_out_rad[a:b], **heads)

    @classmethod
    def from_blocks(cls, blocks: Iterable[EncoderBlockData]) -> EncoderBatch:
        """Concatenate blocks (each must have equal-length 1-D arrays, at least one sample).

        Raises:
            TeInputError: No block, or a block whose arrays do not fit.
        """
        blocks = list(blocks)
        if not blocks:
            msg = 'EncoderBatch.from_blocks: no block'
            raise TeInputError(msg)
        sizes = [np.size(b.theta_in_rad) for b in blocks]
        for b, n in zip(blocks, sizes, strict=True):
            if n == 0 or np.size(b.time_offset_s) != n or np.size(b.theta_out_rad) != n:
                msg = f'EncoderBatch.from_blocks: block seq {b.seq} has arrays of unequal size'
                raise TeInputError(msg)

        def cat(name: str) -> np.ndarray:
            return np.concatenate([np.asarray(getattr(b, name), dtype=np.float64).ravel()
                                   for b in blocks])
        heads: dict[str, Any] = {}
        for side in ('in', 'out'):
            ids = {tuple(getattr(b, f'{side}_head_ids')) for b in blocks}
            if len(ids) > 1:
                msg = (f'EncoderBatch.from_blocks: the blocks carry different {side}put heads '
                       f'{sorted(ids)}: batch them apart')
                raise TeInputError(msg)
            if first := ids.pop():
                heads[f'{side}_head_ids'] = first
                heads[f'theta_{side}_heads_rad'] = np.concatenate(
                    [np.asarray(getattr(b, f'theta_{side}_heads_rad'), dtype=np.float64)
                     for b in blocks], axis=1)
        return cls(seq=np.array([int(b.seq) for b in blocks], dtype=np.int64),
                   stamp_s=np.array([b.stamp_s for b in blocks], dtype=np.float64),
                   sample_rate_hz=np.array([b.sample_rate_hz for b in blocks], dtype=np.float64),
                   starts=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                   time_offset_s=cat('time_offset_s'), theta_in_rad=cat('theta_in_rad'),
                   theta_out_rad=cat('theta_out_rad'), **heads)


def check_block(block: Any) -> CleanBlock | BlockProblem:
    """Check one block without raising; return clean float64 arrays or the problem."""
    seq = getattr(block, 'seq', None)
    if isinstance(seq, bool) or not isinstance(seq, int | np.integer):
        return BlockProblem('malformed', f'block seq {seq!r}: seq must be an integer')
    where = f'block seq {seq}'
    try:
        stamp = float(block.stamp_s)
        rate = float(block.sample_rate_hz)
        offs = np.asarray(block.time_offset_s, dtype=np.float64)
        th_in = np.asarray(block.theta_in_rad, dtype=np.float64)
        th_out = np.asarray(block.theta_out_rad, dtype=np.float64)
        torque = np.asarray(block.torque_out_nm, dtype=np.float64)
    except (AttributeError, TypeError, ValueError, OverflowError) as exc:
        return BlockProblem('malformed', f'{where}: fields not convertible ({exc})')
    if not math.isfinite(stamp):
        return BlockProblem('malformed', f'{where}: stamp_s must be finite, got {stamp!r}')
    if not (math.isfinite(rate) and rate > 0.0):
        return BlockProblem('malformed', f'{where}: sample_rate_hz must be finite and > 0, '
                                     f'got {rate!r}')
    if offs.ndim != 1 or th_in.ndim != 1 or th_out.ndim != 1 or torque.ndim != 1:
        return BlockProblem('malformed', f'{where}: arrays must be 1-D')
    n = th_in.size
    if n == 0:
        return BlockProblem('malformed', f'{where}: empty block')
    if offs.size != n or th_out.size != n:
        return BlockProblem('malformed', f'{where}: array lengths differ: time_offset_s '
                                     f'{offs.size}, theta_in_rad {n}, theta_out_rad {th_out.size}')
    if torque.size not in (0, n):
        return BlockProblem('malformed', f'{where}: torque_out_nm has {torque.size} samples, '
                                     f'expected 0 or {n}')
    # one pass without a temporary: a NaN or inf makes the sum non-finite (finite values
    # overflow only beyond 1e304, which no angle or time reaches). The torque is not used
    # by the TE analysis: a bad torque sample must not cost the block its angles.
    # Time offsets that increase strictly between finite ends within +-1e300 are all finite
    # and sum without overflow (n < 1e8): the increase test (needed anyway) covers them.
    # count_nonzero of the comparison: no .all() wrapper (a NaN compares False: not increasing)
    increasing = n == 1 or int(np.count_nonzero(offs[1:] > offs[:-1])) == n - 1
    offs_ok = increasing and n < _OFFS_SUM_SAFE_N and float(offs[0]) >= -_OFFS_BOUND \
        and float(offs[-1]) <= _OFFS_BOUND
    add = np.add.reduce
    if offs_ok:
        with np.errstate(over='ignore', invalid='ignore'):
            total_in, total_out = float(add(th_in)), float(add(th_out))
        if math.isfinite(total_in) and math.isfinite(total_out):   # the clean block
            return (int(seq), offs + stamp, th_in, th_out, rate)
        names: tuple[str, ...] = ('theta_in_rad', 'theta_out_rad')
        arrays: tuple[np.ndarray, ...] = (th_in, th_out)
        totals = [total_in, total_out]
    else:
        names = ('time_offset_s', 'theta_in_rad', 'theta_out_rad')
        arrays = (offs, th_in, th_out)
        with np.errstate(over='ignore', invalid='ignore'):
            totals = [float(add(a)) for a in arrays]
    for name, arr, total in zip(names, arrays, totals, strict=True):
        if not math.isfinite(total):
            bad_idx = np.flatnonzero(~np.isfinite(arr))
            if bad_idx.size:
                bad = int(bad_idx[0])
                return BlockProblem('non_finite', f'{where}: {name}[{bad}] is {float(arr[bad])!r}')
            return BlockProblem('malformed', f'{where}: {name} values out of range (|x| > 1e300)')
    if not increasing:
        return BlockProblem('malformed', f'{where}: time_offset_s not strictly increasing')
    return (int(seq), offs + stamp, th_in, th_out, rate)


def _whole_number(name: str, value: float, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating) \
            or not math.isfinite(value) or value != round(value) or value < minimum:
        msg = f'{name} must be a whole number >= {minimum}, got {value!r}'
        raise TeConfigError(msg)


@dataclass(frozen=True)
class TeAnalysisConfig:
    """Settings of the streaming TE analysis (SI units).

    Attributes:
        orders: Gear ratio and the spectral lines to report.
        window_revolutions: W, output revolutions per analysis window (whole number >= 1).
        decimated_rate_hz: Rate of the TE samples handed back for live display (> 0).
        max_window_samples: Largest window buffer (>= 16); bounds memory at
            16 bytes per sample.
        samples_per_rev: Angle-grid points per output revolution for the spectrum
            (>= 8), or None for the window's own sample density.
        compute_spectrum: Whether complete windows get an order spectrum.

    Raises:
        TeConfigError: A value breaks the rule stated above.
    """

    orders: OrderSet
    window_revolutions: float = 1.0
    decimated_rate_hz: float = 50.0
    max_window_samples: int = 2_000_000
    samples_per_rev: int | None = None
    compute_spectrum: bool = True

    def __post_init__(self) -> None:
        """Validate."""
        if not isinstance(self.orders, OrderSet):
            msg = f'orders must be an OrderSet, got {type(self.orders).__name__}'
            raise TeConfigError(msg)
        _whole_number('window_revolutions', self.window_revolutions, 1)
        if self.window_revolutions > MAX_WINDOW_REVOLUTIONS:
            msg = (f'window_revolutions must be <= {MAX_WINDOW_REVOLUTIONS}, got '
                   f'{self.window_revolutions!r}')
            raise TeConfigError(msg)
        object.__setattr__(self, 'window_revolutions', float(self.window_revolutions))
        rate = self.decimated_rate_hz
        if not (isinstance(rate, int | float) and math.isfinite(rate) and rate > 0):
            msg = f'decimated_rate_hz must be finite and > 0, got {rate!r}'
            raise TeConfigError(msg)
        _whole_number('max_window_samples', self.max_window_samples, MIN_WINDOW_SAMPLES)
        object.__setattr__(self, 'max_window_samples', int(self.max_window_samples))
        if self.samples_per_rev is not None:
            _whole_number('samples_per_rev', self.samples_per_rev, 8)
            object.__setattr__(self, 'samples_per_rev', int(self.samples_per_rev))

    @property
    def gear_ratio(self) -> float:
        """Overall ratio i (from ``orders``)."""
        return self.orders.gear_ratio


@dataclass(frozen=True)
class GapEvent:
    """Something wrong in the stream.

    Attributes:
        kind: ``'seq_jump'``, ``'time_backwards'``, ``'non_finite'`` or ``'malformed'``.
        seq: Sequence number of the block where it was seen (-1 if unreadable).
        detail: Human-readable description naming the problem (for a seq jump: where in
            the record and how long, from the first sample).
        t_before_s: Time of the last clean sample before it [s, the blocks' clock] (None
            when unknown).
        t_after_s: Time of the first sample after it [s] (None when unknown).
        missing_s: Time without data, ``t_after - t_before - 1 / sample_rate`` [s] (None
            when unknown; 0 when the blocks' times leave no room for the lost ones).
        at_s: ``t_before_s`` from the first clean sample of the stream [s] (None: unknown).
    """

    kind: GapKind
    seq: int
    detail: str
    t_before_s: float | None = None
    t_after_s: float | None = None
    missing_s: float | None = None
    at_s: float | None = None


def seq_jump_event(expected: int, seq: int, t_before: float | None, t_after: float,
                   rate_hz: float, t_first: float | None) -> GapEvent:
    """The :class:`GapEvent` of a block ``seq`` arriving where ``expected`` was due: when and
    for how long the record has no data (``t_before`` = last sample before, ``t_after`` =
    first after, ``t_first`` = first sample of the record; the blocks' clock, s)."""
    detail = f'expected seq {expected}, got {seq}'
    missing = at = None
    if t_before is not None and math.isfinite(t_before):
        if rate_hz > 0:
            missing = round(max(0.0, t_after - t_before - 1.0 / rate_hz), 6)
        if t_first is not None:
            at = round(t_before - t_first, 6)
    if missing is not None and at is not None and t_after > t_before:   # type: ignore[operator]
        detail += f': no data for {missing:.6g} s after {at:.6g} s into the record'
    return GapEvent('seq_jump', seq, detail, t_before, float(t_after), missing, at)


@dataclass(frozen=True)
class WindowResult:
    """One closed analysis window.

    Attributes:
        index: 0, 1, 2... in closing order.
        start_stamp_s: Time of the first sample [s].
        end_stamp_s: Time of the last sample [s].
        complete: True when it covers ``window_revolutions`` whole revolutions with no gap.
        stats: TE statistics of its samples (``revolutions`` = W when complete, else the
            angle travelled from the first to the last sample).
        spectrum: Order spectrum over W revolutions (complete windows only; None also when
            the record is not strictly monotonic in phi, e.g. a reversal).
        first_seq: Sequence number of the block of the first sample.
        last_seq: Sequence number of the block of the last sample.
        close_reason: ``'complete'``, ``'gap'``, ``'overflow'``, ``'flush'``,
            ``'reconfigure'`` or ``'heads'`` (the read heads forming the angle changed).
    """

    index: int
    start_stamp_s: float
    end_stamp_s: float
    complete: bool
    stats: TeStats
    spectrum: OrderSpectrum | None
    first_seq: int
    last_seq: int
    close_reason: CloseReason = 'complete'


@dataclass(frozen=True)
class StreamUpdate:
    """What one :meth:`StreamingTeAnalyzer.push` produced.

    Attributes:
        stamp_s: Time of the first decimated sample [s] (NaN when there is none).
        te_rad: Decimated TE [rad] (read-only).
        phase_out_rad: Decimated reference output angle theta_in / i [rad] (read-only).
        windows: Windows closed by this block (and by a preceding ``reconfigure``).
        gaps: Problems met in this block.
        time_s: Time of each decimated sample [s] (read-only).
        period_s: Nominal spacing of the decimated samples [s] (NaN when unknown).
    """

    stamp_s: float
    te_rad: np.ndarray
    phase_out_rad: np.ndarray
    windows: tuple[WindowResult, ...]
    gaps: tuple[GapEvent, ...]
    time_s: np.ndarray = field(default_factory=_empty_array)
    period_s: float = math.nan


@dataclass(frozen=True)
class BatchUpdate:
    """What one :meth:`StreamingTeAnalyzer.push_batch` produced.

    Attributes:
        windows: Windows closed by the batch (and by a preceding ``reconfigure``).
        gaps: Problems met in the batch, in block order.
    """

    windows: tuple[WindowResult, ...]
    gaps: tuple[GapEvent, ...]


@dataclass(frozen=True)
class OfflineResult:
    """Result of :func:`analyze_blocks`.

    Attributes:
        windows: Every window closed, the last one by the final flush (empty when the
            windows went to an ``on_window`` callback instead).
        cumulative: Statistics over every clean sample.
        counters: Final :attr:`StreamingTeAnalyzer.counters`.
        gaps: Every gap event.
    """

    windows: tuple[WindowResult, ...]
    cumulative: TeStats
    counters: dict[str, int]
    gaps: tuple[GapEvent, ...]
