"""Unit helpers for the edges (re-exported from :mod:`sim.units`, the single definition)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.units import (
    ARCMIN_PER_RAD,
    ARCSEC_PER_RAD,
    arcmin_to_rad,
    arcsec_to_rad,
    deg_to_rad,
    rad_s_to_rpm,
    rad_to_arcmin,
    rad_to_arcsec,
    rad_to_deg,
    rpm_to_rad_s,
)

__all__ = [
    'ARCMIN_PER_RAD',
    'ARCSEC_PER_RAD',
    'JSON_DEG_DIGITS',
    'METRIC_UNIT_NAMES',
    'METRIC_UNIT_SUFFIXES',
    'MetricUnit',
    'arcmin_to_rad',
    'arcsec_to_rad',
    'deg_to_rad',
    'json_deg',
    'json_float',
    'metric_unit',
    'rad_s_to_rpm',
    'rad_to_arcmin',
    'rad_to_arcsec',
    'rad_to_deg',
    'rpm_to_rad_s',
]

#: Decimals of degrees written to JSON: 1e-6 deg = 0.0036", far below any angle we measure.
JSON_DEG_DIGITS = 6


def json_float(x: float) -> float | None:
    """A number for JSON: a plain float, None when not finite (JSON has no NaN).

    Examples:
        >>> json_float(1.5), json_float(float('nan'))
        (1.5, None)
    """
    v = float(x)
    return v if math.isfinite(v) else None


def json_deg(x_rad: float) -> float | None:
    """An angle [rad] as degrees for JSON: rounded to :data:`JSON_DEG_DIGITS` decimals, so
    that a grid phase prints as 120.0, not 120.00000000000001 (the rad round trip); None when
    not finite.

    Examples:
        >>> json_deg(math.radians(120.0)), json_deg(float('nan'))
        (120.0, None)
    """
    v = float(rad_to_deg(x_rad))
    return round(v, JSON_DEG_DIGITS) if math.isfinite(v) else None


# ----------------------------------------------------------------------------- metric units


@dataclass(frozen=True)
class MetricUnit:
    """A stored metric's unit: SI inside, the unit people read at the edge.

    Attributes:
        si: The SI unit the value is stored in (``'rad'``, ``'N m/rad'``, ``'J'``, ...).
        shown: The unit shown in reports, tables and charts (``'arcmin'``, ...).
        per_si: Shown value per SI value (shown = SI x per_si).
    """

    si: str
    shown: str
    per_si: float = 1.0

    def to_shown(self, x_si: float) -> float:
        """An SI value in the shown unit."""
        return float(x_si) * self.per_si

    def from_shown(self, x_shown: float) -> float:
        """A value in the shown unit (a limit typed by a user) in SI."""
        return float(x_shown) / self.per_si


_ANGLE = MetricUnit('rad', 'arcmin', ARCMIN_PER_RAD)
_ONE = MetricUnit('1', '1')

#: The one table of metric units, by name suffix: the first suffix that ends a name wins,
#: so the longer compound suffixes come first (``_nm_per_rad`` is a rigidity, not an angle;
#: ``_rad_s`` a speed). Every metric the results store holds has its unit here
#: (tests/store/test_metric_units.py checks each one a run stores).
METRIC_UNIT_SUFFIXES: tuple[tuple[str, MetricUnit], ...] = (
    ('_nm_per_rad', MetricUnit('N m/rad', 'N m/arcmin', 1.0 / ARCMIN_PER_RAD)),
    ('_rad_s', MetricUnit('rad/s', 'rad/s')),
    ('_rad', _ANGLE),
    ('_nm', MetricUnit('N m', 'N m')),
    ('_j', MetricUnit('J', 'J')),
    ('_w', MetricUnit('W', 'W')),
    ('_hz', MetricUnit('Hz', 'Hz')),
    ('_s', MetricUnit('s', 's')),
    ('_c', MetricUnit('degC', 'degC')),
    ('_k', MetricUnit('K', 'K')),
    ('_m', MetricUnit('m', 'um', 1e6)),
    ('_count', MetricUnit('1', 'count')),
    ('_ratio', _ONE),
)
#: Whole names without a unit suffix (counts and ratios).
METRIC_UNIT_NAMES: dict[str, MetricUnit] = {
    'revolutions': MetricUnit('rev', 'rev'),
    'efficiency': _ONE,
    'efficiency_at_max_load': _ONE,
    'trend_alarms': MetricUnit('1', 'count'),
}
#: Name prefixes of families whose names end in their operating point, not a unit
#: (``sweep:efficiency_3000rpm_200nm``: an efficiency at 3000 rpm and 200 N m).
_PREFIXES = (('efficiency_', _ONE),)
#: Suffixes of derived keys that carry their base metric's unit (an expanded uncertainty).
_DERIVED = ('_u95', '_uc')


def metric_unit(name: str) -> MetricUnit:
    """The unit of a stored metric, a ``line:LABEL`` amplitude or a ``sweep:NAME`` point.

    Raises:
        KeyError: A name the table does not know (its unit would be a guess).

    Examples:
        >>> metric_unit('torsional_rigidity_K_nm_per_rad').shown
        'N m/arcmin'
        >>> metric_unit('te_pp_revolution_max_rad').shown, metric_unit('hysteresis_loss_j').si
        ('arcmin', 'J')
        >>> metric_unit('te_pp_rad_u95').shown, metric_unit('line:1 f_w').shown
        ('arcmin', 'arcmin')
    """
    if name.startswith('line:'):
        return _ANGLE
    base = name.removeprefix('sweep:')
    for d in _DERIVED:
        base = base.removesuffix(d)
    if base in METRIC_UNIT_NAMES:
        return METRIC_UNIT_NAMES[base]
    for prefix, unit in _PREFIXES:
        if base.startswith(prefix):
            return unit
    for suffix, unit in METRIC_UNIT_SUFFIXES:
        if base.endswith(suffix):
            return unit
    msg = f'metric {name!r} has no unit in the metric unit table (core/units.py)'
    raise KeyError(msg)
