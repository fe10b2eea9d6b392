"""Compensation advice as plain data: what the node publishes and the CLI prints.

Mirrors ``rv_te_msgs/CompensationAdvice`` and ``rv_te_msgs/Modification`` so that every
recommendation can be produced and tested without ROS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal, TypeAlias, TypedDict

from rv_te_bench.errors import CompensationError
from sim.units import rad_to_arcmin, rad_to_deg

__all__ = ['Advice', 'AdviceKind', 'Modification', 'ModificationJson', 'advice_kind',
           'modification_value']

#: The compensation the suite can advise: 2K-V assembly phases (Wang 2020 Eq. 21, identified
#: from the measured TE or optimised on the preset) or RV tooth-profile modification (Hu 2020
#: Hu 2020 Eqs 24-27).
AdviceKind: TypeAlias = Literal['assembly-phases', 'tooth-profile']

_ADVICE_BY_MODEL: dict[str, AdviceKind] = {
    'wang2020-2kv': 'assembly-phases',
    'hu2020-rv': 'tooth-profile',
}


def advice_kind(model: str) -> AdviceKind | None:
    """The advice for a bench whose preset has the TE model ``model`` (``Preset.model``).

    The one place the report (``report.analysis``) and the compensation node choose it:
    ``'assembly-phases'`` for ``wang2020-2kv``, ``'tooth-profile'`` for ``hu2020-rv``,
    None for a model without a compensation model.

    Examples:
        >>> advice_kind('wang2020-2kv'), advice_kind('hu2020-rv'), advice_kind('li2023-rv')
        ('assembly-phases', 'tooth-profile', None)
    """
    return _ADVICE_BY_MODEL.get(model)


class ModificationJson(TypedDict):
    """The JSON of :class:`Modification` (None: not finite)."""

    factor: str
    symbol: str
    unit: str
    current_value: float | None
    recommended_value: float | None
    sensitivity_index: float | None


@dataclass(frozen=True)
class Modification:
    """One recommended change to a reducer factor.

    Attributes:
        factor: Human name, e.g. ``"pin radius"``.
        symbol: Symbol used in the paper, e.g. ``"r_rp"``.
        unit: Unit of ``current_value`` / ``recommended_value`` (SI: ``"m"``, ``"rad"``).
        current_value: Value now.
        recommended_value: Value recommended.
        sensitivity_index: Error sensitivity S_j (Hu 2020); NaN where not applicable.
    """

    factor: str
    symbol: str
    unit: str
    current_value: float
    recommended_value: float
    sensitivity_index: float = math.nan

    def to_json_dict(self) -> ModificationJson:
        """JSON-friendly dict (NaN becomes None)."""
        return {
            'factor': self.factor, 'symbol': self.symbol, 'unit': self.unit,
            'current_value': _finite_or_none(self.current_value),
            'recommended_value': _finite_or_none(self.recommended_value),
            'sensitivity_index': _finite_or_none(self.sensitivity_index),
        }


def modification_value(x: float, unit: str, *, html: bool = False) -> str:
    """A modification value for people: radians also in degrees, metres also in mm.

    Text names the unit (``'0.1 rad (5.73 deg)'``); ``html`` leaves it to the table's unit
    column (``'0.1 (5.73&deg;)'``).

    Examples:
        >>> modification_value(0.001, 'm')
        '0.001 m (1.0000 mm)'
        >>> modification_value(0.001, 'm', html=True)
        '0.001 (1.0000 mm)'
    """
    head = f'{x:.6g}' if html else f'{x:.6g} {unit}'
    if unit == 'rad':
        deg = f'{float(rad_to_deg(x)):.2f}'
        return f'{head} ({deg}&deg;)' if html else f'{head} ({deg} deg)'
    if unit == 'm':
        return f'{head} ({x * 1e3:.4f} mm)'
    return head


@dataclass(frozen=True)
class Advice:
    """A recommendation a reducer designer or assembler can act on.

    Attributes:
        method: ``"assembly-phases"``, ``"tooth-profile"`` or ``"identified-assembly-phases"``.
        preset: Preset the advice refers to.
        summary: One line for people.
        te_metric: Which TE statistic before/after are: ``"amplitude"`` or ``"pp"``.
        te_before_rad: Measured or predicted statistic before the change [rad].
        te_after_rad: Predicted statistic after the change [rad].
        modifications: The recommended changes.
        details: Extra JSON-friendly data (tables, paper comparisons).
    """

    method: str
    preset: str
    summary: str
    te_metric: str
    te_before_rad: float
    te_after_rad: float
    modifications: tuple[Modification, ...] = ()
    details: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        """Validate the metric name."""
        if self.te_metric not in {'amplitude', 'pp'}:
            msg = f'te_metric={self.te_metric!r} must be "amplitude" or "pp"'
            raise CompensationError(msg)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict with unit-suffixed keys (arcmin added for people)."""
        return {
            'method': self.method, 'preset': self.preset, 'summary': self.summary,
            'te_metric': self.te_metric,
            'te_before_rad': _finite_or_none(self.te_before_rad),
            'te_after_rad': _finite_or_none(self.te_after_rad),
            'te_before_arcmin': _finite_or_none(float(rad_to_arcmin(self.te_before_rad))),
            'te_after_arcmin': _finite_or_none(float(rad_to_arcmin(self.te_after_rad))),
            'modifications': [m.to_json_dict() for m in self.modifications],
            'details': self.details,
        }


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None
