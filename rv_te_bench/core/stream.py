"""Streaming TE analysis: encoder blocks in, decimated TE and whole-revolution windows out.

A :class:`StreamingTeAnalyzer` takes the blocks an encoder DAQ (or the simulated bench, or a
bag) delivers, computes TE = theta_out - theta_in / i (Wang 2020 Eq. 22, :mod:`rv_te_bench.core.te`)
per sample and

- hands back the TE decimated to ``decimated_rate_hz`` for live display (every q-th sample,
  q = round(sample_rate_hz / decimated_rate_hz), phase-continuous across blocks; picked,
  not averaged, so the plot shows true sample values),
- cuts the clean samples into windows of ``window_revolutions`` whole output revolutions
  of phi = theta_in / i. A window starts at its first clean sample phi_s and takes every
  following sample with |phi - phi_s| < 2 pi W; the first sample at or beyond that bound
  starts the next window. A closed window carries its statistics and (when complete) its
  order spectrum (:func:`rv_te_bench.core.spectrum.order_spectrum`: mean in order 0, no
  detrending, no taper),
- keeps cumulative statistics over every clean sample in O(1) memory.

Bad data never raises from :meth:`StreamingTeAnalyzer.push`: a malformed block, a sequence
number jump, time going backwards or non-finite samples close the open window as partial
(``complete=False``, no spectrum), are counted and returned as :class:`GapEvent` s, and the
analysis resumes with the next clean data. Blocks with a problem inside them (malformed,
non-finite) are dropped whole; a block that is clean in itself but follows a seq jump or
goes back in time is used and starts a new window. Memory is bounded by one window buffer
(at most ``max_window_samples`` samples of two float64 arrays); a window that reaches that
size before completing is closed as partial (``close_reason='overflow'``).

Offline, :meth:`StreamingTeAnalyzer.push_batch` takes many consecutive blocks at once (an
:class:`EncoderBatch`, one MCAP chunk) and analyses runs of clean, continuous blocks as one
array, with the same windows, gaps and counters as block by block; :func:`analyze_blocks`
can hand each window to a callback instead of keeping them all, and compute the window
spectra on a second thread while it reads on (``spectra_thread``: the same results; one
more window's arrays are then held besides the open one). That thread may be one the
caller shares with other work, e.g. the bag reader's read-ahead (``analyze_bag`` does).

A bench numbers its blocks from 0, so a first block with a seq above 0 is a gap too
(``'leading_loss'``: a recorder or TE node that started after the bench lost the blocks before
it).

Not detected as gaps: a forward jump in time between blocks with consecutive sequence
numbers (the DAQ clock is trusted) and a jump of the encoder angles themselves (e.g. a
re-zeroed counter); both show up in the window statistics.
"""

from __future__ import annotations

import contextlib
import math
from collections import deque
from concurrent.futures import Executor, Future
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.spectrum import OrderSpectrum, SpectrumWorkspace, order_spectrum
from rv_te_bench.core.te import RunningStats, TeStats, moments_of_finite, output_phase_and_te
from rv_te_bench.errors import TeConfigError, TeInputError

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable

__all__ = ['SPECTRA_AHEAD', 'BatchUpdate', 'EncoderBatch', 'EncoderBlockData', 'GapEvent',
           'OfflineResult', 'StreamUpdate', 'StreamingTeAnalyzer', 'TeAnalysisConfig',
           'WindowResult', 'analyze_blocks', 'seq_jump_event']

GapKind = Literal['seq_jump', 'time_backwards', 'non_finite', 'malformed', 'leading_loss']
CloseReason = Literal['complete', 'gap', 'overflow', 'flush', 'reconfigure']

_TWO_PI = 2.0 * math.pi
_EMPTY = np.empty(0, dtype=np.float64)
_EMPTY.setflags(write=False)
_INITIAL_CAPACITY = 1 << 16
_MIN_WINDOW_SAMPLES = 16
_SCAN_PIECE = 1 << 16  # samples examined at a time when looking for a window's end
_OFFS_BOUND = 1e300
_OFFS_SUM_SAFE_N = 10**8


def _empty_array() -> np.ndarray:
    return _EMPTY


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
    """

    seq: int
    stamp_s: float
    sample_rate_hz: float
    time_offset_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_out_nm: np.ndarray = field(default_factory=_empty_array)

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
        block = cls(seq, stamp_s, sample_rate_hz, *arrays)
        block.validate()
        return block

    def validate(self) -> None:
        """Check the block.

        Raises:
            TeInputError: Naming the problem: empty block, arrays of different lengths or not
                1-D, non-finite values, time offsets not strictly increasing, sample rate
                <= 0, bad stamp or sequence number.
        """
        out = _normalize(self)
        if isinstance(out, _Problem):
            raise TeInputError(out.detail)


@dataclass(frozen=True)
class _Problem:
    kind: GapKind
    detail: str


# a clean block from _normalize: (seq, sample times t_s, theta_in_rad, theta_out_rad,
# sample_rate_hz); a plain tuple, built once per pushed block
_Clean = tuple[int, np.ndarray, np.ndarray, np.ndarray, float]


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

    def __post_init__(self) -> None:
        """Check the structure."""
        n_blocks = np.size(self.seq)
        n = np.size(self.theta_in_rad)
        shapes = {name: np.shape(getattr(self, name)) for name in (
            'seq', 'stamp_s', 'sample_rate_hz', 'starts', 'time_offset_s', 'theta_in_rad',
            'theta_out_rad')}
        want = {'seq': (n_blocks,), 'stamp_s': (n_blocks,), 'sample_rate_hz': (n_blocks,),
                'starts': (n_blocks + 1,), 'time_offset_s': (n,), 'theta_in_rad': (n,),
                'theta_out_rad': (n,)}
        if n_blocks == 0 or shapes != want:
            msg = f'EncoderBatch arrays do not fit together: shapes {shapes}'
            raise TeInputError(msg)
        starts = np.asarray(self.starts)
        if starts[0] != 0 or starts[-1] != n or not (starts[1:] > starts[:-1]).all():
            msg = (f'EncoderBatch starts must run from 0 to {n} in strictly increasing steps, '
                   f'got {starts[:5].tolist()}...{starts[-2:].tolist()}')
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
        return EncoderBlockData(int(self.seq[k]), float(self.stamp_s[k]),
                                float(self.sample_rate_hz[k]), self.time_offset_s[a:b],
                                self.theta_in_rad[a:b], self.theta_out_rad[a:b])

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
        return cls(seq=np.array([int(b.seq) for b in blocks], dtype=np.int64),
                   stamp_s=np.array([b.stamp_s for b in blocks], dtype=np.float64),
                   sample_rate_hz=np.array([b.sample_rate_hz for b in blocks], dtype=np.float64),
                   starts=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                   time_offset_s=cat('time_offset_s'), theta_in_rad=cat('theta_in_rad'),
                   theta_out_rad=cat('theta_out_rad'))


def _normalize(block: Any) -> _Clean | _Problem:
    """Check one block without raising; return clean float64 arrays or the problem."""
    seq = getattr(block, 'seq', None)
    if isinstance(seq, bool) or not isinstance(seq, int | np.integer):
        return _Problem('malformed', f'block seq {seq!r}: seq must be an integer')
    where = f'block seq {seq}'
    try:
        stamp = float(block.stamp_s)
        rate = float(block.sample_rate_hz)
        offs = np.asarray(block.time_offset_s, dtype=np.float64)
        th_in = np.asarray(block.theta_in_rad, dtype=np.float64)
        th_out = np.asarray(block.theta_out_rad, dtype=np.float64)
        torque = np.asarray(block.torque_out_nm, dtype=np.float64)
    except (AttributeError, TypeError, ValueError, OverflowError) as exc:
        return _Problem('malformed', f'{where}: fields not convertible ({exc})')
    if not math.isfinite(stamp):
        return _Problem('malformed', f'{where}: stamp_s must be finite, got {stamp!r}')
    if not (math.isfinite(rate) and rate > 0.0):
        return _Problem('malformed', f'{where}: sample_rate_hz must be finite and > 0, '
                                     f'got {rate!r}')
    if offs.ndim != 1 or th_in.ndim != 1 or th_out.ndim != 1 or torque.ndim != 1:
        return _Problem('malformed', f'{where}: arrays must be 1-D')
    n = th_in.size
    if n == 0:
        return _Problem('malformed', f'{where}: empty block')
    if offs.size != n or th_out.size != n:
        return _Problem('malformed', f'{where}: array lengths differ: time_offset_s '
                                     f'{offs.size}, theta_in_rad {n}, theta_out_rad {th_out.size}')
    if torque.size not in (0, n):
        return _Problem('malformed', f'{where}: torque_out_nm has {torque.size} samples, '
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
                return _Problem('non_finite', f'{where}: {name}[{bad}] is {float(arr[bad])!r}')
            return _Problem('malformed', f'{where}: {name} values out of range (|x| > 1e300)')
    if not increasing:
        return _Problem('malformed', f'{where}: time_offset_s not strictly increasing')
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
        object.__setattr__(self, 'window_revolutions', float(self.window_revolutions))
        rate = self.decimated_rate_hz
        if not (isinstance(rate, int | float) and math.isfinite(rate) and rate > 0):
            msg = f'decimated_rate_hz must be finite and > 0, got {rate!r}'
            raise TeConfigError(msg)
        _whole_number('max_window_samples', self.max_window_samples, _MIN_WINDOW_SAMPLES)
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
        close_reason: ``'complete'``, ``'gap'``, ``'overflow'``, ``'flush'`` or
            ``'reconfigure'``.
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


class _WindowBuffer:
    """Growable (up to a cap) buffers of phi and TE of the open window."""

    __slots__ = ('_scratch', 'cap', 'first_seq', 'last_seq', 'n', 'phi', 't_first', 't_last',
                 'te')

    def __init__(self, cap: int) -> None:
        self.cap = cap
        self.phi = np.empty(min(_INITIAL_CAPACITY, cap))
        self.te = np.empty(min(_INITIAL_CAPACITY, cap))
        self.n = 0
        self.t_first = math.nan
        self.t_last = math.nan
        self.first_seq = -1
        self.last_seq = -1
        self._scratch = _EMPTY

    def append(self, phi: np.ndarray, te: np.ndarray, t_first: float, t_last: float,
               seq_first: int, seq_last: int) -> None:
        m = phi.size
        if m == 0:
            return
        need = self.n + m
        if need > self.phi.size:
            cap = min(max(need, 2 * self.phi.size), self.cap)
            self.phi = np.concatenate([self.phi[:self.n], np.empty(cap - self.n)])
            self.te = np.concatenate([self.te[:self.n], np.empty(cap - self.n)])
        self.phi[self.n:need] = phi
        self.te[self.n:need] = te
        if self.n == 0:
            self.t_first = t_first
            self.first_seq = seq_first
        self.t_last = t_last
        self.last_seq = seq_last
        self.n = need

    def take(self, m: int, t_first: float, t_last: float, seq_first: int,
             seq_last: int) -> None:
        """Take in the ``m`` samples already written past the end (at ``[n, n + m)``)."""
        if self.n == 0:
            self.t_first = t_first
            self.first_seq = seq_first
        self.t_last = t_last
        self.last_seq = seq_last
        self.n += m

    def clear(self) -> None:
        # the capacity is kept (the next window is about as long; bounded by the cap)
        self.n = 0

    def scratch(self) -> np.ndarray:
        """A work array as long as the buffers (kept: no new pages per window)."""
        if self._scratch.size < self.phi.size:
            self._scratch = np.empty(self.phi.size)
        return self._scratch


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def _first_reach(phi: np.ndarray, start: float, bound: float) -> int:
    """Index of the first sample with |phi - start| >= bound, or -1.

    Scans piece by piece, so the cost grows with the distance to that sample, not with the
    length of ``phi`` (a long batch holds many windows).
    """
    if phi.size <= _SCAN_PIECE:   # one piece (a block pushed live): no slicing
        if (float(np.maximum.reduce(phi)) - start >= bound
                or start - float(np.minimum.reduce(phi)) >= bound):
            return int((np.abs(phi - start) >= bound).argmax())
        return -1
    for a in range(0, phi.size, _SCAN_PIECE):
        piece = phi[a:a + _SCAN_PIECE]
        if (float(np.maximum.reduce(piece)) - start >= bound
                or start - float(np.minimum.reduce(piece)) >= bound):
            return a + int((np.abs(piece - start) >= bound).argmax())
    return -1


def _batch_flags(batch: EncoderBatch) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per block of a batch: (bad, breaks, t_first, t_last).

    ``bad``: the block has a problem of its own (non-finite stamp or values, rate <= 0,
    time offsets not strictly increasing); ``breaks``: the block does not continue the one
    before it in the batch (seq jump or time not after it; False for block 0).
    """
    starts = np.asarray(batch.starts, dtype=np.intp)
    stamp = np.asarray(batch.stamp_s, dtype=np.float64)
    rate = np.asarray(batch.sample_rate_hz, dtype=np.float64)
    offs = np.asarray(batch.time_offset_s, dtype=np.float64)
    with np.errstate(over='ignore', invalid='ignore'):
        bad = ~(np.isfinite(stamp) & np.isfinite(rate) & (rate > 0.0))
        for arr in (offs, batch.theta_in_rad, batch.theta_out_rad):
            # a NaN or inf makes its block's sum non-finite (as in _normalize)
            bad |= ~np.isfinite(np.add.reduceat(np.asarray(arr, dtype=np.float64), starts[:-1]))
    increasing = offs[1:] > offs[:-1]
    increasing[starts[1:-1] - 1] = True   # across block boundaries offsets restart
    if not increasing.all():
        bad[np.searchsorted(starts, np.flatnonzero(~increasing), side='right') - 1] = True
    t_first = stamp + offs[starts[:-1]]
    t_last = stamp + offs[starts[1:] - 1]
    seq = np.asarray(batch.seq, dtype=np.int64)
    breaks = np.zeros(seq.size, dtype=bool)
    breaks[1:] = (seq[1:] != seq[:-1] + 1) | ~(t_first[1:] > t_last[:-1])
    return bad, breaks, t_first, t_last


class StreamingTeAnalyzer:
    """Online TE analysis over blocks; see the module docstring for the rules.

    Examples:
        An ideal 79:1 reducer at 1 output rev/s sampled at 1 kHz: TE is zero and each
        1000-sample block closes one whole-revolution window.

        >>> import numpy as np
        >>> from rv_te_bench.core.orders import OrderSet
        >>> cfg = TeAnalysisConfig(orders=OrderSet(79.0, 25.0))
        >>> ana = StreamingTeAnalyzer(cfg)
        >>> t = np.arange(1000) / 1000.0
        >>> for seq in range(3):
        ...     th_in = 2 * np.pi * 79 * (seq + t)
        ...     up = ana.push(EncoderBlockData(seq, float(seq), 1000.0, t, th_in, th_in / 79))
        >>> ana.counters['complete_windows'], ana.cumulative.pp_rad, up.te_rad.size
        (2, 0.0, 50)
    """

    def __init__(self, config: TeAnalysisConfig) -> None:
        """Start a session with ``config``."""
        self._config = config
        # cumulative statistics: every closed window's moments (one pass per window, the
        # window's own), plus the open window's samples up to _cum_folded when read
        self._cum = RunningStats()
        self._cum_folded = 0
        self._cum_rev = 0.0
        self._cum_key: tuple[Any, ...] = (None, 0, 0.0, None)   # the last read, see cumulative
        self._buf = _WindowBuffer(config.max_window_samples)
        self._spectrum_work = SpectrumWorkspace()   # the window spectra's work arrays
        # analyze_blocks(spectra_thread=True): called with (window index, window buffer)
        # instead of computing a complete window's spectrum here; it may take the buffer's
        # arrays (and give it others of the same size)
        self._spectrum_hook: Callable[[int, _WindowBuffer], None] | None = None
        self._pending: list[WindowResult] = []
        self._last_seq: int | None = None
        self._last_t: float | None = None
        self._t_first: float | None = None   # first clean sample (gap times in the record)
        self._last_phi: float | None = None
        self._decim_offset = 0
        self._n_windows = 0
        self._counters = dict.fromkeys(
            ('blocks', 'samples', 'gaps', 'malformed', 'non_finite', 'seq_jumps',
             'time_backwards', 'leading_loss', 'dropped_blocks', 'windows', 'complete_windows',
             'spectrum_failures'), 0)

    @property
    def config(self) -> TeAnalysisConfig:
        """The configuration in use."""
        return self._config

    @property
    def cumulative(self) -> TeStats:
        """Statistics over every clean sample since the start (or the last reset).

        ``revolutions`` is the output angle travelled over clean, contiguous data. The open
        window's samples are folded in here (what was not yet): a closed window adds the
        moments its statistics come from, so pushing blocks does no per-block pass for this.
        """
        buf = self._buf
        n = buf.n
        cum = self._cum
        if n > self._cum_folded:
            # the buffered TE is finite (checked on the way in): no check, no new array
            cum.add_finite(buf.te[self._cum_folded:n], buf.scratch())
            self._cum_folded = n
        # a second read with nothing new (the TE node's plot message) reuses the first:
        # same accumulator object, as many samples, same angle travelled
        key = self._cum_key
        if key[0] is cum and key[1] == cum.n_samples and key[2] == self._cum_rev:
            return key[3]
        stats = cum.stats(self._cum_rev / _TWO_PI)
        self._cum_key = (cum, cum.n_samples, self._cum_rev, stats)
        return stats

    @property
    def counters(self) -> dict[str, int]:
        """Counts: blocks, samples (clean), gaps (events), malformed, non_finite, seq_jumps,
        time_backwards, leading_loss (1 when the first block's seq is above 0), dropped_blocks
        (malformed + non_finite), windows, complete_windows,
        spectrum_failures (complete windows whose angle grid could not be resampled)."""
        return dict(self._counters)

    def reconfigure(self, config: TeAnalysisConfig, *,
                    reset_cumulative: bool | None = None) -> None:
        """Switch to a new configuration; the open window is closed (partial).

        The closed window is returned by the next :meth:`push` (or :meth:`flush`).

        Args:
            config: The new settings.
            reset_cumulative: Restart the cumulative statistics. None: restart when the
                gear ratio changes (TE values under the old ratio are not comparable).
        """
        self._close('reconfigure', pending=True)
        if reset_cumulative is None:
            reset_cumulative = config.gear_ratio != self._config.gear_ratio
        if reset_cumulative:
            self._cum = RunningStats()
            self._cum_folded = 0
            self._cum_rev = 0.0
        if config.max_window_samples != self._config.max_window_samples:
            self._buf = _WindowBuffer(config.max_window_samples)
        self._config = config
        self._last_phi = None
        self._decim_offset = 0

    def set_decimated_rate(self, decimated_rate_hz: float) -> None:
        """Change only the rate of the TE handed back for display; the window stays open.

        Raises:
            TeConfigError: The rate is not finite and > 0.
        """
        self._config = replace(self._config, decimated_rate_hz=decimated_rate_hz)
        self._decim_offset = 0

    def flush(self) -> tuple[WindowResult, ...]:
        """Close the open window at the end of a recording (partial, ``'flush'``)."""
        self._close('flush', pending=True)
        out = tuple(self._pending)
        self._pending.clear()
        return out

    # ------------------------------------------------------------------ internals

    def _gap(self, gaps: list[GapEvent], kind: GapKind, seq: int, detail: str) -> None:
        gaps.append(GapEvent(kind, seq, detail))
        self._counters['gaps'] += 1
        counter = {'seq_jump': 'seq_jumps', 'time_backwards': 'time_backwards',
                   'non_finite': 'non_finite', 'malformed': 'malformed',
                   'leading_loss': 'leading_loss'}[kind]
        self._counters[counter] += 1

    def _close(self, reason: CloseReason, *, pending: bool = False) -> WindowResult | None:
        buf = self._buf
        if buf.n == 0:
            return None
        phi = buf.phi[:buf.n]
        te = buf.te[:buf.n]
        complete = reason == 'complete'
        w_rev = self._config.window_revolutions
        spectrum = None
        moments = moments_of_finite(te, scratch=buf.scratch())
        if self._cum_folded == 0:
            self._cum.add_moments(moments)
        elif self._cum_folded < te.size:   # part went in when `cumulative` was read
            self._cum.add_moments(moments_of_finite(te[self._cum_folded:],
                                                    scratch=buf.scratch()))
        self._cum_folded = 0
        if complete:
            stats = moments.stats(w_rev)
            if self._config.compute_spectrum and self._spectrum_hook is not None:
                self._spectrum_hook(self._n_windows, buf)
            elif self._config.compute_spectrum:
                try:
                    spectrum = self._window_spectrum(phi, te, buf.t_last - buf.t_first,
                                                     self._spectrum_work)
                except TeInputError:
                    spectrum = None
                    self._counters['spectrum_failures'] += 1
        else:
            stats = moments.stats(abs(float(phi[-1] - phi[0])) / _TWO_PI)
        result = WindowResult(
            index=self._n_windows, start_stamp_s=buf.t_first, end_stamp_s=buf.t_last,
            complete=complete, stats=stats, spectrum=spectrum, first_seq=buf.first_seq,
            last_seq=buf.last_seq, close_reason=reason)
        self._n_windows += 1
        self._counters['windows'] += 1
        self._counters['complete_windows'] += int(complete)
        buf.clear()
        if pending:
            self._pending.append(result)
        return result

    def _window_spectrum(self, phi: np.ndarray, te: np.ndarray, duration_s: float,
                         workspace: SpectrumWorkspace) -> OrderSpectrum:
        """The order spectrum of a complete window (raises TeInputError as order_spectrum)."""
        cfg = self._config
        return order_spectrum(phi, te, cfg.orders, duration_s=duration_s,
                              samples_per_rev=cfg.samples_per_rev,
                              revolutions=round(cfg.window_revolutions), workspace=workspace)

    def _feed(self, phi: np.ndarray, te: np.ndarray, time_at: Callable[[int], float],
              seq_at: Callable[[int], int], out: list[WindowResult]) -> None:
        """Append clean samples to windows, closing those that reach W revolutions.

        ``time_at(i)`` and ``seq_at(i)`` give the time and block seq of sample ``i``.
        """
        buf = self._buf
        bound = _TWO_PI * self._config.window_revolutions
        cap = self._config.max_window_samples
        n = phi.size
        i = 0
        while i < n:
            phi_start = float(phi[i]) if buf.n == 0 else float(buf.phi[0])
            room = cap - buf.n
            # only the samples that still fit are searched: a later end is an overflow
            j = _first_reach(phi[i:i + room + 1], phi_start, bound)
            if j >= 0:
                if j > 0:
                    buf.append(phi[i:i + j], te[i:i + j], time_at(i), time_at(i + j - 1),
                               seq_at(i), seq_at(i + j - 1))
                closed = self._close('complete')
                if closed is not None:
                    out.append(closed)
                i += j
            elif n - i <= room:
                buf.append(phi[i:], te[i:], time_at(i), time_at(n - 1), seq_at(i),
                           seq_at(n - 1))
                i = n
            else:
                if room > 0:
                    buf.append(phi[i:i + room], te[i:i + room], time_at(i),
                               time_at(i + room - 1), seq_at(i), seq_at(i + room - 1))
                closed = self._close('overflow')
                if closed is not None:
                    out.append(closed)
                i += room

    def push(self, block: EncoderBlockData) -> StreamUpdate:
        """Analyse one block; never raises on bad data (see the module docstring).

        Args:
            block: The next block of the stream.

        Returns:
            Decimated TE of the block, windows closed, gap events.
        """
        windows: list[WindowResult] = list(self._pending)
        self._pending.clear()
        gaps: list[GapEvent] = []
        return self._push_one(block, windows, gaps)

    def push_batch(self, batch: EncoderBatch) -> BatchUpdate:
        """Analyse consecutive blocks at once; the same result as pushing them one by one.

        Windows, gaps, counters and statistics equal those of :meth:`push` over
        ``batch.block(0)``, ``batch.block(1)``, ... (cumulative statistics to rounding); the
        decimated display TE is not produced. Runs of clean, continuous blocks are analysed
        as one array; a block with a problem, or one that breaks the continuity, goes
        through :meth:`push` on its own. Never raises on bad data.

        Args:
            batch: The next blocks of the stream.

        Returns:
            Windows closed and gap events.
        """
        windows: list[WindowResult] = list(self._pending)
        self._pending.clear()
        gaps: list[GapEvent] = []
        bad, breaks, t_first, t_last = _batch_flags(batch)
        special = np.flatnonzero(bad | breaks)
        seq = np.asarray(batch.seq, dtype=np.int64)
        n_blocks = seq.size
        k = 0
        while k < n_blocks:
            if bad[k] or (int(seq[k]) != (0 if self._last_seq is None else self._last_seq + 1)) \
                    or (self._last_t is not None and not float(t_first[k]) > self._last_t):
                self._push_one(batch.block(k), windows, gaps)
                k += 1
                continue
            nxt = int(np.searchsorted(special, k, side='right'))
            end = int(special[nxt]) if nxt < special.size else n_blocks
            self._push_run(batch, k, end, t_last, windows)
            k = end
        return BatchUpdate(tuple(windows), tuple(gaps))

    def _push_run(self, batch: EncoderBatch, k0: int, k1: int, t_last: np.ndarray,
                  windows: list[WindowResult]) -> None:
        """Blocks k0..k1-1 of ``batch``: clean and continuous (checked by the caller)."""
        starts = np.asarray(batch.starts, dtype=np.intp)
        a, b = int(starts[k0]), int(starts[k1])
        phi, te = output_phase_and_te(batch.theta_in_rad[a:b], batch.theta_out_rad[a:b],
                                      gear_ratio=self._config.gear_ratio, check=False)
        self._counters['blocks'] += k1 - k0
        rel = starts[k0:k1 + 1] - a
        # angle travelled: within each block first -> last, and between blocks (as push does)
        ends = np.empty(2 * (k1 - k0))
        ends[0::2] = phi[rel[:-1]]
        ends[1::2] = phi[rel[1:] - 1]
        travelled = float(np.abs(np.diff(ends)).sum())
        if self._last_phi is not None:
            travelled += abs(float(ends[0]) - self._last_phi)
        self._cum_rev += travelled
        self._last_phi = float(phi[-1])
        seq = batch.seq
        stamp = batch.stamp_s
        offs = batch.time_offset_s
        self._last_seq = int(seq[k1 - 1])
        self._last_t = float(t_last[k1 - 1])
        if self._t_first is None:
            self._t_first = float(stamp[k0] + offs[a])
        self._counters['samples'] += b - a

        def block_of(i: int) -> int:
            return k0 + int(np.searchsorted(rel, i, side='right')) - 1

        def time_at(i: int) -> float:
            return float(stamp[block_of(i)] + offs[a + i])

        def seq_at(i: int) -> int:
            return int(seq[block_of(i)])

        self._feed(phi, te, time_at, seq_at, windows)
        # the decimation phase moves on as if the blocks had been pushed one by one
        rates = np.asarray(batch.sample_rate_hz[k0:k1], dtype=np.float64)
        q = np.maximum(1, np.round(rates / self._config.decimated_rate_hz)).astype(np.int64)
        if (q == q[0]).all():
            self._decim_offset = (self._decim_offset - (b - a)) % int(q[0])
        else:
            for q_k, n_k in zip(q.tolist(), np.diff(rel).tolist(), strict=True):
                self._decim_offset = (self._decim_offset % q_k - n_k) % q_k

    def _push_one(self, block: EncoderBlockData, windows: list[WindowResult],
                  gaps: list[GapEvent]) -> StreamUpdate:
        self._counters['blocks'] += 1
        clean = _normalize(block)
        if isinstance(clean, _Problem):
            seq = getattr(block, 'seq', -1)
            seq_int = int(seq) if isinstance(seq, int | np.integer) \
                and not isinstance(seq, bool) else -1
            self._gap(gaps, clean.kind, seq_int, clean.detail)
            self._counters['dropped_blocks'] += 1
            self._end_stretch(windows)
            if seq_int >= 0:
                self._last_seq = seq_int
            return StreamUpdate(math.nan, _EMPTY, _EMPTY, tuple(windows), tuple(gaps))
        seq, t, theta_in, theta_out, rate = clean
        n_gaps = len(gaps)   # (push_batch passes one list for all its blocks)
        if self._t_first is None:
            self._t_first = float(t[0])
        if self._last_seq is not None and seq != self._last_seq + 1:
            self._seq_jump(gaps, seq, float(t[0]), rate)
        elif self._last_seq is None and seq > 0:
            # a bench numbers its blocks from 0: the first ones went by before this stream
            # began (a recorder or TE node started late, a bag cut at the front)
            self._gap(gaps, 'leading_loss', seq,
                      f'the first {seq} block(s) (seq 0-{seq - 1}) are missing: '
                      'recording/analysis started after the bench')
        if self._last_t is not None and t[0] <= self._last_t:
            self._gap(gaps, 'time_backwards', seq,
                      f'block seq {seq} starts at {t[0]!r} s, not after {self._last_t!r} s')
        if len(gaps) > n_gaps:
            self._end_stretch(windows)
        self._last_seq = seq
        self._last_t = float(t[-1])
        config = self._config
        buf = self._buf
        n = theta_in.size
        n0 = buf.n
        in_place = n0 + n <= buf.phi.size and n0 + n <= config.max_window_samples
        # Wang 2020 Eq. 22, straight into the window buffer when the block fits (no copy)
        phi, te = output_phase_and_te(
            theta_in, theta_out, gear_ratio=config.gear_ratio, check=False,
            out=(buf.phi[n0:n0 + n], buf.te[n0:n0 + n]) if in_place else None)
        phi_first, phi_last = float(phi[0]), float(phi[-1])
        self._cum_rev += abs(phi_last - phi_first)
        if self._last_phi is not None:
            self._cum_rev += abs(phi_first - self._last_phi)
        self._last_phi = phi_last
        self._counters['samples'] += n
        if in_place and _first_reach(phi, phi_first if n0 == 0 else float(buf.phi[0]),
                                     _TWO_PI * config.window_revolutions) < 0:
            buf.take(n, float(t[0]), float(t[-1]), seq, seq)   # the window goes on
        else:
            if in_place:   # a window ends in this block: _feed closes it and appends
                phi, te = phi.copy(), te.copy()
            self._feed(phi, te, lambda i: float(t[i]), lambda _i: seq, windows)
        q = max(1, round(rate / config.decimated_rate_hz))
        start = self._decim_offset % q
        te_d, phi_d, t_d = te[start::q].copy(), phi[start::q].copy(), t[start::q].copy()
        te_d.setflags(write=False)
        phi_d.setflags(write=False)
        t_d.setflags(write=False)
        self._decim_offset = (start - n) % q
        # positional: stamp_s, te_rad, phase_out_rad, windows, gaps, time_s, period_s
        return StreamUpdate(float(t_d[0]) if t_d.size else math.nan, te_d, phi_d,
                            tuple(windows), tuple(gaps), t_d, q / rate)

    def _seq_jump(self, gaps: list[GapEvent], seq: int, t_after: float, rate: float) -> None:
        """A seq jump, with where it is in the record and how long it lasted."""
        assert self._last_seq is not None
        gap = seq_jump_event(self._last_seq + 1, seq, self._last_t, t_after, rate,
                             self._t_first)
        gaps.append(gap)
        self._counters['gaps'] += 1
        self._counters['seq_jumps'] += 1

    def _end_stretch(self, windows: list[WindowResult]) -> None:
        """A gap: close the open window as partial and forget continuity."""
        closed = self._close('gap')
        if closed is not None:
            windows.append(closed)
        self._last_phi = None
        self._decim_offset = 0


def analyze_blocks(blocks: Iterable[EncoderBlockData | EncoderBatch], config: TeAnalysisConfig,
                   *, on_window: Callable[[WindowResult], None] | None = None,
                   spectra_thread: bool | Executor = False) -> OfflineResult:
    """Run a whole recording through a :class:`StreamingTeAnalyzer` (offline analysis).

    Args:
        blocks: The blocks (or batches of consecutive blocks) in recording order.
        config: Analysis settings.
        on_window: Called with each window as it closes; the windows are then not kept
            (memory stays bounded by one window however long the recording).
        spectra_thread: Compute the window spectra on a second thread while the next
            blocks are analysed (the resampler and the FFT run without the GIL), and here
            while that thread is busy. The windows, their order, the spectra and the
            counters are the same as without; the thread holds one window's phi and TE
            arrays besides the open window's, and at most :data:`SPECTRA_AHEAD` closed
            windows wait behind it. An executor instead of True: its (one) worker thread
            is that thread, shared with the caller's other jobs (such as reading the bag
            ahead); it is not shut down here. Two cores run the caller and one helper
            thread without preempting either (a third runnable thread costs the caller
            CPU time: issue 23, 6-14 % less wall time with one shared helper).

    Returns:
        All windows (the last, partial one from the final flush; none with ``on_window``),
        cumulative statistics, counters and gap events.
    """
    analyzer = StreamingTeAnalyzer(config)
    windows: list[WindowResult] = []
    gaps: list[GapEvent] = []
    keep = windows.extend if on_window is None else (lambda ws: [on_window(w) for w in ws])
    threaded = spectra_thread is not False and config.compute_spectrum
    shared = spectra_thread if isinstance(spectra_thread, Executor) else None
    with _SpectraThread(analyzer, keep, shared) if threaded \
            else contextlib.nullcontext() as spectra:
        closed = keep if spectra is None else spectra.closed
        for item in blocks:
            update = analyzer.push_batch(item) if isinstance(item, EncoderBatch) \
                else analyzer.push(item)
            closed(update.windows)
            gaps.extend(update.gaps)
        closed(analyzer.flush())
        if spectra is not None:
            spectra.drain()
    return OfflineResult(windows=tuple(windows), cumulative=analyzer.cumulative,
                         counters=analyzer.counters, gaps=tuple(gaps))


#: Closed windows of an offline analysis that may wait (in order) behind the one whose
#: spectrum is on the spectra thread.
SPECTRA_AHEAD = 4


class _SpectraThread:
    """The window spectra of :func:`analyze_blocks`, shared by a worker thread and the caller.

    A complete window's spectrum goes to the worker thread when the thread is free, with
    the window's phi and TE arrays (the window buffer gets the arrays of the thread's
    previous window, which is done: nothing is copied); while the thread is busy, the
    calling thread computes the spectrum itself (the same call, the same values), so the
    cores share the spectra as they are free (3-4 % less wall time than every spectrum on
    the thread, measured side by side). :meth:`closed` hands the windows on in closing
    order; at most SPECTRA_AHEAD wait behind the one on the thread. A spectrum that fails
    counts in ``spectrum_failures`` and leaves the window without one, as the analyzer
    does itself. The worker is a thread of its own, or the one of an executor the caller
    shares (left running on exit: only this analysis's pending spectra are cancelled, and
    the one running is waited for).
    """

    def __init__(self, analyzer: StreamingTeAnalyzer,
                 keep: Callable[[list[WindowResult]], object],
                 shared: Executor | None = None) -> None:
        from concurrent.futures import ThreadPoolExecutor

        self._analyzer = analyzer
        self._keep = keep
        self._own = shared is None
        self._pool: Executor = shared if shared is not None else ThreadPoolExecutor(
            max_workers=1, thread_name_prefix='te-spectra')
        self._work = SpectrumWorkspace()            # used by the worker thread only
        self._jobs: dict[int, Future[OrderSpectrum]] = {}   # window index -> its spectrum
        self._on_thread: Future[OrderSpectrum] | None = None   # the thread's latest job
        self._thread_arrays: tuple[np.ndarray, np.ndarray] | None = None   # ... its arrays
        self._queue: deque[WindowResult] = deque()
        analyzer._spectrum_hook = self._submit

    def __enter__(self) -> _SpectraThread:
        return self

    def __exit__(self, *exc: object) -> None:
        self._analyzer._spectrum_hook = None
        if self._own:
            self._pool.shutdown(wait=True, cancel_futures=True)
            return
        from concurrent.futures import wait

        wait([job for job in self._jobs.values() if not job.cancel()])

    def _submit(self, index: int, buf: _WindowBuffer) -> None:
        """The window's spectrum: to the thread if it is free, else computed here."""
        ana = self._analyzer
        n = buf.n
        duration_s = buf.t_last - buf.t_first
        if self._on_thread is not None and not self._on_thread.done():
            job: Future[OrderSpectrum] = Future()
            try:   # with the caller's own workspace
                job.set_result(ana._window_spectrum(
                    buf.phi[:n], buf.te[:n], duration_s, ana._spectrum_work))
            except TeInputError as exc:
                job.set_exception(exc)
            self._jobs[index] = job
            return
        # the thread is free: its previous window's arrays are free too
        phi, te = buf.phi, buf.te
        spare = self._thread_arrays
        buf.phi, buf.te = (spare if spare is not None and spare[0].size == phi.size
                           else (np.empty_like(phi), np.empty_like(te)))
        self._thread_arrays = (phi, te)
        self._on_thread = self._jobs[index] = self._pool.submit(
            ana._window_spectrum, phi[:n], te[:n], duration_s, self._work)

    def closed(self, windows: Iterable[WindowResult]) -> None:
        """Queue closed windows; hand on those at the head whose spectrum is done."""
        self._queue.extend(windows)
        ready = []
        while self._queue:
            job = self._jobs.get(self._queue[0].index)
            if job is not None and not job.done() and len(self._queue) <= SPECTRA_AHEAD:
                break
            ready.append(self._finish(self._queue.popleft()))
        if ready:
            self._keep(ready)

    def drain(self) -> None:
        """Wait for every pending spectrum and hand on the rest of the windows."""
        if self._queue:
            self._keep([self._finish(w) for w in self._queue])
            self._queue.clear()

    def _finish(self, window: WindowResult) -> WindowResult:
        job = self._jobs.pop(window.index, None)
        if job is None:
            return window
        try:
            spectrum = job.result()
        except TeInputError:
            self._analyzer._counters['spectrum_failures'] += 1
            return window
        return replace(window, spectrum=spectrum)
