"""Angular transmission error of one direction of rotation over whole output revolutions.

Catalogue definition (docs/ACCEPTANCE.md): the peak-to-peak TE over one full output
revolution, measured in each direction of rotation separately, with no reversal inside the
revolution. A record of one direction is cut into whole output revolutions of the kinematic
output angle phi = theta_in / i (counted from the record's first sample), the p-p is taken
per revolution, and the largest is the direction's value. For the report the TE is also
averaged into bins of the output position (phi mod 2 pi) and, when lines are given, its
order spectrum is taken over the same whole revolutions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.spectrum import order_spectrum
from rv_te_bench.core.te import TeStats, output_phase_and_te, te_statistics
from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    import numpy.typing as npt

    from rv_te_bench.core.orders import OrderSet
    from rv_te_bench.core.spectrum import OrderSpectrum

__all__ = ['DirectionTe', 'direction_te']

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class DirectionTe:
    """TE of one direction of rotation (SI units).

    Attributes:
        direction: +1 (output turning positively, 'ccw') or -1 ('cw').
        revolutions: Whole output revolutions analysed.
        pp_per_rev_rad: p-p of each revolution [rad].
        stats: Statistics over all the whole revolutions.
        position_rad: Bin centres of the output position, 0..2 pi [rad].
        te_by_position_rad: Mean TE per position bin [rad] (NaN where a bin is empty).
        spectrum: Order spectrum over the same revolutions (None without lines).
    """

    direction: int
    revolutions: int
    pp_per_rev_rad: tuple[float, ...]
    stats: TeStats
    position_rad: np.ndarray = field(repr=False)
    te_by_position_rad: np.ndarray = field(repr=False)
    spectrum: OrderSpectrum | None = field(repr=False, default=None)

    @property
    def te_pp_rad(self) -> float:
        """The direction's value: the largest p-p of one revolution [rad]."""
        return max(self.pp_per_rev_rad) if self.pp_per_rev_rad else math.nan


def direction_te(theta_in_rad: npt.ArrayLike, theta_out_rad: npt.ArrayLike, *,
                 gear_ratio: float, orders: OrderSet | None = None,
                 duration_s: float | None = None, bins: int = 720) -> DirectionTe:
    """TE statistics of a one-direction record over its whole output revolutions.

    Args:
        theta_in_rad, theta_out_rad: Unwrapped encoder angles [rad], one direction only.
        gear_ratio: Overall ratio i (> 0).
        orders: Lines for the order spectrum (None: no spectrum).
        duration_s: Record duration [s] for the spectrum's frequencies.
        bins: Position bins of the averaged curve (>= 8).

    Returns:
        The direction's TE.

    Raises:
        TeInputError: Shapes differ, the input reverses inside the record, or less than
            one whole output revolution is covered.

    Examples:
        A once-per-revolution TE of 2e-4 rad amplitude, forwards over two revolutions:

        >>> phi = np.linspace(0.0, 4 * np.pi, 20001)
        >>> d = direction_te(79 * phi, phi + 2e-4 * np.sin(phi), gear_ratio=79.0)
        >>> d.revolutions, d.direction, [round(p, 7) for p in d.pp_per_rev_rad]
        (2, 1, [0.0004, 0.0004])
    """
    phi, te = output_phase_and_te(np.asarray(theta_in_rad, dtype=np.float64).ravel(),
                                  np.asarray(theta_out_rad, dtype=np.float64).ravel(),
                                  gear_ratio=gear_ratio)
    if phi.size < 2:
        msg = f'a TE record needs at least 2 samples, got {phi.size}'
        raise TeInputError(msg)
    if isinstance(bins, bool) or not isinstance(bins, int) or bins < 8:
        msg = f'bins must be an integer >= 8, got {bins!r}'
        raise TeInputError(msg)
    step = np.diff(phi)
    direction = 1 if phi[-1] >= phi[0] else -1
    if np.any(direction * step < 0):
        at = int(np.flatnonzero(direction * step < 0)[0])
        msg = (f'the input reverses at sample {at + 1}: a TE record of one direction must '
               'not reverse')
        raise TeInputError(msg)
    travel = direction * (phi - phi[0])
    # a periodic record covers its span plus one sample step
    mean_step = float(travel[-1]) / (travel.size - 1)
    revs = math.floor((float(travel[-1]) + mean_step) / _TWO_PI + 1e-9)
    if revs < 1:
        msg = (f'the record covers {float(travel[-1]) / _TWO_PI:.3f} output revolutions; '
               'one whole revolution is needed')
        raise TeInputError(msg)
    rev = np.minimum(np.floor(travel / _TWO_PI + 1e-12).astype(np.int64), revs)
    keep = rev < revs
    te_k, rev_k = te[keep], rev[keep]
    starts = np.flatnonzero(np.r_[True, rev_k[1:] != rev_k[:-1]])
    pp = np.maximum.reduceat(te_k, starts) - np.minimum.reduceat(te_k, starts)
    pos = np.mod(phi[keep], _TWO_PI)
    idx = np.minimum((pos / _TWO_PI * bins).astype(np.int64), bins - 1)
    counts = np.bincount(idx, minlength=bins)
    sums = np.bincount(idx, weights=te_k, minlength=bins)
    with np.errstate(invalid='ignore', divide='ignore'):
        curve = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    centres = (np.arange(bins) + 0.5) * _TWO_PI / bins
    spectrum = None
    if orders is not None:
        spectrum = order_spectrum(phi, te, orders, duration_s=duration_s, revolutions=revs)
    for arr in (curve, centres):
        arr.setflags(write=False)
    return DirectionTe(direction=direction, revolutions=revs,
                       pp_per_rev_rad=tuple(float(x) for x in pp),
                       stats=te_statistics(te_k, revolutions=float(revs)),
                       position_rad=centres, te_by_position_rad=curve, spectrum=spectrum)
