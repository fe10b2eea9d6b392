"""Simulated angle encoders: graduation and eccentricity error, noise, quantisation.

An encoder reading of a shaft at the true (unwrapped) angle ``theta`` is modelled as::

    e(theta)   = sum_k a_k sin(n_k theta + phi_k)      graduation error, harmonics of the rev
               + e_1 sin(theta + phi_e)               mounting eccentricity (1 per rev)
    x          = theta + e(theta) + w,   w ~ N(0, sigma^2)   white read-head noise
    reading    = floor(x / q) * q,       q = 2 pi / counts_per_rev

The floor models the count an incremental/absolute read head reports: the last increment
passed, so the quantisation error lies in (-q, 0] with mean -q/2 and standard deviation
q/sqrt(12). ``counts_per_rev = None`` switches quantisation off (the ``'ideal'`` encoder).
Angles in and out are unwrapped multi-turn float64 radians (DESIGN.md s.5): the count is
kept as a float64 integer, exact up to 2**53 counts (~2.1e6 revolutions of a 32-bit
encoder, ~2.5e8 revolutions of a RON 886 at x1000 interpolation).

Presets (``ENCODER_PRESETS``) state the source of each number and how the accuracy class
(the +-band of the total error) is split into graduation harmonics, eccentricity and noise;
the split is an assumption (data sheets give the band, not the spectrum). The rule applied:
sum of harmonic amplitudes + eccentricity + 3 sigma noise <= accuracy class. The
sub-divisional (interpolation) error inside one signal period is modelled, where stated, as
one harmonic at the line count; sampled at a few kHz it aliases like the real one.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from sim._checks import real_number
from sim.errors import ModelInputError, PresetError
from sim.units import arcsec_to_rad

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = [
    'ENCODER_PRESETS',
    'EncoderSpec',
    'SimulatedEncoder',
    'encoder_preset',
    'encoder_spec_with',
    'remounted',
]

_TWO_PI = 2.0 * math.pi
_MAX_COUNTS_PER_REV = 2**40


def _finite_float(name: str, value: Any, *, nonneg: bool = False) -> float:
    """Return ``value`` as float or raise naming ``name`` and the rule."""
    return real_number(name, value, '>=0' if nonneg else '')


@dataclass(frozen=True)
class EncoderSpec:
    """A rotary angle encoder as the simulation sees it (SI units, radians).

    Attributes:
        name: Model name, e.g. ``'heidenhain-ron886'`` (published in BenchInfo).
        counts_per_rev: Increments per revolution after interpolation (lines x
            interpolation factor, or 2**bits); ``None`` = no quantisation.
        graduation_orders: Harmonic orders n_k of the graduation error (per revolution, >= 1).
        graduation_amplitudes_rad: Peak amplitudes a_k [rad] (>= 0), one per order.
        graduation_phases_rad: Phases phi_k [rad], one per order.
        eccentricity_amplitude_rad: Peak 1-per-rev error from mounting eccentricity [rad]
            (e / R for an eccentricity e on a scale of radius R).
        eccentricity_phase_rad: Its phase [rad].
        noise_sigma_rad: Standard deviation of white read-head noise [rad] (>= 0).
        accuracy_class_arcsec: The +- accuracy band the maker states [arcsec]; for the
            record only, not used in the simulation.
        source: Where the numbers come from.
        assumptions: What the source does not give and this spec assumes.
    """

    name: str
    counts_per_rev: int | None
    graduation_orders: tuple[int, ...] = ()
    graduation_amplitudes_rad: tuple[float, ...] = ()
    graduation_phases_rad: tuple[float, ...] = ()
    eccentricity_amplitude_rad: float = 0.0
    eccentricity_phase_rad: float = 0.0
    noise_sigma_rad: float = 0.0
    accuracy_class_arcsec: float = 0.0
    source: str = ''
    assumptions: str = field(default='', repr=False)

    def __post_init__(self) -> None:
        """Validate every field; sequences are stored as tuples of float/int.

        Raises:
            ModelInputError: A field breaks its rule (the message names field and value).
        """
        if not isinstance(self.name, str) or not self.name.strip():
            msg = f'name must be a non-empty string, got {self.name!r}'
            raise ModelInputError(msg)
        cpr = self.counts_per_rev
        if cpr is not None:
            if isinstance(cpr, bool) or not isinstance(cpr, int | np.integer):
                msg = f'counts_per_rev must be an integer or None, got {cpr!r}'
                raise ModelInputError(msg)
            if not 1 <= cpr <= _MAX_COUNTS_PER_REV:
                msg = f'counts_per_rev must be in [1, 2**40], got {cpr!r}'
                raise ModelInputError(msg)
            object.__setattr__(self, 'counts_per_rev', int(cpr))
        orders = tuple(self.graduation_orders)
        for n in orders:
            if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
                msg = f'graduation_orders must be integers >= 1, got {self.graduation_orders!r}'
                raise ModelInputError(msg)
        amps = tuple(_finite_float('graduation_amplitudes_rad', a, nonneg=True)
                     for a in self.graduation_amplitudes_rad)
        phases = tuple(_finite_float('graduation_phases_rad', p)
                       for p in self.graduation_phases_rad)
        if not len(orders) == len(amps) == len(phases):
            msg = (f'graduation_orders ({len(orders)}), graduation_amplitudes_rad '
                   f'({len(amps)}) and graduation_phases_rad ({len(phases)}) must have the '
                   'same length')
            raise ModelInputError(msg)
        object.__setattr__(self, 'graduation_orders', tuple(int(n) for n in orders))
        object.__setattr__(self, 'graduation_amplitudes_rad', amps)
        object.__setattr__(self, 'graduation_phases_rad', phases)
        for name, nonneg in (('eccentricity_amplitude_rad', True),
                             ('eccentricity_phase_rad', False),
                             ('noise_sigma_rad', True),
                             ('accuracy_class_arcsec', True)):
            object.__setattr__(self, name, _finite_float(name, getattr(self, name),
                                                         nonneg=nonneg))
        for name in ('source', 'assumptions'):
            if not isinstance(getattr(self, name), str):
                msg = f'{name} must be a string, got {getattr(self, name)!r}'
                raise ModelInputError(msg)

    @property
    def resolution_rad(self) -> float:
        """Smallest increment q = 2 pi / counts_per_rev [rad]; 0.0 without quantisation."""
        return 0.0 if self.counts_per_rev is None else _TWO_PI / self.counts_per_rev

    @property
    def worst_case_error_rad(self) -> float:
        """Bound of the modelled error: sum of amplitudes + eccentricity + 3 sigma [rad].

        Quantisation (at most one increment) is not included.
        """
        return (sum(self.graduation_amplitudes_rad) + self.eccentricity_amplitude_rad
                + 3.0 * self.noise_sigma_rad)

    @property
    def error_mean_square_rad2(self) -> float:
        """Mean square of graduation + eccentricity + noise over whole revolutions [rad^2].

        Sum of a_k^2 / 2 (distinct orders, order 1 combined with the eccentricity) plus
        sigma^2; quantisation (q^2 / 12 about its mean -q/2) is not included.
        """
        c: dict[int, complex] = {}
        for n, a, p in zip(self.graduation_orders, self.graduation_amplitudes_rad,
                           self.graduation_phases_rad, strict=True):
            c[n] = c.get(n, 0.0) + a * complex(math.cos(p), math.sin(p))
        c[1] = c.get(1, 0.0) + self.eccentricity_amplitude_rad * complex(
            math.cos(self.eccentricity_phase_rad), math.sin(self.eccentricity_phase_rad))
        return sum(abs(v) ** 2 for v in c.values()) / 2.0 + self.noise_sigma_rad ** 2

    def angle_error_rad(self, theta_true_rad: npt.ArrayLike) -> np.ndarray:
        """Deterministic error (graduation + eccentricity) at the true angle [rad]."""
        th = np.asarray(theta_true_rad, dtype=np.float64)
        err = np.zeros_like(th)
        for n, a, p in zip(self.graduation_orders, self.graduation_amplitudes_rad,
                           self.graduation_phases_rad, strict=True):
            if a:
                err += a * np.sin(n * th + p)
        if self.eccentricity_amplitude_rad:
            err += self.eccentricity_amplitude_rad * np.sin(th + self.eccentricity_phase_rad)
        return err

    def to_plain(self) -> dict[str, Any]:
        """JSON/YAML-friendly dict of the fields (tuples as lists)."""
        out = dataclasses.asdict(self)
        return {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}


def encoder_spec_with(spec: EncoderSpec, **changes: Any) -> EncoderSpec:
    """Copy of ``spec`` with fields replaced and validated again.

    Args:
        spec: The spec to start from.
        **changes: Field names and new values (e.g. ``noise_sigma_rad=0.0``).

    Raises:
        ModelInputError: Unknown field name, or a value that breaks the field's rule.
    """
    known = {f.name for f in dataclasses.fields(EncoderSpec)}
    unknown = sorted(set(changes) - known)
    if unknown:
        msg = f'EncoderSpec has no field(s) {unknown}; fields: {", ".join(sorted(known))}'
        raise ModelInputError(msg)
    return dataclasses.replace(spec, **changes)


def remounted(spec: EncoderSpec, rng: np.random.Generator, *,
              eccentricity_rad: float | None = None) -> EncoderSpec:
    """The same encoder model as another unit or mounting: every graduation harmonic and
    the eccentricity at a new phase drawn uniformly from [0, 2 pi) (a unit's phases are not
    known, only the data sheet's amplitudes), the eccentricity amplitude replaced when given
    (a new mounting).

    Args:
        spec: The encoder.
        rng: Generator of the phases.
        eccentricity_rad: New mounting eccentricity amplitude 2 e / D [rad] (>= 0).
    """
    n = len(spec.graduation_orders)
    phases = tuple(float(p) for p in rng.uniform(0.0, _TWO_PI, n))
    changes: dict[str, Any] = {'graduation_phases_rad': phases,
                               'eccentricity_phase_rad': float(rng.uniform(0.0, _TWO_PI))}
    if eccentricity_rad is not None:
        changes['eccentricity_amplitude_rad'] = eccentricity_rad
    return encoder_spec_with(spec, **changes)


def _as(x_arcsec: float) -> float:
    return float(arcsec_to_rad(x_arcsec))


ENCODER_PRESETS: dict[str, EncoderSpec] = {
    'ideal': EncoderSpec(
        name='ideal', counts_per_rev=None,
        source='reference: no quantisation, no error, no noise',
        assumptions='exact angles; TE from the readings equals the model TE'),
    'heidenhain-ron886': EncoderSpec(
        name='heidenhain-ron886',
        counts_per_rev=36_000 * 1000,
        graduation_orders=(2, 3, 4, 36_000),
        graduation_amplitudes_rad=(_as(0.45), _as(0.2), _as(0.1), _as(0.1)),
        graduation_phases_rad=(0.3, 1.9, 4.1, 0.0),
        eccentricity_amplitude_rad=_as(0.1),
        eccentricity_phase_rad=2.2,
        noise_sigma_rad=_as(0.01),
        accuracy_class_arcsec=1.0,
        source=('HEIDENHAIN RON 886 angle encoder with integral bearing: 36,000 lines '
                '(signal period 36"), system accuracy +-1" (maker\'s data; DESIGN.md s.5); '
                'Wang 2020 bench uses HEIDENHAIN encoders read by an NI card'),
        assumptions=('x1000 interpolation in the EIB/IK220 or DAQ (36e6 counts/rev, '
                     'q = 0.036"); +-1" split as graduation harmonics 2/3/4 of 0.45/0.2/0.1", '
                     'position error within one signal period 0.1" (harmonic 36,000), '
                     'residual 1/rev coupling eccentricity 0.1" (integral bearing), '
                     'noise sigma 0.01"; sum + 3 sigma = 0.98" <= 1"; phases arbitrary')),
    'renishaw-resm': EncoderSpec(
        name='renishaw-resm',
        counts_per_rev=32_768 * 4000,
        graduation_orders=(2, 3, 4),
        graduation_amplitudes_rad=(_as(0.2), _as(0.08), _as(0.04)),
        graduation_phases_rad=(1.1, 0.4, 2.7),
        eccentricity_amplitude_rad=_as(0.03),
        eccentricity_phase_rad=5.0,
        noise_sigma_rad=_as(0.01),
        accuracy_class_arcsec=0.38,
        source=('Renishaw RESM ring encoder, +-0.38" as installed on the Hu 2020 RV-80E bench '
                '(Hu 2020 Table 9, sampled at 250 Hz there)'),
        assumptions=('ring size and interpolation not given: 20 um pitch ring with 32,768 '
                     'lines (~206 mm), x4000 interpolation (5 nm; 1.31e8 counts/rev, '
                     'q = 0.0099"); +-0.38" split as harmonics 2/3/4 of 0.2/0.08/0.04", '
                     'residual eccentricity 0.03" (taper mount / two read heads), noise '
                     'sigma 0.01"; sum + 3 sigma = 0.38"; phases arbitrary')),
    'renishaw-resolute': EncoderSpec(
        name='renishaw-resolute',
        counts_per_rev=2**32,
        graduation_orders=(2, 3, 4),
        graduation_amplitudes_rad=(_as(0.45), _as(0.2), _as(0.1)),
        graduation_phases_rad=(2.0, 3.3, 0.8),
        eccentricity_amplitude_rad=_as(0.1),
        eccentricity_phase_rad=1.4,
        noise_sigma_rad=_as(0.04),
        accuracy_class_arcsec=1.0,
        source=('Renishaw RESOLUTE absolute encoder: 32 bit/rev, installed accuracy to +-1" '
                '(REXA ring), jitter < 10 nm RMS (maker\'s data; DESIGN.md s.5)'),
        assumptions=('ring of ~100 mm diameter: 10 nm jitter -> sigma 0.04"; +-1" split as '
                     'harmonics 2/3/4 of 0.45/0.2/0.1", eccentricity 0.1"; sum + 3 sigma = '
                     '0.97" <= 1"; sub-divisional error (+-40 nm) not modelled; phases '
                     'arbitrary')),
}


def encoder_preset(name: str) -> EncoderSpec:
    """The encoder spec registered under ``name``.

    Raises:
        PresetError: Unknown name (the message lists the known ones).
    """
    spec = ENCODER_PRESETS.get(name) if isinstance(name, str) else None
    if spec is None:
        msg = f'unknown encoder {name!r}; known encoders: {", ".join(sorted(ENCODER_PRESETS))}'
        raise PresetError(msg)
    return spec


class SimulatedEncoder:
    """One encoder read on the DAQ clock: error, noise and quantisation of true angles.

    Args:
        spec: The encoder model.
        rng: Generator for the read-head noise (the only source of randomness).
    """

    def __init__(self, spec: EncoderSpec, rng: np.random.Generator) -> None:
        """Store the spec and the generator (see class docstring)."""
        if not isinstance(spec, EncoderSpec):
            msg = f'spec must be an EncoderSpec, got {type(spec).__name__}'
            raise ModelInputError(msg)
        if not isinstance(rng, np.random.Generator):
            msg = f'rng must be a numpy.random.Generator, got {type(rng).__name__}'
            raise ModelInputError(msg)
        self.spec = spec
        self.rng = rng
        self._q = spec.resolution_rad
        self._counts_per_rad = (0.0 if spec.counts_per_rev is None
                                else spec.counts_per_rev / _TWO_PI)

    def measure(self, theta_true_rad: npt.ArrayLike) -> np.ndarray:
        """Encoder readings of the true shaft angles.

        Args:
            theta_true_rad: True unwrapped shaft angle [rad], 1-D float64 array.

        Returns:
            Readings [rad], unwrapped, same shape, a new array.

        Raises:
            ModelInputError: Not 1-D or not finite.
        """
        th = np.asarray(theta_true_rad, dtype=np.float64)
        if th.ndim != 1:
            msg = f'theta_true_rad must be 1-D, got shape {th.shape}'
            raise ModelInputError(msg)
        if not np.all(np.isfinite(th)):
            msg = 'theta_true_rad must be finite (NaN or inf found)'
            raise ModelInputError(msg)
        x = th + self.spec.angle_error_rad(th)
        if self.spec.noise_sigma_rad:
            x += self.spec.noise_sigma_rad * self.rng.standard_normal(th.size)
        if self.spec.counts_per_rev is not None:
            x = np.floor(x * self._counts_per_rad) * self._q
        return x
