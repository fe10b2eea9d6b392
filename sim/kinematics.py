"""Reducer kinematics: overall ratio, crank speeds, mesh orders and member angles.

Two two-stage reducers share one layout: a first stage where the input sun pinion
(``z_sun``) drives spur gears (``z_planet``) fixed on the crankshafts, which are held by the
carrier (= the output); and a second stage where the crank eccentrics make an
external-toothed member (2K-V: planet gear ``z_gear``; RV: cycloid disc ``z_cycloid``)
orbit inside a fixed internal member (2K-V: ring ``z_ring``; RV: pin ring ``z_pin``).

Derivation (angular speeds, carrier/output speed ``w_c``):

* The eccentric members translate relative to the carrier (parallel cranks), so they spin
  at ``w_c`` and their centre orbits the main axis at the absolute crank rate ``w_abs``.
* Rolling inside the fixed ring: ``w_c = w_abs * (z_gear - z_ring) / z_gear``, hence
  ``w_abs = w_c * z_gear / (z_gear - z_ring)`` and the crank speed relative to the carrier
  ``w_rel = w_abs - w_c = w_c * z_ring / (z_gear - z_ring)``.
* First stage (external mesh, seen from the carrier):
  ``w_rel = -(z_sun / z_planet) * (w_in - w_c)``, so the overall ratio is
  ``i = w_in / w_c = 1 + (z_planet / z_sun) * z_ring / (z_ring - z_gear)``.

Wang 2020 2K-V (12/36, 50/52): i = 79, ``w_rel = -26 w_c``, ``w_abs = -25 w_c``
(f_w = 1.582 Hz at 300 rpm input; DESIGN.md s.4). RV with one pin more than cycloid teeth:
i = 1 + (z_planet / z_sun) * z_pin, ``w_abs = -z_cycloid w_c`` and ``w_rel = -z_pin w_c``.

Mesh frequencies as orders of the output rotation: stage 1 ``z_planet * |w_rel / w_c|``,
stage 2 ``z_ring * |w_abs / w_c|`` (= ``z_gear * |w_rel / w_c|``).

Sign convention: the input angle is positive; the output turns the same way (i > 0); crank
angles are signed (negative: the cranks turn against the input).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from sim.errors import PresetError

if TYPE_CHECKING:
    import numpy.typing as npt

    from sim.presets import Preset

__all__ = [
    'ReducerKinematics',
    'kinematics_2kv',
    'kinematics_from_preset',
    'kinematics_rv',
]

_KINDS = ('2kv', 'rv')


def _check_teeth(name: str, value: object) -> int:
    """Return ``value`` as a positive int or raise naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        msg = f'{name} must be an integer tooth count, got {value!r}'
        raise PresetError(msg)
    if value <= 0:
        msg = f'{name} must be a positive tooth count, got {value!r}'
        raise PresetError(msg)
    return int(value)


@dataclass(frozen=True)
class ReducerKinematics:
    """Speed ratios and mesh orders of a two-stage 2K-V or RV reducer.

    Attributes:
        kind: ``'2kv'`` or ``'rv'``.
        z_sun: Teeth of the input sun pinion (stage 1).
        z_planet: Teeth of the spur gear on each crankshaft (stage 1).
        z_gear: 2K-V: external teeth of the 2nd-stage planet gear; RV: cycloid disc teeth.
        z_ring: 2K-V: internal ring teeth; RV: number of pins.
        gear_ratio: Overall ratio i, input revolutions per output revolution (> 0).
        crank_per_input: Absolute crank revolutions per input revolution (signed); for the
            2K-V this is also the orbit of the 2nd-stage planets.
        crank_rel_per_input: Crank revolutions relative to the carrier per input revolution.
        mesh_orders_out: Every mesh frequency as a (positive) order of the output rotation.
        mesh_labels: One label per mesh order.
    """

    kind: str
    z_sun: int
    z_planet: int
    z_gear: int
    z_ring: int
    gear_ratio: float
    crank_per_input: float
    crank_rel_per_input: float
    mesh_orders_out: tuple[float, ...]
    mesh_labels: tuple[str, ...]

    def __post_init__(self) -> None:
        """Validate the fields (names the field and the rule).

        Raises:
            PresetError: Unknown kind, bad tooth count, non-positive or non-finite ratio,
                mismatched mesh labels.
        """
        if self.kind not in _KINDS:
            msg = f'kind must be one of {_KINDS}, got {self.kind!r}'
            raise PresetError(msg)
        for name in ('z_sun', 'z_planet', 'z_gear', 'z_ring'):
            _check_teeth(name, getattr(self, name))
        if not (math.isfinite(self.gear_ratio) and self.gear_ratio > 0):
            msg = f'gear_ratio must be finite and > 0, got {self.gear_ratio!r}'
            raise PresetError(msg)
        for name in ('crank_per_input', 'crank_rel_per_input'):
            if not math.isfinite(getattr(self, name)):
                msg = f'{name} must be finite, got {getattr(self, name)!r}'
                raise PresetError(msg)
        if len(self.mesh_orders_out) != len(self.mesh_labels):
            msg = (f'mesh_orders_out ({len(self.mesh_orders_out)}) and mesh_labels '
                   f'({len(self.mesh_labels)}) must have the same length')
            raise PresetError(msg)
        if any(not (math.isfinite(o) and o > 0) for o in self.mesh_orders_out):
            msg = f'mesh_orders_out must be finite and > 0, got {self.mesh_orders_out!r}'
            raise PresetError(msg)

    @property
    def crank_per_output(self) -> float:
        """|Absolute crank revolutions per output revolution| (25 for the Wang 2020 2K-V)."""
        return abs(self.crank_per_input * self.gear_ratio)

    @property
    def crank_rel_per_output(self) -> float:
        """|Crank revolutions relative to the carrier per output revolution| (26 for Wang)."""
        return abs(self.crank_rel_per_input * self.gear_ratio)

    def output_period_s(self, input_speed_hz: float) -> float:
        """Duration of one output revolution [s] at ``input_speed_hz`` input revs per second."""
        return self.gear_ratio / input_speed_hz

    def frequencies(self, input_speed_hz: float) -> dict[str, float]:
        """Characteristic frequencies at a constant input speed.

        Args:
            input_speed_hz: Input shaft speed [rev/s = Hz]; its sign is ignored.

        Returns:
            Positive magnitudes [Hz]: ``input_hz``, ``output_hz``, ``crank_hz`` (absolute
            crank rate f_w), ``crank_rel_hz`` (relative to the carrier), ``mesh_stage1_hz``,
            ``mesh_stage2_hz``.
        """
        f_in = abs(float(input_speed_hz))
        f_out = f_in / self.gear_ratio
        out = {
            'input_hz': f_in,
            'output_hz': f_out,
            'crank_hz': abs(self.crank_per_input) * f_in,
            'crank_rel_hz': abs(self.crank_rel_per_input) * f_in,
        }
        for k, order in enumerate(self.mesh_orders_out, start=1):
            out[f'mesh_stage{k}_hz'] = order * f_out
        return out

    def member_angles(self, theta_in_rad: npt.ArrayLike) -> dict[str, np.ndarray]:
        """Rigid-body angles of the members for an input angle (t0 = 0, all zero at start).

        Args:
            theta_in_rad: Input shaft angle [rad], any shape.

        Returns:
            ``input``, ``output``, ``crank_abs``, ``crank_rel`` [rad], signed per the module
            convention, same shape as ``theta_in_rad``.
        """
        th = np.asarray(theta_in_rad, dtype=np.float64)
        return {
            'input': th,
            'output': th / self.gear_ratio,
            'crank_abs': th * self.crank_per_input,
            'crank_rel': th * self.crank_rel_per_input,
        }


def _build(kind: str, z_sun: int, z_planet: int, z_gear: int, z_ring: int,
           labels: tuple[str, str]) -> ReducerKinematics:
    """Shared derivation (module docstring) once the teeth are validated."""
    w_abs = z_gear / (z_gear - z_ring)           # absolute crank speed per output speed
    w_rel = z_ring / (z_gear - z_ring)           # crank speed relative to carrier per output
    ratio = 1.0 + (z_planet / z_sun) * z_ring / (z_ring - z_gear)
    orders = (z_planet * abs(w_rel), z_ring * abs(w_abs))
    return ReducerKinematics(
        kind=kind, z_sun=z_sun, z_planet=z_planet, z_gear=z_gear, z_ring=z_ring,
        gear_ratio=ratio, crank_per_input=w_abs / ratio, crank_rel_per_input=w_rel / ratio,
        mesh_orders_out=orders, mesh_labels=labels)


def kinematics_2kv(z_sun: int, z_planet: int, z_gear: int, z_ring: int,
                   *, key_prefix: str = '') -> ReducerKinematics:
    """Kinematics of a 2K-V reducer (involute planetary 2nd stage with a fixed ring).

    Args:
        z_sun: Input sun pinion teeth.
        z_planet: Crankshaft spur gear teeth.
        z_gear: 2nd-stage planet (external) teeth.
        z_ring: Fixed ring (internal) teeth, > z_gear.
        key_prefix: Prefix for key names in error messages (e.g. ``'kinematics.'``).

    Raises:
        PresetError: Non-positive or non-integer teeth, or z_ring <= z_gear.

    Examples:
        >>> kinematics_2kv(12, 36, 50, 52).gear_ratio
        79.0
    """
    p = key_prefix
    z_sun = _check_teeth(f'{p}z_sun', z_sun)
    z_planet = _check_teeth(f'{p}z_planet', z_planet)
    z_gear = _check_teeth(f'{p}z_gear', z_gear)
    z_ring = _check_teeth(f'{p}z_ring', z_ring)
    if z_ring <= z_gear:
        msg = (f'{p}z_ring ({z_ring}) must be greater than {p}z_gear ({z_gear}) for a 2K-V '
               'reducer (internal ring around the planet gear)')
        raise PresetError(msg)
    w_rel_order = z_ring / (z_ring - z_gear)   # |crank rel. to carrier| per output rev
    w_abs_order = z_gear / (z_ring - z_gear)   # |absolute crank| per output rev (f_w / f_out)
    labels = (f'stage-1 mesh ({z_planet} x crank rel., {z_planet * w_rel_order:g} f_out)',
              f'stage-2 mesh ({z_ring} f_w, {z_ring * w_abs_order:g} f_out)')
    return _build('2kv', z_sun, z_planet, z_gear, z_ring, labels)


def kinematics_rv(z_sun: int, z_planet: int, z_cycloid: int, z_pin: int,
                  *, key_prefix: str = '') -> ReducerKinematics:
    """Kinematics of an RV reducer (cycloid disc in a fixed pin ring, one pin more).

    ``i = 1 + (z_planet / z_sun) * z_pin``; absolute crank speed ``z_cycloid / i`` x input,
    relative to the carrier ``z_pin / i`` x input (both against the input's sense).

    Args:
        z_sun: Input sun pinion teeth.
        z_planet: Crankshaft spur gear teeth.
        z_cycloid: Cycloid disc teeth (stored as ``z_gear``).
        z_pin: Number of pins (stored as ``z_ring``); must be ``z_cycloid + 1``.
        key_prefix: Prefix for key names in error messages; when given, the cycloid and
            pin counts are named ``z_gear``/``z_ring`` as in the preset.

    Raises:
        PresetError: Non-positive or non-integer teeth, or z_pin - z_cycloid != 1.

    Examples:
        >>> round(kinematics_rv(22, 60, 39, 40).gear_ratio, 2)
        110.09
    """
    p = key_prefix
    n_cyc, n_pin = (f'{p}z_gear', f'{p}z_ring') if p else ('z_cycloid', 'z_pin')
    z_sun = _check_teeth(f'{p}z_sun', z_sun)
    z_planet = _check_teeth(f'{p}z_planet', z_planet)
    z_cycloid = _check_teeth(n_cyc, z_cycloid)
    z_pin = _check_teeth(n_pin, z_pin)
    if z_pin - z_cycloid != 1:
        msg = (f'{n_pin} - {n_cyc} must be 1 for an RV reducer (one pin more than cycloid '
               f'teeth), got {z_pin} - {z_cycloid} = {z_pin - z_cycloid}')
        raise PresetError(msg)
    labels = (f'stage-1 mesh ({z_planet} x crank rel., {z_planet * z_pin:g} f_out)',
              f'pin mesh ({z_pin} f_w, {z_pin * z_cycloid:g} f_out)')
    return _build('rv', z_sun, z_planet, z_cycloid, z_pin, labels)


def kinematics_from_preset(preset: Preset) -> ReducerKinematics:
    """Kinematics from a preset's ``[kinematics]`` section.

    Keys: ``kinematics.kind`` (``'2kv'`` | ``'rv'``), ``kinematics.z_sun``,
    ``kinematics.z_planet``, ``kinematics.z_gear`` (RV: cycloid teeth),
    ``kinematics.z_ring`` (RV: pins).

    Raises:
        PresetError: A key is missing or breaks a rule (the message names the key).
    """
    sec = preset.section('kinematics')
    missing = [k for k in ('kind', 'z_sun', 'z_planet', 'z_gear', 'z_ring') if k not in sec]
    if missing:
        msg = (f'preset {preset.name!r}: [kinematics] lacks '
               f'{", ".join("kinematics." + k for k in missing)}')
        raise PresetError(msg)
    kind = sec['kind']
    args = (sec['z_sun'], sec['z_planet'], sec['z_gear'], sec['z_ring'])
    if kind == '2kv':
        return kinematics_2kv(*args, key_prefix='kinematics.')
    if kind == 'rv':
        return kinematics_rv(*args, key_prefix='kinematics.')
    msg = f'preset {preset.name!r}: kinematics.kind must be one of {_KINDS}, got {kind!r}'
    raise PresetError(msg)
