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
array, with the same windows, gaps and counters as block by block. The offline runner
(:func:`rv_te_bench.core.offline.analyze_blocks`: a whole recording, windows to a
callback, the window spectra on a helper thread) is a module of its own, and so are the
record types (:mod:`rv_te_bench.core.stream_records`, re-exported here: the analyzer
takes and returns them).

A bench numbers its blocks from 0, so a first block with a seq above 0 is a gap too
(``'leading_loss'``: a recorder or TE node that started after the bench lost the blocks before
it).

Not detected as gaps: a forward jump in time between blocks with consecutive sequence
numbers (the DAQ clock is trusted) and a jump of the encoder angles themselves (e.g. a
re-zeroed counter); both show up in the window statistics.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.spectrum import OrderSpectrum, SpectrumWorkspace, order_spectrum
from rv_te_bench.core.stream_records import (
    BatchUpdate,
    BlockProblem,
    CloseReason,
    EncoderBatch,
    EncoderBlockData,
    GapEvent,
    GapKind,
    OfflineResult,
    StreamUpdate,
    TeAnalysisConfig,
    WindowResult,
    check_block,
    seq_jump_event,
)
from rv_te_bench.core.te import RunningStats, TeStats, moments_of_finite, output_phase_and_te
from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.core.envelope import MinMaxEnvelope

__all__ = ['BatchUpdate', 'EncoderBatch', 'EncoderBlockData', 'GapEvent', 'OfflineResult',
           'StreamUpdate', 'StreamingTeAnalyzer', 'TeAnalysisConfig', 'WindowBuffer',
           'WindowResult', 'seq_jump_event']

_TWO_PI = 2.0 * math.pi
_EMPTY = np.empty(0, dtype=np.float64)
_EMPTY.setflags(write=False)
_INITIAL_CAPACITY = 1 << 16
_SCAN_PIECE = 1 << 16  # samples examined at a time when looking for a window's end


class WindowBuffer:
    """Growable (up to a cap) buffers of phi and TE of the open window.

    A spectrum hook (:meth:`StreamingTeAnalyzer.set_spectrum_hook`) gets it with a complete
    window and may take its ``phi`` / ``te`` arrays, giving it others of the same size.
    """

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
        self.reserve(need)
        self.phi[self.n:need] = phi
        self.te[self.n:need] = te
        if self.n == 0:
            self.t_first = t_first
            self.first_seq = seq_first
        self.t_last = t_last
        self.last_seq = seq_last
        self.n = need

    def reserve(self, need: int) -> None:
        """Room for ``need`` samples (at most the cap), the window's samples kept."""
        if need > self.phi.size:
            cap = min(max(need, 2 * self.phi.size), self.cap)
            self.phi = np.concatenate([self.phi[:self.n], np.empty(cap - self.n)])
            self.te = np.concatenate([self.te[:self.n], np.empty(cap - self.n)])

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
            # a NaN or inf makes its block's sum non-finite (as in check_block)
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
        # the last read, see cumulative: (accumulator, samples, angle travelled, statistics)
        self._cum_key: tuple[RunningStats | None, int, float, TeStats | None] = (
            None, 0, 0.0, None)
        self._buf = WindowBuffer(config.max_window_samples)
        self._spectrum_work = SpectrumWorkspace()   # the window spectra's work arrays
        # set_spectrum_hook: called with (window index, window buffer) instead of computing
        # a complete window's spectrum here; it may take the buffer's arrays (and give it
        # others of the same size)
        self._spectrum_hook: Callable[[int, WindowBuffer], None] | None = None
        self._envelope: MinMaxEnvelope | None = None   # set_envelope
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
        if key[0] is cum and key[1] == cum.n_samples and key[2] == self._cum_rev \
                and key[3] is not None:
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
        if self._envelope is not None:
            self._envelope.gap()
        if reset_cumulative is None:
            reset_cumulative = config.gear_ratio != self._config.gear_ratio
        if reset_cumulative:
            self._cum = RunningStats()
            self._cum_folded = 0
            self._cum_rev = 0.0
        if config.max_window_samples != self._config.max_window_samples:
            self._buf = WindowBuffer(config.max_window_samples)
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

    def set_spectrum_hook(self, hook: Callable[[int, WindowBuffer], None] | None) -> None:
        """Hand each complete window's spectrum to ``hook(window index, window buffer)``
        instead of computing it here (None: compute it here again).

        The offline runner's helper thread (:func:`rv_te_bench.core.offline.analyze_blocks`)
        computes it with :meth:`window_spectrum` and puts it into the window it hands on;
        a hook that fails to compute one calls :meth:`count_spectrum_failure`.
        """
        self._spectrum_hook = hook

    def set_envelope(self, envelope: MinMaxEnvelope | None) -> None:
        """Fill ``envelope`` with every clean sample's TE, window by window, as windows close
        (in the pass that finds each window's min and max; a gap starts a new segment).
        None: no envelope (the live TE node's default)."""
        self._envelope = envelope

    @property
    def spectrum_workspace(self) -> SpectrumWorkspace:
        """The work arrays of the spectra computed on the analyzer's own thread."""
        return self._spectrum_work

    def count_spectrum_failure(self) -> None:
        """Count a complete window whose spectrum could not be computed (``counters``)."""
        self._counters['spectrum_failures'] += 1

    def window_spectrum(self, phi: np.ndarray, te: np.ndarray, duration_s: float,
                        workspace: SpectrumWorkspace) -> OrderSpectrum:
        """The order spectrum of a complete window under the configuration in use.

        Raises:
            TeInputError: As :func:`~rv_te_bench.core.spectrum.order_spectrum` (a window
                whose angle grid cannot be resampled).
        """
        cfg = self._config
        return order_spectrum(phi, te, cfg.orders, duration_s=duration_s,
                              samples_per_rev=cfg.samples_per_rev,
                              revolutions=round(cfg.window_revolutions), workspace=workspace)

    def split_window(self) -> None:
        """Close the open window as partial (``close_reason='heads'``, no spectrum) before
        samples whose shaft angle comes from another set of read heads (a head missing in
        some blocks, :mod:`rv_te_bench.core.head_combine`): the scale error left in the TE
        changes there, and no spectrum mixes the two. Nothing is lost, continuity is kept
        (no gap is counted); the closed window comes with the next push's windows."""
        self._close('heads', pending=True)

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
        env = self._envelope
        moments = moments_of_finite(te, scratch=buf.scratch(),
                                    min_max=None if env is None else env.add(phi, te))
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
                    spectrum = self.window_spectrum(phi, te, buf.t_last - buf.t_first,
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

    def _feed_in_place(self, phi: np.ndarray, te: np.ndarray,
                       time_at: Callable[[int], float], seq_at: Callable[[int], int],
                       out: list[WindowResult]) -> None:
        """As :meth:`_feed` for samples already written past the end of the window buffer
        (``phi`` and ``te`` are ``buf.phi[n:n + m]`` and ``buf.te[n:n + m]``, all within
        the cap): taken in where the window goes on; from the first sample that ends it,
        the rest is copied out (closing may hand the buffer's arrays to the spectra
        thread) and goes through :meth:`_feed`."""
        buf = self._buf
        m = phi.size
        if m == 0:
            return
        start = float(phi[0]) if buf.n == 0 else float(buf.phi[0])
        j = _first_reach(phi, start, _TWO_PI * self._config.window_revolutions)
        if j < 0:
            buf.take(m, time_at(0), time_at(m - 1), seq_at(0), seq_at(m - 1))
            return
        rest_phi, rest_te = phi[j:].copy(), te[j:].copy()
        if j > 0:
            buf.take(j, time_at(0), time_at(j - 1), seq_at(0), seq_at(j - 1))
        closed = self._close('complete')
        if closed is not None:
            out.append(closed)
        self._feed(rest_phi, rest_te, lambda i: time_at(j + i), lambda i: seq_at(j + i), out)

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
        buf = self._buf
        n0 = buf.n
        # Wang 2020 Eq. 22 straight into the window buffer when the run fits (no copy)
        in_place = n0 + (b - a) <= self._config.max_window_samples
        if in_place:
            buf.reserve(n0 + (b - a))
        phi, te = output_phase_and_te(
            batch.theta_in_rad[a:b], batch.theta_out_rad[a:b],
            gear_ratio=self._config.gear_ratio, check=False,
            out=(buf.phi[n0:n0 + b - a], buf.te[n0:n0 + b - a]) if in_place else None)
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

        if in_place:
            self._feed_in_place(phi, te, time_at, seq_at, windows)
        else:
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
        clean = check_block(block)
        if isinstance(clean, BlockProblem):
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
        if self._envelope is not None:
            self._envelope.gap()
        self._last_phi = None
        self._decim_offset = 0
