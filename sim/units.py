"""Unit conversions at the edges (reports, CLI, plots). Everything inside is SI (REP-103)."""

from __future__ import annotations

import math
from typing import overload

import numpy as np
import numpy.typing as npt

ARCMIN_PER_RAD = 10800.0 / math.pi
ARCSEC_PER_RAD = 648000.0 / math.pi
RAD_S_PER_RPM = 2.0 * math.pi / 60.0


@overload
def rad_to_arcmin(x: float) -> float: ...
@overload
def rad_to_arcmin(x: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
def rad_to_arcmin(x: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """Radians to arcminutes (1 rad = 10800/pi arcmin)."""
    return np.multiply(x, ARCMIN_PER_RAD)


@overload
def arcmin_to_rad(x: float) -> float: ...
@overload
def arcmin_to_rad(x: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
def arcmin_to_rad(x: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """Arcminutes to radians."""
    return np.divide(x, ARCMIN_PER_RAD)


@overload
def rad_to_arcsec(x: float) -> float: ...
@overload
def rad_to_arcsec(x: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
def rad_to_arcsec(x: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """Radians to arcseconds (1 rad = 648000/pi arcsec)."""
    return np.multiply(x, ARCSEC_PER_RAD)


@overload
def arcsec_to_rad(x: float) -> float: ...
@overload
def arcsec_to_rad(x: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
def arcsec_to_rad(x: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """Arcseconds to radians."""
    return np.divide(x, ARCSEC_PER_RAD)


@overload
def rpm_to_rad_s(x: float) -> float: ...
@overload
def rpm_to_rad_s(x: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
def rpm_to_rad_s(x: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """Revolutions per minute to rad/s."""
    return np.multiply(x, RAD_S_PER_RPM)


@overload
def rad_s_to_rpm(x: float) -> float: ...
@overload
def rad_s_to_rpm(x: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
def rad_s_to_rpm(x: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """rad/s to revolutions per minute."""
    return np.divide(x, RAD_S_PER_RPM)


@overload
def deg_to_rad(x: float) -> float: ...
@overload
def deg_to_rad(x: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
def deg_to_rad(x: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """Degrees to radians."""
    return np.deg2rad(x)


@overload
def rad_to_deg(x: float) -> float: ...
@overload
def rad_to_deg(x: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
def rad_to_deg(x: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """Radians to degrees."""
    return np.rad2deg(x)
