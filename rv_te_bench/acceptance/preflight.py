"""Checks of a plan against the bench before anything moves (issue 38, bad input).

* A step that needs a channel the bench does not have (an efficiency map, a no-load or
  starting-torque step without input torque transducer; a temperature-rise or life step
  without a case temperature channel; a back-driving step without an output torque
  transducer) is refused with one line naming the step and the channel.
* A step asking for an input speed above the unit's rating (the preset's
  ``rating.max_output_speed_rpm`` times the ratio) is refused likewise.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from rv_te_bench.errors import AcceptanceError

if TYPE_CHECKING:
    from rv_te_bench.acceptance.plan import Step, TestPlan

__all__ = ['CHANNEL_NAMES', 'NEEDS', 'check_plan', 'step_speeds_rpm']

#: Channel -> what it is called in messages.
CHANNEL_NAMES = {'torque_in': 'input torque transducer', 'torque_out': 'output torque '
                 'transducer', 'temperature': 'case temperature channel'}
#: Step kind -> the channels it needs besides the encoders.
NEEDS: dict[str, tuple[str, ...]] = {
    'efficiency': ('torque_in', 'torque_out'), 'no_load': ('torque_in',),
    'starting_torque': ('torque_in',), 'back_driving': ('torque_out',),
    'temperature_rise': ('temperature',), 'life': ('torque_in', 'temperature'),
    'hysteresis': ('torque_out',)}


def step_speeds_rpm(step: Step) -> list[float]:
    """The input speeds a step commands [rpm] (magnitudes)."""
    out = []
    for key in ('speed_rpm', 'te_speed_rpm', 'no_load_speed_rpm', 'reposition_speed_rpm'):
        v = getattr(step, key, None)
        if isinstance(v, float):
            out.append(abs(v))
    out += [abs(v) for v in getattr(step, 'speeds_rpm', ())]
    return out


def check_plan(plan: TestPlan, *, channels: set[str], max_input_speed_rpm: float = math.inf,
               bench: str = 'the bench') -> None:
    """Raise :class:`AcceptanceError` (one line) at the first step the bench cannot run.

    Args:
        plan: The validated plan.
        channels: The bench's channels (keys of :data:`CHANNEL_NAMES`).
        max_input_speed_rpm: The unit's rated input speed (inf: not stated).
        bench: How the bench is named in the message.
    """
    for j, step in enumerate(plan.steps):
        where = f'step {j} ({step.name!r}, {step.kind})'
        for ch in NEEDS.get(step.kind, ()):
            if ch not in channels:
                msg = (f'{where} needs an {CHANNEL_NAMES[ch]}, which {bench} does not have; '
                       'nothing was run') if ch != 'temperature' else (
                    f'{where} needs a {CHANNEL_NAMES[ch]}, which {bench} does not have; '
                    'nothing was run')
                raise AcceptanceError(msg)
        fast = [s for s in step_speeds_rpm(step) if s > max_input_speed_rpm]
        if fast:
            msg = (f'{where} asks for {max(fast):g} rpm input, above the unit\'s rating of '
                   f'{max_input_speed_rpm:g} rpm; nothing was run')
            raise AcceptanceError(msg)
