"""An encoder preset turned into a scale as mounted on one bench: heads, eccentricity, grade.

The presets of :mod:`sim.encoders` describe an encoder model with one head. A bench mounts a
particular scale: its run-out on the shaft (eccentricity e, as +-412 e/D arcsec, DESIGN.md
s.7), its graduation (a unit of the maker's grade: its own phases), its read heads (1 to
16, at stated angles, each with its own interpolation error and noise), the index at which
it sits on the shaft, its serial number. :func:`mounted_scale` makes that
:class:`~sim.encoders.EncoderSpec` from a preset and the bench's settings; the random parts
(phases of the graduation and of each head's interpolation error) come from a generator, so
one seed gives one scale.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from sim._checks import real_number
from sim.encoders import EncoderSpec, ReadHead, encoder_spec_with, with_heads
from sim.errors import ModelInputError
from sim.read_heads import eccentricity_angle_rad, graduation_from_grade

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = ['mounted_scale']


def _interpolation_of(spec: EncoderSpec) -> tuple[int, float]:
    """(line count, amplitude) of a one-head preset's interpolation harmonic (order > 1000)."""
    for n, a in zip(spec.graduation_orders, spec.graduation_amplitudes_rad, strict=True):
        if n > 1000:
            return n, a
    return spec.signal_periods, 0.0


def mounted_scale(spec: EncoderSpec, rng: np.random.Generator, *,
                  heads_deg: Sequence[float] = (), eccentricity_m: float = 0.0,
                  eccentricity_phase_rad: float | None = None, diameter_m: float = 0.0,
                  grade_arcsec: float = 0.0, tilt_rad: float = 0.0, index_rad: float = 0.0,
                  serial: str = '', interpolation_rad: float | None = None) -> EncoderSpec:
    """``spec`` as one scale mounted on a bench.

    Args:
        spec: The encoder preset.
        rng: Draws the graduation's and the heads' phases (and the eccentricity's phase when
            not given).
        heads_deg: Angles of the read heads around the scale from head 0 [deg]; empty: the
            preset's single head.
        eccentricity_m: Mounting eccentricity (run-out / 2) [m]; with ``diameter_m`` it
            replaces the preset's eccentricity term (0 with no diameter: kept).
        eccentricity_phase_rad: Its direction in scale coordinates [rad] (None: drawn).
        diameter_m: Graduation diameter [m] (0: not stated).
        grade_arcsec: The maker's accuracy of graduation +- [arcsec]; > 0 replaces the
            preset's graduation harmonics by a curve of that grade
            (:func:`~sim.read_heads.graduation_from_grade`); 0 keeps them.
        tilt_rad: Tilt of the scale plane [rad].
        index_rad: The scale's index on its shaft [rad] (reversal).
        serial: The scale's serial number.
        interpolation_rad: Each head's interpolation error amplitude [rad] (None: the
            preset's, from its harmonic at the line count).

    Raises:
        ModelInputError: A bad value (named), or an eccentricity without a diameter.
    """
    ecc = real_number('eccentricity_m', eccentricity_m, '>=0')
    dia = real_number('diameter_m', diameter_m, '>=0')
    if ecc > 0 and dia == 0:
        msg = 'a scale eccentricity needs the scale diameter (angle error 2 e / D)'
        raise ModelInputError(msg)
    changes: dict[str, Any] = {
        'tilt_rad': real_number('tilt_rad', tilt_rad, '>=0'),
        'tilt_phase_rad': float(rng.uniform(0.0, math.pi)),
        'scale_index_rad': real_number('index_rad', index_rad),
        'scale_diameter_m': dia, 'serial': str(serial)}
    if dia > 0:
        changes['eccentricity_amplitude_rad'] = eccentricity_angle_rad(ecc, dia)
        changes['eccentricity_phase_rad'] = (
            float(rng.uniform(0.0, 2 * math.pi)) if eccentricity_phase_rad is None
            else real_number('eccentricity_phase_rad', eccentricity_phase_rad))
    if real_number('grade_arcsec', grade_arcsec, '>=0') > 0:
        lines, _ = _interpolation_of(spec)
        g = graduation_from_grade(grade_arcsec, rng)
        keep = [(n, a, p) for n, a, p in zip(spec.graduation_orders,
                                             spec.graduation_amplitudes_rad,
                                             spec.graduation_phases_rad, strict=True)
                if lines and n == lines]       # the interpolation harmonic stays
        changes['graduation_orders'] = (*g.orders, *(k[0] for k in keep))
        changes['graduation_amplitudes_rad'] = (*g.amplitudes_rad, *(k[1] for k in keep))
        changes['graduation_phases_rad'] = (*g.phases_rad, *(k[2] for k in keep))
    base = encoder_spec_with(spec, **changes)
    angles = [real_number('heads_deg', a) for a in heads_deg]
    if not angles:
        return base
    if len(angles) > 16:
        msg = f'at most 16 read heads per scale, got {len(angles)}'
        raise ModelInputError(msg)
    lines, amp = _interpolation_of(base)
    amp = amp if interpolation_rad is None else real_number('interpolation_rad',
                                                            interpolation_rad, '>=0')
    phases = rng.uniform(0.0, 2 * math.pi, len(angles))
    heads = tuple(ReadHead(angle_rad=math.radians(a), interpolation_rad=amp,
                           interpolation_phase_rad=float(p),
                           noise_sigma_rad=base.noise_sigma_rad)
                  for a, p in zip(angles, phases, strict=True))
    return with_heads(base, heads, signal_periods=lines)
