"""Simulated angle encoders: graduation and eccentricity error, noise, quantisation.

An encoder reading of a shaft at the true (unwrapped) angle ``theta`` is modelled as::

    e(theta)   = sum_k a_k sin(n_k theta + phi_k)      graduation error, harmonics of the rev
               + e_1 sin(theta + phi_e)               mounting eccentricity (1 per rev)
    x          = theta + e(theta) + w,   w ~ N(0, sigma^2)   white read-head noise
    reading    = floor(x / q) * q,       q = 2 pi / counts_per_rev

Several read heads on one scale (``EncoderSpec.heads``, issue 36): head j at ``beta_j``
reads the same scale error at the scale coordinate ``theta - iota - beta_j`` (``iota``: the
scale's index on its shaft, ``scale_index_rad``), plus its own interpolation error at the
line count (``signal_periods``) and its own noise; scale tilt adds an order-2 term. The
model and its derivation: :mod:`sim.read_heads`. With no heads given the encoder has one
head at 0 and reads exactly as above (same numbers, same random draws).

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
from sim.read_heads import ReadHead, tilt_amplitude_rad
from sim.units import arcsec_to_rad

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = [
    'ENCODER_PRESETS',
    'EncoderSpec',
    'ReadHead',
    'SimulatedEncoder',
    'encoder_preset',
    'encoder_spec_with',
    'remounted',
    'with_heads',
]

_TWO_PI = 2.0 * math.pi
_MAX_COUNTS_PER_REV = 2**40


def _finite_float(name: str, value: object, *, nonneg: bool = False) -> float:
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
        heads: Read heads on the scale (:class:`~sim.read_heads.ReadHead`); empty: one head
            at 0 whose noise is ``noise_sigma_rad`` (with heads, each head's own noise).
        signal_periods: Lines (signal periods) per revolution: the order of each head's
            interpolation error (0: none).
        tilt_rad: Tilt of the scale plane against the axis [rad] (order-2 error tau^2 / 4).
        tilt_phase_rad: Direction of the tilt axis chi in the scale coordinate [rad]
            (error +(tau^2 / 4) sin 2 (u - chi)).
        scale_index_rad: The scale turned on its shaft by this [rad] (reversal re-mounting);
            graduation, eccentricity and tilt turn with it.
        scale_diameter_m: Graduation diameter [m] (0: not stated; for the record).
        serial: The scale's serial number ('' : not stated).
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
    heads: tuple[ReadHead, ...] = ()
    signal_periods: int = 0
    tilt_rad: float = 0.0
    tilt_phase_rad: float = 0.0
    scale_index_rad: float = 0.0
    scale_diameter_m: float = 0.0
    serial: str = ''

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
        for name in ('source', 'assumptions', 'serial'):
            if not isinstance(getattr(self, name), str):
                msg = f'{name} must be a string, got {getattr(self, name)!r}'
                raise ModelInputError(msg)
        self._check_heads()

    def _check_heads(self) -> None:
        heads = tuple(self.heads)
        if not all(isinstance(h, ReadHead) for h in heads) or len(heads) > 16:
            msg = f'heads must be at most 16 ReadHead records, got {self.heads!r}'
            raise ModelInputError(msg)
        object.__setattr__(self, 'heads', heads)
        n = self.signal_periods
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
            msg = f'signal_periods must be an integer >= 0, got {n!r}'
            raise ModelInputError(msg)
        object.__setattr__(self, 'signal_periods', int(n))
        for name, nonneg in (('tilt_rad', True), ('tilt_phase_rad', False),
                             ('scale_index_rad', False), ('scale_diameter_m', True)):
            object.__setattr__(self, name, _finite_float(name, getattr(self, name),
                                                         nonneg=nonneg))

    @property
    def n_heads(self) -> int:
        """Read heads on the scale (1 when ``heads`` is empty)."""
        return max(1, len(self.heads))

    @property
    def head_angles_rad(self) -> tuple[float, ...]:
        """Angle of each head around the scale from head 0 [rad] ((0.0,) for one head)."""
        return tuple(h.angle_rad for h in self.heads) or (0.0,)

    def scale_error_rad(self, u_rad: npt.ArrayLike) -> np.ndarray:
        """The scale's own error at scale coordinate ``u`` [rad]: graduation, eccentricity
        and tilt (what moves with the scale; no head's interpolation error, no noise)."""
        u = np.asarray(u_rad, dtype=np.float64)
        err = np.zeros_like(u)
        for n, a, p in zip(self.graduation_orders, self.graduation_amplitudes_rad,
                           self.graduation_phases_rad, strict=True):
            if a:
                err += a * np.sin(n * u + p)
        if self.eccentricity_amplitude_rad:
            err += self.eccentricity_amplitude_rad * np.sin(u + self.eccentricity_phase_rad)
        if self.tilt_rad:
            err += tilt_amplitude_rad(self.tilt_rad) * np.sin(2.0 * (u - self.tilt_phase_rad))
        return err

    def head_errors_rad(self, theta_true_rad: npt.ArrayLike) -> np.ndarray:
        """Deterministic error of every head at the true shaft angle, shape (n_heads, n)
        [rad]: the scale error s at ``u = theta - scale_index - beta_j`` plus head j's
        interpolation error at the lines under it, ``u + s(u)`` (no noise)."""
        th = np.asarray(theta_true_rad, dtype=np.float64)
        heads = self.heads or (ReadHead(),)
        out = np.empty((len(heads), th.size))
        for j, h in enumerate(heads):
            u = th - self.scale_index_rad - h.angle_rad
            out[j] = self.scale_error_rad(u)
            if h.interpolation_rad and self.signal_periods:
                # periodic in the lines actually under the head: at u + s(u) (a 5 um
                # eccentricity moves them by ~1.8 signal periods on 18,000 lines)
                out[j] += h.interpolation_rad * np.sin(self.signal_periods * (u + out[j])
                                                       + h.interpolation_phase_rad)
        return out

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
        """Deterministic error (graduation + eccentricity + tilt) of head 0 at the true
        angle [rad] (without head 0's interpolation error)."""
        th = np.asarray(theta_true_rad, dtype=np.float64)
        return self.scale_error_rad(th - self.scale_index_rad - self.head_angles_rad[0])

    def to_plain(self) -> dict[str, Any]:
        """JSON/YAML-friendly dict of the fields (tuples as lists, heads as dicts); the
        head fields only when the spec has heads or a scale (older records unchanged)."""
        out = dataclasses.asdict(self)
        plain = {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}
        unset = {'heads': [], 'signal_periods': 0, 'tilt_rad': 0.0, 'tilt_phase_rad': 0.0,
                 'scale_index_rad': 0.0, 'scale_diameter_m': 0.0, 'serial': ''}
        if all(plain[k] == v for k, v in unset.items()):
            for k in unset:
                del plain[k]
        return plain


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


def with_heads(spec: EncoderSpec, heads: tuple[ReadHead, ...], *,
               signal_periods: int | None = None, **changes: Any) -> EncoderSpec:
    """``spec`` as a scale read by ``heads``: the graduation harmonic at the line count
    (a one-head preset's interpolation error, e.g. order 36,000 of the RON 886) leaves the
    scale's error, as each head has its own (:attr:`ReadHead.interpolation_rad`).

    Args:
        spec: The encoder (its graduation, eccentricity and counts are kept).
        heads: The read heads (1 .. 16).
        signal_periods: Lines per revolution (default: the largest graduation order above
            1000 of ``spec``, else 0).
        **changes: Further fields to replace (e.g. ``eccentricity_amplitude_rad``).

    Raises:
        ModelInputError: No head, or a field breaks its rule.
    """
    if not heads:
        msg = 'with_heads needs at least one ReadHead'
        raise ModelInputError(msg)
    lines = signal_periods
    if lines is None:
        lines = max((n for n in spec.graduation_orders if n > 1000), default=0)
    keep = [i for i, n in enumerate(spec.graduation_orders) if not (lines and n == lines)]
    fields: dict[str, Any] = {
        'heads': tuple(heads), 'signal_periods': lines,
        'graduation_orders': tuple(spec.graduation_orders[i] for i in keep),
        'graduation_amplitudes_rad': tuple(spec.graduation_amplitudes_rad[i] for i in keep),
        'graduation_phases_rad': tuple(spec.graduation_phases_rad[i] for i in keep)}
    fields.update(changes)
    return encoder_spec_with(spec, **fields)


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

    @staticmethod
    def _checked(theta_true_rad: npt.ArrayLike) -> np.ndarray:
        th = np.asarray(theta_true_rad, dtype=np.float64)
        if th.ndim != 1:
            msg = f'theta_true_rad must be 1-D, got shape {th.shape}'
            raise ModelInputError(msg)
        if not np.isfinite(th).all():
            msg = 'theta_true_rad must be finite (NaN or inf found)'
            raise ModelInputError(msg)
        return th

    def _quantised(self, x: np.ndarray) -> np.ndarray:
        if self.spec.counts_per_rev is not None:
            return np.floor(x * self._counts_per_rad) * self._q
        return x

    def measure(self, theta_true_rad: npt.ArrayLike) -> np.ndarray:
        """Encoder readings of the true shaft angles (head 0 of a scale with several heads:
        use :meth:`measure_heads` for all of them, which draws the same noise for head 0).

        Args:
            theta_true_rad: True unwrapped shaft angle [rad], 1-D float64 array.

        Returns:
            Readings [rad], unwrapped, same shape, a new array.

        Raises:
            ModelInputError: Not 1-D or not finite.
        """
        if self.spec.heads:
            first: npt.NDArray[np.float64] = self.measure_heads(theta_true_rad)[0]
            return first
        th = self._checked(theta_true_rad)
        x = th + self.spec.angle_error_rad(th)
        if self.spec.noise_sigma_rad:
            x += self.spec.noise_sigma_rad * self.rng.standard_normal(th.size)
        return self._quantised(x)

    def measure_heads(self, theta_true_rad: npt.ArrayLike) -> np.ndarray:
        """Readings of every head of the scale, shape (n_heads, n) [rad], each zeroed to
        the shaft angle (unwrapped); one row for an encoder without heads (= :meth:`measure`).

        Raises:
            ModelInputError: Not 1-D or not finite.
        """
        if not self.spec.heads:
            return self.measure(theta_true_rad)[None, :]
        th = self._checked(theta_true_rad)
        x = th + self.spec.head_errors_rad(th)
        sigma = np.array([h.noise_sigma_rad for h in self.spec.heads])
        if sigma.any():
            x += sigma[:, None] * self.rng.standard_normal(x.shape)
        return self._quantised(x)
