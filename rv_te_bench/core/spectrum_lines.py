"""The lines of an order spectrum that no part of the reducer explains ("unassigned").

A report's spectrum table lists the labelled lines of the reducer's
:class:`~rv_te_bench.core.orders.OrderSet` (f_out, crank harmonics, sidebands, mesh orders).
A line at an order no part explains (the 2nd harmonic of the output rotation of an
eccentric output encoder, a fixture's or a motor's line) is as real as a labelled one and
may be larger: it is listed as *unassigned*, never dropped and never forced onto the nearest
part's label.

Threshold. A bin is a line when its amplitude reaches

    threshold = max(NOISE_FACTOR x noise floor, STRONGEST_FRACTION x strongest line),

the noise floor being the median amplitude of the bins above order 0 (most bins of a TE
order spectrum hold no line), the strongest line the largest bin above order 0. A bin
within half a bin spacing of a labelled line's order is that line's (assigned); order 0 is
the mean, not a line. Each bin above the threshold is one line: a periodic TE over whole
output revolutions puts each harmonic on one bin (:mod:`rv_te_bench.core.spectrum`), so
adjacent bins above the threshold are adjacent harmonics, not one smeared line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = ['NOISE_FACTOR', 'STRONGEST_FRACTION', 'UnassignedLine', 'line_threshold_rad',
           'threshold_rule_text', 'unassigned_lines']

#: A line is this many times the median bin amplitude (the noise floor) ...
NOISE_FACTOR = 10.0
#: ... and at least this fraction of the strongest line.
STRONGEST_FRACTION = 0.01


@dataclass(frozen=True)
class UnassignedLine:
    """A spectrum line at an order no labelled part explains.

    Attributes:
        output_order: Order of the output rotation (cycles per output revolution).
        amplitude_rad: Peak amplitude [rad].
    """

    output_order: float
    amplitude_rad: float


def threshold_rule_text() -> str:
    """The rule, in words, for the reports."""
    return (f'a line is a bin of at least {NOISE_FACTOR:g} x the median bin amplitude (the '
            f'noise floor) and at least {100 * STRONGEST_FRACTION:g} % of the strongest line')


def line_threshold_rad(orders: npt.ArrayLike, amplitude_rad: npt.ArrayLike) -> float:
    """The threshold [rad] of the module docstring (NaN: no bin above order 0)."""
    o = np.asarray(orders, dtype=float)
    a = np.asarray(amplitude_rad, dtype=float)
    if o.shape != a.shape:
        msg = f'orders and amplitudes differ in length: {o.size} vs {a.size}'
        raise ValueError(msg)
    above = a[(o > 0) & np.isfinite(a)]
    if above.size == 0:
        return math.nan
    return max(NOISE_FACTOR * float(np.median(above)), STRONGEST_FRACTION * float(above.max()))


def unassigned_lines(orders: npt.ArrayLike, amplitude_rad: npt.ArrayLike,
                     labelled_orders: npt.ArrayLike) -> list[UnassignedLine]:
    """The bins above the threshold that no labelled line explains, strongest first.

    Args:
        orders: Output order of each bin (uniform spacing 1/R for R revolutions).
        amplitude_rad: Peak amplitude of each bin [rad].
        labelled_orders: Output orders of the labelled lines.

    Raises:
        ValueError: ``orders`` and ``amplitude_rad`` differ in length.
    """
    o = np.asarray(orders, dtype=float)
    a = np.asarray(amplitude_rad, dtype=float)
    thr = line_threshold_rad(o, a)
    if not math.isfinite(thr):
        return []
    steps = np.diff(o)
    half_bin = 0.5 * float(np.min(steps[steps > 0])) if np.any(steps > 0) else 0.5
    lab = np.asarray(labelled_orders, dtype=float).reshape(-1)
    assigned = (np.abs(o[:, None] - lab[None, :]) < half_bin).any(axis=1) if lab.size else \
        np.zeros(o.shape, dtype=bool)
    keep = (o > 0) & np.isfinite(a) & (a >= thr) & ~assigned
    idx = np.flatnonzero(keep)
    idx = idx[np.argsort(-a[idx], kind='stable')]
    return [UnassignedLine(float(o[i]), float(a[i])) for i in idx]
