"""What a bench knows about its own errors: the type B inputs of the uncertainty budgets.

One :class:`EncoderErrorModel` per shaft encoder and one :class:`BenchUncertainty` per
bench, in SI units (rad, s, N m, K). Defaults per encoder model come from the maker's data
(:data:`ENCODER_ERROR_DEFAULTS`, each with its source); a bench description's
``uncertainty:`` section (:func:`bench_uncertainty_from_plain`, catalogue units in the
keys) states the bench's own values: measured mounting eccentricity of a scale with its
uncertainty, the DAQ's timing skew between the two channels, the torque sensor's class,
the temperature spread.

An encoder's error is a periodic function of its shaft angle theta, modelled as harmonics
of unknown phase (each phase uniform on [0, 2 pi): the magnitude is bounded by the data
sheet, the phase of this particular unit is not known):

    e(theta) = sum_k g_k sin(k theta + rho_k)          graduation (long-range) error
             + e_1 sin(theta + rho_e)                  mounting eccentricity, e_1 = 2 e / D
             + a_i sin(N theta + rho_i)                position error within one signal
                                                       period (N lines; interpolation)
             + white noise (sigma) + quantisation (q = 2 pi / counts)

The data sheet gives a band +-a for the whole system ("system accuracy") and the position
error within one signal period +-a_i, not the spectrum. The long-range band a_L = a - a_i
is taken as GUM takes a bound, rectangular (u^2 = a_L^2 / 3 at any angle, GUM 4.3.7), and
that variance is spread equally over the harmonic orders 1..4 of the scale revolution:
g_k = a_L sqrt(2 / (3 K)), K = 4 (so sum g_k^2 / 2 = a_L^2 / 3). A bench that has
calibrated its scale (issue 36: several read heads, self-calibration) states its residual
harmonics instead (``graduation_arcsec: {order: amplitude}``).

Thermal expansion: a circular graduation that expands uniformly keeps its angles, so the
temperature enters only through a mismatch of expansion coefficients between a tape scale
and its drum (``cte_mismatch_per_k``; 0 for disc and ring graduations): the reading then
drifts by mismatch x delta T x the angle turned since the reference mark.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, TypedDict

from rv_te_bench.core.units import arcsec_to_rad
from rv_te_bench.errors import TeConfigError

__all__ = [
    'DEFAULT_GRADUATION_ORDERS',
    'ENCODER_ERROR_DEFAULTS',
    'BenchUncertainty',
    'BenchUncertaintyPlain',
    'EncoderErrorModel',
    'EncoderErrorPlain',
    'bench_uncertainty_from_plain',
    'default_encoder_errors',
    'graduation_from_band',
]

#: Harmonic orders of the scale revolution over which a data-sheet band is spread.
DEFAULT_GRADUATION_ORDERS = (1, 2, 3, 4)
_TWO_PI = 2.0 * math.pi


def _as(x_arcsec: float) -> float:
    return float(arcsec_to_rad(x_arcsec))


def graduation_from_band(band_rad: float, orders: tuple[int, ...] = DEFAULT_GRADUATION_ORDERS,
                         ) -> tuple[tuple[int, float], ...]:
    """Harmonics of equal amplitude whose mean square equals a rectangular +-band.

    Examples:
        >>> g = graduation_from_band(1.0)
        >>> len(g), round(sum(a * a / 2 for _, a in g), 12)    # = 1 / 3
        (4, 0.333333333333)
    """
    if not (math.isfinite(band_rad) and band_rad >= 0):
        msg = f'graduation band must be finite and >= 0, got {band_rad!r}'
        raise TeConfigError(msg)
    if band_rad == 0 or not orders:
        return ()
    g = band_rad * math.sqrt(2.0 / (3.0 * len(orders)))
    return tuple((int(k), g) for k in orders)


class EncoderErrorPlain(TypedDict):
    """:meth:`EncoderErrorModel.to_plain` (SI; graduation as [order, amplitude] pairs)."""

    model: str
    accuracy_rad: float
    graduation: list[list[int | float]]
    signal_periods: int
    interpolation_rad: float
    eccentricity_rad: float
    eccentricity_u_rad: float
    noise_sigma_rad: float
    resolution_rad: float
    cte_mismatch_per_k: float
    source: str
    known: bool


class BenchUncertaintyPlain(TypedDict):
    """:meth:`BenchUncertainty.to_plain` (SI; the torque zero None when not stated)."""

    encoder_in: EncoderErrorPlain
    encoder_out: EncoderErrorPlain
    daq_skew_s: float
    torque_zero_nm: float | None
    torque_gain_rel: float
    temperature_spread_k: float
    source: str


@dataclass(frozen=True)
class EncoderErrorModel:
    """The error model of one shaft encoder (SI units: rad).

    Attributes:
        model: Encoder model name (as in BenchInfo).
        accuracy_rad: The maker's +- system accuracy [rad] (for the record).
        graduation: ((order k, amplitude g_k [rad]), ...): long-range graduation error,
            harmonics of the scale revolution of unknown phase.
        signal_periods: Lines (signal periods) per revolution, N (0: not known).
        interpolation_rad: Amplitude of the position error within one signal period [rad].
        eccentricity_rad: Mounting eccentricity of the scale as an angle error amplitude
            2 e / D [rad] (measured; 0 for an encoder with integral bearing, whose system
            accuracy includes it).
        eccentricity_u_rad: Standard uncertainty of ``eccentricity_rad`` [rad].
        noise_sigma_rad: Read-head noise (jitter), standard deviation [rad].
        resolution_rad: Quantisation step q [rad] (0: not quantised / unknown).
        cte_mismatch_per_k: Expansion mismatch of scale and mount [1/K] (0 for a disc or
            ring graduation).
        source: Where the numbers come from.
    """

    model: str
    accuracy_rad: float = 0.0
    graduation: tuple[tuple[int, float], ...] = ()
    signal_periods: int = 0
    interpolation_rad: float = 0.0
    eccentricity_rad: float = 0.0
    eccentricity_u_rad: float = 0.0
    noise_sigma_rad: float = 0.0
    resolution_rad: float = 0.0
    cte_mismatch_per_k: float = 0.0
    source: str = ''
    known: bool = field(default=True, compare=False)

    def __post_init__(self) -> None:
        """Validate (TeConfigError names the field and the value)."""
        for name in ('accuracy_rad', 'interpolation_rad', 'eccentricity_rad',
                     'eccentricity_u_rad', 'noise_sigma_rad', 'resolution_rad',
                     'cte_mismatch_per_k'):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (
                    math.isfinite(v) and (v >= 0 or name == 'cte_mismatch_per_k')):
                msg = f'encoder {self.model!r}: {name} must be a finite number >= 0, got {v!r}'
                raise TeConfigError(msg)
            object.__setattr__(self, name, float(v))
        n = self.signal_periods
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            msg = f'encoder {self.model!r}: signal_periods must be an integer >= 0, got {n!r}'
            raise TeConfigError(msg)
        grad = []
        for item in self.graduation:
            k, g = item
            if isinstance(k, bool) or not isinstance(k, int) or k < 1 or not (
                    math.isfinite(g) and g >= 0):
                msg = (f'encoder {self.model!r}: graduation harmonics must be (order >= 1, '
                       f'amplitude >= 0), got {item!r}')
                raise TeConfigError(msg)
            grad.append((int(k), float(g)))
        object.__setattr__(self, 'graduation', tuple(grad))

    def components(self) -> tuple[tuple[str, int, float], ...]:
        """(name, order per shaft revolution, amplitude [rad]) of every periodic error of
        unknown phase: graduation harmonics, mounting eccentricity (amplitude
        sqrt(e_1^2 + u^2): the measured value and its uncertainty, phase unknown),
        interpolation (order N)."""
        out = [(f'graduation, order {k}', k, g) for k, g in self.graduation if g > 0]
        ecc = math.hypot(self.eccentricity_rad, self.eccentricity_u_rad)
        if ecc > 0:
            out.append(('mounting eccentricity (order 1)', 1, ecc))
        if self.interpolation_rad > 0 and self.signal_periods > 0:
            out.append((f'interpolation (order {self.signal_periods})', self.signal_periods,
                        self.interpolation_rad))
        return tuple(out)

    def long_range_components(self) -> tuple[tuple[str, int, float], ...]:
        """:meth:`components` without the interpolation error."""
        return tuple(c for c in self.components() if not c[0].startswith('interpolation'))

    def to_plain(self) -> EncoderErrorPlain:
        """JSON-friendly (SI)."""
        return {'model': self.model, 'accuracy_rad': self.accuracy_rad,
                'graduation': [[k, g] for k, g in self.graduation],
                'signal_periods': self.signal_periods,
                'interpolation_rad': self.interpolation_rad,
                'eccentricity_rad': self.eccentricity_rad,
                'eccentricity_u_rad': self.eccentricity_u_rad,
                'noise_sigma_rad': self.noise_sigma_rad, 'resolution_rad': self.resolution_rad,
                'cte_mismatch_per_k': self.cte_mismatch_per_k, 'source': self.source,
                'known': self.known}


def _from_data_sheet(model: str, *, accuracy_arcsec: float, interpolation_arcsec: float,
                     signal_periods: int, noise_arcsec: float, counts_per_rev: int | None,
                     source: str) -> EncoderErrorModel:
    return EncoderErrorModel(
        model=model, accuracy_rad=_as(accuracy_arcsec),
        graduation=graduation_from_band(_as(accuracy_arcsec - interpolation_arcsec)),
        signal_periods=signal_periods, interpolation_rad=_as(interpolation_arcsec),
        noise_sigma_rad=_as(noise_arcsec),
        resolution_rad=_TWO_PI / counts_per_rev if counts_per_rev else 0.0, source=source)


#: Error models of the encoders the suite knows, from the makers' data (see ``source``).
ENCODER_ERROR_DEFAULTS: dict[str, EncoderErrorModel] = {
    'ideal': EncoderErrorModel(model='ideal', source='reference encoder: no error'),
    'heidenhain-ron886': _from_data_sheet(
        'heidenhain-ron886', accuracy_arcsec=1.0, interpolation_arcsec=0.4,
        signal_periods=36_000, noise_arcsec=0.01, counts_per_rev=36_000 * 1000,
        source=('HEIDENHAIN "Angle encoders with integral bearing" brochure, RON 886: '
                '36,000 lines (signal period 36"), system accuracy +-1", position error '
                'within one signal period +-0.4" (about 1 % of the signal period), integral '
                'bearing (mounting eccentricity inside the system accuracy); x1000 '
                'interpolation (q = 0.036"); noise 0.01" assumed (not on the data sheet)')),
    'renishaw-resm': _from_data_sheet(
        'renishaw-resm', accuracy_arcsec=0.38, interpolation_arcsec=0.06,
        signal_periods=32_768, noise_arcsec=0.01, counts_per_rev=32_768 * 4000,
        source=('Renishaw RESM ring as installed on the Hu 2020 RV-80E bench: +-0.38" '
                '(Hu 2020 Table 9); 20 um pitch, 32,768 lines (~206 mm, assumed); '
                'sub-divisional error +-30 nm (readhead data) = +-0.06" on that ring; '
                'noise 0.01" assumed; x4000 interpolation')),
    'renishaw-resolute': _from_data_sheet(
        'renishaw-resolute', accuracy_arcsec=1.0, interpolation_arcsec=0.165,
        signal_periods=0, noise_arcsec=0.04, counts_per_rev=2**32,
        source=('Renishaw RESOLUTE absolute encoder with a ~100 mm REXA ring: installed '
                'accuracy to +-1", sub-divisional error +-40 nm (+-0.165" on that ring, '
                'period not stated: taken into the long-range band only for lines), jitter '
                '< 10 nm RMS (0.04"); 32 bit/rev')),
}


def default_encoder_errors(model: str, resolution_rad: float = 0.0) -> EncoderErrorModel:
    """The data-sheet error model of ``model``; an unknown model gets one with no error
    inputs but its quantisation, marked ``known=False`` (the budget says so).

    Args:
        model: Encoder model name (BenchInfo ``encoder_*_model``).
        resolution_rad: Quantisation step from BenchInfo (0: the default's).
    """
    known = ENCODER_ERROR_DEFAULTS.get(model)
    if known is None:
        return EncoderErrorModel(model=model or 'unknown', resolution_rad=max(resolution_rad, 0.0),
                                 source='unknown encoder model: no data-sheet errors',
                                 known=False)
    if resolution_rad > 0 and not math.isclose(resolution_rad, known.resolution_rad,
                                               rel_tol=1e-9):
        return replace(known, resolution_rad=float(resolution_rad))
    return known


@dataclass(frozen=True)
class BenchUncertainty:
    """The bench's type B inputs (SI units).

    Attributes:
        encoder_in: Input-shaft encoder.
        encoder_out: Output-shaft encoder.
        daq_skew_s: Half-width of the timing skew between the two channels' latches [s]
            (rectangular).
        torque_zero_nm: Half-width of the torque sensor's zero/linearity error [N m]
            (rectangular; accuracy class x nominal torque).
        torque_gain_rel: Half-width of its relative sensitivity (gain) error [1].
        temperature_spread_k: Range of the temperature recorded during the test [K]
            (rectangular over that range).
        source: Where the values come from (bench description, defaults).
    """

    encoder_in: EncoderErrorModel
    encoder_out: EncoderErrorModel
    daq_skew_s: float = 100e-9
    torque_zero_nm: float = math.nan
    torque_gain_rel: float = 1e-3
    temperature_spread_k: float = 1.0
    source: str = ''

    def __post_init__(self) -> None:
        """Validate (TeConfigError names the field)."""
        for name in ('daq_skew_s', 'torque_gain_rel', 'temperature_spread_k'):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (
                    math.isfinite(v) and v >= 0):
                msg = f'{name} must be a finite number >= 0, got {v!r}'
                raise TeConfigError(msg)
            object.__setattr__(self, name, float(v))
        z = self.torque_zero_nm
        if isinstance(z, bool) or not isinstance(z, int | float) or z < 0:
            msg = f'torque_zero_nm must be >= 0 (NaN: class x rated torque), got {z!r}'
            raise TeConfigError(msg)

    def torque_zero_for(self, rated_torque_nm: float) -> float:
        """The torque zero/linearity bound [N m]: stated, else 0.1 % of twice the rated
        torque (a sensor sized at 2 T_R, accuracy class 0.1)."""
        if math.isfinite(self.torque_zero_nm):
            return self.torque_zero_nm
        return 1e-3 * 2.0 * rated_torque_nm

    @classmethod
    def defaults(cls, encoder_in_model: str, encoder_out_model: str, *,
                 resolution_in_rad: float = 0.0, resolution_out_rad: float = 0.0,
                 ) -> BenchUncertainty:
        """Data-sheet defaults for the two encoder models; DAQ, torque sensor and
        temperature at the stated defaults."""
        return cls(encoder_in=default_encoder_errors(encoder_in_model, resolution_in_rad),
                   encoder_out=default_encoder_errors(encoder_out_model, resolution_out_rad),
                   source=DEFAULT_BENCH_SOURCE)

    def to_plain(self) -> BenchUncertaintyPlain:
        """JSON-friendly (SI)."""
        return {'encoder_in': self.encoder_in.to_plain(),
                'encoder_out': self.encoder_out.to_plain(),
                'daq_skew_s': self.daq_skew_s,
                'torque_zero_nm': None if math.isnan(self.torque_zero_nm)
                else self.torque_zero_nm,
                'torque_gain_rel': self.torque_gain_rel,
                'temperature_spread_k': self.temperature_spread_k, 'source': self.source}


#: Where the non-encoder defaults come from.
DEFAULT_BENCH_SOURCE = (
    'defaults: DAQ skew +-100 ns (two counter channels latched by one sample clock: one '
    'timebase tick of a 10 MHz clock, conservative for 80-100 MHz counter timebases); '
    'torque sensor accuracy class 0.1 of a nominal torque twice the rated torque, '
    'sensitivity tolerance +-0.1 % (HBM T40B-class flange; state the sensor used); '
    'temperature spread 1 K during the test (laboratory at 20 +- 0.5 degC)')


# --------------------------------------------------------------------------------------
# the bench description's ``uncertainty:`` section (catalogue units in the keys)

_ENCODER_KEYS = {'accuracy_arcsec', 'interpolation_arcsec', 'signal_periods',
                 'graduation_arcsec', 'eccentricity_um', 'eccentricity_u_um',
                 'scale_diameter_mm', 'noise_arcsec', 'cte_mismatch_per_k', 'source'}
_TOP_KEYS = {'encoders', 'daq_skew_ns', 'torque_sensor', 'temperature', 'source'}


def _num(where: str, key: str, v: object, *, minimum: float = 0.0) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
            or v < minimum:
        msg = f'{where}: {key} must be a finite number >= {minimum:g}, got {v!r}'
        raise TeConfigError(msg)
    return float(v)


def _check_keys(where: str, data: Any, allowed: set[str]) -> dict[str, Any]:
    if not isinstance(data, dict):
        msg = f'{where}: must be a mapping, got {data!r}'
        raise TeConfigError(msg)
    if bad := sorted(set(map(str, data)) - allowed):
        msg = f'{where}: unknown key(s) {bad}; allowed: {sorted(allowed)}'
        raise TeConfigError(msg)
    return data


def _encoder_from_plain(where: str, data: Any, base: EncoderErrorModel) -> EncoderErrorModel:
    d = _check_keys(where, data or {}, _ENCODER_KEYS)
    changes: dict[str, Any] = {}
    acc = d.get('accuracy_arcsec')
    interp = d.get('interpolation_arcsec')
    if acc is not None:
        changes['accuracy_rad'] = _as(_num(where, 'accuracy_arcsec', acc))
    if interp is not None:
        changes['interpolation_rad'] = _as(_num(where, 'interpolation_arcsec', interp))
    if 'signal_periods' in d:
        n = d['signal_periods']
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            msg = f'{where}: signal_periods must be an integer >= 0, got {n!r}'
            raise TeConfigError(msg)
        changes['signal_periods'] = n
    if 'graduation_arcsec' in d:
        g = d['graduation_arcsec']
        if not isinstance(g, dict):
            msg = f'{where}: graduation_arcsec must map harmonic orders to amplitudes, got {g!r}'
            raise TeConfigError(msg)
        harm = []
        for k, a in g.items():
            try:
                order = int(k)
            except (TypeError, ValueError):
                order = 0
            if order < 1:
                msg = f'{where}: graduation_arcsec order must be an integer >= 1, got {k!r}'
                raise TeConfigError(msg)
            harm.append((order, _as(_num(where, f'graduation_arcsec.{k}', a))))
        changes['graduation'] = tuple(sorted(harm))
    elif acc is not None or interp is not None:
        a = changes.get('accuracy_rad', base.accuracy_rad)
        i = changes.get('interpolation_rad', base.interpolation_rad)
        changes['graduation'] = graduation_from_band(max(a - i, 0.0))
    if 'eccentricity_um' in d or 'eccentricity_u_um' in d:
        if 'scale_diameter_mm' not in d:
            msg = f'{where}: eccentricity_um needs scale_diameter_mm (angle error = 2 e / D)'
            raise TeConfigError(msg)
        dia = _num(where, 'scale_diameter_mm', d['scale_diameter_mm'], minimum=1e-3)
        e = _num(where, 'eccentricity_um', d.get('eccentricity_um', 0.0))
        ue = _num(where, 'eccentricity_u_um', d.get('eccentricity_u_um', 0.0))
        changes['eccentricity_rad'] = 2.0 * e * 1e-6 / (dia * 1e-3)
        changes['eccentricity_u_rad'] = 2.0 * ue * 1e-6 / (dia * 1e-3)
    if 'noise_arcsec' in d:
        changes['noise_sigma_rad'] = _as(_num(where, 'noise_arcsec', d['noise_arcsec']))
    if 'cte_mismatch_per_k' in d:
        v = d['cte_mismatch_per_k']
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            msg = f'{where}: cte_mismatch_per_k must be a finite number, got {v!r}'
            raise TeConfigError(msg)
        changes['cte_mismatch_per_k'] = abs(float(v))
    src = d.get('source', 'bench description')
    if changes:
        changes['source'] = f'{src}; defaults: {base.source}'
        changes['known'] = True
    return replace(base, **changes)


def bench_uncertainty_from_plain(data: Any, base: BenchUncertainty,
                                 where: str = 'uncertainty') -> BenchUncertainty:
    """Apply a bench description's ``uncertainty:`` mapping to ``base`` (the defaults).

    Keys (catalogue units; every one optional)::

        encoders:
          input:  {accuracy_arcsec, interpolation_arcsec, signal_periods,
                   graduation_arcsec: {order: amplitude}, eccentricity_um,
                   eccentricity_u_um, scale_diameter_mm, noise_arcsec,
                   cte_mismatch_per_k, source}
          output: {...}
        daq_skew_ns: 25            # +- bound of the channel timing skew
        torque_sensor: {accuracy_class_pct: 0.05, nominal_nm: 500, gain_tolerance_pct: 0.1}
        temperature: {spread_k: 0.5}

    Raises:
        TeConfigError: An unknown key or a bad value (names where, the key and the value).
    """
    if data is None:
        return base
    d = _check_keys(where, data, _TOP_KEYS)
    changes: dict[str, Any] = {}
    enc = _check_keys(f'{where}.encoders', d.get('encoders') or {}, {'input', 'output'})
    if 'input' in enc:
        changes['encoder_in'] = _encoder_from_plain(f'{where}.encoders.input', enc['input'],
                                                    base.encoder_in)
    if 'output' in enc:
        changes['encoder_out'] = _encoder_from_plain(f'{where}.encoders.output',
                                                     enc['output'], base.encoder_out)
    if 'daq_skew_ns' in d:
        changes['daq_skew_s'] = _num(where, 'daq_skew_ns', d['daq_skew_ns']) * 1e-9
    if 'torque_sensor' in d:
        ts = _check_keys(f'{where}.torque_sensor', d['torque_sensor'] or {},
                         {'accuracy_class_pct', 'nominal_nm', 'gain_tolerance_pct'})
        if 'accuracy_class_pct' in ts or 'nominal_nm' in ts:
            if not {'accuracy_class_pct', 'nominal_nm'} <= set(ts):
                msg = f'{where}.torque_sensor: give accuracy_class_pct with nominal_nm'
                raise TeConfigError(msg)
            changes['torque_zero_nm'] = (
                _num(where, 'torque_sensor.accuracy_class_pct', ts['accuracy_class_pct'])
                * 1e-2 * _num(where, 'torque_sensor.nominal_nm', ts['nominal_nm']))
        if 'gain_tolerance_pct' in ts:
            changes['torque_gain_rel'] = _num(where, 'torque_sensor.gain_tolerance_pct',
                                              ts['gain_tolerance_pct']) * 1e-2
    if 'temperature' in d:
        tt = _check_keys(f'{where}.temperature', d['temperature'] or {}, {'spread_k'})
        if 'spread_k' in tt:
            changes['temperature_spread_k'] = _num(where, 'temperature.spread_k',
                                                   tt['spread_k'])
    if changes:
        changes['source'] = f'{d.get("source", "bench description")}; {base.source}'
    return replace(base, **changes)
