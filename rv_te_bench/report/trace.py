"""The thinned TE trace an analysis keeps for its plots (:class:`TeTrace`).

A type of its own module: the analysis result (:mod:`.results`) holds one and the
uncertainty budgets (:mod:`.uncertainty`) read its extremes, without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from rv_te_bench.core.envelope import EnvelopeData

    FloatArray = npt.NDArray[np.float64]

__all__ = ['TeTrace']


@dataclass(frozen=True)
class TeTrace:
    """A thinned TE trace for plots: every ``stride``-th sample, NaN rows at gaps; and the
    min/max envelope of every clean sample (what long records are drawn from).

    Attributes:
        theta_out_rad: Output angle [rad] (unwrapped, as recorded).
        te_rad: TE at those samples [rad].
        stride: Every how many samples one was kept.
        envelope: TE min and max per bucket of consecutive samples over the whole record
            (:class:`~rv_te_bench.core.envelope.EnvelopeData`), or None.
    """

    theta_out_rad: FloatArray = field(repr=False)
    te_rad: FloatArray = field(repr=False)
    stride: int = 1
    envelope: EnvelopeData | None = field(default=None, repr=False)
