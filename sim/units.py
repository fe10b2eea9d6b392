"""Unit conversions at the edges (reports, CLI, plots). Everything inside is SI (REP-103)."""

from __future__ import annotations

import math

import numpy as np

ARCMIN_PER_RAD = 10800.0 / math.pi
ARCSEC_PER_RAD = 648000.0 / math.pi
RAD_S_PER_RPM = 2.0 * math.pi / 60.0


def rad_to_arcmin(x):
    """Radians to arcminutes (1 rad = 10800/pi arcmin)."""
    return np.multiply(x, ARCMIN_PER_RAD)


def arcmin_to_rad(x):
    """Arcminutes to radians."""
    return np.divide(x, ARCMIN_PER_RAD)


def rad_to_arcsec(x):
    """Radians to arcseconds (1 rad = 648000/pi arcsec)."""
    return np.multiply(x, ARCSEC_PER_RAD)


def arcsec_to_rad(x):
    """Arcseconds to radians."""
    return np.divide(x, ARCSEC_PER_RAD)


def rpm_to_rad_s(x):
    """Revolutions per minute to rad/s."""
    return np.multiply(x, RAD_S_PER_RPM)


def rad_s_to_rpm(x):
    """rad/s to revolutions per minute."""
    return np.divide(x, RAD_S_PER_RPM)


def deg_to_rad(x):
    """Degrees to radians."""
    return np.deg2rad(x)


def rad_to_deg(x):
    """Radians to degrees."""
    return np.rad2deg(x)
