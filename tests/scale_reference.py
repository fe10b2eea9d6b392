"""Read heads on a graduated scale, by exact geometry: the tests' own model (not ``sim``).

A scale of radius R turns with its shaft (angle theta), re-mounted on it at the index iota;
its graduation centre sits e off the axis at psi (scale frame), its plane is tilted by tau
about the axis at chi (scale frame). Head j sits at beta_j. Written out from the geometry,
with no linearisation:

* the head looks at the scale point whose angle about the graduation centre is, in the
  scale frame, ``u_geo = theta - iota - beta - arg(R - e exp(i(theta - iota - beta + psi)))``
  (reading direction; ``arg(R e^{i beta} - c) - beta`` is the angle the offset centre adds);
* the tilted circle puts graduation line u_g where its projection lies:
  ``u_g = chi + atan2(sin(u_geo - chi), cos(u_geo - chi) cos tau)``;
* the head reports that line's value with the graduation error g, ``v = u_g + g(u_g)``, and
  its own interpolation error p_j, periodic between the lines as they lie (in v):
  ``reading = theta + (v - (theta - iota - beta)) + p_j(v) + noise``.

Reducer TE comes from :mod:`tests.wang2020_reference` or a sinusoid written in the test.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, field

import numpy as np

ARCSEC_RAD = math.pi / (180.0 * 3600.0)


@dataclass(frozen=True)
class Scale:
    """A scale and its heads (SI: m, rad)."""

    radius_m: float = 0.05
    eccentricity_m: float = 0.0
    psi_rad: float = 0.0
    tilt_rad: float = 0.0
    chi_rad: float = 0.0
    index_rad: float = 0.0
    orders: tuple[int, ...] = ()
    amplitudes_rad: tuple[float, ...] = ()
    phases_rad: tuple[float, ...] = ()
    lines: int = 0
    heads_rad: tuple[float, ...] = (0.0,)
    interp_rad: tuple[float, ...] = ()
    interp_phase_rad: tuple[float, ...] = ()
    noise_rad: tuple[float, ...] = field(default=())

    def graduation_rad(self, u: np.ndarray) -> np.ndarray:
        """g(u) = sum a_k sin(k u + phi_k) = Im P(z), P(z) = sum_k a_k e^{i phi_k} z^k at
        z = e^{iu}, by Horner's rule (one complex exponential per sample instead of one sine
        per order and sample; |z| = 1, so the rounding stays ~ k_max eps sum a_k)."""
        u = np.asarray(u, dtype=np.float64)
        if not self.orders:
            return np.zeros_like(u)
        coef = np.zeros(max(self.orders) + 1, dtype=np.complex128)
        for k, a, p in zip(self.orders, self.amplitudes_rad, self.phases_rad, strict=True):
            coef[k] += a * cmath.exp(1j * p)
        z = np.exp(1j * u)
        acc = np.full(u.shape, coef[-1])
        for c in coef[-2:0:-1]:
            acc *= z
            acc += c
        acc *= z
        return acc.imag.copy()

    def readings(self, theta_rad: np.ndarray, rng: np.random.Generator | None = None,
                 ) -> np.ndarray:
        """Every head's reading, shape (heads, n) [rad] (exact geometry, see module)."""
        th = np.asarray(theta_rad, dtype=np.float64)
        out = np.empty((len(self.heads_rad), th.size))
        for j, beta in enumerate(self.heads_rad):
            nominal = th - self.index_rad - beta
            centre = np.angle(self.radius_m - self.eccentricity_m
                              * np.exp(1j * (nominal + self.psi_rad)))
            u_geo = nominal - centre
            d = u_geo - self.chi_rad
            u_g = self.chi_rad + np.arctan2(np.sin(d), np.cos(d) * math.cos(self.tilt_rad))
            u_g = u_geo + np.angle(np.exp(1j * (u_g - u_geo)))   # same turn as u_geo
            read = u_g + self.graduation_rad(u_g)     # the line value under the head
            r = th + (read - nominal)
            if self.interp_rad and self.lines:   # periodic between the lines as they are
                r += self.interp_rad[j] * np.sin(self.lines * read + self.interp_phase_rad[j])
            if rng is not None and self.noise_rad and self.noise_rad[j]:
                r += self.noise_rad[j] * rng.standard_normal(th.size)
            out[j] = r
        return out

    def scale_error_rad(self, u: np.ndarray) -> np.ndarray:
        """The scale's own error at scale coordinate u (head at 0, index 0, no noise,
        no interpolation) [rad], exact geometry."""
        ref = Scale(radius_m=self.radius_m, eccentricity_m=self.eccentricity_m,
                    psi_rad=self.psi_rad, tilt_rad=self.tilt_rad, chi_rad=self.chi_rad,
                    orders=self.orders, amplitudes_rad=self.amplitudes_rad,
                    phases_rad=self.phases_rad)
        return ref.readings(np.asarray(u, dtype=np.float64))[0] - u


def harmonics(values: np.ndarray, max_order: int) -> np.ndarray:
    """Complex amplitudes c_k (k = 1..max_order) of samples of one period taken at
    u = 2 pi n / N: values = c0 + sum Re(c_k e^{iku}) (numpy's FFT)."""
    n = values.size
    spec = np.fft.rfft(values) * (2.0 / n)
    return spec[1:max_order + 1]


def whole_revolutions_fft(angle_rad: np.ndarray, values: np.ndarray, max_order: int,
                          n_grid: int = 8192) -> np.ndarray:
    """Harmonics of ``values`` as a function of ``angle`` over the whole revolutions the
    record spans: the values interpolated onto a uniform grid of each whole revolution,
    then averaged over revolutions (``np.interp`` + FFT: independent of the code's fold)."""
    a0 = float(angle_rad[0])
    revs = math.floor((float(angle_rad[-1]) - a0) / (2 * math.pi))
    assert revs >= 1, 'need one whole revolution'
    grid = a0 + 2 * math.pi * np.arange(revs * n_grid) / n_grid
    v = np.interp(grid, angle_rad, values).reshape(revs, n_grid).mean(axis=0)
    # the grid starts at a0, not at 0: turn the phase reference to angle 0
    ks = np.arange(1, max_order + 1)
    return harmonics(v, max_order) * np.exp(-1j * ks * a0)
