"""Envelopes of the live page: min and max of every sample behind a column, no sample dropped.

At 10 kHz a browser must not get every sample, and must not miss one either: the server
sends, per column, the min and max of the samples behind it (an envelope), so a one-sample
spike stays on screen. Two kinds, both numpy-vectorised, no ROS:

* :class:`AngleEnvelopes`: TE per bin of the output angle within a revolution (revolutions
  counted from the session's first output angle, as the TE node counts its windows), for
  the last few revolutions visited.
* :class:`TimeEnvelopes`: a pyramid over the sample index (level ``l`` bins hold
  ``base_samples * 2**l`` consecutive samples) with the TE and torque min/max and the first
  and last time and angles of each bin (mean speeds), each level a ring of ``ring`` bins. A
  view of any span is drawn from the finest level that fits it in ``max_columns`` bins.

Every bin carries the *generation* in which it last changed, so a client is sent the bins
changed since its own cursor: a stalled client gets the current envelope when it is ready
again, not a backlog. The page merges bins into its pixel columns (min of mins, max of
maxes), which is exact: the envelope of a union is the union of the envelopes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ['AngleEnvelopes', 'TimeEnvelopes', 'TimeView']

TWO_PI = 2.0 * math.pi


class AngleEnvelopes:
    """TE min/max per output-angle bin for the last ``keep`` revolutions visited.

    Revolution ``k`` covers ``theta0 + [2 pi k, 2 pi (k + 1))`` of the unwrapped output angle
    (negative ``k`` when the output turns backwards); bin ``b`` of ``n_bins`` covers
    ``[b, b + 1) * 360 / n_bins`` degrees into the revolution.
    """

    def __init__(self, n_bins: int = 2048, keep: int = 2) -> None:
        """Empty; the first sample pushed sets the origin ``theta0``."""
        if n_bins < 1 or keep < 1:
            msg = f'n_bins and keep must be >= 1, got {n_bins=}, {keep=}'
            raise ValueError(msg)
        self.n_bins = n_bins
        self.keep = keep
        self.theta0_rad = math.nan
        #: revolution index -> (min, max, gen) arrays; insertion order = order of last visit
        self.revs: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        #: first sample index of each revolution visited (kept for every revolution)
        self.rev_start_sample: dict[int, int] = {}
        self.current: int | None = None

    def push(self, theta_out_rad: np.ndarray, te_rad: np.ndarray, first_sample: int,
             gen: int) -> None:
        """Add samples (unwrapped output angle, TE, both [rad]) numbered from ``first_sample``."""
        ok = np.isfinite(theta_out_rad) & np.isfinite(te_rad)
        if not ok.all():
            idx = np.flatnonzero(ok)
            theta_out_rad, te_rad = theta_out_rad[idx], te_rad[idx]
            sample_no = first_sample + idx
        else:
            sample_no = first_sample + np.arange(len(te_rad))
        if not len(te_rad):
            return
        if math.isnan(self.theta0_rad):
            self.theta0_rad = float(theta_out_rad[0])
        rel = (theta_out_rad - self.theta0_rad) / TWO_PI
        rev = np.floor(rel).astype(np.int64)
        bins = np.minimum(((rel - rev) * self.n_bins).astype(np.int64), self.n_bins - 1)
        # runs of one revolution, in time order (a reversal may come back to a revolution)
        cuts = np.flatnonzero(np.diff(rev)) + 1
        starts = np.concatenate(([0], cuts))
        ends = np.concatenate((cuts, [len(rev)]))
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            self._add(int(rev[a]), bins[a:b], te_rad[a:b], int(sample_no[a]), gen)

    def _add(self, k: int, bins: np.ndarray, te: np.ndarray, sample_no: int, gen: int) -> None:
        arrays = self.revs.pop(k, None)
        if arrays is None:
            arrays = (np.full(self.n_bins, np.inf), np.full(self.n_bins, -np.inf),
                      np.zeros(self.n_bins, np.int64))
            self.rev_start_sample.setdefault(k, sample_no)
        self.revs[k] = arrays   # most recently visited last
        while len(self.revs) > self.keep:
            del self.revs[next(iter(self.revs))]
        lo, hi, g = arrays
        np.minimum.at(lo, bins, te)
        np.maximum.at(hi, bins, te)
        g[bins] = gen
        self.current = k

    def previous(self) -> int | None:
        """The revolution visited before the current one (None: only one so far)."""
        others = [k for k in self.revs if k != self.current]
        return others[-1] if others else None


@dataclass(frozen=True)
class TimeView:
    """Bins ``first_bin .. last_bin`` of pyramid level ``level`` (``samples_per_bin`` each)."""

    level: int
    samples_per_bin: int
    first_bin: int
    last_bin: int


#: Fields of a time bin: reduced with min, max, first or last over the bin's samples.
MIN_FIELDS = ('te_min', 'torque_min')
MAX_FIELDS = ('te_max', 'torque_max')
EDGE_FIELDS = ('t', 'theta_in', 'theta_out')   # first and last of each: *_first, *_last


class TimeEnvelopes:
    """A min/max pyramid over the sample index (see the module docstring)."""

    def __init__(self, *, base_samples: int = 8, levels: int = 24, ring: int = 4096,
                 max_columns: int = 2048) -> None:
        """Empty pyramid; ``base_samples`` must be a power of two, ``ring >= 2 max_columns``."""
        if base_samples < 1 or base_samples & (base_samples - 1):
            msg = f'base_samples must be a power of two, got {base_samples!r}'
            raise ValueError(msg)
        if ring < 2 * max_columns:
            msg = f'ring ({ring}) must hold two views of max_columns ({max_columns})'
            raise ValueError(msg)
        self.base_bits = base_samples.bit_length() - 1
        self.n_levels = levels
        self.ring = ring
        self.max_columns = max_columns
        self.n_samples = 0   # samples pushed so far (the next sample's index)
        # per level: bin index per slot (-1 empty), gen per slot, mins (ring, 2),
        # maxs (ring, 2), firsts (ring, 3), lasts (ring, 3)
        self.idx = np.full((levels, ring), -1, np.int64)
        self.gen = np.zeros((levels, ring), np.int64)
        self.mins = np.full((levels, ring, 2), np.nan)
        self.maxs = np.full((levels, ring, 2), np.nan)
        self.firsts = np.full((levels, ring, 3), np.nan)
        self.lasts = np.full((levels, ring, 3), np.nan)

    def push(self, t_s: np.ndarray, theta_in_rad: np.ndarray, theta_out_rad: np.ndarray,
             te_rad: np.ndarray, torque_nm: np.ndarray | None, gen: int) -> int:
        """Add consecutive samples; returns the index of the first one."""
        n = len(t_s)
        first = self.n_samples
        if not n:
            return first
        self.n_samples += n
        tq = torque_nm if torque_nm is not None and len(torque_nm) == n else np.full(n, np.nan)
        vmin = np.column_stack((te_rad, tq))
        vmax = vmin
        edges = np.column_stack((t_s, theta_in_rad, theta_out_rad))
        # NaN (a bad sample, no torque sensor) must not poison a bin: fmin/fmax ignore it
        bins = (first + np.arange(n)) >> self.base_bits
        bin_ids, mins, maxs, fst, lst = _reduce(bins, vmin, vmax, edges, edges)
        for level in range(self.n_levels):
            if level:
                bin_ids_up = bin_ids >> 1
                bin_ids, mins, maxs, fst, lst = _reduce(bin_ids_up, mins, maxs, fst, lst)
            self._merge(level, bin_ids, mins, maxs, fst, lst, gen)
        return first

    def _merge(self, level: int, bin_ids: np.ndarray, mins: np.ndarray, maxs: np.ndarray,
               fst: np.ndarray, lst: np.ndarray, gen: int) -> None:
        slots = bin_ids % self.ring
        same = self.idx[level, slots] == bin_ids   # the bin holds samples already: combine
        if same.any():
            s = slots[same]
            mins[same] = np.fmin(mins[same], self.mins[level, s])
            maxs[same] = np.fmax(maxs[same], self.maxs[level, s])
            fst[same] = self.firsts[level, s]
        self.idx[level, slots] = bin_ids
        self.gen[level, slots] = gen
        self.mins[level, slots] = mins
        self.maxs[level, slots] = maxs
        self.firsts[level, slots] = fst
        self.lasts[level, slots] = lst

    def view(self, first_sample: int) -> TimeView | None:
        """The finest level showing samples ``first_sample ..`` now in at most
        ``max_columns`` bins (None: no sample yet)."""
        if self.n_samples == 0:
            return None
        first_sample = min(max(first_sample, 0), self.n_samples - 1)
        last = self.n_samples - 1
        for level in range(self.n_levels):
            bits = self.base_bits + level
            a, b = first_sample >> bits, last >> bits
            if b - a + 1 <= self.max_columns:
                return TimeView(level, 1 << bits, int(a), int(b))
        bits = self.base_bits + self.n_levels - 1
        b = last >> bits
        return TimeView(self.n_levels - 1, 1 << bits, int(max(b - self.max_columns + 1, 0)),
                        int(b))

    def rows(self, view: TimeView, since_gen: int) -> tuple[int, dict[str, np.ndarray]]:
        """Bins of ``view`` changed after generation ``since_gen``: (first bin, columns).

        The changed bins of a time stream are a suffix of the view (samples arrive in
        order), so the answer is one contiguous run from the first changed bin to the end
        (empty arrays when nothing changed). A bin that left the ring is NaN.
        """
        ids = np.arange(view.first_bin, view.last_bin + 1)
        slots = ids % self.ring
        level = view.level
        present = self.idx[level, slots] == ids
        changed = np.flatnonzero(present & (self.gen[level, slots] > since_gen))
        if since_gen <= 0:
            start = 0
        elif not len(changed):
            return view.last_bin + 1, {}
        else:
            start = int(changed[0])
        ids, slots, present = ids[start:], slots[start:], present[start:]
        cols: dict[str, np.ndarray] = {}
        for j, name in enumerate(MIN_FIELDS):
            cols[name] = np.where(present, self.mins[level, slots, j], np.nan)
        for j, name in enumerate(MAX_FIELDS):
            cols[name] = np.where(present, self.maxs[level, slots, j], np.nan)
        for j, name in enumerate(EDGE_FIELDS):
            cols[f'{name}_first'] = np.where(present, self.firsts[level, slots, j], np.nan)
            cols[f'{name}_last'] = np.where(present, self.lasts[level, slots, j], np.nan)
        return view.first_bin + start, cols


def _reduce(bins: np.ndarray, vmin: np.ndarray, vmax: np.ndarray, first: np.ndarray,
            last: np.ndarray) -> tuple[np.ndarray, ...]:
    """Group consecutive equal bin ids: (ids, min, max, first, last) per group."""
    cuts = np.flatnonzero(np.diff(bins)) + 1
    starts = np.concatenate(([0], cuts))
    ends = np.concatenate((cuts - 1, [len(bins) - 1]))
    if len(starts) == len(bins):   # one sample per group: nothing to reduce
        return bins, vmin.copy(), vmax.copy(), first.copy(), last.copy()
    with np.errstate(invalid='ignore'):
        mins = np.fmin.reduceat(vmin, starts, axis=0)
        maxs = np.fmax.reduceat(vmax, starts, axis=0)
    return bins[starts], mins, maxs, first[starts], last[ends]
