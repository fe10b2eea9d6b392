"""An encoder calibration: a scale's error curve that later sessions take off its readings.

The record (:class:`EncoderCalibration`) names the scale (its serial number), when and how
it was calibrated (self-calibration from several heads, reversal, or an external
certificate), the harmonics of its error with their standard uncertainties, the orders the
method could not see, and how long it is valid. The error is written in the scale's own
coordinate ``u`` (the reading of the calibrating head 0 minus the scale's index on its
shaft), as ``e(u) = sum_k a_k sin(k u + phi_k)``; a head at ``beta`` around the scale from
that head 0, on a scale mounted at index ``iota``, reads it at ``u = reading - iota - beta``,
so its corrected reading is ``reading - e(reading - iota - beta)``.

A calibration that holds order 1 holds the eccentricity of the mounting it was made in:
it is valid while the scale stays mounted (``mounting`` names it); re-mounted scales need a
new one. The file form (YAML, catalogue units: arcsec, deg) is :meth:`EncoderCalibration.to_plain`
/ :func:`calibration_from_plain`; files are read and written by
:mod:`rv_te_bench.io.calibration_file`.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from rv_te_bench.core.bench_uncertainty import EncoderErrorModel
from rv_te_bench.core.units import arcsec_to_rad, deg_to_rad, rad_to_arcsec, rad_to_deg
from rv_te_bench.errors import EncoderCalibrationError

if TYPE_CHECKING:
    import numpy.typing as npt

    from rv_te_bench.core.selfcal import HarmonicEstimate

__all__ = ['CALIBRATION_FORMAT', 'CalibrationFile', 'CalibrationHarmonic', 'EncoderCalibration',
           'calibration_from_estimate', 'calibration_from_plain']

#: The file format's name and version (the first key of a calibration file).
CALIBRATION_FORMAT = 'rv-te encoder calibration 1'
_MAX_HARMONICS = 1024
_TEXT_KEYS = ('scale_serial', 'date', 'method', 'valid_until', 'mounting', 'encoder_model',
              'source')


@dataclass(frozen=True)
class CalibrationHarmonic:
    """One harmonic of the scale error: ``a sin(k u + phi)`` (SI).

    Attributes:
        order: k >= 1.
        amplitude_rad: a >= 0 [rad].
        phase_rad: phi [rad].
        u_rad: Standard uncertainty of the harmonic as a vector (of its sine and of its
            cosine part) [rad], >= 0.
    """

    order: int
    amplitude_rad: float
    phase_rad: float
    u_rad: float

    @property
    def c_rad(self) -> complex:
        """Complex amplitude c with ``a sin(k u + phi) = Re(c e^{iku})``."""
        return -1j * self.amplitude_rad * complex(math.cos(self.phase_rad),
                                                  math.sin(self.phase_rad))


def _date(where: str, key: str, text: str) -> _dt.date | None:
    if not text:
        return None
    try:
        return _dt.date.fromisoformat(text[:10])
    except ValueError:
        msg = f'{where}: {key} must be an ISO date (YYYY-MM-DD), got {text!r}'
        raise EncoderCalibrationError(msg) from None


class HarmonicPlain(TypedDict):
    """A harmonic in the file form (catalogue units)."""

    order: int
    amplitude_arcsec: float
    phase_deg: float
    u_arcsec: float


class CalibrationFile(TypedDict):
    """:meth:`EncoderCalibration.to_plain`: the file form (catalogue units: arcsec, deg)."""

    format: str
    scale_serial: str
    date: str
    method: str
    valid_until: str
    mounting: str
    encoder_model: str
    source: str
    coordinate: str
    max_order: int
    undetermined_orders: list[int]
    harmonics: list[HarmonicPlain]


@dataclass(frozen=True)
class EncoderCalibration:
    """A calibration of one scale (see the module docstring).

    Attributes:
        scale_serial: The scale's serial number (required: a calibration belongs to one scale).
        date: ISO date of the calibration.
        method: How it was made (e.g. ``'self-calibration from 4 read heads'``).
        harmonics: The determined harmonics.
        undetermined_orders: Orders <= ``max_order`` the method could not see: they stay
            in the corrected readings.
        max_order: Highest order considered.
        valid_until: ISO date after which it is refused ('' : no expiry).
        mounting: The mounting it holds for (order 1 is that mounting's eccentricity).
        encoder_model: The encoder model (for the record).
        source: The sessions it came from.
        origin: Where it was read from, for messages.
    """

    scale_serial: str
    date: str
    method: str
    harmonics: tuple[CalibrationHarmonic, ...]
    undetermined_orders: tuple[int, ...] = ()
    max_order: int = 0
    valid_until: str = ''
    mounting: str = ''
    encoder_model: str = ''
    source: str = ''
    origin: str = '<encoder calibration>'

    def __post_init__(self) -> None:
        """Validate (EncoderCalibrationError names the origin, the key and the value)."""
        w = self.origin
        for key in _TEXT_KEYS:
            v = getattr(self, key)
            if not isinstance(v, str) or len(v) > 4096:
                msg = f'{w}: {key} must be a string of at most 4096 characters, got {v!r}'
                raise EncoderCalibrationError(msg)
        if not self.scale_serial.strip():
            msg = f'{w}: scale_serial is required (a calibration belongs to one scale)'
            raise EncoderCalibrationError(msg)
        if _date(w, 'date', self.date) is None:
            msg = f'{w}: date is required (ISO date of the calibration)'
            raise EncoderCalibrationError(msg)
        _date(w, 'valid_until', self.valid_until)
        hs = tuple(self.harmonics)
        if len(hs) > _MAX_HARMONICS or not all(isinstance(h, CalibrationHarmonic) for h in hs):
            msg = f'{w}: harmonics must be at most {_MAX_HARMONICS} CalibrationHarmonic records'
            raise EncoderCalibrationError(msg)
        orders = [h.order for h in hs]
        if len(set(orders)) != len(orders):
            msg = f'{w}: harmonics list an order twice: {sorted(orders)}'
            raise EncoderCalibrationError(msg)
        for h in hs:
            if isinstance(h.order, bool) or not isinstance(h.order, int) or h.order < 1 or not (
                    all(math.isfinite(x) for x in (h.amplitude_rad, h.phase_rad, h.u_rad))
                    and h.amplitude_rad >= 0 and h.u_rad >= 0):
                msg = (f'{w}: harmonic {h.order!r} needs order >= 1, amplitude >= 0, a finite '
                       f'phase and uncertainty >= 0, got {h!r}')
                raise EncoderCalibrationError(msg)
        object.__setattr__(self, 'harmonics', tuple(sorted(hs, key=lambda h: h.order)))
        und = tuple(sorted({int(k) for k in self.undetermined_orders}))
        if set(und) & set(orders):
            msg = f'{w}: orders {sorted(set(und) & set(orders))} both determined and undetermined'
            raise EncoderCalibrationError(msg)
        object.__setattr__(self, 'undetermined_orders', und)
        top = max([*orders, *und, int(self.max_order)], default=0)
        object.__setattr__(self, 'max_order', top)

    @property
    def orders(self) -> tuple[int, ...]:
        """Determined orders."""
        return tuple(h.order for h in self.harmonics)

    def error_rad(self, u_rad: npt.ArrayLike) -> np.ndarray:
        """The scale error at scale coordinate ``u`` [rad]."""
        u = np.asarray(u_rad, dtype=np.float64)
        out = np.zeros_like(u)
        for h in self.harmonics:
            if h.amplitude_rad:
                out += h.amplitude_rad * np.sin(h.order * u + h.phase_rad)
        return out

    def correct(self, reading_rad: npt.ArrayLike, *, head_angle_rad: float = 0.0,
                index_rad: float = 0.0) -> np.ndarray:
        """Readings of a head at ``head_angle_rad`` (scale at ``index_rad``) corrected [rad].

        The error is evaluated at the reading itself (it differs from the true angle by
        arcseconds: an order-k error moves by k x that, far below its uncertainty).
        """
        r = np.asarray(reading_rad, dtype=np.float64)
        corrected: npt.NDArray[np.float64] = r - self.error_rad(r - index_rad - head_angle_rad)
        return corrected

    def check_for(self, scale_serial: str, *, when: _dt.date | None = None) -> None:
        """Refuse a calibration for another scale, or one expired at ``when``.

        Raises:
            EncoderCalibrationError: Names both serials, or the expiry date.
        """
        if scale_serial != self.scale_serial:
            given = f'scale {scale_serial!r}' if scale_serial else 'a scale with no serial given'
            msg = (f'{self.origin}: the calibration is for scale {self.scale_serial!r}, the bench '
                   f'reports {given}: a scale\'s calibration cannot correct another scale '
                   '(state encoders.output.serial in the bench description)')
            raise EncoderCalibrationError(msg)
        end = _date(self.origin, 'valid_until', self.valid_until)
        day = when or _dt.datetime.now(tz=_dt.UTC).date()
        if end is not None and day > end:
            msg = (f'{self.origin}: the calibration of scale {self.scale_serial!r} expired on '
                   f'{self.valid_until} (today {day.isoformat()}): calibrate the scale again')
            raise EncoderCalibrationError(msg)

    def residual_error_model(self, base: EncoderErrorModel) -> EncoderErrorModel:
        """``base`` (the data sheet's model) after this calibration, for the uncertainty
        budgets: the determined orders leave only their uncertainty; the mounting
        eccentricity is in order 1 when that was determined; the undetermined orders keep
        the data sheet's amplitude; interpolation and noise are unchanged."""
        left = dict(base.graduation)
        for h in self.harmonics:
            left[h.order] = h.u_rad
        ecc, ecc_u = base.eccentricity_rad, base.eccentricity_u_rad
        if 1 in self.orders:
            ecc, ecc_u = 0.0, 0.0
        return replace(base, graduation=tuple(sorted(left.items())), eccentricity_rad=ecc,
                       eccentricity_u_rad=ecc_u,
                       source=f'{base.source}; calibrated: {self.describe()}')

    def describe(self) -> str:
        """One line for people."""
        und = ', '.join(map(str, self.undetermined_orders[:8]))
        more = ', ...' if len(self.undetermined_orders) > 8 else ''
        return (f'scale {self.scale_serial} calibrated {self.date[:10]} by {self.method}: '
                f'{len(self.harmonics)} harmonics up to order {self.max_order}'
                + (f', orders {und}{more} not determined' if und else ''))

    def to_plain(self) -> CalibrationFile:
        """The file form (catalogue units: arcsec, deg)."""
        return {
            'format': CALIBRATION_FORMAT,
            'scale_serial': self.scale_serial, 'date': self.date, 'method': self.method,
            'valid_until': self.valid_until, 'mounting': self.mounting,
            'encoder_model': self.encoder_model, 'source': self.source,
            'coordinate': 'u = reading - scale index - head angle; e(u) = sum a sin(k u + phi)',
            'max_order': self.max_order,
            'undetermined_orders': list(self.undetermined_orders),
            'harmonics': [{'order': h.order,
                           'amplitude_arcsec': float(rad_to_arcsec(h.amplitude_rad)),
                           'phase_deg': float(rad_to_deg(h.phase_rad)),
                           'u_arcsec': float(rad_to_arcsec(h.u_rad))} for h in self.harmonics],
        }


def _num(where: str, key: str, v: object, *, nonneg: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or (
            nonneg and v < 0):
        rule = 'a finite number' + (' >= 0' if nonneg else '')
        msg = f'{where}: {key} must be {rule}, got {v!r}'
        raise EncoderCalibrationError(msg)
    return float(v)


def calibration_from_plain(data: Any, origin: str = '<encoder calibration>',
                           ) -> EncoderCalibration:
    """Validate the file form (see :meth:`EncoderCalibration.to_plain`).

    Raises:
        EncoderCalibrationError: A missing, unknown or bad key (one line naming it).
    """
    if not isinstance(data, dict):
        msg = f'{origin}: must be a mapping, got {type(data).__name__}'
        raise EncoderCalibrationError(msg)
    d = dict(data)
    fmt = d.pop('format', None)
    if fmt != CALIBRATION_FORMAT:
        msg = f'{origin}: format must be {CALIBRATION_FORMAT!r}, got {fmt!r}'
        raise EncoderCalibrationError(msg)
    d.pop('coordinate', None)
    text = {k: d.pop(k, '') for k in _TEXT_KEYS}
    text = {k: (str(v) if isinstance(v, int | float | _dt.date) and not isinstance(v, bool)
                else v) for k, v in text.items()}
    raw = d.pop('harmonics', [])
    und = d.pop('undetermined_orders', [])
    top = d.pop('max_order', 0)
    if d:
        msg = f'{origin}: unknown key(s) {sorted(map(str, d))}'
        raise EncoderCalibrationError(msg)
    if not isinstance(raw, list) or not isinstance(und, list) or not all(
            isinstance(k, int) and not isinstance(k, bool) for k in [*und, top]):
        msg = (f'{origin}: harmonics must be a list, undetermined_orders a list of integers '
               'and max_order an integer')
        raise EncoderCalibrationError(msg)
    hs = []
    for i, item in enumerate(raw):
        where = f'{origin}: harmonics[{i}]'
        if not isinstance(item, dict) or set(item) != {'order', 'amplitude_arcsec',
                                                        'phase_deg', 'u_arcsec'}:
            msg = (f'{where} must have exactly order, amplitude_arcsec, phase_deg, u_arcsec, '
                   f'got {item!r}')
            raise EncoderCalibrationError(msg)
        k = item['order']
        if isinstance(k, bool) or not isinstance(k, int) or k < 1:
            msg = f'{where}: order must be an integer >= 1, got {k!r}'
            raise EncoderCalibrationError(msg)
        hs.append(CalibrationHarmonic(
            order=k,
            amplitude_rad=float(arcsec_to_rad(_num(where, 'amplitude_arcsec',
                                                   item['amplitude_arcsec'], nonneg=True))),
            phase_rad=float(deg_to_rad(_num(where, 'phase_deg', item['phase_deg']))),
            u_rad=float(arcsec_to_rad(_num(where, 'u_arcsec', item['u_arcsec'], nonneg=True)))))
    return EncoderCalibration(harmonics=tuple(hs), undetermined_orders=tuple(und),
                              max_order=int(top), origin=origin, **text)


def calibration_from_estimate(estimate: HarmonicEstimate, *, scale_serial: str,
                              date: str | None = None, valid_until: str = '',
                              mounting: str = '', encoder_model: str = '', source: str = '',
                              ) -> EncoderCalibration:
    """The calibration record of a self-calibration or reversal estimate.

    Raises:
        EncoderCalibrationError: No serial, or a bad date.
    """
    day = date or _dt.datetime.now(tz=_dt.UTC).date().isoformat()
    hs = []
    for k, c, u, ok in zip(estimate.orders.tolist(), estimate.c_rad.tolist(),
                           estimate.u_rad.tolist(), estimate.observable.tolist(), strict=True):
        if ok:
            z = complex(c) * 1j             # a e^{i phi}
            hs.append(CalibrationHarmonic(order=int(k), amplitude_rad=abs(z),
                                          phase_rad=math.atan2(z.imag, z.real), u_rad=float(u)))
    return EncoderCalibration(
        scale_serial=scale_serial, date=day, method=estimate.method, harmonics=tuple(hs),
        undetermined_orders=estimate.unobservable_orders,
        max_order=int(estimate.orders[-1]) if estimate.orders.size else 0,
        valid_until=valid_until, mounting=mounting, encoder_model=encoder_model,
        source=source)
