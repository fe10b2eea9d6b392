"""What a step's segments are to the code on either side of them: the data of one segment
(:class:`SegmentData`, what the result functions read, whether the live runner, a
recorded session or an imported file filled it) and what a step kind's program builder may
add segments to (:class:`ProgramSink`, the part of
:class:`~rv_te_bench.acceptance.runner.StepRunner` the builders use).

A module of its own so that the step kinds (``_results``, ``_loss_results``,
``loss_steps``) and the runner import it, not each other.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

__all__ = ['ProgramSink', 'SegmentData']


@dataclass(eq=False)
class SegmentData:
    """The data of one segment of a step (SI units).

    Attributes:
        role: 'te' | 'sweep' | 'preload' | 'cycle' | 'reposition'.
        label: direction, speed_rpm, load_nm, settle_s (drives); position (hysteresis).
        theta_in_rad, theta_out_rad, torque_out_nm: The samples (torque empty: no channel).
        torque_in_nm, temp_case_degc: Input torque [N m] and case temperature [degC]
            (empty: no channel).
        time_s: Sample times [s] (None: consecutive at the bench's rate).
        note: Why the segment cannot be analysed ('' when it can).
        found: What the data said about the segment (found speed, load, times), for the
            report of a recorded test.
    """

    role: str
    label: dict[str, Any]
    theta_in_rad: np.ndarray = field(default_factory=lambda: np.zeros(0))
    theta_out_rad: np.ndarray = field(default_factory=lambda: np.zeros(0))
    torque_out_nm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    torque_in_nm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    temp_case_degc: np.ndarray = field(default_factory=lambda: np.zeros(0))
    time_s: np.ndarray | None = None
    note: str = ''
    found: dict[str, Any] = field(default_factory=dict)


class ProgramSink(Protocol):
    """Where a step kind's program builder puts the bench segments of its step."""

    #: Name of the value the live line shows while the step runs ('te_pp_rad', ...).
    live_name: str

    def add_segment(self, plain: dict[str, Any], role: str, label: dict[str, Any]) -> None:
        """Append a bench segment (``sim.program`` plain form) with its role and label."""

    def add_drive(self, speed_rpm: float, load_nm: float, sign: int, revs: int,
                  settle_s: float, role: str, label: dict[str, Any]) -> None:
        """A drive segment of ``settle_s`` plus ``revs`` whole output revolutions (+2 %)."""
