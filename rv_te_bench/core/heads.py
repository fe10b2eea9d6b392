"""Several read heads on one scale: how their readings combine, and what that cancels.

Head j sits at ``beta_j`` around the scale (from head 0) and reads, zeroed to the shaft
angle, ``r_j = theta + s(theta - beta_j) + noise`` (the scale's error ``s`` at the point
under the head; see :mod:`sim.read_heads` for the physics, derived there independently).
Write the scale error as harmonics of the scale revolution, ``s(u) = sum_k Re(c_k e^{iku})``.
A weighted mean of the heads, ``sum_j w_j r_j`` with ``sum_j w_j = 1``, then carries

    sum_k Re(c_k H_k e^{ik theta}),      H_k = sum_j w_j e^{-ik beta_j}

so order k of the scale error passes with the gain ``|H_k|``. Equal-division averaging,
N heads 360/N deg apart with w_j = 1/N, has ``H_k = 1`` when N divides k and 0 otherwise:
it cancels every harmonic that is not a multiple of N (2 diametric heads: all odd orders,
eccentricity included) and leaves the multiples of N untouched. Those stay **ambiguous**:
nothing the heads see tells them from the reducer's own TE at the same output order.

For heads that are not equally spaced, :class:`HeadLayout` takes the weights of least norm
(least noise) that keep ``sum w = 1`` and cancel order 1 (``H_1 = 0``, the mounting
eccentricity, the largest encoder term); for equal spacing these are the equal weights.
A layout for which no such weights exist (two heads not diametric), or only with a noise
gain above :data:`MAX_NOISE_GAIN`, or with two heads at the same place, is refused with a
:class:`~rv_te_bench.errors.HeadLayoutError` naming the angles.

The head differences ``r_j - r_0`` hold ``c_k (e^{-ik beta_j} - e^{-ik beta_0})`` and no
reducer TE: order k is **observable** (self-calibration, :mod:`rv_te_bench.core.selfcal`)
when that vector is not small (:meth:`HeadLayout.observability`); for equal division the
unobservable orders are again the multiples of N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from rv_te_bench.core.units import rad_to_deg
from rv_te_bench.errors import HeadLayoutError

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

    import numpy.typing as npt

__all__ = ['CANCEL_TOL', 'MAX_NOISE_GAIN', 'MIN_OBSERVABILITY', 'MIN_SEPARATION_RAD',
           'HeadLayout', 'HeadLayoutJson']

_TWO_PI = 2.0 * math.pi
#: |H_k| below this counts as cancelled.
CANCEL_TOL = 1e-6
#: Two heads closer than this (0.5 deg) are one head twice.
MIN_SEPARATION_RAD = math.radians(0.5)
#: Weights whose noise gain sqrt(N sum w^2) exceeds this are refused (ill-conditioned).
MAX_NOISE_GAIN = 3.0
#: An order is observable from the head differences when |a_k| / sqrt(2 N) reaches this
#: (1 for the best layouts; an estimate's uncertainty grows as 1 / observability).
MIN_OBSERVABILITY = 0.1


def _deg_list(angles: Iterable[float]) -> str:
    return '[' + ', '.join(f'{float(rad_to_deg(a)):.6g}' for a in angles) + '] deg'


class HeadLayoutJson(TypedDict):
    """The JSON of :class:`HeadLayout` (degrees for people, radians kept)."""

    n_heads: int
    head_ids: list[int]
    angles_rad: list[float]
    angles_deg: list[float]
    weights: list[float]
    equally_spaced: bool
    noise_gain: float
    ambiguous_orders: list[int]
    unobservable_orders: list[int]
    max_order: int
    description: str


@dataclass(frozen=True)
class HeadLayout:
    """The read heads of one scale and the weights of their mean.

    Build it with :meth:`of`. Attributes are read-only tuples.

    Attributes:
        angles_rad: Angle of each head around the scale from head 0 [rad] (head 0 first).
        weights: Weight of each head in the mean (sum 1; 1/N for equal division).
        head_ids: The heads' numbers on the bench (default 0 .. N-1).
    """

    angles_rad: tuple[float, ...]
    weights: tuple[float, ...]
    head_ids: tuple[int, ...]

    @classmethod
    def of(cls, angles_rad: Sequence[float], *, head_ids: Sequence[int] | None = None,
           ) -> HeadLayout:
        """The layout of heads at ``angles_rad``, with its weights.

        Args:
            angles_rad: 1 .. 16 finite angles [rad].
            head_ids: Their numbers (default 0 .. N-1).

        Raises:
            HeadLayoutError: No head, a non-finite angle, two heads at the same place, or
                no weighting cancels order 1 (names the angles).

        Examples:
            >>> lay = HeadLayout.of([0.0, math.pi])
            >>> lay.weights, lay.remaining_orders(6)
            ((0.5, 0.5), (2, 4, 6))
        """
        try:
            ang = tuple(float(a) for a in angles_rad)
        except (TypeError, ValueError):
            msg = f'head angles must be numbers, got {angles_rad!r}'
            raise HeadLayoutError(msg) from None
        if not 1 <= len(ang) <= 16 or not all(math.isfinite(a) for a in ang):
            msg = f'need 1 to 16 finite head angles, got {list(angles_rad)!r}'
            raise HeadLayoutError(msg)
        ids = tuple(range(len(ang))) if head_ids is None else tuple(int(i) for i in head_ids)
        if len(ids) != len(ang) or len(set(ids)) != len(ids):
            msg = f'head_ids must be {len(ang)} distinct numbers, got {list(ids)!r}'
            raise HeadLayoutError(msg)
        wrapped = np.mod(np.asarray(ang), _TWO_PI)
        for j in range(len(ang)):
            for m in range(j):
                gap = abs((wrapped[j] - wrapped[m] + math.pi) % _TWO_PI - math.pi)
                if gap < MIN_SEPARATION_RAD:
                    msg = (f'heads {ids[m]} and {ids[j]} sit at the same place ({_deg_list(ang)}):'
                           ' a head counted twice cannot be averaged or self-calibrated')
                    raise HeadLayoutError(msg)
        return cls(ang, _weights(ang), ids)

    @property
    def n_heads(self) -> int:
        """Number of heads."""
        return len(self.angles_rad)

    @property
    def equally_spaced(self) -> bool:
        """Heads 360/N deg apart (within 0.01 deg)."""
        n = self.n_heads
        if n < 2:
            return False
        a = np.sort(np.mod(np.asarray(self.angles_rad) - self.angles_rad[0], _TWO_PI))
        return bool(np.all(np.abs(a - _TWO_PI * np.arange(n) / n) < math.radians(0.01)))

    @property
    def noise_gain(self) -> float:
        """Noise of the weighted mean over that of one head's noise / sqrt(N):
        ``sqrt(N sum w^2)`` (1 for equal weights)."""
        w = np.asarray(self.weights)
        return float(math.sqrt(self.n_heads * float(w @ w)))

    def transfer(self, orders: npt.ArrayLike) -> np.ndarray:
        """Gain H_k of the weighted mean for scale-error order k (complex)."""
        k = np.asarray(orders, dtype=np.float64)
        b = np.asarray(self.angles_rad)
        w = np.asarray(self.weights)
        gain: npt.NDArray[np.complex128] = np.exp(-1j * k[..., None] * b) @ w
        return gain

    def remaining_orders(self, max_order: int) -> tuple[int, ...]:
        """Orders 1 .. max_order the weighted mean does not cancel (|H_k| > CANCEL_TOL):
        the scale-error orders still ambiguous with the reducer's TE."""
        ks = np.arange(1, int(max_order) + 1)
        return tuple(int(k) for k in ks[np.abs(self.transfer(ks)) > CANCEL_TOL])

    def difference_vectors(self, orders: npt.ArrayLike) -> np.ndarray:
        """a_jk = e^{-ik beta_j} - e^{-ik beta_0} for heads j = 1 .. N-1, shape (K, N-1)."""
        k = np.asarray(orders, dtype=np.float64)
        b = np.asarray(self.angles_rad)
        a: npt.NDArray[np.complex128] = (np.exp(-1j * k[:, None] * b[None, 1:])
                                         - np.exp(-1j * k[:, None] * b[0]))
        return a

    def observability(self, orders: npt.ArrayLike) -> np.ndarray:
        """|a_k| / sqrt(2 N) per order: 1 for equal division where N does not divide k, 0
        where it does or with one head (the self-calibration's uncertainty scales as
        1 / observability)."""
        k = np.asarray(orders, dtype=np.float64)
        if self.n_heads < 2:
            return np.zeros(k.shape)
        a = self.difference_vectors(k)
        obs: npt.NDArray[np.float64] = np.sqrt(np.sum(np.abs(a) ** 2, axis=1)
                                               / (2.0 * self.n_heads))
        return obs

    def unobservable_orders(self, max_order: int) -> tuple[int, ...]:
        """Orders 1 .. max_order the head differences cannot see (observability below
        :data:`MIN_OBSERVABILITY`)."""
        ks = np.arange(1, int(max_order) + 1)
        return tuple(int(k) for k in ks[self.observability(ks) < MIN_OBSERVABILITY])

    def combine(self, readings_rad: npt.ArrayLike) -> np.ndarray:
        """The weighted mean of the heads' readings, shape (N, n) -> (n,) [rad].

        Raises:
            HeadLayoutError: The first axis is not one row per head.
        """
        r = np.asarray(readings_rad, dtype=np.float64)
        if r.ndim != 2 or r.shape[0] != self.n_heads:
            msg = f'readings must have one row per head ({self.n_heads}), got shape {r.shape}'
            raise HeadLayoutError(msg)
        if self.n_heads == 1:
            row: npt.NDArray[np.float64] = r[0].copy()
            return row
        combined: npt.NDArray[np.float64] = np.asarray(self.weights) @ r
        return combined

    def subset(self, head_ids: Sequence[int]) -> HeadLayout:
        """The layout of some of the heads (a block that lacks one).

        Raises:
            HeadLayoutError: An unknown head, or the heads left cannot be averaged.
        """
        pos = {h: j for j, h in enumerate(self.head_ids)}
        try:
            idx = [pos[int(h)] for h in head_ids]
        except KeyError as exc:
            msg = f'head {exc.args[0]} is not one of the heads {list(self.head_ids)}'
            raise HeadLayoutError(msg) from None
        return HeadLayout.of([self.angles_rad[j] for j in idx],
                             head_ids=[self.head_ids[j] for j in idx])

    def describe(self, max_order: int = 0) -> str:
        """One line for people: heads, averaging, orders it leaves (up to ``max_order``,
        default 4 N)."""
        n = self.n_heads
        if n == 1:
            return ('one read head: no scale-error order cancels; its eccentricity (order 1) '
                    'and graduation error add to the reducer\'s lines')
        top = max_order or 4 * n
        left = self.remaining_orders(top)
        if self.equally_spaced:
            how = (f'{n} heads equally spaced, equal-division averaging: every scale '
                   f'harmonic that is not a multiple of {n} cancels')
        else:
            how = (f'{n} heads at {_deg_list(self.angles_rad)}, weights '
                   f'{", ".join(f"{w:.3f}" for w in self.weights)} (noise gain '
                   f'{self.noise_gain:.2f}): order 1 cancels')
        shown = ', '.join(map(str, left)) or 'none'
        return f'{how}; orders still ambiguous with the reducer (<= {top}): {shown}'

    def to_plain(self, max_order: int = 0) -> HeadLayoutJson:
        """JSON-friendly record (degrees for people, radians kept)."""
        top = max_order or 4 * self.n_heads
        return {'n_heads': self.n_heads, 'head_ids': list(self.head_ids),
                'angles_rad': list(self.angles_rad),
                'angles_deg': [float(rad_to_deg(a)) for a in self.angles_rad],
                'weights': list(self.weights), 'equally_spaced': self.equally_spaced,
                'noise_gain': self.noise_gain,
                'ambiguous_orders': list(self.remaining_orders(top)),
                'unobservable_orders': list(self.unobservable_orders(top)),
                'max_order': top, 'description': self.describe(top)}


def _weights(angles: tuple[float, ...]) -> tuple[float, ...]:
    """Least-norm weights with sum 1 and H_1 = 0 (see the module docstring)."""
    n = len(angles)
    if n == 1:
        return (1.0,)
    b = np.asarray(angles)
    a = np.vstack([np.ones(n), np.cos(b), np.sin(b)])
    rhs = np.array([1.0, 0.0, 0.0])
    w, *_ = np.linalg.lstsq(a, rhs, rcond=None)
    if np.max(np.abs(a @ w - rhs)) > 1e-9:
        msg = (f'no weighting of heads at {_deg_list(angles)} cancels the once-per-revolution '
               'scale error (eccentricity): two heads must be diametric (180 deg apart), '
               'three or more must not crowd together')
        raise HeadLayoutError(msg)
    gain = math.sqrt(n * float(w @ w))
    if gain > MAX_NOISE_GAIN:
        msg = (f'heads at {_deg_list(angles)} cancel the once-per-revolution error only with '
               f'weights {np.round(w, 3).tolist()} (noise gain {gain:.1f} > '
               f'{MAX_NOISE_GAIN:g}): spread the heads around the scale')
        raise HeadLayoutError(msg)
    return tuple(float(x) for x in w)
