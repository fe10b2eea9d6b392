"""Harmonics of one revolution from a record of any length, with their uncertainty.

Several channels (head differences, or a TE) sampled against an angle are folded, block by
block and in fixed memory, onto ``n_bins`` equal bins of ``angle mod 2 pi``. Per bin and
channel the sums ``n, sum x, sum x^2, sum y_j, sum x y_j, sum y_j y_l`` (x the angle's offset
from the bin centre) give the bin mean moved to the bin centre along the in-bin slope, and
the scatter about that line, pooled over the bins, gives the noise covariance of the
channels (type A: white within a bin; slow drifts between revolutions are not in it).

The complex amplitude of order k of channel j, with ``y(u) = c0 + sum_k Re(c_k e^{iku})``,
is the DFT of the centred bin values, corrected for the averaging over a bin of width h
(``sinc(k h / 2)``)::

    c_k = (2 / M) sum_b y_b e^{-ik u_b} / sinc(k h / 2)

exact for every order below M / 2 when all M bins hold samples (one whole revolution or
more). Its real and imaginary parts have the covariance ``(2 / M^2) sum_b Sigma / n_b``
across channels (Sigma the pooled in-bin covariance).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rv_te_bench.errors import TeInputError

__all__ = ['DEFAULT_HARMONIC_BINS', 'ChannelHarmonics', 'HarmonicFold']

_TWO_PI = 2.0 * math.pi
#: Bins per revolution: orders up to 1023 resolved, 0.35 deg per bin.
DEFAULT_HARMONIC_BINS = 2048


@dataclass(frozen=True)
class ChannelHarmonics:
    """Complex harmonic amplitudes of several channels and their noise covariance.

    Attributes:
        orders: Orders k (>= 1), shape (K,).
        c: Complex amplitudes, shape (m, K): channel j holds ``Re(c[j, k] e^{iku})``.
        cov: Covariance of the real (and, equally, of the imaginary) parts across channels,
            shape (m, m); the same for every order (white in-bin noise).
        mean: Order-0 term per channel, shape (m,).
        n_samples: Samples folded.
        revolutions: Revolutions the angle spanned.
    """

    orders: np.ndarray
    c: np.ndarray
    cov: np.ndarray
    mean: np.ndarray
    n_samples: int
    revolutions: float


class HarmonicFold:
    """Folds channels against an angle onto equal bins of one revolution (fixed memory).

    Args:
        n_channels: Channels per sample (>= 1).
        n_bins: Bins per revolution (>= 16, even).

    Raises:
        TeInputError: Bad counts.

    Examples:
        >>> u = np.linspace(0.0, 2 * np.pi, 50_000, endpoint=False)
        >>> f = HarmonicFold(1, n_bins=64)
        >>> f.add(u, (1e-5 * np.sin(3 * u + 0.2))[None, :])
        >>> h = f.harmonics([3])
        >>> round(abs(h.c[0, 0]) * 1e5, 6), round(float(np.angle(h.c[0, 0] * 1j)), 6)
        (1.0, 0.2)
    """

    def __init__(self, n_channels: int, *, n_bins: int = DEFAULT_HARMONIC_BINS) -> None:
        """Start empty (see the class docstring)."""
        for name, v, low in (('n_channels', n_channels, 1), ('n_bins', n_bins, 16)):
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < low:
                msg = f'{name} must be an integer >= {low}, got {v!r}'
                raise TeInputError(msg)
        if n_bins % 2:
            msg = f'n_bins must be even, got {n_bins}'
            raise TeInputError(msg)
        self.n_channels = int(n_channels)
        self.n_bins = int(n_bins)
        self._h = _TWO_PI / self.n_bins
        m = self.n_channels
        self._n = np.zeros(self.n_bins)
        self._sx = np.zeros(self.n_bins)
        self._sxx = np.zeros(self.n_bins)
        self._sy = np.zeros((m, self.n_bins))
        self._sxy = np.zeros((m, self.n_bins))
        self._syy = np.zeros((m, m, self.n_bins))
        self._ref: np.ndarray | None = None
        self._lo = math.inf
        self._hi = -math.inf
        self.n_samples = 0
        self.skipped = 0

    def add(self, angle_rad: npt.ArrayLike, values: npt.ArrayLike) -> None:
        """Fold samples: ``angle_rad`` shape (n,), ``values`` shape (n_channels, n).

        Samples with a non-finite angle or value are skipped (counted in ``skipped``).

        Raises:
            TeInputError: Shapes that do not fit.
        """
        u = np.asarray(angle_rad, dtype=np.float64)
        y = np.asarray(values, dtype=np.float64)
        if u.ndim != 1 or y.shape != (self.n_channels, u.size):
            msg = (f'angle_rad must be 1-D and values ({self.n_channels}, n), got {u.shape} and '
                   f'{y.shape}')
            raise TeInputError(msg)
        ok = np.isfinite(u) & np.all(np.isfinite(y), axis=0)
        if not ok.all():
            self.skipped += int(u.size - np.count_nonzero(ok))
            u, y = u[ok], y[:, ok]
        if u.size == 0:
            return
        if self._ref is None:
            self._ref = y[:, 0].copy()
        y = y - self._ref[:, None]
        self._lo = min(self._lo, float(u.min()))
        self._hi = max(self._hi, float(u.max()))
        w = np.mod(u, _TWO_PI)
        b = np.minimum((w / self._h).astype(np.int64), self.n_bins - 1)
        x = w - (b + 0.5) * self._h
        nb = self.n_bins
        self._n += np.bincount(b, minlength=nb)
        self._sx += np.bincount(b, weights=x, minlength=nb)
        self._sxx += np.bincount(b, weights=x * x, minlength=nb)
        for j in range(self.n_channels):
            self._sy[j] += np.bincount(b, weights=y[j], minlength=nb)
            self._sxy[j] += np.bincount(b, weights=x * y[j], minlength=nb)
            for m in range(j + 1):
                s = np.bincount(b, weights=y[j] * y[m], minlength=nb)
                self._syy[j, m] += s
                if m != j:
                    self._syy[m, j] += s
        self.n_samples += int(u.size)

    @property
    def revolutions(self) -> float:
        """Revolutions the folded angle spanned (max - min over 2 pi)."""
        return (self._hi - self._lo) / _TWO_PI if self.n_samples else 0.0

    @property
    def empty_bins(self) -> int:
        """Bins with no sample (the harmonics need none empty)."""
        return int(np.count_nonzero(self._n == 0))

    def _centred(self) -> tuple[np.ndarray, np.ndarray]:
        """Bin values at the centres (m, M) and the pooled in-bin covariance (m, m).

        A bin's mean is moved to its centre along its own least-squares slope when its
        samples spread over the bin (standard deviation of their offsets at least half that
        of a uniform spread, and three or more samples); otherwise (a sparse record: a few
        samples per bin, often at nearly the same offset revolution after revolution) that
        slope is noise divided by a tiny spread, and the slope of the curve between the
        neighbouring bins' means is used instead (every bin holds a sample here).
        """
        n = self._n
        xbar = self._sx / n
        cxx = self._sxx - self._sx * xbar
        ybar = self._sy / n
        cxy = self._sxy - self._sx * ybar
        own = (n >= 3) & (cxx >= n * self._h**2 / 48.0)
        slope = np.where(own, cxy / np.where(own, cxx, 1.0), 0.0)
        if not own.all():
            # the curve's slope from the neighbours' means, at their sample positions
            pos = (np.arange(self.n_bins) + 0.5) * self._h + xbar
            ahead = np.roll(pos, -1)
            ahead[-1] += _TWO_PI
            behind = np.roll(pos, 1)
            behind[0] -= _TWO_PI
            fd = (np.roll(ybar, -1, axis=1) - np.roll(ybar, 1, axis=1)) / (ahead - behind)
            slope = np.where(own, slope, fd)
        centred = ybar - slope * xbar
        cyy = self._syy - self._sy[:, None, :] * ybar[None, :, :]
        cyy -= np.where(own, cxy[:, None, :] * cxy[None, :, :] / np.where(own, cxx, 1.0), 0.0)
        dof = float(np.sum(np.where(own, n - 2.0, n - 1.0)))
        cov = cyy.sum(axis=2) / dof if dof > 0 else np.full(cyy.shape[:2], np.nan)
        return centred, cov

    def harmonics(self, orders: npt.ArrayLike) -> ChannelHarmonics:
        """Complex amplitudes of ``orders`` with their covariance.

        Raises:
            TeInputError: A bin without samples (less than one whole revolution, or a gap
                that leaves part of the revolution unvisited), or an order outside
                1 .. n_bins / 2 - 1.
        """
        ks = np.asarray(orders, dtype=np.int64).ravel()
        if ks.size and (ks.min() < 1 or ks.max() >= self.n_bins // 2):
            msg = f'orders must lie in 1 .. {self.n_bins // 2 - 1}, got {ks.tolist()}'
            raise TeInputError(msg)
        if self.empty_bins:
            msg = (f'{self.empty_bins} of {self.n_bins} angle bins hold no sample: the record '
                   f'spans {self.revolutions:.3f} revolutions; harmonics need every part of at '
                   'least one whole revolution')
            raise TeInputError(msg)
        centred, sigma = self._centred()
        m = self.n_bins
        spec = np.fft.rfft(centred, axis=1)
        # bin b's centre sits at (b + 1/2) h: shift the phase reference to u = 0
        shift = np.exp(-1j * ks * self._h / 2.0)
        sinc = np.sinc(ks * self._h / (2.0 * math.pi))    # numpy sinc(x) = sin(pi x)/(pi x)
        c = (2.0 / m) * spec[:, ks] * shift / sinc
        cov = sigma * (2.0 / m**2) * float(np.sum(1.0 / self._n)) / float(np.mean(sinc) ** 2)
        assert self._ref is not None  # set with the first samples
        mean = spec[:, 0].real / m + self._ref
        return ChannelHarmonics(orders=ks, c=c, cov=cov, mean=mean,
                                n_samples=self.n_samples, revolutions=self.revolutions)
