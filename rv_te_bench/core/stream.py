"""Streaming TE analysis: encoder blocks in, decimated TE and whole-revolution windows out.

A :class:`StreamingTeAnalyzer` takes the blocks an encoder DAQ (or the simulated bench, or a
bag) delivers, computes TE = theta_out - theta_in / i (Eq. 22, :mod:`rv_te_bench.core.te`)
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

Not detected as gaps: a forward jump in time between blocks with consecutive sequence
numbers (the DAQ clock is trusted) and a jump of the encoder angles themselves (e.g. a
re-zeroed counter); both show up in the window statistics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.spectrum import OrderSpectrum, order_spectrum
from rv_te_bench.core.te import RunningStats, TeStats, te_statistics
from rv_te_bench.errors import TeConfigError, TeInputError

if TYPE_CHECKING:
    from collections.abc import Iterable

__all__ = ['EncoderBlockData', 'GapEvent', 'OfflineResult', 'StreamUpdate',
           'StreamingTeAnalyzer', 'TeAnalysisConfig', 'WindowResult', 'analyze_blocks']

GapKind = Literal['seq_jump', 'time_backwards', 'non_finite', 'malformed']
CloseReason = Literal['complete', 'gap', 'overflow', 'flush', 'reconfigure']

_TWO_PI = 2.0 * math.pi
_EMPTY = np.empty(0, dtype=np.float64)
_EMPTY.setflags(write=False)
_INITIAL_CAPACITY = 1 << 16
_MIN_WINDOW_SAMPLES = 16


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
                time_offset_s: Any, theta_in_rad: Any, theta_out_rad: Any,  # noqa: ANN401
                torque_out_nm: Any = ()) -> EncoderBlockData:  # noqa: ANN401
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


@dataclass(frozen=True)
class _Clean:
    seq: int
    t_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    sample_rate_hz: float


def _normalize(block: Any) -> _Clean | _Problem:  # noqa: ANN401, C901, PLR0911, PLR0912
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
    with np.errstate(over='ignore', invalid='ignore'):
        totals = [float(np.add.reduce(a)) for a in (offs, th_in, th_out)]
    for name, arr, total in zip(('time_offset_s', 'theta_in_rad', 'theta_out_rad'),
                                (offs, th_in, th_out), totals, strict=True):
        if not math.isfinite(total):
            bad_idx = np.flatnonzero(~np.isfinite(arr))
            if bad_idx.size:
                bad = int(bad_idx[0])
                return _Problem('non_finite', f'{where}: {name}[{bad}] is {float(arr[bad])!r}')
            return _Problem('malformed', f'{where}: {name} values out of range (|x| > 1e300)')
    if n > 1 and not (offs[1:] > offs[:-1]).all():
        return _Problem('malformed', f'{where}: time_offset_s not strictly increasing')
    return _Clean(int(seq), offs + stamp, th_in, th_out, rate)


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
        detail: Human-readable description naming the problem.
    """

    kind: GapKind
    seq: int
    detail: str


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
class OfflineResult:
    """Result of :func:`analyze_blocks`.

    Attributes:
        windows: Every window closed, the last one by the final flush.
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

    __slots__ = ('cap', 'first_seq', 'last_seq', 'n', 'phi', 't_first', 't_last', 'te')

    def __init__(self, cap: int) -> None:
        self.cap = cap
        self.phi = np.empty(min(_INITIAL_CAPACITY, cap))
        self.te = np.empty(min(_INITIAL_CAPACITY, cap))
        self.n = 0
        self.t_first = math.nan
        self.t_last = math.nan
        self.first_seq = -1
        self.last_seq = -1

    def append(self, phi: np.ndarray, te: np.ndarray, t_first: float, t_last: float,
               seq: int) -> None:
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
            self.first_seq = seq
        self.t_last = t_last
        self.last_seq = seq
        self.n = need

    def clear(self) -> None:
        # the capacity is kept (the next window is about as long; bounded by the cap)
        self.n = 0


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


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
        self._cum = RunningStats()
        self._cum_rev = 0.0
        self._buf = _WindowBuffer(config.max_window_samples)
        self._pending: list[WindowResult] = []
        self._last_seq: int | None = None
        self._last_t: float | None = None
        self._last_phi: float | None = None
        self._decim_offset = 0
        self._n_windows = 0
        self._counters = dict.fromkeys(
            ('blocks', 'samples', 'gaps', 'malformed', 'non_finite', 'seq_jumps',
             'time_backwards', 'dropped_blocks', 'windows', 'complete_windows',
             'spectrum_failures'), 0)

    @property
    def config(self) -> TeAnalysisConfig:
        """The configuration in use."""
        return self._config

    @property
    def cumulative(self) -> TeStats:
        """Statistics over every clean sample since the start (or the last reset).

        ``revolutions`` is the output angle travelled over clean, contiguous data.
        """
        return self._cum.stats(revolutions=self._cum_rev / _TWO_PI)

    @property
    def counters(self) -> dict[str, int]:
        """Counts: blocks, samples (clean), gaps (events), malformed, non_finite, seq_jumps,
        time_backwards, dropped_blocks (malformed + non_finite), windows, complete_windows,
        spectrum_failures (complete windows whose angle grid could not be resampled)."""  # noqa: D205, D209
        return dict(self._counters)

    def reconfigure(self, config: TeAnalysisConfig, *, reset_cumulative: bool | None = None) -> None:
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
                   'non_finite': 'non_finite', 'malformed': 'malformed'}[kind]
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
        if complete:
            stats = te_statistics(te, revolutions=w_rev)
            if self._config.compute_spectrum:
                try:
                    spectrum = order_spectrum(
                        phi, te, self._config.orders, duration_s=buf.t_last - buf.t_first,
                        samples_per_rev=self._config.samples_per_rev,
                        revolutions=round(w_rev))
                except TeInputError:
                    spectrum = None
                    self._counters['spectrum_failures'] += 1
        else:
            stats = te_statistics(te, revolutions=abs(float(phi[-1] - phi[0])) / _TWO_PI)
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

    def _feed(self, phi: np.ndarray, te: np.ndarray, t: np.ndarray, seq: int,
              out: list[WindowResult]) -> None:
        """Append clean samples to windows, closing those that reach W revolutions."""
        buf = self._buf
        bound = _TWO_PI * self._config.window_revolutions
        cap = self._config.max_window_samples
        n = phi.size
        i = 0
        while i < n:
            phi_start = float(phi[i]) if buf.n == 0 else float(buf.phi[0])
            rest = phi[i:]
            j = -1
            if (float(np.maximum.reduce(rest)) - phi_start >= bound
                    or phi_start - float(np.minimum.reduce(rest)) >= bound):
                reached = np.abs(rest - phi_start) >= bound
                j = int(reached.argmax())
            room = cap - buf.n
            if j >= 0 and j <= room:
                buf.append(phi[i:i + j], te[i:i + j], float(t[i]), float(t[i + j - 1]), seq)
                closed = self._close('complete')
                if closed is not None:
                    out.append(closed)
                i += j
            elif j < 0 and n - i <= room:
                buf.append(phi[i:], te[i:], float(t[i]), float(t[-1]), seq)
                i = n
            else:
                if room > 0:
                    buf.append(phi[i:i + room], te[i:i + room], float(t[i]),
                               float(t[i + room - 1]), seq)
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
        self._counters['blocks'] += 1
        windows: list[WindowResult] = list(self._pending)
        self._pending.clear()
        gaps: list[GapEvent] = []
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
        seq, t = clean.seq, clean.t_s
        if self._last_seq is not None and seq != self._last_seq + 1:
            self._gap(gaps, 'seq_jump', seq, f'expected seq {self._last_seq + 1}, got {seq}')
        if self._last_t is not None and t[0] <= self._last_t:
            self._gap(gaps, 'time_backwards', seq,
                      f'block seq {seq} starts at {t[0]!r} s, not after {self._last_t!r} s')
        if gaps:
            self._end_stretch(windows)
        self._last_seq = seq
        self._last_t = float(t[-1])
        ratio = self._config.gear_ratio
        phi = clean.theta_in_rad / ratio
        te = clean.theta_out_rad - phi
        self._cum.update(te)
        self._cum_rev += abs(float(phi[-1] - phi[0]))
        if self._last_phi is not None:
            self._cum_rev += abs(float(phi[0]) - self._last_phi)
        self._last_phi = float(phi[-1])
        self._counters['samples'] += phi.size
        self._feed(phi, te, t, seq, windows)
        q = max(1, round(clean.sample_rate_hz / self._config.decimated_rate_hz))
        start = self._decim_offset % q
        idx = slice(start, None, q)
        te_d, phi_d, t_d = te[idx].copy(), phi[idx].copy(), t[idx].copy()
        self._decim_offset = (start - phi.size) % q
        return StreamUpdate(
            stamp_s=float(t_d[0]) if t_d.size else math.nan, te_rad=_readonly(te_d),
            phase_out_rad=_readonly(phi_d), windows=tuple(windows), gaps=tuple(gaps),
            time_s=_readonly(t_d), period_s=q / clean.sample_rate_hz)

    def _end_stretch(self, windows: list[WindowResult]) -> None:
        """A gap: close the open window as partial and forget continuity."""
        closed = self._close('gap')
        if closed is not None:
            windows.append(closed)
        self._last_phi = None
        self._decim_offset = 0


def analyze_blocks(blocks: Iterable[EncoderBlockData], config: TeAnalysisConfig) -> OfflineResult:
    """Run a whole recording through a :class:`StreamingTeAnalyzer` (offline analysis).

    Args:
        blocks: The blocks in recording order.
        config: Analysis settings.

    Returns:
        All windows (the last, partial one from the final flush), cumulative statistics,
        counters and gap events.
    """
    analyzer = StreamingTeAnalyzer(config)
    windows: list[WindowResult] = []
    gaps: list[GapEvent] = []
    for block in blocks:
        update = analyzer.push(block)
        windows.extend(update.windows)
        gaps.extend(update.gaps)
    windows.extend(analyzer.flush())
    return OfflineResult(windows=tuple(windows), cumulative=analyzer.cumulative,
                         counters=analyzer.counters, gaps=tuple(gaps))
