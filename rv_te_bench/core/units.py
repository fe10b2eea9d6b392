"""Unit helpers for the edges (re-exported from :mod:`sim.units`, the single definition)."""

from __future__ import annotations

import math

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
    'arcmin_to_rad',
    'arcsec_to_rad',
    'deg_to_rad',
    'json_deg',
    'json_float',
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
