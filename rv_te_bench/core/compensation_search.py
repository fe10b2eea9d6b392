"""The compensation node's searches as plain functions of their inputs (issue 41 item 4).

Each takes what it needs (the preset, the measured data, the search settings) and returns
the :class:`~rv_te_bench.core.advice.Advice`; nothing else is read or kept. That is what
lets the node run them in a worker process of its own
(:mod:`rv_te_bench.nodes.search_process`): the arguments and the advice cross the process
boundary by pickling, and the same call in the node's own process gives the same advice.

* :func:`preset_phases_advice`: the Wang 2020 Eq. 21 assembly-phase optimum of a 2K-V
  preset (a prediction from its nominal eccentricities).
* :func:`identified_phases_advice`: this unit's eccentricities identified from its measured
  TE (Wang 2020 Eqs 1-8) and the re-assembly phases for it.
* :func:`tooth_advice`: the Hu 2020 Eqs 24-27 tooth-profile compensation of an RV preset
  for a measured TE statistic.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy.typing as npt

    from rv_te_bench.core.advice import Advice
    from rv_te_bench.core.phases import ProgressCallback
    from sim.presets import Preset

__all__ = ['identified_phases_advice', 'preset_phases_advice', 'tooth_advice']


def preset_phases_advice(preset: Preset, *, step_deg: float, refine: bool,
                         progress: ProgressCallback | None = None) -> Advice:
    """The assembly phases that minimise the preset's max |NLTE| (Wang 2020 Eq. 21).

    Args:
        preset: A 2K-V preset (``sim.wang2020`` parameters).
        step_deg: Phase grid step [deg].
        refine: Refine the grid optimum below the grid step.
        progress: Called with the fraction done (it may raise to abort the search).
    """
    from rv_te_bench.core.phases import optimise_phases
    from sim.wang2020 import Wang2kvParams

    params = Wang2kvParams.from_preset(preset)
    result = optimise_phases(params, step_deg=step_deg, refine=refine, progress=progress)
    return result.to_advice(preset.name)


def identified_phases_advice(preset: Preset, phase_out_rad: npt.ArrayLike,
                             te_rad: npt.ArrayLike, *, step_deg: float, refine: bool,
                             progress: ProgressCallback | None = None) -> Advice:
    """This unit's eccentricities from its TE record and the re-assembly phases for them.

    Args:
        preset: The unit's 2K-V preset (geometry and part magnitudes).
        phase_out_rad: Output angle of each TE sample [rad].
        te_rad: The measured TE [rad], same length.
        step_deg, refine: As :func:`preset_phases_advice` (the same search, so that the
            two recommendations differ only in the unit they are for).
        progress: As :func:`preset_phases_advice`.

    Raises:
        rv_te_bench.core.identification.CompensationError: The record cannot be identified,
            or the model explains too little of it (``PoorFitError``).
    """
    from rv_te_bench.core.identify import identified_advice
    from sim.wang2020 import Wang2kvParams

    params = Wang2kvParams.from_preset(preset)
    return identified_advice(phase_out_rad, te_rad, params, preset_name=preset.name,
                             step_deg=step_deg, refine=refine, progress=progress)


def tooth_advice(preset: Preset, measured_rad: float, *, te_metric: str) -> Advice:
    """The tooth-profile compensation of an RV preset for the measured TE statistic
    ``measured_rad`` [rad] (``te_metric``: ``'pp'`` or ``'amplitude'``)."""
    from rv_te_bench.core.tooth_compensation import tooth_profile_advice

    return tooth_profile_advice(preset, measured_rad, te_metric=te_metric)
