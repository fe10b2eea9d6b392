"""Raw chunks -> SI samples, with the drop-outs of the record found and described.

:class:`ChunkConverter` scales each :class:`~._common.RawChunk` to SI (time since the first
sample [s], angles [rad] as recorded, torque [N m]) and decides which samples are good:

* a sample with a non-finite time or angle is dropped (``non_finite``);
* a sample whose time is not after the last good one is dropped (``time_backwards``: a
  clock reset, a duplicated or out-of-order row);
* a good sample more than :data:`STEP_PERIODS` (1.5) sample periods after the last good one
  starts a new stretch (``time_step``: rows missing from the file, the DAQ's drop-out).

Dropped samples and time steps between two good samples make one :class:`Break` (the
samples from it on follow a drop-out), exactly the rule of the live JointState adapter
(:mod:`rv_te_bench.core.joint_state`). The bag writer turns a break into a skipped block
sequence number, the evidence every consumer (TE node, ``rv-te analyze``, ``identify``,
the report) reads as a gap. Samples dropped before the first good one or after the last
are counted (:attr:`ChunkConverter.leading_dropped`, :meth:`ChunkConverter.finish`).

Integer time columns (epoch nanoseconds, JointState stamps) are subtracted in int64 before
they become float64 seconds, so no precision is lost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from rv_te_bench.errors import DataImportError
from sim.units import ARCMIN_PER_RAD, ARCSEC_PER_RAD

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.io.importers._common import RawChunk

__all__ = ['STEP_PERIODS', 'Break', 'BreakReason', 'ChunkConverter', 'SiChunk']

#: A time step above this many sample periods is a drop-out (as the live adapter's).
STEP_PERIODS = 1.5
BreakReason = Literal['time_step', 'time_backwards', 'non_finite']
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class Break:
    """A drop-out: the good samples from ``index`` on follow it.

    Attributes:
        index: Index into the chunk's (good) samples of the first sample after it.
        reason: What broke the record first: ``time_step``, ``time_backwards`` or
            ``non_finite``.
        t_before_s: Time of the last good sample before it [s since the first sample].
        t_after_s: Time of the first good sample after it [s].
        dropped: Samples in the file between the two that were not used.
        where: Where in the file it begins (``line N`` / ``sample N``), for messages.
    """

    index: int
    reason: BreakReason
    t_before_s: float
    t_after_s: float
    dropped: int
    where: str


@dataclass(frozen=True)
class SiChunk:
    """Good, consecutive samples in SI (angles as recorded, not yet unwrapped).

    Attributes:
        t_s: Time since the first good sample of the file [s], strictly increasing.
        theta_in_rad: Input angle [rad].
        theta_out_rad: Output angle [rad].
        torque_out_nm: Torque [N m] (empty when none).
        breaks: Drop-outs inside this chunk (and one at index 0 when the previous chunk
            ended in one), in order.
        theta_out_heads_rad: The output scale's further heads [rad], (N-1, n), NaN where a
            head has no reading (the sample is kept), or None.
        loss: Input torque [N m] and case temperature [degC], (2, n), NaN where there is
            no reading, or None (issue 38).
    """

    t_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_out_nm: np.ndarray
    breaks: tuple[Break, ...] = ()
    theta_out_heads_rad: np.ndarray | None = None
    loss: np.ndarray | None = None


def to_rad_factor(unit: str, counts_per_rev: int | None, where: str) -> float:
    """Radians per unit of an angle column (``counts`` needs the counts per revolution)."""
    if unit == 'counts':
        if counts_per_rev is None:
            msg = (f'{where}: unit counts needs the counts per revolution (the bench '
                   'description encoders.*.counts_per_rev or --counts-per-rev-in/-out)')
            raise DataImportError(msg)
        return _TWO_PI / counts_per_rev
    return {'rad': 1.0, 'deg': math.pi / 180.0, 'arcmin': 1.0 / ARCMIN_PER_RAD,
            'arcsec': 1.0 / ARCSEC_PER_RAD, 'rev': _TWO_PI}[unit]


def estimate_rate_hz(t_s: np.ndarray) -> float | None:
    """The sample rate from the median positive time step (None with fewer than 2)."""
    steps = np.diff(t_s[np.isfinite(t_s)])
    steps = steps[steps > 0]
    if steps.size == 0:
        return None
    return 1.0 / float(np.median(steps))


def _scaled(a: np.ndarray, k: float) -> np.ndarray:
    """``a`` as float64 times ``k`` (``a`` itself when ``k`` is 1: ``x * 1.0`` is ``x``, bit
    for bit, so the copy would change nothing)."""
    a = np.asarray(a, dtype=np.float64)
    out: np.ndarray = a if k == 1.0 else a * k
    return out


class ChunkConverter:
    """RawChunk -> :class:`SiChunk`: SI units, checks, drop-outs (stateful across chunks).

    Args:
        origin: The file, for messages.
        labels: Column / channel name per role (``time``, ``in``, ``out``, ``torque``).
        locate: Sample index -> ``'line N'`` / ``'sample N'`` for messages.
        k_in: Radians per unit of the input column.
        k_out: Radians per unit of the output column.
        time_scale_s: Seconds per time-column unit (None: fixed rate).
        rate_hz: Sample rate [Hz]: the fixed rate without a time column, and the period
            that drop-outs are measured against; None: the median step of the first chunk.
        torque_scale_nm: Recorded torque x this = N m.
        torque_in_scale_nm: Recorded input torque x this = N m.
    """

    def __init__(self, *, origin: str, labels: dict[str, str],
                 locate: Callable[[int], str], k_in: float, k_out: float,
                 time_scale_s: float | None, rate_hz: float | None,
                 torque_scale_nm: float, torque_in_scale_nm: float = 1.0) -> None:
        self.origin = origin
        self.labels = labels
        self.locate = locate
        self.k_in = k_in
        self.k_out = k_out
        self.time_scale_s = time_scale_s
        self.rate_hz = rate_hz
        self.torque_scale_nm = torque_scale_nm
        self.torque_in_scale_nm = torque_in_scale_nm
        self.t0: int | float | None = None     # first good time value (file unit)
        self.t0_s = math.nan                   # ... in s (absolute when the column is)
        self._last_s = -math.inf               # last good sample's time [s since t0]
        self._open: tuple[BreakReason, int, str] | None = None   # dropped, not yet closed
        self.samples = 0                       # good samples
        self.dropped = 0                       # samples not used
        self.leading_dropped = 0               # ... before the first good sample

    def fail(self, role: str, index: int, what: str) -> None:
        """Raise one line naming the file, the column, the row or sample and the fault."""
        msg = f'{self.origin}: column {self.labels[role]!r}, {self.locate(index)}: {what}'
        raise DataImportError(msg)

    def _times(self, raw: RawChunk, n: int) -> np.ndarray:
        """Times [s since the first good sample] (NaN where the file's is not finite)."""
        if raw.time is None:
            assert self.rate_hz is not None
            if self.t0 is None:
                self.t0, self.t0_s = 0, 0.0
            return np.arange(raw.first, raw.first + n, dtype=np.float64) / self.rate_hz
        assert self.time_scale_s is not None
        t = np.asarray(raw.time)
        if t.dtype.kind in 'iu':
            t = t.astype(np.int64, copy=False)
            if self.t0 is None:
                self.t0 = int(t[0])
                self.t0_s = self.t0 * self.time_scale_s
            return _scaled((t - np.int64(self.t0)).astype(np.float64), self.time_scale_s)
        t = np.asarray(t, dtype=np.float64)
        if self.t0 is None:
            finite = np.flatnonzero(np.isfinite(t))
            if finite.size == 0:
                return np.full(n, math.nan)
            self.t0 = float(t[finite[0]])
            self.t0_s = self.t0 * self.time_scale_s
        return _scaled(t - self.t0, self.time_scale_s)

    def __call__(self, raw: RawChunk) -> SiChunk:
        """Convert and check one chunk (its samples follow the previous chunk's)."""
        n = raw.theta_in.size
        if raw.theta_out.size != n or (raw.time is not None and raw.time.size != n) \
                or (raw.torque is not None and raw.torque.size != n):
            msg = f'{self.origin}: channels of different lengths near {self.locate(raw.first)}'
            raise DataImportError(msg)
        t_s = self._times(raw, n)
        th_in = _scaled(raw.theta_in, self.k_in)
        th_out = _scaled(raw.theta_out, self.k_out)
        if self.rate_hz is None:
            ok = np.isfinite(t_s) & np.isfinite(th_in) & np.isfinite(th_out)
            self.rate_hz = estimate_rate_hz(t_s[ok])
        fast = self._clean(raw, n, t_s, th_in, th_out)
        if fast is not None:
            return fast
        ok = np.isfinite(t_s) & np.isfinite(th_in) & np.isfinite(th_out)
        # a good sample is after every earlier good one (a running maximum: a dropped
        # sample never raises it)
        tf = np.where(ok, t_s, -np.inf)
        before = np.maximum.accumulate(np.concatenate([[self._last_s], tf]))[:-1]
        good = ok & (t_s > before)
        idx = np.flatnonzero(good)
        self.dropped += n - idx.size
        every = idx.size == n     # all good (the usual chunk): slices, not gathers
        torque = np.zeros(0)
        if raw.torque is not None:
            torque = (np.asarray(raw.torque, dtype=np.float64) if every else
                      np.asarray(raw.torque, dtype=np.float64)[idx]) * self.torque_scale_nm
            bad = np.flatnonzero(~np.isfinite(torque))
            if bad.size:
                self.fail('torque', raw.first + int(idx[bad[0]]),
                          f'value {raw.torque[idx[bad[0]]]!r} is not finite')
        breaks = self._breaks(raw, ok, idx, t_s)
        if idx.size:
            self._last_s = float(t_s[idx[-1]])
        tail = n - 1 - int(idx[-1]) if idx.size else n
        if tail:   # the chunk ends in dropped samples: the break closes in a later chunk
            k = n - tail
            reason: BreakReason = 'non_finite' if not ok[k] else 'time_backwards'
            if self._open is None:
                self._open = (reason, tail, self.locate(raw.first + k))
            else:
                self._open = (self._open[0], self._open[1] + tail, self._open[2])
        self.samples += idx.size
        heads = None
        if raw.out_heads is not None:
            if raw.out_heads.shape[-1] != n:
                msg = (f'{self.origin}: head channels of different lengths near '
                       f'{self.locate(raw.first)}')
                raise DataImportError(msg)
            heads = np.asarray(raw.out_heads, dtype=np.float64)[:, idx] * self.k_out
        loss = None
        if raw.loss is not None:
            loss = np.asarray(raw.loss, dtype=np.float64)[:, idx] * np.array(
                [[self.torque_in_scale_nm], [1.0]])
        if every:
            return SiChunk(t_s=t_s, theta_in_rad=th_in, theta_out_rad=th_out,
                           torque_out_nm=torque, breaks=breaks, theta_out_heads_rad=heads,
                           loss=loss)
        return SiChunk(t_s=t_s[idx], theta_in_rad=th_in[idx], theta_out_rad=th_out[idx],
                       torque_out_nm=torque, breaks=breaks, theta_out_heads_rad=heads,
                       loss=loss)

    def _clean(self, raw: RawChunk, n: int, t_s: np.ndarray, th_in: np.ndarray,
               th_out: np.ndarray) -> SiChunk | None:
        """The usual chunk, every sample good and no drop-out, in a few passes (issue 41):
        the SiChunk ``__call__`` would make of it, or None (``__call__`` looks closer).

        All finite: the sums are (a NaN or an infinity makes its sum one; an overflowing
        sum only sends the chunk the long way). Times increasing and no step beyond
        STEP_PERIODS: the smallest and largest step say so; times made from the rate are
        (the index over the rate, exactly rounded, never repeats below 2**52 samples).
        """
        if self._open is not None or n == 0 or self.rate_hz is None:
            return None
        if not (math.isfinite(float(np.add.reduce(th_in)))
                and math.isfinite(float(np.add.reduce(th_out)))):
            return None
        limit = STEP_PERIODS / self.rate_hz
        first = float(t_s[0])
        if not first > self._last_s or (self._last_s != -math.inf
                                          and not first - self._last_s <= limit):
            return None
        if raw.time is not None and n > 1:
            if not math.isfinite(float(np.add.reduce(t_s))):
                return None
            steps = t_s[1:] - t_s[:-1]
            if not (float(steps.min()) > 0 and float(steps.max()) <= limit):
                return None
        torque = np.zeros(0)
        if raw.torque is not None:
            torque = _scaled(raw.torque, self.torque_scale_nm)
            if not math.isfinite(float(np.add.reduce(torque))):
                return None    # __call__ names the bad value
        heads = loss = None
        if raw.out_heads is not None:
            if raw.out_heads.shape[-1] != n:
                return None
            heads = np.asarray(raw.out_heads, dtype=np.float64) * self.k_out
        if raw.loss is not None:
            loss = np.asarray(raw.loss, dtype=np.float64) * np.array(
                [[self.torque_in_scale_nm], [1.0]])
        self._last_s = float(t_s[-1])
        self.samples += n
        return SiChunk(t_s=t_s, theta_in_rad=th_in, theta_out_rad=th_out, torque_out_nm=torque,
                       theta_out_heads_rad=heads, loss=loss)

    def _breaks(self, raw: RawChunk, ok: np.ndarray, idx: np.ndarray,
                t_s: np.ndarray) -> tuple[Break, ...]:
        """The drop-outs before each good sample (a Python loop over drop-outs only)."""
        if idx.size == 0:
            return ()
        assert self.rate_hz is not None
        every = idx.size == t_s.size
        ta = t_s if every else t_s[idx]
        prev_t = np.concatenate([[self._last_s], ta[:-1]])
        dropped = np.zeros(idx.size, dtype=np.int64) if every else np.diff(idx, prepend=-1) - 1
        jump = (ta - prev_t) > STEP_PERIODS / self.rate_hz
        at = np.flatnonzero(jump) if every else np.flatnonzero(jump | (dropped > 0))
        out: list[Break] = []
        for j in at.tolist():
            k = int(idx[j - 1]) + 1 if j else 0     # first sample after the last good one
            if j == 0 and self._open is not None:
                reason, carried, where = self._open
                self._open = None
                count = carried + int(dropped[0])
            elif dropped[j] > 0:
                reason = 'non_finite' if not ok[k] else 'time_backwards'
                count, where = int(dropped[j]), self.locate(raw.first + k)
            else:
                reason, count, where = 'time_step', 0, self.locate(raw.first + int(idx[j]))
            if j == 0 and self._last_s == -math.inf:   # before the first good sample
                self.leading_dropped = count
                continue
            out.append(Break(j, reason, float(prev_t[j]), float(ta[j]), count, where))
        return tuple(out)

    def finish(self) -> tuple[int, str] | None:
        """End of the file: (samples dropped after the last good one, where), or None."""
        if self._open is None:
            return None
        _, count, where = self._open
        return count, where
