"""What the eccentricity identification of a 2K-V unit finds (:mod:`.identify`): the
:class:`Identification` record with its fit quality (:class:`FitQuality`), the thresholds
that judge them, what one TE record can and cannot tell (:data:`OBSERVABILITY`), and the
error that withholds advice on a poor fit.

The result types only, in a module of their own: the identification
(:mod:`.identify`) builds them, its uncertainty budgets
(:mod:`.identify_uncertainty`) and the Monte Carlo check read them, without importing
each other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NotRequired, SupportsFloat, TypedDict

from rv_te_bench.core.phases import PHASE_NAMES, EccentricGeometry
from rv_te_bench.core.units import json_deg, rad_to_arcmin, rad_to_arcsec
from rv_te_bench.errors import CompensationError

__all__ = ['LABEL_MISFIT_FLOOR', 'LABEL_RATIO_RESOLVED', 'MIN_EXPLAINED_FRACTION', 'OBSERVABILITY',
           'SPLIT_WELL_POSED_DEG_PER_PCT', 'FitQuality', 'FitQualityJson', 'Identification',
           'IdentificationJson', 'IdentificationU95Json', 'Observability', 'PoorFitError',
           'json_rounded']

#: label_ratio above which pair 1 and pair 2 count as told apart ...
LABEL_RATIO_RESOLVED = 2.0
#: ... provided the other labelling misfits the magnitudes by at least this share of the
#: largest magnitude (inspection measures magnitudes to about that).
LABEL_MISFIT_FLOOR = 0.01
#: Re-assembly advice needs the model to explain at least this share of the TE variance
#: (residual rms <= 10 % of the TE standard deviation).
MIN_EXPLAINED_FRACTION = 0.99
#: A split counts as well posed when a 1 % vector error turns no part phase by more.
SPLIT_WELL_POSED_DEG_PER_PCT = 5.0


class Observability(TypedDict):
    """What one TE record identifies and what needs the measured part magnitudes."""

    identified_from_te: list[str]
    needs_part_magnitudes: list[str]


class FitQualityJson(TypedDict):
    """The JSON of :class:`FitQuality` (None: not finite)."""

    residual_rms_arcsec: float | None
    te_std_arcsec: float | None
    noise_rms_arcsec: float | None
    explained_fraction: float | None
    min_explained_fraction: float
    acceptable: bool
    residual_rms_rad: float | None
    te_std_rad: float | None
    noise_rms_rad: float | None


class IdentificationJson(TypedDict):
    """The JSON of :class:`Identification` (None: not finite, or not resolved), with its U
    when the bench's uncertainty is known (:func:`.identify.identification_u95_json`)."""

    e_um: dict[str, float | None]
    e_m: dict[str, float]
    phases_deg: dict[str, float | None]
    phases_rad: dict[str, float]
    sigma_um: dict[str, float | None]
    sigma_deg: dict[str, float | None]
    residual_rms_arcsec: float | None
    offset_arcmin: float | None
    fit: FitQualityJson | None
    contact_fraction: list[float | None]
    output_revolutions: float | None
    n_samples: int
    assumed_e_um: dict[str, float | None]
    split_residual_um: float | None
    split_deg_per_pct_vector_error: float | None
    split_deg_per_um_magnitude_error: float | None
    split_well_posed: bool | None
    labels_swapped: bool
    label_ratio: float | None
    label_misfit_um: float | None
    labels_resolved: bool | None
    observability: Observability
    notes: list[str]
    u95_m: NotRequired[dict[str, float | None]]
    u95_rad: NotRequired[dict[str, float | None]]
    u95_um: NotRequired[dict[str, float | None]]
    u95_deg: NotRequired[dict[str, float | None]]
    uncertainty: NotRequired[dict[str, dict[str, Any]]]


class IdentificationU95Json(TypedDict):
    """The U keys :func:`.identify.identification_u95_json` adds to
    :class:`IdentificationJson` (None: not finite; each budget's own JSON)."""

    u95_m: dict[str, float | None]
    u95_rad: dict[str, float | None]
    u95_um: dict[str, float | None]
    u95_deg: dict[str, float | None]
    uncertainty: dict[str, dict[str, Any]]


#: What one TE record identifies and what needs the measured part magnitudes (for output).
OBSERVABILITY: Observability = {
    'identified_from_te': [
        'Q1 = e_p1 e^(i theta_p1) + e_g e^(i theta_g): pair-1 sum of planet and revolution '
        'eccentricity',
        'Q2 = e_p2 e^(i theta_p2) - e_g e^(i theta_g): pair-2 sum',
        'E = e_ot e^(i theta_ot): output-wheel eccentricity',
        'up to the exact label swap (Q1, Q2, E) -> (Q2, Q1, -E)',
    ],
    'needs_part_magnitudes': [
        'theta_p1, theta_p2, theta_g (the split of Q1, Q2 into planet and revolution '
        'eccentricity) and so the re-assembly advice: they need e_p1, e_p2, e_g measured on '
        'the parts (runout inspection); one TE record cannot separate them',
        'which pair is pair 1 (resolved only when the planet magnitudes differ)',
    ],
}


class PoorFitError(CompensationError):
    """The eccentricity model explains too little of the TE: advice withheld.

    Attributes:
        identification: The identification (with its fit quality) that was judged.
    """

    def __init__(self, message: str, identification: Identification) -> None:
        """Keep the identification for callers that report it anyway."""
        super().__init__(message)
        self.identification = identification

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled with its identification (the compensation node's search runs in a worker
        process and hands its errors back)."""
        return (type(self), (str(self), self.identification))


@dataclass(frozen=True)
class FitQuality:
    """How well the identified model explains the record (sample level).

    Attributes:
        residual_rms_rad: RMS of measured minus fitted TE over all samples [rad].
        te_std_rad: Standard deviation of the measured TE [rad].
        explained_fraction: 1 - residual sum of squares / total sum of squares (0..1).
        noise_rms_rad: Sample-to-sample TE noise estimated without the model [rad] (NaN when
            the record is too coarse to tell noise from signal, e.g. decimated).
        min_explained_fraction: Threshold below which advice is withheld.
    """

    residual_rms_rad: float
    te_std_rad: float
    explained_fraction: float
    noise_rms_rad: float = math.nan
    min_explained_fraction: float = MIN_EXPLAINED_FRACTION

    @property
    def acceptable(self) -> bool:
        """The model explains enough of the TE for re-assembly advice."""
        return self.explained_fraction >= self.min_explained_fraction

    def describe(self) -> str:
        """One line for people."""
        noise = ('' if not math.isfinite(self.noise_rms_rad) else
                 f', encoder noise {float(rad_to_arcsec(self.noise_rms_rad)):.3f}"')
        return (f'fit residual {float(rad_to_arcsec(self.residual_rms_rad)):.3f}" rms{noise}, '
                f'TE std {float(rad_to_arcsec(self.te_std_rad)):.2f}": the model explains '
                f'{100 * self.explained_fraction:.3f} % of the TE variance')

    def to_json_dict(self) -> FitQualityJson:
        """JSON-friendly dict (arcsec for people, rad kept)."""
        return {
            'residual_rms_arcsec': json_rounded(rad_to_arcsec(self.residual_rms_rad), 4),
            'te_std_arcsec': json_rounded(rad_to_arcsec(self.te_std_rad), 4),
            'noise_rms_arcsec': json_rounded(rad_to_arcsec(self.noise_rms_rad), 4),
            'explained_fraction': json_rounded(self.explained_fraction, 6),
            'min_explained_fraction': self.min_explained_fraction,
            'acceptable': self.acceptable,
            'residual_rms_rad': json_rounded(self.residual_rms_rad),
            'te_std_rad': json_rounded(self.te_std_rad),
            'noise_rms_rad': json_rounded(self.noise_rms_rad),
        }


@dataclass(frozen=True)
class Identification:
    """Eccentricities of one 2K-V unit identified from a TE record.

    Attributes:
        e_m: Identified magnitudes [m]: ``e_ot`` and the pair sums ``pair1`` (|Q1|) and
            ``pair2`` (|Q2|).
        phases_rad: Identified phases [rad]: ``theta_ot``, ``pair1`` (arg Q1), ``pair2``
            (arg Q2), and ``theta_p1``, ``theta_p2``, ``theta_g`` when the part magnitudes
            resolve the split (see ``assumed_e_m``).
        residual_rms_rad: RMS of measured minus fitted TE over all samples [rad].
        offset_rad: Fitted TE offset c (encoder zeros) [rad].
        contact_fraction: Share of samples where pair 1 / pair 2 carries the TE.
        output_revolutions: Output revolutions the record spans.
        n_samples: Samples used.
        assumed_e_m: Part magnitudes (e_p1, e_p2, e_g) used to split Q1, Q2 [m] (empty:
            no split).
        split_residual_m: RMS misfit of that split [m] (large: magnitudes inconsistent).
        labels_swapped: The fit's pair labels were swapped to match the part magnitudes.
        label_ratio: Split misfit of the other labelling over that of the chosen one
            (>= 1; below :data:`LABEL_RATIO_RESOLVED` the labels are ambiguous: planets of
            nearly equal eccentricity; the advice is then nearly the same either way).
        label_misfit_m: Split misfit of the other labelling [m] (below
            :data:`LABEL_MISFIT_FLOOR` of the largest magnitude the labels are ambiguous
            too: an error of the measured magnitudes could swap them).
        geometry: Geometry (alpha, r_p, crank order) used for the fit.
        fit: Fit quality (residual, explained fraction, noise estimate).
        sigma_m: 1-sigma vector error of ``pair1``, ``pair2``, ``e_ot`` from the noise [m].
        sigma_rad: 1-sigma error of the phases from the noise [rad] (split phases too).
        split_deg_per_pct: Largest turn of a split phase per 1 % vector error [deg].
        split_deg_per_um: Largest turn of a split phase per 1 um magnitude error [deg].
    """

    e_m: dict[str, float]
    phases_rad: dict[str, float]
    residual_rms_rad: float
    offset_rad: float
    contact_fraction: tuple[float, float]
    output_revolutions: float
    n_samples: int
    assumed_e_m: dict[str, float] = field(default_factory=dict)
    split_residual_m: float = math.nan
    labels_swapped: bool = False
    label_ratio: float = math.nan
    label_misfit_m: float = math.nan
    geometry: EccentricGeometry | None = field(default=None, repr=False)
    fit: FitQuality | None = None
    sigma_m: dict[str, float] = field(default_factory=dict)
    sigma_rad: dict[str, float] = field(default_factory=dict)
    split_deg_per_pct: float = math.nan
    split_deg_per_um: float = math.nan

    @property
    def pair_phasors_m(self) -> tuple[complex, complex, complex]:
        """(Q1, Q2, E) as complex eccentricity vectors [m]."""
        def z(mag: str, ph: str) -> complex:
            return self.e_m[mag] * complex(math.cos(self.phases_rad[ph]),
                                           math.sin(self.phases_rad[ph]))
        return z('pair1', 'pair1'), z('pair2', 'pair2'), z('e_ot', 'theta_ot')

    @property
    def labels_resolved(self) -> bool:
        """Whether the part magnitudes told pair 1 from pair 2 (see ``label_misfit_m``)."""
        big = max(self.assumed_e_m.values(), default=0.0)
        return (self.label_ratio >= LABEL_RATIO_RESOLVED
                and not self.label_misfit_m < LABEL_MISFIT_FLOOR * big)

    @property
    def split_resolved(self) -> bool:
        """Whether theta_p1, theta_p2 and theta_g are available."""
        return all(n in self.phases_rad for n in PHASE_NAMES)

    @property
    def split_well_posed(self) -> bool:
        """Split available, labels resolved and a 1 % vector error turns it <= 5 deg."""
        return (self.split_resolved and self.labels_resolved
                and self.split_deg_per_pct <= SPLIT_WELL_POSED_DEG_PER_PCT)

    def notes(self) -> list[str]:
        """Warnings for people about what this result can and cannot be trusted for."""
        out = []
        if self.fit is not None and not self.fit.acceptable:
            out.append(f'poor fit: {self.fit.describe()} (advice needs '
                       f'{100 * self.fit.min_explained_fraction:g} %)')
        if self.output_revolutions < 0.99:
            out.append('less than one output revolution: e_ot is poorly determined')
        if min(self.contact_fraction) < 0.02:
            out.append(f'one pair carried only {100 * min(self.contact_fraction):.1f} % of the '
                       'record: its sum is poorly determined')
        if self.split_resolved:
            if not self.labels_resolved:
                out.append('planets of nearly equal eccentricity: pair labels ambiguous')
            if self.split_deg_per_pct > SPLIT_WELL_POSED_DEG_PER_PCT:
                out.append(f'ill-posed split: a 1 % error of Q1/Q2 turns the part phases by up '
                           f'to {self.split_deg_per_pct:.1f} deg')
            if self.split_deg_per_um > SPLIT_WELL_POSED_DEG_PER_PCT:
                out.append(f'a 1 um error of a part magnitude turns the part phases by up to '
                           f'{self.split_deg_per_um:.1f} deg: the split needs well measured '
                           'magnitudes')
            big = max(self.assumed_e_m.values(), default=0.0)
            if big > 0 and self.split_residual_m > 0.05 * big:
                out.append(f'the part magnitudes do not fit the identified sums (misfit '
                           f'{self.split_residual_m * 1e6:.2f} um): measure the parts')
        return out

    def to_json_dict(self) -> IdentificationJson:
        """JSON-friendly dict with unit suffixes (um, deg, arcsec for people)."""
        return {
            'e_um': {k: json_rounded(v * 1e6, 6) for k, v in self.e_m.items()},
            'e_m': dict(self.e_m),
            'phases_deg': {k: json_deg(v) for k, v in self.phases_rad.items()},
            'phases_rad': dict(self.phases_rad),
            'sigma_um': {k: json_rounded(v * 1e6, 6) for k, v in self.sigma_m.items()},
            'sigma_deg': {k: json_deg(v) for k, v in self.sigma_rad.items()},
            'residual_rms_arcsec': json_rounded(rad_to_arcsec(self.residual_rms_rad), 4),
            'offset_arcmin': json_rounded(rad_to_arcmin(self.offset_rad), 6),
            'fit': None if self.fit is None else self.fit.to_json_dict(),
            'contact_fraction': [json_rounded(c, 4) for c in self.contact_fraction],
            'output_revolutions': json_rounded(self.output_revolutions, 6),
            'n_samples': self.n_samples,
            'assumed_e_um': {k: json_rounded(v * 1e6, 6) for k, v in self.assumed_e_m.items()},
            'split_residual_um': json_rounded(self.split_residual_m * 1e6, 6),
            'split_deg_per_pct_vector_error': json_rounded(self.split_deg_per_pct, 4),
            'split_deg_per_um_magnitude_error': json_rounded(self.split_deg_per_um, 4),
            'split_well_posed': self.split_well_posed if self.split_resolved else None,
            'labels_swapped': self.labels_swapped,
            'label_ratio': json_rounded(self.label_ratio, 4),
            'label_misfit_um': json_rounded(self.label_misfit_m * 1e6, 6),
            'labels_resolved': self.labels_resolved if self.split_resolved else None,
            'observability': OBSERVABILITY,
            'notes': self.notes(),
        }


def json_rounded(x: SupportsFloat, digits: int | None = None) -> float | None:
    """A finite float (rounded to ``digits`` decimals for the JSON edge) or None."""
    v = float(x)
    if not math.isfinite(v):
        return None
    return round(v, digits) if digits is not None else v
