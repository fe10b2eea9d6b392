"""Min/max envelope of a TE record of any length, in bounded memory.

A plot of a life test (10 hours at 10 kHz: 360 million samples) cannot draw every sample,
and a plot of every k-th sample misses the peaks between them (and aliases the tooth-mesh
orders into slow beats). :class:`MinMaxEnvelope` keeps, for consecutive buckets of samples,
the smallest and the largest TE and the output phase where the bucket starts: drawn as a
band, it contains every sample of the record, and its memory is bounded by ``max_buckets``
however long the record. When the buckets outnumber ``max_buckets``, neighbours are merged in
pairs (min of the mins, max of the maxes: exact), so a bucket holds at most ``bucket_samples``
samples (a doubling power of two).

It also keeps the band folded onto one output revolution (``fold_bins`` bins of angle from
the record's first sample, over every revolution), for the plot that shows repeatability:
each run of ``fine_samples`` consecutive samples goes into the bin where it starts (a run
that crosses into the next bin is counted in the first one: the folded band is placed to
within ``fine_samples`` samples of angle: 1.2 deg at 10 kHz and 1 output rev/s, 0.2 deg
at 10 rpm).

The streaming analyzer fills it window by window
(:meth:`rv_te_bench.core.stream.StreamingTeAnalyzer.set_envelope`), from the window's own TE
array and in the same pass that finds the window's min and max; a gap starts a new segment,
and buckets are never merged across one (the plot shows the break).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ['EnvelopeData', 'MinMaxEnvelope']

FloatArray = npt.NDArray[np.float64]
_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class EnvelopeData:
    """The envelope of a record.

    Attributes:
        phi_rad: Output phase theta_in / i where each bucket starts [rad].
        min_rad: Smallest TE in each bucket [rad].
        max_rad: Largest TE in each bucket [rad].
        segment: Segment of each bucket (a gap between two segments).
        bucket_samples: Most samples in one bucket.
        n_samples: Samples in the envelope.
        fold_min_rad: Smallest TE in each bin of output angle from the first sample (mod
            one revolution, ``fold_bins`` bins from 0); NaN where no sample fell.
        fold_max_rad: Largest TE in each of those bins; NaN where no sample fell.
    """

    phi_rad: FloatArray
    min_rad: FloatArray
    max_rad: FloatArray
    segment: npt.NDArray[np.int64]
    bucket_samples: int
    n_samples: int
    fold_min_rad: FloatArray
    fold_max_rad: FloatArray

    @property
    def size(self) -> int:
        """Number of buckets."""
        return int(self.phi_rad.size)


class MinMaxEnvelope:
    """Buckets of consecutive samples with their TE min and max; see the module docstring.

    Examples:
        >>> import numpy as np
        >>> env = MinMaxEnvelope(max_buckets=4, bucket_samples=2, fine_samples=1, fold_bins=4)
        >>> te = np.array([0.0, 3.0, -1.0, 2.0, 5.0, 4.0, 1.0, 0.5, 7.0])
        >>> lo, hi = env.add(np.arange(9.0), te)
        >>> d = env.data()
        >>> (d.bucket_samples, d.min_rad.tolist(), d.max_rad.tolist(), (lo, hi))
        (4, [-1.0, 0.5, 7.0], [3.0, 5.0, 7.0], (-1.0, 7.0))
        >>> d.fold_max_rad.tolist()   # phase 0..8 rad: bins of a quarter turn
        [3.0, 7.0, 5.0, 4.0]
    """

    def __init__(self, max_buckets: int = 20_000, bucket_samples: int = 256, *,
                 fold_bins: int = 720, fine_samples: int = 32) -> None:
        """An empty envelope: at most ``max_buckets`` buckets (>= 2), first of
        ``bucket_samples`` samples (a power of two, >= ``fine_samples``, also a power of
        two); ``fold_bins`` (>= 1) bins per output revolution for the folded band."""
        def pow2(k: int) -> bool:
            return k >= 1 and not k & (k - 1)

        if max_buckets < 2 or not pow2(bucket_samples) or not pow2(fine_samples) \
                or fine_samples > bucket_samples or fold_bins < 1:
            msg = (f'need max_buckets >= 2, bucket_samples and fine_samples powers of two '
                   f'(fine <= bucket), fold_bins >= 1; got {max_buckets}, {bucket_samples}, '
                   f'{fine_samples}, {fold_bins}')
            raise ValueError(msg)
        self._max = int(max_buckets)
        self._b = int(bucket_samples)
        self._fine = int(fine_samples)
        self._fold_lo = np.full(int(fold_bins), np.inf)
        self._fold_hi = np.full(int(fold_bins), -np.inf)
        self._phi_ref: float | None = None
        self._parts: list[tuple[FloatArray, FloatArray, FloatArray, npt.NDArray[np.int64]]] = []
        self._count = 0
        self._segment = 0
        self._n = 0

    @property
    def bucket_samples(self) -> int:
        """Samples per bucket for the next :meth:`add`."""
        return self._b

    def add(self, phi_rad: FloatArray, te_rad: FloatArray) -> tuple[float, float]:
        """Add consecutive samples (1-D float64, equal length, finite, at least one).

        Returns:
            (min, max) of ``te_rad``: the same values as ``np.min`` / ``np.max`` (a min of
            bucket minima is the minimum), so a caller needs no pass of its own.
        """
        fine = np.arange(0, te_rad.size, self._fine)
        f_lo = np.minimum.reduceat(te_rad, fine)
        f_hi = np.maximum.reduceat(te_rad, fine)
        f_phi = phi_rad[fine]
        if self._phi_ref is None:
            self._phi_ref = float(phi_rad[0])
        nb = self._fold_lo.size
        turn = np.mod(np.abs(f_phi - self._phi_ref), _TWO_PI)
        bins = np.minimum((turn * (nb / _TWO_PI)).astype(np.intp), nb - 1)
        # runs of one bin (the phase moves on monotonically): reduced first, then scattered
        runs = np.flatnonzero(bins[1:] != bins[:-1]) + 1
        runs = np.concatenate(([0], runs))
        np.minimum.at(self._fold_lo, bins[runs], np.minimum.reduceat(f_lo, runs))
        np.maximum.at(self._fold_hi, bins[runs], np.maximum.reduceat(f_hi, runs))
        starts = np.arange(0, fine.size, self._b // self._fine)
        lo = np.minimum.reduceat(f_lo, starts)
        hi = np.maximum.reduceat(f_hi, starts)
        self._parts.append((f_phi[starts], lo, hi,
                            np.full(starts.size, self._segment, dtype=np.int64)))
        self._count += starts.size
        self._n += te_rad.size
        while self._count > self._max:
            self._halve()
        return float(np.minimum.reduce(lo)), float(np.maximum.reduce(hi))

    def gap(self) -> None:
        """A gap: the next samples start a new segment (never merged with this one)."""
        if self._count:
            self._segment += 1

    def _joined(self) -> tuple[FloatArray, FloatArray, FloatArray, npt.NDArray[np.int64]]:
        if not self._parts:
            z = np.zeros(0)
            return z, z, z, np.zeros(0, dtype=np.int64)
        if len(self._parts) > 1:
            self._parts = [tuple(np.concatenate(a) for a in zip(*self._parts, strict=True))]  # type: ignore[list-item]
        return self._parts[0]

    def _halve(self) -> None:
        """Merge neighbouring buckets in pairs within each segment; double the bucket size."""
        phi, lo, hi, seg = self._joined()
        new_seg = np.ones(seg.size, dtype=bool)
        new_seg[1:] = seg[1:] != seg[:-1]
        first = np.flatnonzero(new_seg)
        local = np.arange(seg.size) - np.repeat(first, np.diff(np.append(first, seg.size)))
        starts = np.flatnonzero(local % 2 == 0)
        self._parts = [(phi[starts], np.minimum.reduceat(lo, starts),
                        np.maximum.reduceat(hi, starts), seg[starts])]
        self._count = starts.size
        self._b *= 2

    def data(self) -> EnvelopeData:
        """The envelope so far (copies)."""
        phi, lo, hi, seg = self._joined()
        seen = np.isfinite(self._fold_lo)
        return EnvelopeData(phi_rad=phi.copy(), min_rad=lo.copy(), max_rad=hi.copy(),
                            segment=seg.copy(), bucket_samples=self._b, n_samples=self._n,
                            fold_min_rad=np.where(seen, self._fold_lo, np.nan),
                            fold_max_rad=np.where(seen, self._fold_hi, np.nan))
