"""What the output encoder could put on the once-per-output-revolution line.

The largest line of most TE spectra sits at order 1 of the output (one per output
revolution), and the suite reads it as the reducer's: output-wheel eccentricity e_ot, the
identified Q terms, the re-assembly advice. An output scale mounted ``e`` off its axis,
read by one head, adds ``2 e / D`` rad (+-412 e/D arcsec, e in um, D in mm; DESIGN.md s.7) on
exactly that order, and its graduation error adds more; one head cannot tell the two apart.

:func:`once_per_rev_note` states, for a result that rests on that line, how much of it the
encoder could produce, and flags it when that reaches :data:`COMPARABLE_FRACTION` of the
line; several heads whose mean cancels order 1, or a calibration of the scale that holds
order 1, separate it (the note then says how, and what is left).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypedDict

from rv_te_bench.core.units import rad_to_arcsec

if TYPE_CHECKING:
    import numpy.typing as npt

    from rv_te_bench.core.bench_uncertainty import EncoderErrorModel
    from rv_te_bench.core.encoder_calibration import EncoderCalibration
    from rv_te_bench.core.heads import HeadLayout
    from sim.bench_info import BenchInfoData

__all__ = ['COMPARABLE_FRACTION', 'OncePerRevNote', 'OncePerRevNoteJson', 'line_amplitude_rad',
           'note_for_bench',
           'once_per_rev_note']

#: The encoder's possible share of the once-per-revolution line above which results resting
#: on that line are flagged (a 10 % error of e_ot is ten times the identification's own).
COMPARABLE_FRACTION = 0.1


def _arcsec(x: float) -> str:
    return f'{float(rad_to_arcsec(x)):.3g}"'


class OncePerRevNoteJson(TypedDict):
    """The JSON of :class:`OncePerRevNote` (None: not finite)."""

    possible_arcsec: float
    line_arcsec: float | None
    fraction: float | None
    comparable: bool
    separated: bool
    how: str
    source: str
    text: str
    possible_rad: float


@dataclass(frozen=True)
class OncePerRevNote:
    """The encoder's possible part of the once-per-output-revolution line.

    Attributes:
        possible_rad: Amplitude the output encoder could add at order 1 [rad] (after any
            averaging or calibration: what is left).
        line_rad: Amplitude of the measured order-1 line [rad] (NaN: not known).
        separated: Several heads or a calibration took the encoder's order 1 out.
        how: How the encoder's order 1 is (or is not) separated, for people.
        source: Where ``possible_rad`` comes from.
    """

    possible_rad: float
    line_rad: float
    separated: bool
    how: str
    source: str

    @property
    def fraction(self) -> float:
        """possible / line (NaN when the line is not known or zero)."""
        if not (math.isfinite(self.line_rad) and self.line_rad > 0):
            return math.nan
        return self.possible_rad / self.line_rad

    @property
    def comparable(self) -> bool:
        """The encoder could produce at least :data:`COMPARABLE_FRACTION` of the line."""
        f = self.fraction
        return math.isfinite(f) and f >= COMPARABLE_FRACTION

    def text(self) -> str:
        """One or two sentences for the report and the advice."""
        if self.separated:
            return (f'Once-per-revolution line: the output encoder\'s part is separated '
                    f'({self.how}); what is left of it is at most {_arcsec(self.possible_rad)}.')
        line = ('' if not math.isfinite(self.line_rad) else
                f' of the measured {_arcsec(self.line_rad)} line'
                f' ({100 * self.fraction:.0f} %)')
        flag = (' The line, e_ot, the identified Q terms and the re-assembly advice may be '
                'the encoder\'s, not the reducer\'s: measure with two or more read heads, by '
                'reversal (rv-te selfcal), or apply a calibration of the scale.'
                if self.comparable else '')
        return (f'Once-per-revolution line: with one read head and no calibration, the output '
                f'encoder could produce {_arcsec(self.possible_rad)}{line} ({self.source}).'
                f'{flag}')

    def to_plain(self) -> OncePerRevNoteJson:
        """JSON-friendly (arcsec for people, rad kept)."""
        return {'possible_arcsec': float(rad_to_arcsec(self.possible_rad)),
                'line_arcsec': (float(rad_to_arcsec(self.line_rad))
                                if math.isfinite(self.line_rad) else None),
                'fraction': self.fraction if math.isfinite(self.fraction) else None,
                'comparable': self.comparable, 'separated': self.separated,
                'how': self.how, 'source': self.source, 'text': self.text(),
                'possible_rad': self.possible_rad}


def once_per_rev_note(*, line_rad: float = math.nan,
                      eccentricity_m: float = 0.0, diameter_m: float = 0.0,
                      error_model: EncoderErrorModel | None = None,
                      layout: HeadLayout | None = None,
                      calibration: EncoderCalibration | None = None) -> OncePerRevNote:
    """How much of the once-per-revolution line the output encoder could produce.

    Args:
        line_rad: The measured order-1 amplitude [rad] (NaN: not known).
        eccentricity_m: The output scale's stated mounting eccentricity (run-out / 2) [m].
        diameter_m: Its graduation diameter [m] (0: not stated).
        error_model: The encoder's data-sheet model (its order-1 graduation and
            eccentricity amplitudes are used when the bench states no run-out).
        layout: The output scale's heads (None or one head: no averaging).
        calibration: A calibration applied to the output readings.

    Returns:
        The note (see :class:`OncePerRevNote`).
    """
    sources = []
    ecc = 0.0
    if eccentricity_m > 0 and diameter_m > 0:
        ecc = 2.0 * eccentricity_m / diameter_m
        sources.append(f'scale eccentricity {eccentricity_m * 1e6:.3g} um on a '
                       f'{diameter_m * 1e3:.4g} mm scale: 412 e/D = {_arcsec(ecc)}')
    grad1 = 0.0
    if error_model is not None:
        grad1 = sum(a for k, a in error_model.graduation if k == 1)
        if ecc == 0.0 and error_model.eccentricity_rad > 0:
            ecc = math.hypot(error_model.eccentricity_rad, error_model.eccentricity_u_rad)
            sources.append(f'stated eccentricity {_arcsec(ecc)}')
        if grad1 > 0:
            sources.append(f'order-1 graduation error of the {error_model.model} data sheet '
                           f'{_arcsec(grad1)}')
    possible = ecc + grad1
    source = '; '.join(sources) or 'no scale run-out or data sheet stated: assumed 0'
    if calibration is not None and 1 in calibration.orders:
        u1 = next(h.u_rad for h in calibration.harmonics if h.order == 1)
        return OncePerRevNote(2.0 * u1, line_rad, True,
                              f'calibration applied: {calibration.describe()}',
                              f'2 u of the calibrated order 1 ({_arcsec(u1)})')
    if layout is not None and layout.n_heads > 1:
        gain = float(abs(layout.transfer([1])[0]))
        return OncePerRevNote(gain * possible, line_rad, gain < 1e-3, layout.describe(), source)
    return OncePerRevNote(possible, line_rad, False, 'one read head, no calibration', source)


def note_for_bench(info: BenchInfoData, heads_record: dict[str, Any] | None,
                   line_rad: float) -> OncePerRevNote:
    """The note for a bench's record and what its TE node did with the heads (the YAML of
    ``te/encoder_heads``: ``{'output': {'mode', 'layout', 'calibration'}, ...}``; None: one
    head, nothing applied)."""
    from rv_te_bench.core.bench_uncertainty import default_encoder_errors
    from rv_te_bench.core.encoder_calibration import calibration_from_plain
    from rv_te_bench.core.heads import HeadLayout

    out = (heads_record or {}).get('output') or {}
    layout = cal = None
    if out.get('mode') == 'average' and (lay := out.get('layout')):
        layout = HeadLayout.of(lay['angles_rad'])
    if out.get('calibration'):
        cal = calibration_from_plain(out['calibration'], 'te/encoder_heads')
    return once_per_rev_note(
        line_rad=line_rad, eccentricity_m=info.encoder_out_scale_eccentricity_m,
        diameter_m=info.encoder_out_scale_diameter_m,
        error_model=(default_encoder_errors(info.encoder_out_model,
                                            info.encoder_out_resolution_rad)
                     if info.encoder_out_model else None),
        layout=layout, calibration=cal)


def line_amplitude_rad(theta_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike) -> float:
    """Amplitude of the TE's order-1 line over whole output revolutions [rad] (NaN with
    less than one)."""
    import numpy as np

    from rv_te_bench.core.harmonic_fold import HarmonicFold
    from rv_te_bench.errors import TeInputError

    th = np.asarray(theta_out_rad, dtype=np.float64)
    te = np.asarray(te_rad, dtype=np.float64)
    bins = 64 if th.size < 20_000 else 1024
    fold = HarmonicFold(1, n_bins=bins)
    fold.add(th, te[None, :])
    try:
        return float(abs(fold.harmonics([1]).c[0, 0]))
    except TeInputError:
        return math.nan
