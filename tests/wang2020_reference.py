"""An independent Wang 2020 2K-V no-load TE model for tests (written from the paper, not sim).

Wang, Su, Zou, SV-JME 66 (2020) 2, Section 2.1.1, transcribed term by term:

* Eq. 1: Delta_1(t) = e_p1 sin[theta_p1(t) - a] + e_g sin[theta_g(t) - a]
  + e_ot sin[theta_ot(t) - a] - (the same three terms at t0);
* Eq. 2: Delta_2(t) = e_p2 sin[theta_p2(t) - a] + e_g sin[theta_g(t) - a + pi]
  + e_ot sin[theta_ot(t) - a + pi] - (the same at t0);
* Eq. 5: NLTE_i = Delta_i / r_p (radians here; the paper multiplies by 10800/pi for arcmin);
* Eq. 8: NLTE = max(NLTE_1, NLTE_2).

Angle laws (DESIGN.md s.4, from Eqs 1-4 and the kinematics): the planet and revolution
eccentricity phases turn with the absolute crank angle, theta_x(t) = theta_x(t0) + k_c phi
(k_c = -25 for i = 79: 1 + (36/12) 52/(52 - 50)), the output-wheel phase with the output
angle, theta_ot(t) = theta_ot(t0) + phi, where phi = theta_in / i is the output angle the
kinematics drive (t0: theta_in = 0). The measured output angle is theta_out = phi + NLTE.

Nothing here imports ``sim`` or ``rv_te_bench``: test units generated with this module are
an independent check of the identification (issue #15).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Table 2 of Wang 2020 and DESIGN.md s.4 (r_p = 65 mm cos 20 deg).
ALPHA_RAD = math.radians(35.266)
R_P_M = 0.065 * math.cos(math.radians(20.0))
RATIO = 1.0 + (36.0 / 12.0) * 52.0 / (52.0 - 50.0)          # 79
CRANK_ORDER = 1.0 - 52.0 / (52.0 - 50.0)   # -25: absolute crank turns per output turn (-26 + 1)
TABLE2_E_M = (1e-5, 2e-5, 1e-5, 1e-5)                          # e_p1, e_p2, e_g, e_ot
TABLE2_PHASES_DEG = (90.0, 180.0, -135.0, 90.0)    # theta_p1, theta_p2, theta_g, theta_ot
ARCSEC_RAD = math.pi / (180.0 * 3600.0)


@dataclass(frozen=True)
class Unit:
    """One 2K-V unit: eccentricities [m] and assembly phases at t0 [rad]."""

    e_p1: float
    e_p2: float
    e_g: float
    e_ot: float
    theta_p1: float
    theta_p2: float
    theta_g: float
    theta_ot: float

    @property
    def pair_sums_m(self) -> tuple[complex, complex, complex]:
        """What one TE record can identify: Q1 = p1 + g, Q2 = p2 - g, E (complex, [m])."""
        def z(e: float, th: float) -> complex:
            return e * complex(math.cos(th), math.sin(th))
        g = z(self.e_g, self.theta_g)
        return (z(self.e_p1, self.theta_p1) + g, z(self.e_p2, self.theta_p2) - g,
                z(self.e_ot, self.theta_ot))


def table2_unit() -> Unit:
    """The unit of Wang 2020 Table 2."""
    return Unit(*TABLE2_E_M, *(math.radians(d) for d in TABLE2_PHASES_DEG))


def random_unit(rng: np.random.Generator, *, e_min_m: float = 0.5e-5,
                e_max_m: float = 2.5e-5) -> Unit:
    """Eccentricities uniform in [e_min, e_max] (Table 2: 10-20 um), phases uniform."""
    e = rng.uniform(e_min_m, e_max_m, size=4)
    ph = rng.uniform(-math.pi, math.pi, size=4)
    return Unit(*(float(x) for x in e), *(float(x) for x in ph))


def mesh_line_increments_m(phi_rad: np.ndarray, u: Unit) -> tuple[np.ndarray, np.ndarray]:
    """Delta_1, Delta_2 of Wang 2020 Eqs 1-2 [m] at output angles phi (t0 at phi = 0)."""
    a = ALPHA_RAD
    p1 = u.theta_p1 + CRANK_ORDER * phi_rad
    p2 = u.theta_p2 + CRANK_ORDER * phi_rad
    g = u.theta_g + CRANK_ORDER * phi_rad
    ot = u.theta_ot + phi_rad
    d1 = (u.e_p1 * np.sin(p1 - a) + u.e_g * np.sin(g - a) + u.e_ot * np.sin(ot - a)
          - u.e_p1 * math.sin(u.theta_p1 - a) - u.e_g * math.sin(u.theta_g - a)
          - u.e_ot * math.sin(u.theta_ot - a))
    d2 = (u.e_p2 * np.sin(p2 - a) + u.e_g * np.sin(g - a + math.pi)
          + u.e_ot * np.sin(ot - a + math.pi)
          - u.e_p2 * math.sin(u.theta_p2 - a) - u.e_g * math.sin(u.theta_g - a + math.pi)
          - u.e_ot * math.sin(u.theta_ot - a + math.pi))
    return d1, d2


def nlte_rad(phi_rad: np.ndarray, u: Unit) -> np.ndarray:
    """Wang 2020 Eqs 5 and 8: max(Delta_1, Delta_2) / r_p [rad]."""
    d1, d2 = mesh_line_increments_m(np.asarray(phi_rad, dtype=np.float64), u)
    return np.maximum(d1, d2) / R_P_M


def contact_fraction(u: Unit, n: int = 100_000) -> tuple[float, float]:
    """Share of one output revolution where pair 1 / pair 2 carries (Eq. 8's max)."""
    phi = np.arange(n) * (2 * math.pi / n)
    d1, d2 = mesh_line_increments_m(phi, u)
    f1 = float(np.mean(d1 >= d2))
    return f1, 1.0 - f1


def encoder_record(u: Unit, rng: np.random.Generator, *, n_samples: int,
                   revolutions: float = 1.0, noise_arcsec: float = 0.2,
                   theta_in_start_rad: float = 0.0, offset_rad: float = 0.0,
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(theta_in, theta_out) [rad] of a bench run at constant speed, white noise on both.

    ``noise_arcsec`` is the standard deviation of each encoder's read-head noise; the
    output encoder's zero is off by ``offset_rad`` (Eq. 22 TE has an arbitrary offset).
    """
    span = revolutions * 2 * math.pi * RATIO
    theta_in = theta_in_start_rad + np.arange(n_samples) * (span / n_samples)
    phi = theta_in / RATIO
    theta_out = phi + nlte_rad(phi, u) + offset_rad
    sigma = noise_arcsec * ARCSEC_RAD
    return (theta_in + sigma * rng.standard_normal(n_samples),
            theta_out + sigma * rng.standard_normal(n_samples))


# ------------------------------------------------------------------ judging an identification


def dphase_deg(a: float, b: float) -> float:
    """|a - b| wrapped to [0, 180] deg (a, b in rad)."""
    return abs(math.degrees((a - b + math.pi) % (2 * math.pi) - math.pi))


def identified_phasors(ident: dict) -> tuple[complex, complex, complex]:
    """(Q1, Q2, E) of an identification as the JSON of ``rv-te identify`` / ``analyze``
    gives it (``e_m`` and ``phases_rad`` of pair1, pair2, e_ot): what :func:`vector_error`
    compares with the true unit."""
    def z(mag: str, ph: str) -> complex:
        return ident['e_m'][mag] * complex(math.cos(ident['phases_rad'][ph]),
                                           math.sin(ident['phases_rad'][ph]))
    return z('pair1', 'pair1'), z('pair2', 'pair2'), z('e_ot', 'theta_ot')


def vector_error(u: Unit, got: tuple[complex, complex, complex]) -> tuple[float, bool]:
    """Largest |identified - true| over (Q1, Q2, E) / largest |true|, in the labelling that
    fits best; and whether that is the swapped one (Q2, Q1, -E)."""
    true = u.pair_sums_m
    big = max(abs(z) for z in true)
    same = max(abs(a - b) for a, b in zip(got, true, strict=True)) / big
    swap = max(abs(a - b) for a, b in zip(got, (true[1], true[0], -true[2]), strict=True)) / big
    return min(same, swap), swap < same


def split_brute(q1: complex, q2: complex, e: tuple[float, float, float],
                ) -> tuple[np.ndarray, float]:
    """Split the pair sums with the magnitudes (e_p1, e_p2, e_g) by brute force.

    theta_g minimises (|Q1 - g| - e_p1)^2 + (|Q2 + g| - e_p2)^2 on |g| = e_g (grid of
    0.01 deg, then 4e-5 deg); returns (theta_p1, theta_p2, theta_g) [rad] and the RMS misfit.
    """
    e_p1, e_p2, e_g = e
    th = np.linspace(-math.pi, math.pi, 36001)
    for _ in range(2):
        g = e_g * np.exp(1j * th)
        cost = (np.abs(q1 - g) - e_p1) ** 2 + (np.abs(q2 + g) - e_p2) ** 2
        k = int(np.argmin(cost))
        th = np.linspace(th[k] - 4e-4, th[k] + 4e-4, 1001)
    g = e_g * np.exp(1j * th[500])
    misfit = math.sqrt(((abs(q1 - g) - e_p1) ** 2 + (abs(q2 + g) - e_p2) ** 2) / 2)
    return np.array([np.angle(q1 - g), np.angle(q2 + g), th[500]]), misfit


def split_well_posed(u: Unit, rng: np.random.Generator) -> bool:
    """Whether the split of this unit's sums is well posed, judged from the true unit.

    Well posed: perturbing Q1 and Q2 by 0.1 % of the larger in 20 random directions moves
    no split phase by more than 0.5 deg, and the swapped labelling misfits the true
    magnitudes by more than 0.5 % of the largest (so the magnitudes tell the pairs apart).
    """
    q1, q2, _ = u.pair_sums_m
    e = (u.e_p1, u.e_p2, u.e_g)
    base, _ = split_brute(q1, q2, e)
    big = max(abs(q1), abs(q2))
    for _ in range(20):
        d = 1e-3 * big * np.exp(1j * rng.uniform(-math.pi, math.pi, 2))
        moved, _ = split_brute(q1 + d[0], q2 + d[1], e)
        if max(dphase_deg(a, b) for a, b in zip(moved, base, strict=True)) > 0.5:
            return False
    _, swapped_misfit = split_brute(q2, q1, e)
    return swapped_misfit > 5e-3 * max(e)
