"""Unit helpers for the edges (re-exported from :mod:`sim.units`, the single definition)."""

from __future__ import annotations

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
    'arcmin_to_rad',
    'arcsec_to_rad',
    'deg_to_rad',
    'rad_s_to_rpm',
    'rad_to_arcmin',
    'rad_to_arcsec',
    'rad_to_deg',
    'rpm_to_rad_s',
]
