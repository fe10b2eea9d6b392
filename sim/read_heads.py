"""Read heads on an angle scale, and a scale's graduation error from the maker's grade.

A graduated scale (ring or disc) turns with its shaft; read heads sit still around it. With
the shaft at the true angle ``theta`` and the scale turned on its shaft by the index
``iota`` (0 normally; a reversal measurement re-mounts it at e.g. 180 deg), head ``j`` at
``beta_j`` around the scale (from head 0, in the direction the shaft turns) looks at the
scale coordinate::

    u_j = theta - iota - beta_j

and reads, zeroed so that every head reads the shaft angle (its constant offset removed)::

    r_j = theta + s(u_j) + p_j(u_j) + w_j

* ``s(u)``, the scale's own error, moves with the scale: the graduation error (harmonics of
  the scale revolution, :func:`graduation_from_grade`), the eccentricity of the graduation
  on its centring e (angle error ``e / R = 2 e / D`` at order 1; 5 um on a 100 mm ring:
  +-20.6", DESIGN.md s.7) and the tilt tau of the scale plane against the axis (the head
  sees the graduation line u where its projection lies: ``u - proj(u) = +(tau^2 / 4)
  sin 2 (u - chi)`` at order 2, chi the tilt axis in scale coordinates);
* ``p_j``, head j's own interpolation (sub-divisional) error, one harmonic at the line
  count N of the scale with the head's amplitude and phase;
* ``w_j``, head j's white noise.

Derivation of the eccentricity term: the graduation centre sits ``e`` off the axis at
angle ``theta + psi``; the head at ``beta`` sees the scale point whose angle about the
graduation centre is ``beta - (e / R) sin(theta + psi - beta)`` to first order in e / R,
so the reading carries ``(e / R) sin(u + psi)``: the same harmonic of u for every head.
That is why equally spaced heads cancel it in their mean and why their differences observe
it (the self-calibration of :mod:`rv_te_bench.core.selfcal`).

Assumption for re-indexing: the scale is re-mounted with its own centring (ring on its
hub), so its eccentricity and tilt turn with it; an error of the hub's seat on the shaft
stays with the shaft and is, for every method here, part of the reducer's line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from sim._checks import real_number
from sim.errors import ModelInputError
from sim.units import arcsec_to_rad

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = [
    'GRADUATION_DECAY',
    'GRADUATION_ORDERS',
    'ReadHead',
    'ScaleGraduation',
    'eccentricity_angle_rad',
    'equally_spaced_heads',
    'graduation_from_grade',
    'tilt_amplitude_rad',
]

_TWO_PI = 2.0 * math.pi
#: Orders of the scale revolution a grade is spread over by :func:`graduation_from_grade`.
GRADUATION_ORDERS = tuple(range(1, 33))
#: Amplitude of order k proportional to k ** -GRADUATION_DECAY.
GRADUATION_DECAY = 1.0


@dataclass(frozen=True)
class ReadHead:
    """One read head of a scale.

    Attributes:
        angle_rad: Where the head sits around the scale, from head 0, in the direction the
            shaft turns [rad] (head 0 at 0).
        interpolation_rad: Amplitude of its position error within one signal period [rad]
            (a harmonic at the scale's line count).
        interpolation_phase_rad: Its phase [rad].
        noise_sigma_rad: Standard deviation of its white noise [rad].
    """

    angle_rad: float = 0.0
    interpolation_rad: float = 0.0
    interpolation_phase_rad: float = 0.0
    noise_sigma_rad: float = 0.0

    def __post_init__(self) -> None:
        """Validate (finite; amplitude and noise >= 0)."""
        for name, rule in (('angle_rad', ''), ('interpolation_rad', '>=0'),
                           ('interpolation_phase_rad', ''), ('noise_sigma_rad', '>=0')):
            object.__setattr__(self, name, real_number(f'ReadHead.{name}', getattr(self, name),
                                                       rule))  # type: ignore[arg-type]


@dataclass(frozen=True)
class ScaleGraduation:
    """The graduation error of one scale, harmonics of the scale revolution.

    Attributes:
        orders: Harmonic orders k >= 1.
        amplitudes_rad: Peak amplitude a_k [rad] per order.
        phases_rad: Phase phi_k [rad] per order: the error is sum a_k sin(k u + phi_k).
    """

    orders: tuple[int, ...]
    amplitudes_rad: tuple[float, ...]
    phases_rad: tuple[float, ...]


def graduation_from_grade(grade_arcsec: float, rng: np.random.Generator, *,
                          orders: Sequence[int] = GRADUATION_ORDERS,
                          decay: float = GRADUATION_DECAY) -> ScaleGraduation:
    """A graduation error curve of a scale of the maker's accuracy grade +-``grade_arcsec``.

    Data sheets state the band (e.g. "accuracy of graduation +-1"), not the spectrum.
    Assumed here: the error is a sum of harmonics of the scale revolution whose amplitudes
    fall as ``k ** -decay`` (long-range pitch errors of a divided circle dominate: order
    1/k is the conservative end of what published self-calibrations of circular scales
    show) with the sum of the amplitudes equal to the band (so the curve stays within the
    grade whatever the phases); the phases of one scale are unknown: uniform on [0, 2 pi).

    Args:
        grade_arcsec: The maker's +- accuracy of graduation [arcsec] (>= 0).
        rng: Generator of the phases.
        orders: Harmonic orders (integers >= 1).
        decay: Exponent of the amplitude law (>= 0).

    Raises:
        ModelInputError: A bad grade, order or exponent.

    Examples:
        >>> g = graduation_from_grade(1.0, np.random.default_rng(0), orders=(1, 2))
        >>> [round(a / arcsec_to_rad(1.0), 4) for a in g.amplitudes_rad]
        [0.6667, 0.3333]
    """
    grade = real_number('grade_arcsec', grade_arcsec, '>=0')
    dec = real_number('decay', decay, '>=0')
    ks = tuple(int(k) for k in orders)
    if not ks or any(k < 1 for k in ks) or len(set(ks)) != len(ks):
        msg = f'orders must be distinct integers >= 1, got {list(orders)!r}'
        raise ModelInputError(msg)
    w = np.array([k ** -dec for k in ks])
    amps = float(arcsec_to_rad(grade)) * w / w.sum()
    phases = rng.uniform(0.0, _TWO_PI, len(ks))
    return ScaleGraduation(ks, tuple(float(a) for a in amps), tuple(float(p) for p in phases))


def eccentricity_angle_rad(eccentricity_m: float, diameter_m: float) -> float:
    """Angle error amplitude of a scale mounted ``e`` off its axis: 2 e / D [rad].

    +-412 e/D arcsec with e in um and D in mm (DESIGN.md s.7).

    Examples:
        >>> round(eccentricity_angle_rad(5e-6, 0.1) * 648000 / math.pi, 2)   # 5 um, 100 mm
        20.63
    """
    e = real_number('eccentricity_m', eccentricity_m, '>=0')
    d = real_number('diameter_m', diameter_m, '>0')
    return 2.0 * e / d


def tilt_amplitude_rad(tilt_rad: float) -> float:
    """Order-2 angle error amplitude of a scale plane tilted by ``tau``: tau^2 / 4 [rad].

    A circle of angle u tilted by tau about the axis at chi projects to the angle
    ``proj(u) = chi + atan(tan(u - chi) cos tau) = u - (tau^2 / 4) sin 2 (u - chi) + O(tau^4)``;
    the head over ``proj(u)`` reads u: an error of ``+(tau^2 / 4) sin 2 (u - chi)``.
    """
    t = real_number('tilt_rad', tilt_rad, '>=0')
    return t * t / 4.0


def equally_spaced_heads(n_heads: int, rng: np.random.Generator | None = None, *,
                         interpolation_rad: float = 0.0, noise_sigma_rad: float = 0.0,
                         ) -> tuple[ReadHead, ...]:
    """``n_heads`` heads at 360/n deg apart, each with its own interpolation phase.

    Args:
        n_heads: 1 .. 16.
        rng: Draws each head's interpolation phase (uniform); None: phase 0 for all.
        interpolation_rad: Amplitude of each head's interpolation error [rad].
        noise_sigma_rad: Each head's noise [rad].
    """
    if isinstance(n_heads, bool) or not isinstance(n_heads, int | np.integer) \
            or not 1 <= n_heads <= 16:
        msg = f'n_heads must be an integer in 1..16, got {n_heads!r}'
        raise ModelInputError(msg)
    phases = (rng.uniform(0.0, _TWO_PI, int(n_heads)) if rng is not None
              else np.zeros(int(n_heads)))
    return tuple(ReadHead(angle_rad=_TWO_PI * j / n_heads, interpolation_rad=interpolation_rad,
                          interpolation_phase_rad=float(phases[j]),
                          noise_sigma_rad=noise_sigma_rad) for j in range(int(n_heads)))
