"""Unwrapping each angle channel, also across a drop-out, or splitting the record there.

Within continuous data a channel that is not a multi-turn counter is unwrapped as
``numpy.unwrap`` does: a step of more than half a turn between two samples is a wrap of a
single-turn encoder (this needs less than half a turn per sample: input speed below
``30 * sample_rate_hz`` rpm, true of every TE bench).

Across a drop-out (:class:`~._convert.Break`) nothing is guessed:

* a **multi-turn** channel (``multi``, or ``auto`` whose readings span more than one turn)
  keeps its recorded advance: the counter counted through the drop-out;
* a **single-turn** channel (``single``, or ``auto`` otherwise) only knows its angle modulo
  a turn after the drop-out. The advance is predicted from the speed before (a least-squares
  slope over the last :data:`SPEED_WINDOW_S`) and the speed after (the first
  :data:`SPEED_WINDOW_S` after it), each widened by three standard errors. The whole number
  of turns is taken when exactly one candidate advance lies within half a turn of every
  predicted one. Otherwise the turn count is ambiguous (a long drop-out at a changing
  speed): the record is **split** there, and what follows is a new segment (a bag of its
  own) whose angles continue as recorded.

Every drop-out becomes an :class:`ImportGap` (time, length, samples, the advance of each
channel and how it was found); the pieces of data come out as :class:`Piece` s in order.
Memory: the data after a drop-out is held until :data:`SPEED_WINDOW_S` of it is read.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

if TYPE_CHECKING:
    import numpy.typing as npt

    from rv_te_bench.io.importers._convert import Break, SiChunk

__all__ = ['SPEED_WINDOW_S', 'ImportGap', 'Piece', 'TurnStitcher']

#: Time over which the speed before and after a drop-out is fitted [s].
SPEED_WINDOW_S = 0.2
_MAX_SPEED_SAMPLES = 4096
_TWO_PI = 2.0 * math.pi
Turns = Literal['auto', 'single', 'multi']
How = Literal['counter', 'speed', 'ambiguous']


@dataclass(frozen=True)
class ImportGap:
    """A drop-out of the imported record (SI units).

    Attributes:
        reason: ``time_step``, ``time_backwards`` or ``non_finite``.
        t_before_s: Last good sample before it [s since the first sample of the file].
        t_after_s: First good sample after it [s].
        missing_s: Time with no data: ``t_after - t_before - 1 / rate`` [s].
        samples_dropped: Samples in the file that were not used (bad time or angle).
        samples_missing: Samples the times say are missing (not in the file).
        where: Where in the file it begins (``line N`` / ``sample N``).
        advance_in_rev: Input advance across it [rev] (NaN when ambiguous).
        advance_out_rev: Output advance across it [rev] (NaN when ambiguous).
        how_in: ``counter`` (multi-turn, as recorded), ``speed`` (single-turn, turns from
            the speed before and after) or ``ambiguous`` (split).
        how_out: Likewise for the output.
        split: The turn count was ambiguous: a new segment starts after it.
    """

    reason: str
    t_before_s: float
    t_after_s: float
    missing_s: float
    samples_dropped: int
    samples_missing: int
    where: str
    advance_in_rev: float
    advance_out_rev: float
    how_in: How
    how_out: How
    split: bool

    def describe(self) -> str:
        """One line: where, how long, why, and how the turns were found."""
        why = {'time_step': 'time step', 'time_backwards': 'time going backwards',
               'non_finite': 'non-finite values'}.get(self.reason, self.reason)
        turns = []
        for role, adv, how in (('input', self.advance_in_rev, self.how_in),
                               ('output', self.advance_out_rev, self.how_out)):
            if how == 'ambiguous':
                turns.append(f'{role} turns ambiguous')
            elif how == 'speed':
                turns.append(f'{role} {adv:.4g} rev from its speed')
        tail = f'; {", ".join(turns)}' if turns else ''
        split = '; the record is split: a new segment starts here' if self.split else ''
        dropped = f', {self.samples_dropped} dropped' if self.samples_dropped else ''
        return (f'drop-out at {self.t_before_s:.6g} s ({self.where}): {self.missing_s:.6g} s '
                f'without data ({why}; {self.samples_missing} samples missing{dropped})'
                f'{tail}{split}')

    def to_json_dict(self) -> dict[str, object]:
        """JSON-friendly dict (NaN -> None)."""
        out: dict[str, object] = {}
        for k, v in self.__dict__.items():
            out[k] = None if isinstance(v, float) and not math.isfinite(v) else v
        return out


@dataclass(frozen=True)
class Piece:
    """Good samples to write, unwrapped; ``gap`` is the drop-out before them (None: they
    continue the previous piece); ``new_segment``: they start a new segment;
    ``theta_out_heads_rad``: the output scale's further heads (N-1, n), unwrapped (NaN
    where a head had no reading), or None."""

    t_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_out_nm: np.ndarray
    gap: ImportGap | None = None
    new_segment: bool = False
    theta_out_heads_rad: np.ndarray | None = None
    loss: np.ndarray | None = None     # (2, n): input torque [N m], case temperature [degC]


def heads_beside(raw_heads: np.ndarray, raw_out: np.ndarray, out_rad: np.ndarray,
                 ) -> np.ndarray:
    """Further heads of one scale unwrapped beside head 0: each head reads the same shaft
    within arcseconds (plus its constant zero), so its turn is head 0's: ``x_j = x_0 +
    wrap(r_j - r_0)`` with wrap to [-pi, pi). A missing reading (NaN) stays missing; no
    state is needed across drop-outs."""
    d = raw_heads - raw_out[None, :]
    heads: npt.NDArray[np.float64] = out_rad[None, :] + (np.mod(d + math.pi, _TWO_PI)
                                                         - math.pi)
    return heads


def _slope(t: np.ndarray, x: np.ndarray) -> tuple[float, float] | None:
    """Least-squares slope of x(t) and its standard error (None with < 2 samples)."""
    if t.size < 2:
        return None
    tc = t - t.mean()
    sxx = float(tc @ tc)
    if not sxx > 0:
        return None
    xc = x - x.mean()
    v = float(tc @ xc) / sxx
    if t.size < 3:
        return v, 0.0
    r = xc - v * tc
    return v, math.sqrt(float(r @ r) / (t.size - 2) / sxx)


def _wrap_turns(x: np.ndarray, prev: float) -> np.ndarray | int:
    """Whole turns (int64, cumulative) that unwrap ``x`` after the reading ``prev``:
    numpy.unwrap's rule (a step beyond half a turn), counted in integers so that the
    unwrapped angle, ``x + 2 pi K``, does not depend on where the file was cut in chunks.
    0 (an int) when no step is beyond half a turn (the usual chunk: no array of zeros)."""
    if x.size and abs(float(x[0]) - prev) < math.pi:
        steps = x[1:] - x[:-1]
        if not steps.size or (float(steps.max()) < math.pi and float(steps.min()) > -math.pi):
            return 0
    d = np.diff(x, prepend=prev)
    big = np.flatnonzero(np.abs(d) >= math.pi)   # the few steps that can wrap
    if not big.size:
        return 0
    k = np.zeros(x.size, dtype=np.int64)
    db = d[big]
    dmod = np.mod(db + math.pi, _TWO_PI) - math.pi
    dmod[(dmod == -math.pi) & (db > 0)] = math.pi
    k[big] = np.rint((dmod - db) / _TWO_PI).astype(np.int64)
    np.cumsum(k, out=k)
    return k


def _plus_turns(raw: np.ndarray, k: np.ndarray | int) -> np.ndarray:
    """``raw + 2 pi k`` (the same bits for a constant ``k`` given as an int)."""
    if isinstance(k, int):
        out: np.ndarray = raw + _TWO_PI * float(k)
        return out
    out = raw + _TWO_PI * k.astype(np.float64)
    return out


class _Channel:
    """One angle channel's unwrapping state: the unwrapped angle is the recorded one plus
    ``2 pi k`` whole turns (an integer carried across chunks and drop-outs)."""

    def __init__(self, turns: Turns, window: int) -> None:
        self.turns = turns
        self.window = window
        self.prev_raw = math.nan      # last recorded (scaled) value
        self.k = 0                    # whole turns added at that sample
        self.wraps = 0
        self.jumps = 0                # steps beyond half a turn left in a counter ('multi')
        self.lo = math.inf            # recorded range (multi-turn evidence)
        self.hi = -math.inf
        self.tail_t = np.empty(0)     # the last samples, unwrapped (speed before a gap)
        self.tail_x = np.empty(0)

    @property
    def multi_turn(self) -> bool:
        return self.turns == 'multi' or (self.turns == 'auto'
                                         and self.hi - self.lo > _TWO_PI * (1 + 1e-9))

    def local(self, raw: np.ndarray, prev: float) -> np.ndarray | int:
        """Whole turns (cumulative, int64; an int when constant) that unwrap ``raw`` within
        itself after ``prev`` (none for a counter)."""
        if self.turns == 'auto' and not self.multi_turn:   # (once it is, it stays so)
            self.lo = min(self.lo, float(raw.min()))
            self.hi = max(self.hi, float(raw.max()))
        if self.turns == 'multi':
            self.jumps += int(np.count_nonzero(np.abs(np.diff(raw, prepend=prev)) > math.pi))
            return 0
        turns = _wrap_turns(raw, prev)
        if not isinstance(turns, int):
            self.wraps += int(np.count_nonzero(np.diff(turns, prepend=0)))
        return turns

    def _emit(self, t: np.ndarray, raw: np.ndarray, k: np.ndarray | int) -> np.ndarray:
        """The unwrapped angles; remember the end of the piece (state for what follows)."""
        x = _plus_turns(raw, k)
        self.prev_raw = float(raw[-1])
        self.k = k if isinstance(k, int) else int(k[-1])
        if t.size >= self.window:
            self.tail_t, self.tail_x = t[-self.window:].copy(), x[-self.window:].copy()
        else:
            self.tail_t = np.concatenate([self.tail_t, t])[-self.window:]
            self.tail_x = np.concatenate([self.tail_x, x])[-self.window:]
        return x

    def continue_(self, t: np.ndarray, raw: np.ndarray) -> np.ndarray:
        """Unwrap a piece that continues the last one."""
        turns = self.local(raw, raw[0] if math.isnan(self.prev_raw) else self.prev_raw)
        return self._emit(t, raw, turns + self.k)

    def across(self, t: np.ndarray, raw: np.ndarray) -> tuple[np.ndarray, float, How]:
        """Unwrap the data after a drop-out: (angles, advance [rad], how)."""
        turns = self.local(raw, raw[0])      # within the new stretch, from its first value
        u = _plus_turns(raw, turns)
        d = float(raw[0]) - self.prev_raw    # the recorded advance across the drop-out
        k: int | None
        how: How
        if self.multi_turn:
            k, how = 0, 'counter'
        else:
            k = self._turns_from_speed(t, u, d)
            how = 'speed' if k is not None else 'ambiguous'
        advance = d + _TWO_PI * k if k is not None else math.nan
        x = self._emit(t, raw, turns + (self.k + (k or 0)))
        return x, advance, how

    def _turns_from_speed(self, t: np.ndarray, u: np.ndarray, d: float) -> int | None:
        """The whole turns to add to the recorded advance ``d``, or None if ambiguous."""
        if self.tail_t.size == 0:
            return None
        dt = float(t[0] - self.tail_t[-1])
        preds: list[float] = []
        for fit in (_slope(self.tail_t, self.tail_x), _slope(t, u)):
            if fit is not None:
                v, se = fit
                preds += [(v - 3 * se) * dt, (v + 3 * se) * dt]
        if not preds:
            return None
        lo, hi = min(preds), max(preds)
        # the candidate d + 2 pi k must lie within half a turn of every prediction
        k = math.floor((hi - math.pi - d) / _TWO_PI) + 1   # the least above hi - pi
        cand = d + _TWO_PI * k
        if hi - math.pi < cand < lo + math.pi:
            return k
        return None


class TurnStitcher:
    """SiChunks (recorded angles, breaks) -> :class:`Piece` s (unwrapped, gaps described).

    Args:
        turns_in: How the input turns (``auto``, ``single``, ``multi``; module docstring).
        turns_out: How the output turns.
        rate_hz: Sample rate [Hz] (the speed-fit window and the missing time).
    """

    def __init__(self, *, turns_in: Turns, turns_out: Turns, rate_hz: float) -> None:
        window = int(min(_MAX_SPEED_SAMPLES, max(2, round(SPEED_WINDOW_S * rate_hz))))
        self.rate_hz = rate_hz
        self.window = window
        self.ch_in = _Channel(turns_in, window)
        self.ch_out = _Channel(turns_out, window)
        self.gaps: list[ImportGap] = []
        self._pending: list[tuple[np.ndarray, ...]] = []
        self._pending_break: Break | None = None

    @property
    def wraps(self) -> tuple[int, int]:
        """Wraps unwrapped within continuous data (input, output)."""
        return self.ch_in.wraps, self.ch_out.wraps

    @property
    def jumps(self) -> tuple[int, int]:
        """Steps beyond half a turn between two samples of a channel kept as recorded
        (``multi``): a single-turn encoder's wraps when the channel was misdeclared."""
        return self.ch_in.jumps, self.ch_out.jumps

    def push(self, chunk: SiChunk) -> list[Piece]:
        """Take one chunk; the pieces that can be written now."""
        out: list[Piece] = []
        brk_at = {b.index: b for b in chunk.breaks}
        bounds = [0, *brk_at, chunk.t_s.size]
        heads = (chunk.theta_out_heads_rad if chunk.theta_out_heads_rad is not None
                 else np.empty((0, chunk.t_s.size)))
        loss = chunk.loss if chunk.loss is not None else np.empty((0, chunk.t_s.size))
        arrays = (chunk.t_s, chunk.theta_in_rad, chunk.theta_out_rad, chunk.torque_out_nm)
        for a, b in itertools.pairwise(bounds):
            if a == b:
                continue
            part = (*(arr[a:b] if arr.size else arr for arr in arrays), heads[:, a:b],
                    loss[:, a:b])
            brk = brk_at.get(a)
            if brk is not None:
                if self._pending_break is not None:
                    out.append(self._resolve())
                self._pending_break = brk
                self._pending = [part]
            elif self._pending_break is not None:
                self._pending.append(part)
            else:
                out.append(self._continue(part))
            if self._pending_break is not None and \
                    sum(p[0].size for p in self._pending) >= self.window:
                out.append(self._resolve())
        return out

    def finish(self) -> list[Piece]:
        """End of the data: the piece held after the last drop-out, if any."""
        return [self._resolve()] if self._pending_break is not None else []

    def _continue(self, part: tuple[np.ndarray, ...]) -> Piece:
        t, th_in, th_out, tq, heads, loss = part
        x_out = self.ch_out.continue_(t, th_out)
        return Piece(t, self.ch_in.continue_(t, th_in), x_out, tq,
                     theta_out_heads_rad=heads_beside(heads, th_out, x_out) if heads.size
                     else None, loss=loss if loss.shape[0] else None)

    def _resolve(self) -> Piece:
        brk, parts = self._pending_break, self._pending
        assert brk is not None
        self._pending_break, self._pending = None, []
        t, th_in, th_out, tq = (np.concatenate([p[i] for p in parts]) for i in range(4))
        heads = np.concatenate([p[4] for p in parts], axis=1)
        loss = np.concatenate([p[5] for p in parts], axis=1)
        x_in, adv_in, how_in = self.ch_in.across(t, th_in)
        x_out, adv_out, how_out = self.ch_out.across(t, th_out)
        split = 'ambiguous' in (how_in, how_out)
        period = 1.0 / self.rate_hz
        span = brk.t_after_s - brk.t_before_s
        missing = max(0, round(span * self.rate_hz) - 1 - brk.dropped)
        gap = ImportGap(brk.reason, brk.t_before_s, brk.t_after_s, max(0.0, span - period),
                        brk.dropped, missing, brk.where, adv_in / _TWO_PI, adv_out / _TWO_PI,
                        how_in, how_out, split)
        self.gaps.append(gap)
        if split:   # the speeds of the new segment are its own
            for ch, x in ((self.ch_in, x_in), (self.ch_out, x_out)):
                ch.tail_t, ch.tail_x = t[-self.window:].copy(), x[-self.window:].copy()
        return Piece(t, x_in, x_out, tq, gap=gap, new_segment=split,
                     theta_out_heads_rad=heads_beside(heads, th_out, x_out) if heads.size
                     else None, loss=loss if loss.shape[0] else None)
