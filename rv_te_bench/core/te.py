"""Transmission error from two shaft encoders (Wang 2020 Eq. 22) and its statistics.

Wang 2020 Eq. 22 is printed in the mesh-line form

    TE = (theta_2 - r_g * theta_1 / r_p) * 10800 / (r_p * pi)    [arcmin]

which divides by the base radius r_p twice. Its consistent form keeps the mesh-line
displacement r_p * theta_2 - r_g * theta_1 [m] and turns it back into an output angle by
dividing once by r_p:

    TE = (r_p * theta_2 - r_g * theta_1) / r_p = theta_2 - theta_1 * r_g / r_p    [rad]

For a single mesh r_g / r_p = 1 / i. With two shaft encoders the same reasoning applies to
the whole train: theta_1 is the input-shaft angle, theta_2 the output-shaft angle and i the
overall ratio (input revolutions per output revolution), so

    TE = theta_out - theta_in / i    [rad],    TE[arcmin] = TE[rad] * 10800 / pi.

Sign convention: TE > 0 when the output shaft is ahead of where an ideal (error-free)
reducer driven by the same input angle would put it. Both angles are unwrapped,
multi-turn, measured positive in the same sense of rotation of their shafts.

Statistics follow the papers: peak-to-peak (max - min), amplitude (max |TE|), mean and
(population) standard deviation, preferably over whole output revolutions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.core._checks import finite_positive
from rv_te_bench.core.units import rad_to_arcmin
from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = ['RunningStats', 'TeMoments', 'TeStats', 'moments_of_finite',
           'output_phase_and_te', 'stats_of_finite',
           'te_statistics', 'transmission_error_rad']

# OpenBLAS runs ddot on one thread up to 10,000 elements (no worker threads woken)
_DOT_SINGLE_THREAD_N = 8192


def _check_ratio(gear_ratio: float) -> float:
    return finite_positive(gear_ratio, 'gear_ratio', TeInputError)


def output_phase_and_te(
    theta_in_rad: npt.ArrayLike, theta_out_rad: npt.ArrayLike, *, gear_ratio: float,
    check: bool = True, out: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Wang 2020 Eq. 22 with the output phase it is taken at: (theta_in / i, TE).

    The one place the suite forms TE = theta_out - theta_in / i from encoder angles
    (batch, streaming, folding, acceptance steps): phi = theta_in / i first, then
    TE = theta_out - phi, so every caller gets bit-identical values.

    Args:
        theta_in_rad: Unwrapped input-shaft angle [rad], any shape.
        theta_out_rad: Unwrapped output-shaft angle [rad], same shape.
        gear_ratio: Overall ratio i, input revolutions per output revolution (> 0).
        check: Check ``gear_ratio`` and the shapes (False on hot paths whose caller holds a
            checked ratio and arrays of one length; then nothing is checked here).
        out: ``(phi, te)`` float64 arrays of the angles' shape to write into (the streaming
            analysis writes straight into its window buffer); None: new arrays.

    Returns:
        ``(phi, te)``: the ideal output angle theta_in / i [rad] and TE [rad], float64,
        same shape. Positive TE: the output leads the ideal ratio.

    Raises:
        TeInputError: With ``check``: shapes differ or ``gear_ratio`` is not finite and > 0.
    """
    theta_in = np.asarray(theta_in_rad, dtype=np.float64)
    theta_out = np.asarray(theta_out_rad, dtype=np.float64)
    if check:
        gear_ratio = _check_ratio(gear_ratio)
        if theta_in.shape != theta_out.shape:
            msg = f'shape mismatch: {theta_in.shape=} vs {theta_out.shape=}'
            raise TeInputError(msg)
    if out is not None:
        phi = np.divide(theta_in, gear_ratio, out=out[0])
        return phi, np.subtract(theta_out, phi, out=out[1])
    phi = theta_in / gear_ratio
    return phi, theta_out - phi


def transmission_error_rad(
    theta_in_rad: npt.ArrayLike, theta_out_rad: npt.ArrayLike, *, gear_ratio: float,
) -> np.ndarray:
    """Output-side transmission error, TE = theta_out - theta_in / i (Wang 2020 Eq. 22).

    Args:
        theta_in_rad: Unwrapped input-shaft angle [rad], any shape.
        theta_out_rad: Unwrapped output-shaft angle [rad], same shape.
        gear_ratio: Overall ratio i, input revolutions per output revolution (> 0).

    Returns:
        TE [rad], float64, same shape. Positive: the output leads the ideal ratio.

    Raises:
        TeInputError: Shapes differ or ``gear_ratio`` is not finite and > 0.

    Examples:
        An ideal 79:1 reducer gives zero; an output 1 arcmin ahead gives +1 arcmin:

        >>> import numpy as np
        >>> from rv_te_bench.core.units import arcmin_to_rad, rad_to_arcmin
        >>> theta_in = np.array([0.0, 1.0, 2.0]) * 2 * np.pi * 79
        >>> transmission_error_rad(theta_in, theta_in / 79, gear_ratio=79).tolist()
        [0.0, 0.0, 0.0]
        >>> te = transmission_error_rad([0.0], [float(arcmin_to_rad(1.0))], gear_ratio=79)
        >>> round(float(rad_to_arcmin(te[0])), 12)
        1.0
    """
    return output_phase_and_te(theta_in_rad, theta_out_rad, gear_ratio=gear_ratio)[1]


def _none_if_nan(x: float) -> float | None:
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class TeStats:
    """TE statistics over a stretch of samples (SI units).

    Attributes:
        pp_rad: Peak-to-peak, max(TE) - min(TE) [rad].
        amplitude_rad: Amplitude as the papers define it, max |TE| [rad].
        mean_rad: Mean TE [rad].
        std_rad: Population standard deviation of TE [rad].
        revolutions: Output revolutions covered (NaN when unknown).
        n_samples: Number of samples; 0 gives NaN statistics.
    """

    pp_rad: float
    amplitude_rad: float
    mean_rad: float
    std_rad: float
    revolutions: float
    n_samples: int

    @classmethod
    def empty(cls, revolutions: float = math.nan) -> TeStats:
        """Statistics of no samples: every value NaN, ``n_samples`` 0."""
        nan = math.nan
        return cls(nan, nan, nan, nan, float(revolutions), 0)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict with arcmin and rad keys (NaN becomes None).

        Examples:
            >>> d = TeStats(0.001, 0.0006, 0.0, 0.0003, 1.0, 10).to_json_dict()
            >>> round(d['te_pp_arcmin'], 6), d['te_pp_rad'], d['n_samples']
            (3.437747, 0.001, 10)
        """
        out: dict[str, Any] = {}
        for name in ('pp', 'amplitude', 'mean', 'std'):
            value_rad = float(getattr(self, f'{name}_rad'))
            out[f'te_{name}_arcmin'] = _none_if_nan(float(rad_to_arcmin(value_rad)))
            out[f'te_{name}_rad'] = _none_if_nan(value_rad)
        out['revolutions'] = _none_if_nan(float(self.revolutions))
        out['n_samples'] = int(self.n_samples)
        return out


def te_statistics(te_rad: npt.ArrayLike, *, revolutions: float = math.nan) -> TeStats:
    """Peak-to-peak, amplitude, mean and standard deviation of a TE record.

    Args:
        te_rad: TE samples [rad], any shape (flattened).
        revolutions: Output revolutions the record covers (reported, not used).

    Returns:
        The statistics; an empty record gives :meth:`TeStats.empty`.

    Raises:
        TeInputError: A sample is NaN or infinite.

    Examples:
        >>> s = te_statistics([-1.0, 0.0, 3.0])
        >>> (s.pp_rad, s.amplitude_rad, s.mean_rad, s.n_samples)
        (4.0, 3.0, 0.6666666666666666, 3)
    """
    te = np.asarray(te_rad, dtype=np.float64).ravel()
    if te.size == 0:
        return TeStats.empty(revolutions)
    if not np.all(np.isfinite(te)):
        bad = int(np.flatnonzero(~np.isfinite(te))[0])
        msg = f'te_rad[{bad}] is not finite ({te[bad]!r})'
        raise TeInputError(msg)
    return stats_of_finite(te, revolutions=revolutions)


def stats_of_finite(te_rad: np.ndarray, *, revolutions: float = math.nan,
                    scratch: np.ndarray | None = None) -> TeStats:
    """:func:`te_statistics` of a non-empty 1-D float64 record known to be finite.

    For callers that checked the samples already (the streaming analysis): no finiteness
    pass, and the deviations go into ``scratch`` (at least as long as ``te_rad``) instead
    of a new array. The arithmetic is numpy's ``mean``/``std`` (pairwise sums), so the
    values equal those of :func:`te_statistics` bit for bit.
    """
    return moments_of_finite(te_rad, scratch=scratch).stats(revolutions)


@dataclass(frozen=True)
class TeMoments:
    """Count, extremes, mean and sum of squared deviations (M2) of a finite TE record.

    What :class:`RunningStats` merges (:meth:`RunningStats.add_moments`) and what
    :class:`TeStats` is derived from, so that a window's statistics and the cumulative
    statistics come from one pass over the window.

    Attributes:
        n_samples: Number of samples (> 0).
        min_rad: Smallest TE [rad].
        max_rad: Largest TE [rad].
        mean_rad: Mean TE [rad].
        m2_rad2: Sum of squared deviations from the mean [rad^2].
    """

    n_samples: int
    min_rad: float
    max_rad: float
    mean_rad: float
    m2_rad2: float

    def stats(self, revolutions: float = math.nan) -> TeStats:
        """The :class:`TeStats` of the record."""
        lo, hi = self.min_rad, self.max_rad
        return TeStats(pp_rad=hi - lo, amplitude_rad=max(abs(lo), abs(hi)),
                       mean_rad=self.mean_rad,
                       std_rad=math.sqrt(self.m2_rad2 / self.n_samples),
                       revolutions=float(revolutions), n_samples=self.n_samples)


def moments_of_finite(te_rad: np.ndarray, *, scratch: np.ndarray | None = None,
                      min_max: tuple[float, float] | None = None) -> TeMoments:
    """:class:`TeMoments` of a non-empty 1-D float64 record known to be finite.

    Pairwise sums as numpy's ``mean``/``std``; the deviations are squared in ``scratch``
    (at least as long as ``te_rad``) when given, else in a new array. ``min_max``: the
    record's (min, max) when the caller has them already (no pass for them here).
    """
    n = te_rad.size
    if min_max is None:
        lo = float(np.minimum.reduce(te_rad))
        hi = float(np.maximum.reduce(te_rad))
    else:
        lo, hi = min_max
    mean = float(np.add.reduce(te_rad)) / n
    dev = np.subtract(te_rad, mean, out=None if scratch is None else scratch[:n])
    np.multiply(dev, dev, out=dev)
    return TeMoments(int(n), lo, hi, mean, float(np.add.reduce(dev)))


class RunningStats:
    """Mergeable running min / max / mean / variance of TE with O(1) memory.

    Blocks are combined with Chan, Golub and LeVeque's pairwise update of the sum of
    squared deviations (M2), so the result does not depend on how the samples were cut
    into blocks (to rounding) and does not suffer the cancellation of sum-of-squares.

    Examples:
        >>> rs = RunningStats()
        >>> rs.update([1.0, 2.0])
        >>> other = RunningStats()
        >>> other.update([3.0, 4.0])
        >>> rs.merge(other)
        >>> s = rs.stats()
        >>> (s.mean_rad, round(s.std_rad ** 2, 12), s.pp_rad, s.n_samples)
        (2.5, 1.25, 3.0, 4)
    """

    __slots__ = ('_m2', '_max', '_mean', '_min', '_n')

    def __init__(self) -> None:
        """Start with no samples."""
        self._n = 0
        self._mean = 0.0
        self._m2 = 0.0
        self._min = math.inf
        self._max = -math.inf

    @property
    def n_samples(self) -> int:
        """Number of samples seen."""
        return self._n

    def _combine(self, n_b: int, mean_b: float, m2_b: float, min_b: float, max_b: float) -> None:
        n_a = self._n
        n = n_a + n_b
        delta = mean_b - self._mean
        self._mean += delta * (n_b / n)
        self._m2 += m2_b + delta * delta * (n_a * n_b / n)
        self._n = n
        self._min = min(self._min, min_b)
        self._max = max(self._max, max_b)

    def update(self, te_rad: npt.ArrayLike) -> None:
        """Add a block of TE samples [rad].

        Raises:
            TeInputError: The block holds NaN or infinite values (nothing is added).
        """
        te = np.asarray(te_rad, dtype=np.float64).ravel()
        n_b = te.size
        if n_b == 0:
            return
        mean_b = float(np.add.reduce(te)) / n_b
        if not math.isfinite(mean_b):
            msg = 'RunningStats.update: te_rad holds NaN or infinite values'
            raise TeInputError(msg)
        dev = te - mean_b
        # square in place and sum (pairwise): no BLAS call, whose worker threads would
        # spin on the other cores after every block
        np.multiply(dev, dev, out=dev)
        self._combine(n_b, mean_b, float(np.add.reduce(dev)), float(np.minimum.reduce(te)),
                      float(np.maximum.reduce(te)))

    def add_moments(self, moments: TeMoments) -> None:
        """Fold in a record summarised by its :class:`TeMoments` (as :meth:`update` would,
        to rounding: the record's own pass is reused instead of a second one)."""
        self._combine(moments.n_samples, moments.mean_rad, moments.m2_rad2, moments.min_rad,
                      moments.max_rad)

    def add_finite(self, te_rad: np.ndarray, scratch: np.ndarray) -> None:
        """Fold in a non-empty 1-D float64 record known to be finite (as
        ``add_moments(moments_of_finite(te_rad, scratch=scratch))``: min and max exact, mean
        and M2 to rounding) in fewer passes and without the intermediate object: the
        streaming analysis folds each new block in when its cumulative statistics are read,
        after every block on the TE node."""
        n = te_rad.size
        lo = float(np.minimum.reduce(te_rad))
        hi = float(np.maximum.reduce(te_rad))
        # one pass fewer than mean-then-deviations: sums of the deviations from the
        # midrange c (within pp / 2 of the mean, so M2 = S2 - S1^2 / n loses at most
        # ~log2(n / 4) bits, in practice none: pp^2 / (4 var) is ~2 for a TE record)
        c = 0.5 * (lo + hi)
        dev = np.subtract(te_rad, c, out=scratch[:n])
        s1 = float(np.add.reduce(dev))
        if n <= _DOT_SINGLE_THREAD_N:   # BLAS ddot: one thread at this size
            s2 = float(np.dot(dev, dev))
        else:
            np.multiply(dev, dev, out=dev)
            s2 = float(np.add.reduce(dev))
        self._combine(n, c + s1 / n, max(s2 - s1 * s1 / n, 0.0), lo, hi)

    def merge(self, other: RunningStats) -> None:
        """Fold in another accumulator (as if its samples had been added here)."""
        if other._n == 0:
            return
        self._combine(other._n, other._mean, other._m2, other._min, other._max)

    def copy(self) -> RunningStats:
        """An independent copy."""
        out = RunningStats()
        out._n, out._mean, out._m2 = self._n, self._mean, self._m2
        out._min, out._max = self._min, self._max
        return out

    def stats(self, revolutions: float = math.nan) -> TeStats:
        """Statistics of every sample seen so far (NaN when none)."""
        if self._n == 0:
            return TeStats.empty(revolutions)
        lo, hi = self._min, self._max
        # positional: (pp, amplitude, mean, std, revolutions, n_samples)
        return TeStats(hi - lo, max(abs(lo), abs(hi)), self._mean,
                       math.sqrt(max(self._m2, 0.0) / self._n), float(revolutions), self._n)
