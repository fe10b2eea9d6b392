"""Lubricant viscosity against temperature: the Walther equation of ASTM D341.

ASTM D341 (viscosity-temperature charts for liquid petroleum products) draws kinematic
viscosity against temperature as a straight line in the coordinates

    log10(log10(Z)) = A - B log10(T),    Z = nu + 0.7,

with ``nu`` in mm^2/s (cSt) and ``T`` the absolute temperature in kelvin. Two measured
viscosities (an oil's data sheet gives nu at 40 degC and 100 degC) fix A and B; the line
then interpolates between them and extrapolates beyond. ``Z = nu + 0.7`` is the standard's
form for nu >= 2 mm^2/s (below that it adds small exponential corrections, which reducer
oils in -20 .. 120 degC never need): :func:`walther_viscosity_mm2_s` refuses viscosities
under 2 mm^2/s rather than return a value the law does not cover.

Temperatures cross the API in degC (case and oil temperatures as benches log them) and are
converted with T = t + 273.15; the constants A and B are for T in kelvin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from sim._checks import real_number
from sim.errors import ModelInputError, PresetError

if TYPE_CHECKING:
    import numpy.typing as npt

    from sim.presets import Preset

__all__ = ['KELVIN_OFFSET', 'Lubricant', 'walther_constants', 'walther_viscosity_mm2_s']

#: degC -> K.
KELVIN_OFFSET = 273.15
#: Lowest viscosity the plain Walther form (Z = nu + 0.7) covers [mm^2/s] (ASTM D341).
MIN_VISCOSITY_MM2_S = 2.0


def walther_constants(nu1_mm2_s: float, t1_k: float, nu2_mm2_s: float,
                      t2_k: float) -> tuple[float, float]:
    """Walther constants (A, B) of the line through two (viscosity, temperature) points.

    Args:
        nu1_mm2_s, nu2_mm2_s: Kinematic viscosities [mm^2/s], >= 2, different.
        t1_k, t2_k: Their absolute temperatures [K], > 0, different.

    Returns:
        ``(A, B)`` of log10 log10(nu + 0.7) = A - B log10 T (T in K).

    Raises:
        ModelInputError: A value out of range, equal temperatures, or equal viscosities.

    Examples:
        >>> a, b = walther_constants(32.0, 313.0, 5.4, 373.0)
        >>> round(a, 4), round(b, 4)
        (9.5259, 3.7449)
    """
    for name, v in (('nu1_mm2_s', nu1_mm2_s), ('nu2_mm2_s', nu2_mm2_s)):
        if real_number(name, v, '>0') < MIN_VISCOSITY_MM2_S:
            msg = (f'{name} must be >= {MIN_VISCOSITY_MM2_S} mm^2/s (the Walther form of '
                   f'ASTM D341), got {v!r}')
            raise ModelInputError(msg)
    t1 = real_number('t1_k', t1_k, '>0')
    t2 = real_number('t2_k', t2_k, '>0')
    if t1 == t2 or nu1_mm2_s == nu2_mm2_s:
        msg = (f'two different points are needed, got ({nu1_mm2_s!r} mm^2/s, {t1_k!r} K) and '
               f'({nu2_mm2_s!r} mm^2/s, {t2_k!r} K)')
        raise ModelInputError(msg)
    y1 = math.log10(math.log10(nu1_mm2_s + 0.7))
    y2 = math.log10(math.log10(nu2_mm2_s + 0.7))
    b = (y1 - y2) / (math.log10(t2) - math.log10(t1))
    a = y1 + b * math.log10(t1)
    return a, b


def walther_viscosity_mm2_s(temp_k: npt.ArrayLike, a: float, b: float) -> np.ndarray:
    """Kinematic viscosity [mm^2/s] at absolute temperatures ``temp_k`` [K] (vectorised).

    Raises:
        ModelInputError: A temperature that is not finite and > 0, or a result below
            2 mm^2/s (outside the Walther form).
    """
    t = np.asarray(temp_k, dtype=np.float64)
    ok = np.isfinite(t) & (t > 0.0)
    if not np.all(ok):
        msg = f'temperatures must be finite and > 0 K, got {np.ravel(t[~ok])[:3]}'
        raise ModelInputError(msg)
    nu = 10.0 ** (10.0 ** (a - b * np.log10(t))) - 0.7
    if np.any(nu < MIN_VISCOSITY_MM2_S):
        k = np.argmin(nu)
        msg = (f'viscosity {float(np.ravel(nu)[k]):.3g} mm^2/s at {float(np.ravel(t)[k]):.1f} K '
               f'is below {MIN_VISCOSITY_MM2_S} mm^2/s, outside the Walther form of ASTM D341')
        raise ModelInputError(msg)
    return nu


@dataclass(frozen=True)
class Lubricant:
    """A lubricant (the base oil of a grease) described by two data-sheet viscosities.

    Attributes:
        nu40_mm2_s: Kinematic viscosity at 40 degC [mm^2/s] (ISO 3448 VG grades are this).
        nu100_mm2_s: Kinematic viscosity at 100 degC [mm^2/s], < nu40.
        name: What it is (for the record).
        walther_a, walther_b: The ASTM D341 constants through the two points (T in K).
    """

    nu40_mm2_s: float
    nu100_mm2_s: float
    name: str = ''
    walther_a: float = field(init=False, repr=False)
    walther_b: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field) and store A, B."""
        for f in ('nu40_mm2_s', 'nu100_mm2_s'):
            object.__setattr__(self, f, real_number(f'Lubricant.{f}', getattr(self, f), '>0'))
        if not self.nu100_mm2_s < self.nu40_mm2_s:
            msg = (f'Lubricant.nu100_mm2_s ({self.nu100_mm2_s}) must be below nu40_mm2_s '
                   f'({self.nu40_mm2_s}): oils thin as they warm')
            raise ModelInputError(msg)
        a, b = walther_constants(self.nu40_mm2_s, 40.0 + KELVIN_OFFSET,
                                 self.nu100_mm2_s, 100.0 + KELVIN_OFFSET)
        object.__setattr__(self, 'walther_a', a)
        object.__setattr__(self, 'walther_b', b)

    def viscosity_mm2_s(self, temp_degc: npt.ArrayLike) -> np.ndarray:
        """Kinematic viscosity [mm^2/s] at temperatures [degC] (vectorised)."""
        return walther_viscosity_mm2_s(np.asarray(temp_degc, dtype=np.float64)
                                       + KELVIN_OFFSET, self.walther_a, self.walther_b)

    @classmethod
    def from_preset(cls, preset: Preset) -> Lubricant:
        """Read ``lubricant.nu40_mm2_s``, ``lubricant.nu100_mm2_s`` (and ``name``).

        Raises:
            PresetError: Missing or invalid values (the message names the key).
        """
        sec: dict[str, Any] = preset.section('lubricant')
        missing = [k for k in ('nu40_mm2_s', 'nu100_mm2_s') if k not in sec]
        if missing:
            msg = f'preset {preset.name!r} has no lubricant.{missing[0]}'
            raise PresetError(msg)
        try:
            return cls(sec['nu40_mm2_s'], sec['nu100_mm2_s'], str(sec.get('name', '')))
        except ModelInputError as exc:
            msg = f'preset {preset.name!r}: {exc}'
            raise PresetError(msg) from None
