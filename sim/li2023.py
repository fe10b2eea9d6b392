"""Li 2023 lumped-parameter dynamic model of an RV reducer with machining/assembly errors.

Li, Huang, Ding, Guo, Niu, *Machines* 2023, 11, 626. Two parts:

1. **Loaded tooth contact analysis** of the cycloid-pin pair (Li 2023 Eqs 1-7,
   :func:`ltca`): Hertz line-contact stiffness per pin (Li 2023 Eq. 2), compatibility
   (Li 2023 Eq. 3: unmodified profile, zero initial backlash, so every pin on the loaded side
   touches), moment equilibrium (Li 2023 Eq. 4), resultant force at the pitch point
   (Li 2023 Eqs 5-6) and the equivalent pressure angle
   ``beta = atan(F_r / F_t)`` and mesh stiffness ``k_cr = F_cr cos(beta) / (e z_c dphi)``
   (Li 2023 Eq. 7). Li 2023 Eq. 5 as printed sums the *magnitudes* of the radial components,
   ``F_ci sqrt(1 - (l_ci / r_c)^2)``; that is what is implemented (it gives the paper's
   ~32 deg).
2. **Dynamic model** (Li 2023 Eqs 8-36, :class:`Li2023DteModel`): sun, M planets, M
   crankshafts, N cycloid discs and the output disc, 3 DOF each (x, y, theta): 6M + 3N + 6
   DOF. Every elastic element is a spring on a relative displacement
   ``delta = g(t) . q + eps(t)``;
   the stiffness matrix is ``K(t) = sum k(t) g g^T`` and the error force
   ``F = -sum k g eps``. That keeps K symmetric, which the printed Li 2023 Eqs 29-33 are not.

Coordinates: translations in a frame turning with the output at its nominal (kinematic)
angle ``theta_in / i`` (the paper's S_i); rotations are absolute deviations from the
kinematic motion implied by the measured input angle. The input is driven kinematically:
``k_st`` (Table 2) is read as the input shaft between that driven angle and the sun.
With that, TE = theta_out - theta_in / i is the output disc's rotation coordinate.

Relative displacements (n_i = cos(alpha) e_t(psi_i) + sin(alpha) e_r(psi_i), phi_j the
eccentric direction of disc j in the output frame, t_j/r_j its tangential/radial unit
vectors, a_H the crank circle radius, r_c = e z_c):

* sun-planet mesh (Li 2023 Eq. 23): ``n_i . (u_s - u_pi) + r_bs th_s + r_bp th_pi
  + n_i . (d_s - d_pi)`` (sun/planet eccentricity, Li 2023 Eq. 12);
* planet-crank bending/torsion (k_H, k_Ht): ``u_pi - u_Hi``, ``th_pi - th_Hi``;
* crank support in the output disc (Li 2023 Eq. 26): ``u_Hi - u_o - a_H th_o e_t(psi_i) - d_oHi``
  (hole error, Li 2023 Eq. 19);
* turning-arm bearing (Li 2023 Eq. 25): ``u_Hi + e th_Hi t_j - u_cj - a_H th_cj e_t(psi_i)
  + d_dj - d_cHi`` (cam and disc-hole errors, Li 2023 Eqs 15-16);
* pin mesh (Li 2023 Eq. 28): ``-(cos(beta) t_j + sin(beta) r_j) . u_cj - r_c cos(beta) th_cj
  + e_crj`` (composite error, Li 2023 Eq. 18);
* supports (Li 2023 Eqs 24, 27): ``u_s - d_sa``, ``u_o - d_oa`` (assembly errors fixed in the
  housing, Li 2023 Eqs 14, 21); sun torsion ``th_s`` (k_st); output torsion ``th_o`` (k_ot).

The kinematic motion (input advanced by a, output a / i, cranks -z_c a / i, discs
translated along their eccentric and turned by a / i) leaves every one of these at zero
except the input shaft: the ratios are built in, not fitted (tests check it).

Documented simplifications (the paper is unclear or silent):

* Gyroscopic and centripetal terms (omega_o G, omega_o^2 K_Omega, F_c of Li 2023 Eqs 34-36) are
  dropped: omega_o = 1.3 rad/s at 1500 rpm, so m omega_o^2 <= 26 N/m against stiffnesses
  >= 4.7e7 N/m (< 1e-6 relative).
* Inertial loads of input speed changes are not modelled: the nominal motion follows the
  given theta_in sample by sample (cubic Hermite between samples with omega_in).
* beta is the paper's mean 31.9 deg (``tca.pressure_angle_deg``; 0 selects the LTCA mean,
  32.9 deg here: docs/DESIGN_NOTES.md 'Paper vs suite'); k_cr(t) keeps
  the LTCA harmonics (Li 2023 Eq. 11); both are computed at the preset's TCA torque, not the live
  load. The dynamic model uses the unmodified profile; :func:`ltca` also computes the
  modified one (``modification_m``).
* Sun-planet mesh stiffness: rectangular wave between k1 (single pair) and 2 k1 (double
  pair) over the contact ratio, mean from the preset, truncated Fourier series (Li 2023 Eq. 9).
* Bearing clearances (Li 2023 Eqs 17, 20, 22) are left out: the paper gives no values, and in a
  linear model a clearance is only a constant offset.
* Damping: stiffness-proportional, ``C = b K_mean`` (not given in the paper; zeta calibrated
  to the paper's 0.78" DTE without errors, E_cr to its 17.25" with errors).
* The sun assembly error acts only through the sun support (Li 2023 Eq. 24); adding
  Li 2023 Eq. 13's mesh term as well would count it twice.
* The pin-mesh stiffness mean is the paper's 1.24e9 N/m (``stiffness.pin_mesh_n_m``, the
  value the paper feeds into its dynamic model); the LTCA curve is scaled to it. The
  LTCA here gives ~3.6e9 N/m (0 in the preset selects it).

Consequence of the symmetric layout (worth knowing when reading spectra): with three
equally spaced planets meshing in phase (z_s psi_i = 0 mod 2 pi) and two discs 180 deg
apart (z_r pi = 0 mod 2 pi), the sun/planet eccentricities and the sun/output assembly
errors of Table 3 (same value on every part) excite only translational modes, which are
exactly decoupled from the torsion: they move the members (Fig. 10) but not the TE. The
hole and cam errors, fixed in the output frame, shift the mean TE. The once-per-output-rev
DTE comes from the composite mesh error E_cr (Li 2023 Eq. 18).

Integration: the mesh stiffnesses make the system stiff (natural frequencies 0.4 to
10.8 kHz against mesh excitation at ~300 Hz at 1500 rpm). Measured: scipy RK45 (the
paper's ode45, rtol 1e-6) needed 3136 steps for 50 ms (16 us mean step, set by stability,
not accuracy), a real-time factor of ~0.003 in Python. Here: Newmark average acceleration
(trapezoidal; unconditionally stable for linear time-invariant systems, no numerical
damping) with steps of at most ``solver.max_step_s`` = 0.25 ms, which differs from a 16x
finer step by <= 0.11 arcsec. ``K(t)`` is a trigonometric polynomial in the eccentric
angles times the mesh stiffnesses, so the effective matrices ``K + 2/h C + 4/h^2 M`` of a
batch of steps come from one matrix product (64 steps at a time on the TE path, so that
they stay in the CPU cache). When only displacements are watched (``te_rad``), a step
runs on z = [p; a2 M w] (p: the right-hand side without the force) instead of
x = [q, v, a]: one add, one Cholesky solve (LAPACK dposv, 30 x 30, called through SciPy's
Cython LAPACK table without the f2py wrapper) and one 60 x 90 matrix-vector product,
~5 us; the same scheme as the x form (equal to ~1e-11 arcsec; the x form runs when a
velocity or acceleration is watched). Real-time factor at 10 kHz samples, blocks of 100:
~11 (benchmarks/README.md, ``benchmarks/bench_li2023.py``).
"""

from __future__ import annotations

import ctypes
import functools
import itertools
import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.linalg.lapack import dposv as _dposv

from sim.errors import ModelInputError, PresetError
from sim.kinematics import kinematics_from_preset


def _lapack_dposv() -> Any:   # a ctypes function or None (checked where the path is chosen)
    """LAPACK dposv as a ctypes function (SciPy's public Cython LAPACK table), or None.

    Called with the addresses of its eight arguments; about 1.5 us less per call than the
    f2py wrapper, which matters at one solve per Newmark step.
    """
    try:
        from scipy.linalg import cython_lapack
        cap = cython_lapack.__pyx_capi__['dposv']
        get_name = ctypes.pythonapi.PyCapsule_GetName
        get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
        get_ptr = ctypes.pythonapi.PyCapsule_GetPointer
        get_ptr.restype = ctypes.c_void_p
        get_ptr.argtypes = [ctypes.py_object, ctypes.c_char_p]
        ptr = get_ptr(cap, get_name(cap))
    except (ImportError, KeyError, AttributeError, ValueError):
        return None
    return ctypes.PYFUNCTYPE(None, *[ctypes.c_void_p] * 8)(ptr)


_DPOSV = _lapack_dposv()
# Newmark steps whose effective matrices are assembled at once on the TE path: 100 x 900
# doubles (0.7 MB) stay in the L2 cache for the solves (2048 at once cost ~2.5 us a step;
# 100: a bench block of 100 samples at 10 kHz in one go). Products of more than ~200,000
# multiply-adds are cut into row slices (_serial_matmul): above OpenBLAS's threading
# threshold (m n k = 262144) a small product waited for a busy second core on the shared
# 2-core machine (blocks of 1000 ran at 0.9x real time instead of 12x).
_SUB_STEPS = 100
_BLAS_SERIAL_MNK = 200_000
#: Newmark operators of one step size: ([P; R], L, P, W, K_eff constant part).
_NewmarkOps = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _serial_matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` (2-D) in row slices small enough that OpenBLAS runs them on one thread."""
    rows = max(1, _BLAS_SERIAL_MNK // max(1, a.shape[1] * b.shape[1]))
    if a.shape[0] <= rows:
        prod: npt.NDArray[np.float64] = a @ b
        return prod
    out = np.empty((a.shape[0], b.shape[1]))
    for r0 in range(0, a.shape[0], rows):
        np.matmul(a[r0:r0 + rows], b, out=out[r0:r0 + rows])
    return out

if TYPE_CHECKING:
    import numpy.typing as npt

    from sim.kinematics import ReducerKinematics
    from sim.presets import Preset

__all__ = [
    'Li2023DteModel',
    'Li2023Params',
    'LtcaResult',
    'build_te_model',
    'ltca',
    'params_from_preset',
]

# field -> (preset key, rule); rules: 'pos' > 0, 'nonneg' >= 0, 'int1'|'int0' integer >= 1|0,
# 'frac' in (0, 1], 'poisson' in (0, 0.5), 'ratio' in (1, 2), 'angle' finite, 'bool'
_FIELDS: dict[str, tuple[str, str]] = {
    'z_sun': ('kinematics.z_sun', 'int1'),
    'z_planet': ('kinematics.z_planet', 'int1'),
    'z_cycloid': ('kinematics.z_gear', 'int1'),
    'z_pin': ('kinematics.z_ring', 'int1'),
    'n_cranks': ('layout.n_cranks', 'int1'),
    'n_discs': ('layout.n_discs', 'int1'),
    'module_m': ('geometry.module_m', 'pos'),
    'pressure_angle_deg': ('geometry.pressure_angle_deg', 'pos'),
    'pin_radius_m': ('geometry.pin_radius_m', 'pos'),
    'pin_circle_radius_m': ('geometry.pin_circle_radius_m', 'pos'),
    'eccentricity_m': ('geometry.eccentricity_m', 'pos'),
    'face_width_m': ('geometry.face_width_m', 'pos'),
    'youngs_modulus_pa': ('material.youngs_modulus_pa', 'pos'),
    'poisson': ('material.poisson', 'poisson'),
    'tca_torque_nm': ('tca.torque_nm', 'pos'),
    'disc_load_share': ('tca.disc_load_share', 'frac'),
    'beta_fixed_deg': ('tca.pressure_angle_deg', 'nonneg'),
    'tca_grid_points': ('tca.grid_points', 'int1'),
    'm_sun_kg': ('mass.sun_kg', 'pos'),
    'm_planet_kg': ('mass.planet_kg', 'pos'),
    'm_crank_kg': ('mass.crank_kg', 'pos'),
    'm_disc_kg': ('mass.disc_kg', 'pos'),
    'm_output_kg': ('mass.output_kg', 'pos'),
    'j_sun_kg_m2': ('inertia.sun_kg_m2', 'pos'),
    'j_planet_kg_m2': ('inertia.planet_kg_m2', 'pos'),
    'j_crank_kg_m2': ('inertia.crank_kg_m2', 'pos'),
    'j_disc_kg_m2': ('inertia.disc_kg_m2', 'pos'),
    'j_output_kg_m2': ('inertia.output_kg_m2', 'pos'),
    'k_sun_torsion_nm_rad': ('stiffness.sun_torsional_nm_rad', 'pos'),
    'k_sun_radial_n_m': ('stiffness.sun_radial_n_m', 'pos'),
    'k_crank_torsion_nm_rad': ('stiffness.crank_torsional_nm_rad', 'pos'),
    'k_crank_bending_n_m': ('stiffness.crank_bending_n_m', 'pos'),
    'k_crank_bearing_n_m': ('stiffness.crank_bearing_n_m', 'pos'),
    'k_arm_bearing_n_m': ('stiffness.turning_arm_bearing_n_m', 'pos'),
    'k_output_radial_n_m': ('stiffness.output_radial_n_m', 'pos'),
    'k_output_torsion_nm_rad': ('stiffness.output_torsional_nm_rad', 'nonneg'),
    'k_sun_planet_n_m': ('stiffness.sun_planet_mesh_n_m', 'pos'),
    'k_pin_mesh_n_m': ('stiffness.pin_mesh_n_m', 'nonneg'),
    'sun_planet_contact_ratio': ('stiffness.sun_planet_contact_ratio', 'ratio'),
    'sun_planet_harmonics': ('stiffness.sun_planet_harmonics', 'int0'),
    'pin_mesh_harmonics': ('stiffness.pin_mesh_harmonics', 'int0'),
    'damping_zeta': ('damping.zeta', 'nonneg'),
    'damping_ref_frequency_hz': ('damping.ref_frequency_hz', 'pos'),
    'errors_enabled': ('errors.enabled', 'bool'),
    'sun_ecc_m': ('errors.sun_ecc_m', 'nonneg'),
    'sun_ecc_deg': ('errors.sun_ecc_deg', 'angle'),
    'planet_ecc_m': ('errors.planet_ecc_m', 'nonneg'),
    'planet_ecc_deg': ('errors.planet_ecc_deg', 'angle'),
    'sun_assembly_m': ('errors.sun_assembly_m', 'nonneg'),
    'sun_assembly_deg': ('errors.sun_assembly_deg', 'angle'),
    'disc_hole_m': ('errors.disc_hole_m', 'nonneg'),
    'disc_hole_deg': ('errors.disc_hole_deg', 'angle'),
    'cam_ecc_m': ('errors.cam_ecc_m', 'nonneg'),
    'cam_ecc_deg': ('errors.cam_ecc_deg', 'angle'),
    'output_hole_m': ('errors.output_hole_m', 'nonneg'),
    'output_hole_deg': ('errors.output_hole_deg', 'angle'),
    'output_assembly_m': ('errors.output_assembly_m', 'nonneg'),
    'output_assembly_deg': ('errors.output_assembly_deg', 'angle'),
    'pin_composite_m': ('errors.pin_composite_m', 'nonneg'),
    'pin_composite_deg': ('errors.pin_composite_deg', 'angle'),
    'max_step_s': ('solver.max_step_s', 'pos'),
    'chunk_steps': ('solver.chunk_steps', 'int1'),
}


def _check(name: str, key: str, rule: str, value: object) -> None:
    """Raise PresetError naming ``key`` when ``value`` breaks ``rule``."""
    if rule == 'bool':
        if not isinstance(value, bool):
            msg = f'{key} must be true or false, got {value!r}'
            raise PresetError(msg)
        return
    if rule in {'int1', 'int0'}:
        lo = 1 if rule == 'int1' else 0
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < lo:
            msg = f'{key} must be an integer >= {lo}, got {value!r}'
            raise PresetError(msg)
        return
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        msg = f'{key} must be a finite number, got {value!r}'
        raise PresetError(msg)
    bad = {'pos': value <= 0, 'nonneg': value < 0, 'frac': not 0 < value <= 1,
           'poisson': not 0 < value < 0.5, 'ratio': not 1 < value < 2, 'angle': False}[rule]
    if bad:
        rule_text = {'pos': '> 0', 'nonneg': '>= 0', 'frac': 'in (0, 1]',
                     'poisson': 'in (0, 0.5) (a Poisson ratio)', 'ratio': 'in (1, 2)'}
        msg = f'{key} must be {rule_text[rule]}, got {value!r} ({name})'
        raise PresetError(msg)


@dataclass(frozen=True)
class Li2023Params:
    """Parameters of the Li 2023 RV model (SI units; angles in degrees only in ``*_deg``).

    Field names carry their unit; each maps to one preset key (see ``_FIELDS``), and
    ``__post_init__`` names that key when a rule is broken.
    """

    z_sun: int
    z_planet: int
    z_cycloid: int
    z_pin: int
    n_cranks: int
    n_discs: int
    module_m: float
    pressure_angle_deg: float
    pin_radius_m: float
    pin_circle_radius_m: float
    eccentricity_m: float
    face_width_m: float
    youngs_modulus_pa: float
    poisson: float
    tca_torque_nm: float
    disc_load_share: float
    beta_fixed_deg: float
    tca_grid_points: int
    m_sun_kg: float
    m_planet_kg: float
    m_crank_kg: float
    m_disc_kg: float
    m_output_kg: float
    j_sun_kg_m2: float
    j_planet_kg_m2: float
    j_crank_kg_m2: float
    j_disc_kg_m2: float
    j_output_kg_m2: float
    k_sun_torsion_nm_rad: float
    k_sun_radial_n_m: float
    k_crank_torsion_nm_rad: float
    k_crank_bending_n_m: float
    k_crank_bearing_n_m: float
    k_arm_bearing_n_m: float
    k_output_radial_n_m: float
    k_output_torsion_nm_rad: float
    k_sun_planet_n_m: float
    k_pin_mesh_n_m: float
    sun_planet_contact_ratio: float
    sun_planet_harmonics: int
    pin_mesh_harmonics: int
    damping_zeta: float
    damping_ref_frequency_hz: float
    errors_enabled: bool
    sun_ecc_m: float
    sun_ecc_deg: float
    planet_ecc_m: float
    planet_ecc_deg: float
    sun_assembly_m: float
    sun_assembly_deg: float
    disc_hole_m: float
    disc_hole_deg: float
    cam_ecc_m: float
    cam_ecc_deg: float
    output_hole_m: float
    output_hole_deg: float
    output_assembly_m: float
    output_assembly_deg: float
    pin_composite_m: float
    pin_composite_deg: float
    max_step_s: float
    chunk_steps: int

    def __post_init__(self) -> None:
        """Validate every field.

        Raises:
            PresetError: A value breaks its rule (the message names the preset key), the
                pin count is not z_cycloid + 1, or the pin circle is too small.
        """
        for f in fields(self):
            key, rule = _FIELDS[f.name]
            _check(f.name, key, rule, getattr(self, f.name))
        if not self.beta_fixed_deg < 90.0:
            msg = f'tca.pressure_angle_deg must be in [0, 90), got {self.beta_fixed_deg!r}'
            raise PresetError(msg)
        if self.z_pin != self.z_cycloid + 1:
            msg = (f'kinematics.z_ring ({self.z_pin}) must be kinematics.z_gear + 1 '
                   f'({self.z_cycloid + 1}) for an RV cycloid stage')
            raise PresetError(msg)
        if not self.eccentricity_m * self.z_pin < self.pin_circle_radius_m:
            msg = (f'geometry.pin_circle_radius_m ({self.pin_circle_radius_m!r}) must exceed '
                   f'eccentricity_m * z_ring ({self.eccentricity_m * self.z_pin!r}): K1 < 1')
            raise PresetError(msg)

    @property
    def gear_ratio(self) -> float:
        """Overall ratio i = 1 + (z_planet / z_sun) z_pin."""
        return 1.0 + self.z_planet / self.z_sun * self.z_pin

    @property
    def crank_circle_radius_m(self) -> float:
        """Radius of the crank axes = stage-1 centre distance m (z_s + z_p) / 2 [m]."""
        return self.module_m * (self.z_sun + self.z_planet) / 2.0


def params_from_preset(preset: Preset) -> Li2023Params:
    """Build validated :class:`Li2023Params` from a ``li2023-rv`` style preset.

    Raises:
        PresetError: A key is missing or a value breaks its rule (the key is named).
    """
    kwargs: dict[str, Any] = {}
    for name, (key, rule) in _FIELDS.items():
        value = preset[key]
        if rule not in {'int1', 'int0', 'bool'} and isinstance(value, int) \
                and not isinstance(value, bool):
            value = float(value)
        kwargs[name] = value
    return Li2023Params(**kwargs)


# --------------------------------------------------------------------------------------
# Loaded tooth contact analysis (Li 2023 Eqs 1-7)
# --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LtcaResult:
    """Equivalent cycloid-pin mesh over one pin-mesh period (one disc).

    Attributes:
        crank_angle_rad: Absolute eccentric angle Phi (pin 0 at angle 0), shape (G,),
            spanning one mesh period [0, 2 pi / z_pin).
        pressure_angle_rad: Equivalent pressure angle beta (Li 2023 Eq. 7), shape (G,).
        mesh_stiffness_n_m: Equivalent mesh stiffness k_cr (Li 2023 Eq. 7), shape (G,).
        rotation_rad: Elastic rotation dphi_c of the disc (Li 2023 Eqs 3-4), shape (G,).
        contacts: Number of loaded pins, shape (G,).
        max_pin_force_n: Largest pin force, shape (G,).
    """

    crank_angle_rad: np.ndarray
    pressure_angle_rad: np.ndarray
    mesh_stiffness_n_m: np.ndarray
    rotation_rad: np.ndarray
    contacts: np.ndarray
    max_pin_force_n: np.ndarray


def _cycloid_curvature_radius(theta_rel: np.ndarray, p: Li2023Params) -> np.ndarray:
    """Signed curvature radius of the cycloid tooth at the contact with a pin [m].

    The pin-centre locus in the disc frame is ``z(Phi) = (r_p e^{i th} - e e^{i Phi})
    e^{i Phi / z_c}``; its curvature is evaluated analytically at Phi = 0 for the pin at
    relative angle ``theta_rel`` (pin angle minus eccentric angle). The tooth is that curve
    offset inwards by the pin radius. Positive: convex tooth; negative: concave.
    """
    rp, e, zc, rr = p.pin_circle_radius_m, p.eccentricity_m, p.z_cycloid, p.pin_radius_m
    w = rp * np.exp(1j * theta_rel) - e
    w1 = -1j * e
    w2 = e
    z1 = w1 + w * (1j / zc)
    z2 = w2 + 2.0 * w1 * (1j / zc) - w / zc**2
    kappa = np.imag(np.conj(z1) * z2) / np.abs(z1) ** 3
    rho0 = 1.0 / np.abs(kappa)
    centre = w + 1j * z1 / np.abs(z1) / kappa
    convex = np.abs(centre) < np.abs(w)
    rho: npt.NDArray[np.float64] = np.where(convex, rho0 - rr, -(rho0 + rr))
    return rho


def _hertz_stiffness(force_n: np.ndarray, rho_c: np.ndarray, p: Li2023Params) -> np.ndarray:
    """Hertz line-contact stiffness k_n of Li 2023 Eq. 2 [N/m] at a pin force (half-width b)."""
    c = (1.0 - p.poisson**2) / p.youngs_modulus_pa
    rr = p.pin_radius_m
    inv_r = 1.0 / rr + 1.0 / rho_c                 # concave tooth: rho_c < 0
    r_star = 1.0 / inv_r
    b = np.sqrt(4.0 * np.maximum(force_n, 1e-9) * r_star * 2.0 * c
                / (np.pi * p.face_width_m))
    denom = c * (np.log(4.0 * np.abs(rho_c) / b) - 0.5) + c * (np.log(4.0 * rr / b) - 0.5)
    k: npt.NDArray[np.float64] = np.pi * p.face_width_m / (2.0 * denom)
    return k


def ltca(params: Li2023Params, *, torque_nm: float | None = None,
         crank_angle_rad: npt.ArrayLike | None = None,
         modification_m: tuple[float, float] = (0.0, 0.0)) -> LtcaResult:
    """Loaded TCA of one cycloid disc (Li 2023 Eqs 2-7), unmodified or modified profile.

    Unmodified (the default): every pin on the loaded side (relative angle in (pi, 2 pi)) is
    in contact (Li 2023 Eq. 3 with zero backlash); its normal deflection is ``l_i dphi``
    (Li 2023 Eq. 4), its force ``k_n(F) l_i dphi`` with the load-dependent Hertz stiffness of
    Li 2023 Eq. 2; ``dphi`` is found so that ``sum F_i l_i`` equals the disc torque.

    Modified (``modification_m = (roller position, roller radius)``, Li 2023 s.4.1: -0.05 and
    -0.01 mm): each pin has the initial normal clearance of the modification, written as
    Hu 2020 Eq. 32 (shift ``delta_r_p`` = roller position, isometric ``delta_r_rp`` = roller
    radius; zero at ``cos phi = K1``), i.e. the backlash ``phi_bl,i = Delta_i / l_i`` of
    Li 2023 Eq. 3: a pin carries load only once ``l_i dphi > Delta_i``, with the deflection
    ``l_i dphi - Delta_i``. The Hertz stiffness of the unmodified tooth is kept (the
    modification changes the tooth's curvature by < 0.1 %).

    Args:
        params: Model parameters.
        torque_nm: Disc torque [N m]; default ``tca_torque_nm * disc_load_share``.
        crank_angle_rad: Absolute eccentric angles [rad]; default ``tca_grid_points``
            points over one pin-mesh period.
        modification_m: (roller position, roller radius) modification [m].

    Returns:
        The equivalent pressure angle and mesh stiffness at each angle.

    Raises:
        ModelInputError: Torque not finite and > 0, or a modification not finite.
    """
    p = params
    t_disc = p.tca_torque_nm * p.disc_load_share if torque_nm is None else float(torque_nm)
    if not (math.isfinite(t_disc) and t_disc > 0):
        msg = f'torque_nm must be finite and > 0, got {torque_nm!r}'
        raise ModelInputError(msg)
    d_rp, d_rrp = (float(v) for v in modification_m)
    if not (math.isfinite(d_rp) and math.isfinite(d_rrp)):
        msg = f'modification_m must be two finite lengths [m], got {modification_m!r}'
        raise ModelInputError(msg)
    if crank_angle_rad is None:
        phi = np.arange(p.tca_grid_points) * (2.0 * np.pi / p.z_pin / p.tca_grid_points)
    else:
        phi = np.atleast_1d(np.asarray(crank_angle_rad, dtype=np.float64))
    k1 = p.eccentricity_m * p.z_pin / p.pin_circle_radius_m
    r_c = p.eccentricity_m * p.z_cycloid
    th = 2.0 * np.pi * np.arange(p.z_pin)[None, :] / p.z_pin - phi[:, None]
    s = np.sqrt(1.0 + k1**2 - 2.0 * k1 * np.cos(th))
    lever = -r_c * np.sin(th) / s                  # > 0 on the loaded side
    loaded = lever > 1e-9 * r_c
    lever = np.where(loaded, lever, 0.0)
    rho_c = _cycloid_curvature_radius(th, p)
    # initial clearance of the modification (Hu 2020 Eq. 32 at the pin's angle -th from the
    # line of centres on the loaded side); 0 without modification
    psi = -th
    clearance = (d_rrp * (1.0 - np.sin(psi) / s)
                 - d_rp * (1.0 - k1 * np.cos(psi) - math.sqrt(1.0 - k1 * k1) * np.sin(psi)) / s)

    def forces(dphi: np.ndarray) -> np.ndarray:
        delta = np.maximum(lever * dphi[:, None] - clearance, 0.0)
        f = 1.0e9 * delta
        for _ in range(12):                         # F = k_n(F) delta; k_n ~ log(F)
            f = _hertz_stiffness(f, rho_c, p) * delta
        return np.where(loaded & (delta > 0.0), f, 0.0)

    lo = np.full(phi.shape, 1e-9)
    hi = np.full(phi.shape, 1e-1)
    for _ in range(56):                             # bisection on log(dphi): 2e-7 rel.
        mid = np.sqrt(lo * hi)
        torque = np.sum(forces(mid) * lever, axis=1)
        too_big = torque > t_disc
        hi = np.where(too_big, mid, hi)
        lo = np.where(too_big, lo, mid)
    dphi = np.sqrt(lo * hi)
    f = forces(dphi)
    f_t = np.sum(f * lever, axis=1) / r_c                             # Li 2023 Eq. 5
    f_r = np.sum(f * np.sqrt(np.clip(1.0 - (lever / r_c) ** 2, 0.0, None)), axis=1)
    beta = np.arctan2(f_r, f_t)                                       # Li 2023 Eq. 7
    f_cr = np.hypot(f_t, f_r)                                         # Li 2023 Eq. 6
    k_cr = f_cr * np.cos(beta) / (r_c * dphi)                         # Li 2023 Eq. 7
    arrays = (phi.copy(), beta, k_cr, dphi, (f > 0.0).sum(axis=1), f.max(axis=1))
    for arr in arrays:
        arr.setflags(write=False)
    return LtcaResult(*arrays)


@functools.lru_cache(maxsize=8)
def _ltca_cached(params: Li2023Params) -> LtcaResult:
    """LTCA at the preset torque, cached per parameter set (parameters are frozen)."""
    return ltca(params)


def _quantise(h: np.ndarray) -> np.ndarray:
    """Round step sizes to 6 significant digits.

    Sample clocks far from t = 0 give intervals that differ in their last bits; rounding
    lets consecutive steps share one set of Newmark operators (the kinematic phases still
    use the exact sample times; a 1e-6 relative step change is far below the scheme's
    own error).
    """
    e = np.floor(np.log10(h))
    mant = np.round(h / 10.0**e, 5)
    # a step just below a power of ten rounds to a mantissa of 10: renormalise, so that
    # 0.99999999e-4 and 1.00000001e-4 both give 1.0 * 1e-4 (one operator set, not two)
    up = mant >= 10.0
    rounded: npt.NDArray[np.float64] = (np.where(up, mant / 10.0, mant)
                                        * 10.0 ** np.where(up, e + 1.0, e))
    return rounded


# --------------------------------------------------------------------------------------
# Dynamic model
# --------------------------------------------------------------------------------------

def _trig2(phi: np.ndarray) -> np.ndarray:
    """Basis [1, cos, sin, cos 2, sin 2] at angles ``phi``, shape (..., 5)."""
    return np.stack([np.ones_like(phi), np.cos(phi), np.sin(phi),
                     np.cos(2 * phi), np.sin(2 * phi)], axis=-1)


class _Layout:
    """DOF indices: sun, planets, cranks, discs, output; each (x, y, theta)."""

    def __init__(self, m: int, n: int) -> None:
        self.m, self.n = m, n
        self.sun = 0
        self.planet = [3 + 3 * i for i in range(m)]
        self.crank = [3 + 3 * m + 3 * i for i in range(m)]
        self.disc = [3 + 6 * m + 3 * j for j in range(n)]
        self.out = 3 + 6 * m + 3 * n
        self.ndof = 6 * m + 3 * n + 6


class Li2023DteModel:
    """Dynamic transmission error of the Li 2023 RV model, advanced block by block.

    Attributes:
        kinematics: Ratios and mesh orders (from the preset's ``[kinematics]``).
        params: The validated parameters.
        beta_rad: Equivalent pressure angle used in the dynamic model [rad]: the preset's
            ``tca.pressure_angle_deg`` (the paper's 31.9 deg), or the LTCA mean when that is 0.
        ndof: Number of degrees of freedom, 6 M + 3 N + 6.
    """

    def __init__(self, params: Li2023Params, kinematics: ReducerKinematics) -> None:
        """Assemble the constant and trigonometric parts of M, C and K.

        Args:
            params: Validated parameters.
            kinematics: Kinematics of the same reducer.

        Raises:
            PresetError: The kinematics ratio differs from the parameters' ratio.
        """
        p = params
        if not math.isclose(kinematics.gear_ratio, p.gear_ratio, rel_tol=1e-12):
            msg = (f'kinematics gear_ratio {kinematics.gear_ratio!r} differs from the '
                   f'model ratio {p.gear_ratio!r}')
            raise PresetError(msg)
        self.params = p
        self.kinematics = kinematics
        self._lay = lay = _Layout(p.n_cranks, p.n_discs)
        self.ndof = lay.ndof
        tca = _ltca_cached(p)
        self.ltca_result = tca
        self.beta_rad = (math.radians(p.beta_fixed_deg) if p.beta_fixed_deg > 0
                         else float(np.mean(tca.pressure_angle_rad)))
        # Fourier series of k_cr over the mesh period (argument z_pin * Phi)
        spec = np.fft.rfft(tca.mesh_stiffness_n_m) / tca.mesh_stiffness_n_m.size
        nh = min(p.pin_mesh_harmonics, spec.size - 1)
        # k = mean + Re(sum c_l e^{i l z Phi}); a preset mean (> 0) rescales the LTCA curve
        scale = 1.0 if p.k_pin_mesh_n_m == 0 else p.k_pin_mesh_n_m / float(spec[0].real)
        self._kcr_mean = float(spec[0].real) * scale
        self._kcr_harm = 2.0 * spec[1:nh + 1] * scale
        alpha = math.radians(p.pressure_angle_deg)
        self._alpha = alpha
        self._r_bs = p.module_m * p.z_sun * math.cos(alpha) / 2.0
        self._r_bp = p.module_m * p.z_planet * math.cos(alpha) / 2.0
        self._a_h = p.crank_circle_radius_m
        self._r_c = p.eccentricity_m * p.z_cycloid
        self._psi = 2.0 * np.pi * np.arange(p.n_cranks) / p.n_cranks
        self._disc_phase = 2.0 * np.pi * np.arange(p.n_discs) / p.n_discs
        # sun-planet rectangular wave: k1 single pair, 2 k1 over (eps - 1) of the period
        eps = p.sun_planet_contact_ratio
        k1 = p.k_sun_planet_n_m / eps
        width = 2.0 * np.pi * (eps - 1.0)
        ls = np.arange(1, p.sun_planet_harmonics + 1)
        self._ksp_harm = 2.0 * k1 / (np.pi * ls) * np.sin(ls * width / 2.0)
        self._build_matrices()
        self._build_error_patterns()
        self._keff_buf = np.empty((_SUB_STEPS, self.ndof**2))
        self._ops_cache: dict[float, _NewmarkOps] = {}
        self.reset()

    # ---- assembly ----------------------------------------------------------------------
    def _g_mesh(self, i: int) -> np.ndarray:
        lay, n = self._lay, self._n_sp(i)
        g = np.zeros(lay.ndof)
        g[0:2] = n
        g[2] = self._r_bs
        g[lay.planet[i]:lay.planet[i] + 2] = -n
        g[lay.planet[i] + 2] = self._r_bp
        return g

    def _n_sp(self, i: int) -> np.ndarray:
        psi, a = self._psi[i], self._alpha
        return np.array([-math.cos(a) * math.sin(psi) + math.sin(a) * math.cos(psi),
                         math.cos(a) * math.cos(psi) + math.sin(a) * math.sin(psi)])

    def _g_carrier(self, i: int) -> np.ndarray:
        """Crank-support bearing i, rows x and y (2, ndof)."""
        lay, psi = self._lay, self._psi[i]
        g = np.zeros((2, lay.ndof))
        c = lay.crank[i]
        g[0, c], g[1, c + 1] = 1.0, 1.0
        g[0, lay.out], g[1, lay.out + 1] = -1.0, -1.0
        g[0, lay.out + 2] = self._a_h * math.sin(psi)
        g[1, lay.out + 2] = -self._a_h * math.cos(psi)
        return g

    def _g_arm(self, i: int, j: int, phi: np.ndarray) -> np.ndarray:
        """Turning-arm bearing (crank i, disc j) at eccentric angles phi: (S, 2, ndof)."""
        lay, psi, e = self._lay, self._psi[i], self.params.eccentricity_m
        g = np.zeros((*phi.shape, 2, lay.ndof))
        c, d = lay.crank[i], lay.disc[j]
        g[..., 0, c] = 1.0
        g[..., 1, c + 1] = 1.0
        g[..., 0, c + 2] = -e * np.sin(phi)
        g[..., 1, c + 2] = e * np.cos(phi)
        g[..., 0, d] = -1.0
        g[..., 1, d + 1] = -1.0
        g[..., 0, d + 2] = self._a_h * math.sin(psi)
        g[..., 1, d + 2] = -self._a_h * math.cos(psi)
        return g

    def _g_pin(self, j: int, phi: np.ndarray) -> np.ndarray:
        """Pin mesh of disc j at eccentric angles phi: (S, ndof)."""
        lay, b = self._lay, self.beta_rad
        d = lay.disc[j]
        g = np.zeros((*phi.shape, lay.ndof))
        # n = cos(b) t + sin(b) r, t = (-sin, cos), r = (cos, sin)
        g[..., d] = -(-math.cos(b) * np.sin(phi) + math.sin(b) * np.cos(phi))
        g[..., d + 1] = -(math.cos(b) * np.cos(phi) + math.sin(b) * np.sin(phi))
        g[..., d + 2] = -self._r_c * math.cos(b)
        return g

    def _build_matrices(self) -> None:
        p, lay = self.params, self._lay
        nd = lay.ndof
        mass = np.zeros(nd)
        mass[0:3] = (p.m_sun_kg, p.m_sun_kg, p.j_sun_kg_m2)
        for i in range(lay.m):
            mass[lay.planet[i]:lay.planet[i] + 3] = (p.m_planet_kg, p.m_planet_kg,
                                                     p.j_planet_kg_m2)
            mass[lay.crank[i]:lay.crank[i] + 3] = (p.m_crank_kg, p.m_crank_kg,
                                                   p.j_crank_kg_m2)
        for j in range(lay.n):
            mass[lay.disc[j]:lay.disc[j] + 3] = (p.m_disc_kg, p.m_disc_kg, p.j_disc_kg_m2)
        mass[lay.out:lay.out + 3] = (p.m_output_kg, p.m_output_kg, p.j_output_kg_m2)
        self.mass_matrix = np.diag(mass)

        k0 = np.zeros((nd, nd))
        k0[0, 0] += p.k_sun_radial_n_m
        k0[1, 1] += p.k_sun_radial_n_m
        k0[2, 2] += p.k_sun_torsion_nm_rad
        o = lay.out
        k0[o, o] += p.k_output_radial_n_m
        k0[o + 1, o + 1] += p.k_output_radial_n_m
        k0[o + 2, o + 2] += p.k_output_torsion_nm_rad
        for i in range(lay.m):
            pl, cr = lay.planet[i], lay.crank[i]
            for a, b, k in ((pl, cr, p.k_crank_bending_n_m), (pl + 1, cr + 1,
                            p.k_crank_bending_n_m), (pl + 2, cr + 2,
                            p.k_crank_torsion_nm_rad)):
                g = np.zeros(nd)
                g[a], g[b] = 1.0, -1.0
                k0 += k * np.outer(g, g)
            gc = self._g_carrier(i)
            k0 += p.k_crank_bearing_n_m * gc.T @ gc
        # phi-dependent parts, fitted exactly as trig polynomials of degree 2
        samples = 2.0 * np.pi * np.arange(8) / 8
        basis = _trig2(samples)                                       # (8, 5)
        pinv = np.linalg.pinv(basis)                                  # (5, 8)
        arm, pin = [], []
        for j in range(lay.n):
            ka = np.zeros((8, nd, nd))
            for i in range(lay.m):
                g = self._g_arm(i, j, samples)
                ka += p.k_arm_bearing_n_m * np.einsum('sra,srb->sab', g, g)
            gp = self._g_pin(j, samples)
            kp = np.einsum('sa,sb->sab', gp, gp)                      # per unit k_cr
            arm.append(np.tensordot(pinv, ka, axes=1).reshape(5, -1))
            pin.append(np.tensordot(pinv, kp, axes=1).reshape(5, -1))
        self._sp_mats = np.stack([np.outer(self._g_mesh(i), self._g_mesh(i)).ravel()
                                  for i in range(lay.m)])
        self._basis = np.concatenate([k0.reshape(1, -1), self._sp_mats, *arm, *pin])
        self._vary_cols = np.nonzero(np.any(self._basis[1:] != 0, axis=0))[0]
        self._vary_basis = self._basis[1:, self._vary_cols]
        # dposv (uplo 'L' on the C-ordered matrix) reads only the upper triangle (row <= col)
        up = self._vary_cols[self._vary_cols // nd <= self._vary_cols % nd]
        self._vary_cols_up = up
        self._vary_basis_up = np.ascontiguousarray(self._basis[1:, up])
        # mean over the eccentric angles and mesh phases: the constant terms
        k_mean = (k0 + p.k_sun_planet_n_m * self._sp_mats.sum(0).reshape(nd, nd)
                  + sum(a[0].reshape(nd, nd) for a in arm)
                  + self._kcr_mean * sum(b[0].reshape(nd, nd) for b in pin))
        self.mean_stiffness_matrix = k_mean
        b_r = 2.0 * p.damping_zeta / (2.0 * np.pi * p.damping_ref_frequency_hz)
        self.damping_matrix = b_r * k_mean

    # ---- time-varying quantities -------------------------------------------------------
    def _angles(self, theta_in: np.ndarray) -> dict[str, np.ndarray]:
        kin = self.kinematics
        out = theta_in / kin.gear_ratio
        return {'out': out, 'sun_rel': theta_in - out,
                'crank_rel': theta_in * kin.crank_rel_per_input,
                'crank_abs': theta_in * kin.crank_per_input}

    def _mesh_stiffness(self, ang: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """k_sp (S, M) and k_cr (S, N) [N/m] (Li 2023 Eqs 8-11)."""
        p = self.params
        ls = np.arange(1, self._ksp_harm.size + 1)
        ph = p.z_sun * (ang['sun_rel'][:, None] + self._psi[None, :])          # Li 2023 Eq. 8
        # einsum, not @: numpy hands (S, M, L) @ (L,) to BLAS as one (S M) x L gemv, which
        # OpenBLAS splits over threads from S ~ 600 on (a busy second core stalls it)
        ksp = p.k_sun_planet_n_m + np.einsum('sml,l->sm', np.cos(ls * ph[..., None]),
                                             self._ksp_harm)
        lc = np.arange(1, self._kcr_harm.size + 1)
        big = ang['crank_abs'][:, None] + self._disc_phase[None, :]
        ex = np.exp(1j * lc * p.z_pin * big[..., None])
        kcr = self._kcr_mean + np.real(np.einsum('snl,l->sn', ex, self._kcr_harm))
        return ksp, kcr

    def stiffness_matrix(self, theta_in_rad: npt.ArrayLike) -> np.ndarray:
        """K(t) at input angles ``theta_in_rad`` (kinematic phases), shape (S, n, n)."""
        th = np.atleast_1d(np.asarray(theta_in_rad, dtype=np.float64))
        kmat: npt.NDArray[np.float64] = (self._coeffs(th) @ self._basis).reshape(
            th.size, self.ndof, self.ndof)
        return kmat

    def _phase(self, th: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """Kinematic angles and mesh stiffnesses at input angles ``th``."""
        ang = self._angles(th)
        return (ang, *self._mesh_stiffness(ang))

    def _coeffs(self, th: np.ndarray,
                _phase: tuple[dict[str, np.ndarray], np.ndarray, np.ndarray] | None = None,
                ) -> np.ndarray:
        ang, ksp, kcr = self._phase(th) if _phase is None else _phase
        phi = ang['crank_rel'][:, None] + self._disc_phase[None, :]           # (S, N)
        w = _trig2(phi)                                                       # (S, N, 5)
        s = th.size
        return np.concatenate([np.ones((s, 1)), ksp, w.reshape(s, -1),
                               (w * kcr[..., None]).reshape(s, -1)], axis=1)

    def forces(self, theta_in_rad: np.ndarray, load_nm: np.ndarray,
               _phase: tuple[dict[str, np.ndarray], np.ndarray, np.ndarray] | None = None,
               ) -> np.ndarray:
        """Generalised force vector F(t) (load + error excitation), shape (S, n)."""
        lay = self._lay
        th = np.atleast_1d(np.asarray(theta_in_rad, dtype=np.float64))
        f = np.zeros((th.size, lay.ndof))
        f[:, lay.out + 2] = -np.asarray(load_nm, dtype=np.float64)
        if not self.params.errors_enabled:
            return f
        ang, ksp, kcr = self._phase(th) if _phase is None else _phase
        f += _serial_matmul(self._error_basis(ang, ksp, kcr), self._err_map) + self._f_hole
        return f

    @staticmethod
    def _error_basis(ang: dict[str, np.ndarray], ksp: np.ndarray,
                     kcr: np.ndarray) -> np.ndarray:
        """Functions of time the error forces are linear in, shape (S, 3 + 2 + 4 M + 6 N).

        [1, cos c, sin c, cos o, sin o, k_sp,i (cos s, sin s, cos c, sin c),
        k_cr,j (cos o, sin o) x (1, cos c, sin c)] with o the output angle, s the sun and
        c the crank angle relative to the output frame: every term of
        :meth:`_error_forces` is a constant times one of these (angle-sum identities).
        """
        s = ang['out'].size
        trig = np.empty((s, 6))
        np.cos(ang['crank_rel'], out=trig[:, 0])
        np.sin(ang['crank_rel'], out=trig[:, 1])
        np.cos(ang['out'], out=trig[:, 2])
        np.sin(ang['out'], out=trig[:, 3])
        np.cos(ang['sun_rel'], out=trig[:, 4])
        np.sin(ang['sun_rel'], out=trig[:, 5])
        crank = np.concatenate([np.ones((s, 1)), trig[:, :2]], axis=1)       # (S, 3)
        sp = ksp[:, :, None] * trig[:, None, [4, 5, 0, 1]]                    # (S, M, 4)
        pin = (kcr[:, :, None, None] * trig[:, None, 2:4, None]
               * crank[:, None, None, :])                                     # (S,N,2,3)
        return np.concatenate([crank, trig[:, 2:4], sp.reshape(s, -1),
                               pin.reshape(s, -1)], axis=1)

    def _error_forces(self, ang: dict[str, np.ndarray], ksp: np.ndarray,
                      kcr: np.ndarray) -> np.ndarray:
        """F = -sum k g eps of the Table 3 errors, spring by spring, shape (S, n).

        The physics, written out; :meth:`forces` uses the same forces as one product
        ``_error_basis(...) @ _err_map`` fitted from this at construction (exact to
        ~4e-15 of the largest force: they are linear in the basis functions).
        """
        p = self.params
        rad = math.radians
        out, crank = ang['out'], ang['crank_rel']
        s = out.size
        feats: list[np.ndarray] = []
        # sun / output assembly errors: fixed in the housing, seen from the output frame
        a_s = rad(p.sun_assembly_deg) - out
        a_o = rad(p.output_assembly_deg) - out
        feats += [p.sun_assembly_m * np.cos(a_s), p.sun_assembly_m * np.sin(a_s),
                  p.output_assembly_m * np.cos(a_o), p.output_assembly_m * np.sin(a_o)]
        # sun-planet mesh: eccentricities turning with the sun and the planets (Li 2023 Eq. 12)
        b_s = rad(p.sun_ecc_deg) + ang['sun_rel']
        b_p = rad(p.planet_ecc_deg) + crank
        dx = p.sun_ecc_m * np.cos(b_s) - p.planet_ecc_m * np.cos(b_p)
        dy = p.sun_ecc_m * np.sin(b_s) - p.planet_ecc_m * np.sin(b_p)
        nsp = self._nsp_all                                                   # (2, M)
        feats += list((ksp * (dx[:, None] * nsp[0] + dy[:, None] * nsp[1])).T)
        # turning-arm bearings: cam error (Li 2023 Eq. 16) minus the disc-hole error
        # (Li 2023 Eq. 15)
        phi = crank[:, None] + self._disc_phase[None, :]                     # (S, N)
        cphi, sphi = np.cos(phi), np.sin(phi)
        cam = phi + rad(p.cam_ecc_deg)
        ex = (p.cam_ecc_m * np.cos(cam))[:, None, :] - self._hole_xy[0][None, :, None]
        ey = (p.cam_ecc_m * np.sin(cam))[:, None, :] - self._hole_xy[1][None, :, None]
        e = p.eccentricity_m
        arm = np.stack([ex, ey, e * (ey * cphi[:, None, :] - ex * sphi[:, None, :]),
                        ex * self._ah_sc[0][None, :, None]
                        - ey * self._ah_sc[1][None, :, None]], axis=-1)       # (S,M,N,4)
        # pin mesh: composite error (Li 2023 Eq. 18)
        e_cr = p.pin_composite_m * np.sin(out + rad(p.pin_composite_deg))
        kce = kcr * e_cr[:, None]                                            # (S, N)
        cb, sb = math.cos(self.beta_rad), math.sin(self.beta_rad)
        pin = np.stack([kce * (sb * cphi - cb * sphi), kce * (cb * cphi + sb * sphi),
                        kce * (self._r_c * cb)], axis=-1)                    # (S, N, 3)
        feat = np.concatenate([np.stack(feats, axis=1), arm.reshape(s, -1),
                               pin.reshape(s, -1)], axis=1)
        return _serial_matmul(feat, self._err_pattern) + self._f_hole

    def _build_error_patterns(self) -> None:
        """Fixed parts of :meth:`_error_forces`: DOF patterns, hole-error constants."""
        p, lay = self.params, self._lay
        nd, rad = lay.ndof, math.radians
        self._nsp_all = np.stack([self._n_sp(i) for i in range(lay.m)], axis=1)
        hole = rad(p.disc_hole_deg) + self._psi
        self._hole_xy = np.stack([p.disc_hole_m * np.cos(hole), p.disc_hole_m * np.sin(hole)])
        self._ah_sc = np.stack([self._a_h * np.sin(self._psi), self._a_h * np.cos(self._psi)])
        rows: list[np.ndarray] = []

        def row() -> np.ndarray:
            rows.append(np.zeros(nd))
            return rows[-1]

        o = lay.out
        row()[0] = p.k_sun_radial_n_m
        row()[1] = p.k_sun_radial_n_m
        row()[o] = p.k_output_radial_n_m
        row()[o + 1] = p.k_output_radial_n_m
        for i in range(lay.m):
            row()[:] = -self._g_mesh(i)
        k = p.k_arm_bearing_n_m
        for i in range(lay.m):
            c = lay.crank[i]
            for j in range(lay.n):
                d = lay.disc[j]
                r = row()
                r[c], r[d] = -k, k
                r = row()
                r[c + 1], r[d + 1] = -k, k
                row()[c + 2] = -k
                row()[d + 2] = -k
        for j in range(lay.n):
            d = lay.disc[j]
            row()[d] = 1.0
            row()[d + 1] = 1.0
            row()[d + 2] = 1.0
        self._err_pattern = np.array(rows)
        # crank support: hole error in the output disc, fixed in the disc (Li 2023 Eq. 19)
        f_hole = np.zeros(nd)
        for i in range(lay.m):
            ang = self._psi[i] + rad(p.output_hole_deg)
            d_oh = p.output_hole_m * np.array([math.cos(ang), math.sin(ang)])
            f_hole += p.k_crank_bearing_n_m * (d_oh @ self._g_carrier(i))
        self._f_hole = f_hole
        # the error forces as one linear map of _error_basis, fitted on random angles and
        # mesh stiffnesses (exact: the forces are linear in those functions)
        rng = np.random.default_rng(0)
        n_fit = 8 * (5 + 4 * lay.m + 6 * lay.n)
        ang = {k: rng.uniform(0.0, 2.0 * np.pi, n_fit) for k in ('out', 'sun_rel', 'crank_rel')}
        # stiffnesses of their real size: every term then weighs in the fit as in use
        ksp = p.k_sun_planet_n_m * rng.uniform(0.5, 1.5, (n_fit, lay.m))
        kcr = self._kcr_mean * rng.uniform(0.5, 1.5, (n_fit, lay.n))
        basis = self._error_basis(ang, ksp, kcr)
        target = self._error_forces(ang, ksp, kcr) - f_hole
        scale = np.abs(basis).max(axis=0)                 # columns of 1 and of ~1e9
        self._err_map = np.linalg.lstsq(basis / scale, target, rcond=None)[0] / scale[:, None]
        resid = np.abs(basis @ self._err_map - target).max()
        if not resid <= 1e-12 * max(1.0, float(np.abs(target).max())):
            msg = f'error forces are not linear in their basis (residual {resid:.3g})'
            raise RuntimeError(msg)

    def static_response(self, theta_in_rad: float, load_nm: float) -> np.ndarray:
        """Quasi-static displacement q = K^-1 F at one input angle, shape (n,)."""
        k = self.stiffness_matrix(np.array([theta_in_rad]))[0]
        f = self.forces(np.array([theta_in_rad]), np.array([load_nm]))[0]
        return np.linalg.solve(k, f)

    # ---- time integration --------------------------------------------------------------
    def reset(self) -> None:
        """Forget the state: the next call starts at static equilibrium."""
        self._state: np.ndarray | None = None
        self._zstate: tuple[float, np.ndarray, np.ndarray] | None = None
        self._last: tuple[float, float, float, float] | None = None

    def te_rad(self, t_s: npt.ArrayLike, theta_in_rad: npt.ArrayLike,
               omega_in_rad_s: npt.ArrayLike, load_nm: npt.ArrayLike) -> np.ndarray:
        """Dynamic TE = theta_out - theta_in / i at the samples [rad]; advances the state.

        The first sample of a run is the static equilibrium at that input angle and load;
        each later sample is reached by Newmark steps of at most ``max_step_s``, with the
        input angle interpolated by cubic Hermite (theta, omega) and the load linearly.

        Args:
            t_s: Sample times [s], 1-D, strictly increasing (also across calls).
            theta_in_rad: Unwrapped input angle [rad], same shape.
            omega_in_rad_s: Input speed [rad/s], same shape.
            load_nm: Output load torque [N m] (resisting), same shape.

        Returns:
            TE [rad], shape like ``t_s``.

        Raises:
            ModelInputError: Shapes differ, non-finite values, or time not increasing.
        """
        io = self._lay.out + 2
        return self._samples(t_s, theta_in_rad, omega_in_rad_s, load_nm, np.array([io]))[:, 0]

    _MEMBERS = ('sun', 'planet', 'crank', 'disc', 'output')

    def state_index(self, member: str, number: int = 0, coord: str = 'theta',
                    kind: str = 'q') -> int:
        """Index into the state vector [q, dq/dt, d2q/dt2] for :meth:`response`.

        Args:
            member: ``'sun'``, ``'planet'``, ``'crank'``, ``'disc'`` or ``'output'``.
            number: Planet/crank (0..M-1) or disc (0..N-1) number.
            coord: ``'x'``, ``'y'`` [m, output frame] or ``'theta'`` [rad, deviation from
                the kinematic angle].
            kind: ``'q'`` displacement, ``'v'`` velocity, ``'a'`` acceleration.

        Raises:
            ModelInputError: Unknown member, number, coordinate or kind.
        """
        lay = self._lay
        bases = {'sun': [lay.sun], 'planet': lay.planet, 'crank': lay.crank,
                 'disc': lay.disc, 'output': [lay.out]}
        if member not in bases or not 0 <= number < len(bases[member]):
            msg = f'unknown member {member!r} number {number!r}'
            raise ModelInputError(msg)
        if coord not in {'x', 'y', 'theta'} or kind not in {'q', 'v', 'a'}:
            msg = f'coord must be x, y or theta and kind q, v or a, got {coord!r}, {kind!r}'
            raise ModelInputError(msg)
        return (bases[member][number] + ('x', 'y', 'theta').index(coord)
                + ('q', 'v', 'a').index(kind) * self.ndof)

    def response(self, t_s: npt.ArrayLike, theta_in_rad: npt.ArrayLike,
                 omega_in_rad_s: npt.ArrayLike, load_nm: npt.ArrayLike,
                 state_indices: npt.ArrayLike) -> np.ndarray:
        """Like :meth:`te_rad` but returns chosen state entries, shape (n, k).

        Args:
            t_s: Sample times [s] (see :meth:`te_rad`).
            theta_in_rad: Input angle [rad].
            omega_in_rad_s: Input speed [rad/s].
            load_nm: Output load torque [N m].
            state_indices: Indices from :meth:`state_index`.

        Raises:
            ModelInputError: As :meth:`te_rad`, or an index out of range.
        """
        idx = np.atleast_1d(np.asarray(state_indices, dtype=np.int64))
        if idx.ndim != 1 or np.any(idx < 0) or np.any(idx >= 3 * self.ndof):
            msg = f'state_indices must be in [0, {3 * self.ndof}), got {idx!r}'
            raise ModelInputError(msg)
        return self._samples(t_s, theta_in_rad, omega_in_rad_s, load_nm, idx)

    def _samples(self, t_s: npt.ArrayLike, theta_in_rad: npt.ArrayLike,
                 omega_in_rad_s: npt.ArrayLike, load_nm: npt.ArrayLike,
                 watch: np.ndarray) -> np.ndarray:
        """Validate, advance, and return state entries ``watch`` at the samples."""
        t, th, om, ld = (np.asarray(a, dtype=np.float64) for a in
                         (t_s, theta_in_rad, omega_in_rad_s, load_nm))
        if t.ndim != 1 or not (t.shape == th.shape == om.shape == ld.shape):
            msg = (f'inputs must be 1-D of one length: {t.shape=}, {th.shape=}, '
                   f'{om.shape=}, {ld.shape=}')
            raise ModelInputError(msg)
        if t.size == 0:
            return np.zeros((0, watch.size))
        for name, a in (('t_s', t), ('theta_in_rad', th), ('omega_in_rad_s', om),
                        ('load_nm', ld)):
            if not np.all(np.isfinite(a)):
                msg = f'{name} must be finite'
                raise ModelInputError(msg)
        if np.any(np.diff(t) <= 0) or (self._last is not None and t[0] <= self._last[0]):
            msg = 't_s must be strictly increasing (also from one call to the next)'
            raise ModelInputError(msg)
        te = np.empty((t.size, watch.size))
        start = 0
        if self._state is None:
            q0 = self.static_response(float(th[0]), float(ld[0]))
            self._state = np.concatenate([q0, np.zeros(2 * self.ndof)])
            te[0] = self._state[watch]
            self._last = (float(t[0]), float(th[0]), float(om[0]), float(ld[0]))
            start = 1
        if start < t.size:
            prev = self._last
            assert prev is not None  # set with the state, on the first call
            tt = np.concatenate([[prev[0]], t[start:]])
            tht = np.concatenate([[prev[1]], th[start:]])
            omt = np.concatenate([[prev[2]], om[start:]])
            ldt = np.concatenate([[prev[3]], ld[start:]])
            te[start:] = self._advance(tt, tht, omt, ldt, watch)
            self._last = (float(t[-1]), float(th[-1]), float(om[-1]), float(ld[-1]))
        return te

    def _advance(self, t: np.ndarray, th: np.ndarray, om: np.ndarray,
                 ld: np.ndarray, watch: np.ndarray) -> np.ndarray:
        """Integrate over the intervals of (t, th, om, ld); state[watch] at t[1:]."""
        p = self.params
        dt = np.diff(t)
        nsub = np.maximum(1, np.ceil(dt / p.max_step_s - 1e-9)).astype(np.int64)
        total = int(nsub.sum())
        if total == dt.size:
            # one step per sample interval (sampling at >= 1 / max_step_s): the Hermite
            # weights at s = 1 are (0, 0, 1, 0), so the same values without the arithmetic
            h = _quantise(dt)
            th_s, ld_s = th[1:], ld[:-1] + (ld[1:] - ld[:-1])
            out = np.empty((dt.size, watch.size))
            for c0 in range(0, total, p.chunk_steps):
                c1 = min(total, c0 + p.chunk_steps)
                out[c0:c1] = self._run_chunk(th_s[c0:c1], ld_s[c0:c1], h[c0:c1], watch)
            return out
        interval = np.repeat(np.arange(dt.size), nsub)
        offset = np.arange(total) - np.repeat(np.cumsum(nsub) - nsub, nsub)
        frac = (offset + 1) / nsub[interval]                    # end of each step in (0, 1]
        h = _quantise(dt[interval] / nsub[interval])
        # cubic Hermite for theta_in, linear for the load, at the end of each step
        s = frac
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        d = dt[interval]
        th_s = (h00 * th[interval] + h10 * d * om[interval] + h01 * th[interval + 1]
                + h11 * d * om[interval + 1])
        ld_s = ld[interval] + s * (ld[interval + 1] - ld[interval])
        is_end = offset == nsub[interval] - 1
        out = np.empty((dt.size, watch.size))
        ndone = 0
        for c0 in range(0, total, p.chunk_steps):
            c1 = min(total, c0 + p.chunk_steps)
            traj = self._run_chunk(th_s[c0:c1], ld_s[c0:c1], h[c0:c1], watch)
            ends = is_end[c0:c1]
            k = int(ends.sum())
            out[ndone:ndone + k] = traj[ends]
            ndone += k
        return out

    def _run_chunk(self, th: np.ndarray, ld: np.ndarray, h: np.ndarray,
                   watch: np.ndarray) -> np.ndarray:
        """Newmark (beta = 1/4, gamma = 1/2) over one batch; state[watch] after each step.

        The effective matrices ``K(t_n+1) + (2/h) C + (4/h^2) M`` of the whole batch come
        from one matrix product; each step then costs one Cholesky solve (LAPACK dposv;
        the matrix is symmetric positive definite). When only displacements are watched
        the steps run in :meth:`_run_chunk_q` (same scheme, cheaper form); this loop on
        x = [q, v, a] serves velocities and accelerations.
        """
        nd = self.ndof
        c = self.damping_matrix
        a0 = 4.0 / h**2
        a1 = 2.0 / h
        # K_eff = K0 + a0 M + a1 C + (time-varying part, nonzero on few entries only)
        m_flat, c_flat = self.mass_matrix.ravel(), c.ravel()
        phase = self._phase(th)
        vary = self._coeffs(th, phase)[:, 1:]
        f = self.forces(th, ld, phase)
        # the z form pays a conversion per run of equal steps: for steps that change all
        # the time (jittery sample clocks) the x form below is cheaper
        if (_DPOSV is not None and int(watch.max()) < nd
                and 16 * np.count_nonzero(h[1:] != h[:-1]) <= h.size):
            return self._run_chunk_q(vary, f, h, watch)
        keff = self._basis[0] + a0[:, None] * m_flat + a1[:, None] * c_flat
        keff[:, self._vary_cols] += _serial_matmul(vary, self._vary_basis)
        x = self._state
        io = int(watch[0])
        single = watch.size == 1
        te = np.empty((th.size, watch.size))
        h_prev = math.nan
        for n in range(th.size):
            if h[n] != h_prev:
                h_prev = h[n]
                stacked, lmat = self._ops(float(h_prev))[:2]
            y = stacked @ x
            rhs = y[:nd]
            rhs += f[n]
            _, q_new, info = _dposv(keff[n].reshape(nd, nd), rhs, lower=1,
                                    overwrite_a=1, overwrite_b=1)
            if info != 0:
                msg = f'Newmark step matrix not positive definite (dposv info {info})'
                raise ModelInputError(msg)
            x = lmat @ q_new
            x += y[nd:]
            if single:
                te[n, 0] = x[io]
            else:
                te[n] = x[watch]
        self._state = x
        self._zstate = None
        return te

    def _ops(self, h: float) -> _NewmarkOps:
        """Cached Newmark operators of step ``h``: ([P; R], L, W) (see :meth:`_run_chunk_q`)."""
        ops = self._ops_cache.get(h)
        if ops is None:
            if len(self._ops_cache) > 64:
                self._ops_cache.clear()
            nd = self.ndof
            pmat, lmat, rmat = self._newmark_operators(h)
            a0 = 4.0 / h**2
            eye, m = np.eye(nd), self.mass_matrix
            # z' = W [q'; z], z = [p; m2]: p' = B q' - p - m2, m2' = 4 a0 M q' - m2
            bq = 4.0 * a0 * m + (4.0 / h) * self.damping_matrix
            wmat = np.block([[bq, -eye, -eye], [4.0 * a0 * m, np.zeros((nd, nd)), -eye]])
            keff0 = self._basis[0] + a0 * m.ravel() + (2.0 / h) * self.damping_matrix.ravel()
            ops = self._ops_cache[h] = (np.concatenate([pmat, rmat]), lmat, pmat, wmat, keff0)
        return ops

    def _run_chunk_q(self, vary: np.ndarray, f: np.ndarray, h: np.ndarray,
                     watch: np.ndarray) -> np.ndarray:
        """Newmark over one batch when only displacements are watched (the TE path).

        Same scheme as :meth:`_run_chunk`, written on the 2 n vector z = [p; m2] with
        ``p = M u + C w`` (the right-hand side without the force), ``u = a0 q + a2 v + a``,
        ``w = a1 q + v`` and ``m2 = a2 M w``: the Newmark updates of v and a become
        ``u' = 4 a0 q' - a2 w - u`` and ``w' = 2 a1 q' - w``, so a step is one add
        (``p + F``), one Cholesky solve (LAPACK dposv called directly, no wrapper
        overhead) and one 2n x 3n matrix-vector product. q, v, a are recovered at the end.
        The effective matrices (``vary`` holds their time-varying coefficients) are
        assembled ``_SUB_STEPS`` at a time into one buffer that stays in the CPU cache.
        """
        nd, steps = self.ndof, h.size
        out = np.empty((steps, watch.size))
        cuts = [0, *(np.flatnonzero(h[1:] != h[:-1]) + 1).tolist(), steps]
        f = np.ascontiguousarray(f)
        keff = self._keff_buf
        vcols, vbasis = self._vary_cols_up, self._vary_basis_up
        info = ctypes.c_int(0)
        uplo, n_c, one = ctypes.c_char(b'L'), ctypes.c_int(nd), ctypes.c_int(1)
        p_uplo, p_n, p_one, p_info = (ctypes.addressof(o) for o in (uplo, n_c, one, info))
        x = self._state
        assert x is not None  # set by the first step before any batch
        mdiag = np.diag(self.mass_matrix)
        c = self.damping_matrix
        for s0, s1 in itertools.pairwise(cuts):
            hs = float(h[s0])
            a0, a1, a2 = 4.0 / hs**2, 2.0 / hs, 4.0 / hs
            _, _, pmat, wmat, keff0 = self._ops(hs)
            m = s1 - s0
            zb = np.empty((m + 1, 3 * nd))
            zs = self._zstate
            if zs is not None and zs[0] == hs and zs[1] is x:
                zb[0, nd:] = zs[2]
            else:
                zb[0, nd:2 * nd] = pmat @ x
                zb[0, 2 * nd:] = a2 * mdiag * (a1 * x[:nd] + x[nd:2 * nd])
            base_k, stride_k = keff.ctypes.data, keff.strides[0]
            base_q, stride_q = zb.ctypes.data, zb.strides[0]
            add, matmul = np.add, np.matmul
            for b0 in range(0, m, _SUB_STEPS):
                b1 = min(m, b0 + _SUB_STEPS)
                kb = keff[:b1 - b0]
                kb[:] = keff0
                kb[:, vcols] += _serial_matmul(vary[s0 + b0:s0 + b1], vbasis)
                addr_k = base_k - b0 * stride_k
                for n, (zp, fn, zq, za, zn) in enumerate(zip(
                        zb[b0:b1, nd:2 * nd], f[s0 + b0:s0 + b1], zb[b0:b1, :nd],
                        zb[b0:b1], zb[b0 + 1:b1 + 1, nd:], strict=True), start=b0):
                    add(zp, fn, out=zq)
                    _DPOSV(p_uplo, p_n, p_one, addr_k + n * stride_k, p_n,
                           base_q + n * stride_q, p_n, p_info)
                    if info.value != 0:
                        msg = ('Newmark step matrix not positive definite '
                               f'(dposv info {info.value})')
                        raise ModelInputError(msg)
                    matmul(wmat, za, out=zn)
            q_all = zb[:m, :nd]
            out[s0:s1] = q_all[:, watch]
            # back to x = [q, v, a]
            q = q_all[-1].copy()
            z_end = zb[m, nd:].copy()
            w = z_end[nd:] / (a2 * mdiag)
            v = w - a1 * q
            a = (z_end[:nd] - c @ w) / mdiag - a0 * q - a2 * v
            x = np.concatenate([q, v, a])
            self._zstate = (hs, x, z_end)
        self._state = x
        return out

    def _newmark_operators(self, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Constant parts of one Newmark step of size ``h`` on x = [q, v, a].

        ``rhs = F + P x``; after solving ``K_eff q' = rhs``: ``x' = L q' + R x`` with
        ``a' = a0 (q' - q) - a2 v - a`` and ``v' = v + h/2 (a + a')``.
        """
        nd = self.ndof
        m, c = self.mass_matrix, self.damping_matrix
        a0, a1, a2 = 4.0 / h**2, 2.0 / h, 4.0 / h
        eye, z = np.eye(nd), np.zeros((nd, nd))
        pmat = np.concatenate([a0 * m + a1 * c, a2 * m + c, m], axis=1)
        acc_x = np.concatenate([-a0 * eye, -a2 * eye, -eye], axis=1)     # a' = a0 q' + acc_x x
        lmat = np.concatenate([eye, (h / 2.0) * a0 * eye, a0 * eye], axis=0)
        v_x = np.concatenate([z, eye, (h / 2.0) * eye], axis=1) + (h / 2.0) * acc_x
        rmat = np.concatenate([np.zeros((nd, 3 * nd)), v_x, acc_x], axis=0)
        return pmat, lmat, rmat


def build_te_model(preset: Preset, mode: str) -> Li2023DteModel:
    """Factory registered for ``model = "li2023-rv"`` (see sim.models).

    Args:
        preset: A ``li2023-rv`` style preset (overrides applied).
        mode: ``'dte'`` (dynamic transmission error) is the only mode.

    Raises:
        ModelInputError: Unknown mode.
        PresetError: A preset value breaks its rule.
    """
    if mode != 'dte':
        msg = f'model li2023-rv supports mode "dte" only, got {mode!r}'
        raise ModelInputError(msg)
    return Li2023DteModel(params_from_preset(preset), kinematics_from_preset(preset))
