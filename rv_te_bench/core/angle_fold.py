"""TE folded onto one output revolution: what identification needs of a record, streamed.

The eccentricity TE of a 2K-V unit (Wang 2020 Eqs 1-8) is a periodic function of the
kinematic output angle ``phi = theta_in / i`` (one output revolution holds whole crank
revolutions), so a record of any length can be reduced, sample by sample and in memory of
fixed size, to per-bin sums over ``n_bins`` equal bins of ``phi mod 2 pi``::

    n, sum x, sum x^2, sum y, sum x y, sum y^2      x = phi - bin centre, y = TE - y_ref

From these the fit works on the bin means (at the bins' mean angle, weighted by the counts)
and the *sample-level* residual of a model m is exact up to the model's curvature inside a
bin: for each bin, ``sum (y - m)^2 = S_yy - 2 m' S_xy + m'^2 S_xx + n (ybar - m(xbar))^2``
(centred sums S, m' the model slope at the bin's mean angle). With 2^15 bins a bin spans
0.011 deg of output angle (0.27 deg of crank angle); the model's curvature adds < 1e-4" and
a contact change inside a bin at most ~0.1" to that bin alone.

Noise floor: white read-head noise of both encoders is estimated without a model from the
second differences of consecutive samples, ``y[k+1] - 2 y[k] + y[k-1]`` (variance 6 sigma^2
for white noise), robustly (median absolute value; contact changes are a few samples per
crank revolution). The TE's own curvature adds ``|TE''| dphi^2``; :meth:`FoldedTe.noise_rms_rad`
withholds the estimate when that is not small (decimated records).

The choice of phi matters: the measured output angle is ``theta_in / i + TE``; folding on
it would shift the crank phase by ``|k_c| TE`` (1.3 deg for 3' of TE) and smear the
identification (issue #15). :meth:`AngleFold.add_encoders` takes both encoders and folds on
``theta_in / i``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from rv_te_bench.core.te import output_phase_and_te
from rv_te_bench.errors import TeInputError

__all__ = ['DEFAULT_BINS', 'AngleFold', 'FoldedTe']

FloatArray = npt.NDArray[np.float64]
_TWO_PI = 2.0 * math.pi
#: Bins per output revolution (0.011 deg each).
DEFAULT_BINS = 2**15
_NOISE_SAMPLES = 4096         # second differences taken from each stretch at most
_NOISE_STRETCHES = 100_000    # stretches whose noise estimates are kept at most
_MAD_TO_SIGMA = 1.0 / 0.6744897501960817   # sigma of a normal = MAD / Phi^-1(3/4)


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class FoldedTe:
    """A TE record folded onto one output revolution (occupied bins only).

    Attributes:
        n_bins: Bins per output revolution.
        bins: Index of each occupied bin (int64, increasing, read-only).
        counts: Samples per occupied bin (int64, read-only).
        phi_rad: Mean output angle of each occupied bin's samples, in [0, 2 pi) [rad].
        te_rad: Mean TE of each occupied bin [rad].
        s_xx: Centred sum of squared angle offsets per bin [rad^2].
        s_xy: Centred angle x TE cross sum per bin [rad^2].
        s_yy: Centred sum of squared TE deviations per bin [rad^2].
        n_samples: Samples folded.
        te_mean_rad: Mean TE over all samples [rad].
        te_ss_rad2: Sum of squared TE deviations from that mean over all samples [rad^2].
        span_rad: Output angle travelled, max - min of the unwrapped phi seen [rad].
        d2_abs_median_rad: Median |second difference| of consecutive TE samples [rad] (NaN:
            no stretch of 3 samples).
        dphi_abs_median_rad: Median |phi step| between consecutive samples [rad].
    """

    n_bins: int
    bins: npt.NDArray[np.int64] = field(repr=False)
    counts: npt.NDArray[np.int64] = field(repr=False)
    phi_rad: FloatArray = field(repr=False)
    te_rad: FloatArray = field(repr=False)
    s_xx: FloatArray = field(repr=False)
    s_xy: FloatArray = field(repr=False)
    s_yy: FloatArray = field(repr=False)
    n_samples: int = 0
    te_mean_rad: float = math.nan
    te_ss_rad2: float = math.nan
    span_rad: float = 0.0
    d2_abs_median_rad: float = math.nan
    dphi_abs_median_rad: float = math.nan

    @property
    def te_std_rad(self) -> float:
        """Standard deviation of the TE samples about their mean [rad]."""
        return math.sqrt(self.te_ss_rad2 / self.n_samples) if self.n_samples else math.nan

    @property
    def output_revolutions(self) -> float:
        """Output revolutions the record spans."""
        return self.span_rad / _TWO_PI

    def coarse(self, factor: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(counts, mean phi [rad], mean TE [rad]) over groups of ``factor`` adjacent bins."""
        groups = self.bins // int(factor)
        _, idx = np.unique(groups, return_inverse=True)
        n = np.asarray(np.bincount(idx, weights=self.counts), dtype=np.float64)  # float: weighted
        return (n, np.bincount(idx, weights=self.counts * self.phi_rad) / n,
                np.bincount(idx, weights=self.counts * self.te_rad) / n)

    def rss_rad2(self, model_rad: FloatArray, slope: FloatArray) -> float:
        """Sample-level residual sum of squares of a model [rad^2].

        Args:
            model_rad: Model TE at ``phi_rad`` of each occupied bin [rad].
            slope: Model dTE/dphi there [rad/rad] (within-bin part of the residual).
        """
        between = self.counts * (self.te_rad - model_rad) ** 2
        within = self.s_yy - 2.0 * slope * self.s_xy + slope * slope * self.s_xx
        return float(np.sum(between) + np.sum(np.maximum(within, 0.0)))

    def noise_rms_rad(self, curvature_rad: float = 0.0) -> float:
        """Sample-to-sample TE noise estimated from second differences [rad], or NaN.

        Args:
            curvature_rad: Bound of |d^2 TE / dphi^2| of the signal [rad/rad^2]; the
                estimate is withheld (NaN) when the signal's own second differences
                (``curvature * dphi^2``) would reach a third of it.
        """
        if not (math.isfinite(self.d2_abs_median_rad) and math.isfinite(self.dphi_abs_median_rad)):
            return math.nan
        sigma = self.d2_abs_median_rad * _MAD_TO_SIGMA / math.sqrt(6.0)
        signal = abs(curvature_rad) * self.dphi_abs_median_rad ** 2
        return sigma if signal <= sigma / 3.0 else math.nan


class AngleFold:
    """Accumulates TE samples into per-bin sums over one output revolution (fixed memory).

    Examples:
        >>> import numpy as np
        >>> phi = np.linspace(0.0, 4 * np.pi, 20_000, endpoint=False)
        >>> fold = AngleFold(n_bins=64)
        >>> fold.add(phi, 1e-4 * np.sin(phi))
        >>> r = fold.result()
        >>> r.n_samples, r.counts.sum(), round(r.output_revolutions, 3)
        (20000, np.int64(20000), 2.0)
    """

    def __init__(self, *, n_bins: int = DEFAULT_BINS) -> None:
        """Start empty.

        Raises:
            TeInputError: ``n_bins`` is not an integer >= 8.
        """
        if isinstance(n_bins, bool) or not isinstance(n_bins, int | np.integer) or n_bins < 8:
            msg = f'n_bins must be an integer >= 8, got {n_bins!r}'
            raise TeInputError(msg)
        self.n_bins = int(n_bins)
        self._h = _TWO_PI / self.n_bins
        self._sums = np.zeros((6, self.n_bins))
        self._y_ref = math.nan
        self._phi_min = math.inf
        self._phi_max = -math.inf
        self._d2: list[float] = []
        self._dphi: list[float] = []
        self.n_samples = 0
        self.skipped = 0

    def add(self, phi_rad: npt.ArrayLike, te_rad: npt.ArrayLike) -> None:
        """Fold consecutive samples (output angle phi = theta_in / i [rad], TE [rad]).

        Samples with a non-finite angle or TE are skipped and counted in ``skipped``.
        Consecutive means one stretch of the record in sample order: the noise estimate
        uses second differences inside the stretch.

        Raises:
            TeInputError: The arrays are not 1-D of equal length.
        """
        phi = np.asarray(phi_rad, dtype=np.float64)
        te = np.asarray(te_rad, dtype=np.float64)
        if phi.ndim != 1 or phi.shape != te.shape:
            msg = f'phi_rad and te_rad must be 1-D of equal length, got {phi.shape} and {te.shape}'
            raise TeInputError(msg)
        ok = np.isfinite(phi) & np.isfinite(te)
        if ok.all():
            self._noise(phi, te)
        else:   # the stretch breaks at the bad samples: no noise estimate across them
            self.skipped += int(phi.size - np.count_nonzero(ok))
            phi, te = phi[ok], te[ok]
        if phi.size == 0:
            return
        if math.isnan(self._y_ref):
            self._y_ref = float(te[0])
        self._phi_min = min(self._phi_min, float(phi.min()))
        self._phi_max = max(self._phi_max, float(phi.max()))
        wrapped = np.mod(phi, _TWO_PI)
        b = np.minimum((wrapped * (1.0 / self._h)).astype(np.int64), self.n_bins - 1)
        x = wrapped - (b + 0.5) * self._h
        y = te - self._y_ref
        nb = self.n_bins
        s = self._sums
        s[0] += np.bincount(b, minlength=nb)
        s[1] += np.bincount(b, weights=x, minlength=nb)
        s[2] += np.bincount(b, weights=x * x, minlength=nb)
        s[3] += np.bincount(b, weights=y, minlength=nb)
        s[4] += np.bincount(b, weights=x * y, minlength=nb)
        s[5] += np.bincount(b, weights=y * y, minlength=nb)
        self.n_samples += int(phi.size)

    def add_encoders(self, theta_in_rad: npt.ArrayLike, theta_out_rad: npt.ArrayLike, *,
                     gear_ratio: float) -> None:
        """Fold consecutive encoder samples: TE of Wang 2020 Eq. 22 at phi = theta_in / i.

        Raises:
            TeInputError: Shapes differ, or ``gear_ratio`` is not finite and > 0.
        """
        self.add(*output_phase_and_te(theta_in_rad, theta_out_rad, gear_ratio=gear_ratio))

    def _noise(self, phi: FloatArray, te: FloatArray) -> None:
        if te.size < 3 or len(self._d2) >= _NOISE_STRETCHES:
            return
        y = te[:_NOISE_SAMPLES]
        d2 = np.abs(y[2:] - 2.0 * y[1:-1] + y[:-2])
        self._d2.append(float(np.median(d2)))
        self._dphi.append(float(np.median(np.abs(np.diff(phi[:_NOISE_SAMPLES])))))

    def result(self) -> FoldedTe:
        """The record folded so far (occupied bins only; read-only arrays)."""
        s = self._sums
        occ = np.flatnonzero(s[0] > 0)
        n = s[0, occ]
        sx, sxx, sy, sxy, syy = (s[k, occ] for k in range(1, 6))
        xbar = sx / n
        ybar = sy / n
        centres = (occ + 0.5) * self._h
        total = float(n.sum())
        ysum = float(sy.sum())
        ss = float(syy.sum()) - ysum * ysum / total if total else math.nan
        return FoldedTe(
            n_bins=self.n_bins, bins=_readonly(occ.astype(np.int64)),
            counts=_readonly(n.astype(np.int64)),
            phi_rad=_readonly(centres + xbar),
            te_rad=_readonly(ybar + (0.0 if math.isnan(self._y_ref) else self._y_ref)),
            s_xx=_readonly(np.maximum(sxx - sx * xbar, 0.0)),
            s_xy=_readonly(sxy - sx * ybar),
            s_yy=_readonly(np.maximum(syy - sy * ybar, 0.0)),
            n_samples=self.n_samples,
            te_mean_rad=(ysum / total + self._y_ref) if total else math.nan,
            te_ss_rad2=max(ss, 0.0) if total else math.nan,
            span_rad=(self._phi_max - self._phi_min) if total else 0.0,
            d2_abs_median_rad=float(np.median(self._d2)) if self._d2 else math.nan,
            dphi_abs_median_rad=float(np.median(self._dphi)) if self._dphi else math.nan)
