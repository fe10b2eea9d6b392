"""The simulated bench driven the way a ros2_control bench is: setpoints, block by block.

A ros2_control test bench has a drive motor on the input shaft and a load (brake) motor on
the output shaft, each behind a forward command controller: the drive takes a velocity,
the load an effort (torque) or a position. :class:`CommandedBench` takes the latest such
setpoints (:class:`BenchCommand`) and simulates the next block of samples with them
(:meth:`sim.program.ProgramSimulator.hold`), so a command held for many blocks is one
segment (the dynamic model is not restarted):

* drive velocity != 0: the input turns at that speed; the load effort is the torque the
  load motor applies to the output (the bench convention's load is its negative); a load
  in position mode applies nothing while the input turns (the load motor follows);
* drive velocity == 0: the input is held (locked); the load effort is held on the output
  (:class:`~sim.program.TorqueSegment`) or the output is moved to the load position
  (:class:`~sim.program.OutputPositionSegment`).

Every sign is the joint's: a positive effort twists the output positively, as the
joint's effort reads back (ros2_control: command and state interfaces of a joint share
their sense).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from sim._checks import real_number
from sim.errors import ModelInputError
from sim.program import DriveSegment, OutputPositionSegment, TorqueSegment
from sim.units import RAD_S_PER_RPM

if TYPE_CHECKING:
    from sim.bench import BenchBlock
    from sim.program import ProgramSimulator

__all__ = ['LOAD_MODES', 'BenchCommand', 'CommandedBench']

LOAD_MODES = ('effort', 'position')


@dataclass(frozen=True)
class BenchCommand:
    """The setpoints of the two forward command controllers (SI, joint senses).

    Attributes:
        drive_velocity_rad_s: Input (drive) joint velocity [rad/s].
        load_mode: ``'effort'`` or ``'position'``: the load joint's command interface.
        load_value: Load joint effort [N m] or position [rad].
    """

    drive_velocity_rad_s: float = 0.0
    load_mode: str = 'effort'
    load_value: float = 0.0

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field)."""
        object.__setattr__(self, 'drive_velocity_rad_s', real_number(
            'drive_velocity_rad_s', self.drive_velocity_rad_s, ''))
        object.__setattr__(self, 'load_value', real_number('load_value', self.load_value, ''))
        if self.load_mode not in LOAD_MODES:
            msg = f'load_mode must be one of {LOAD_MODES}, got {self.load_mode!r}'
            raise ModelInputError(msg)


class CommandedBench:
    """Runs a :class:`~sim.program.ProgramSimulator` from setpoints (see the module docstring).

    Args:
        sim: The simulated bench.
        max_input_speed_rad_s: The drive's own speed limit (setpoints beyond are clipped,
            as a drive's velocity limit does) [rad/s].
    """

    def __init__(self, sim: ProgramSimulator, *,
                 max_input_speed_rad_s: float = 1e4 * RAD_S_PER_RPM) -> None:
        """Start with the input held and no load."""
        self.sim = sim
        self.command = BenchCommand()
        self.max_input_speed_rad_s = float(max_input_speed_rad_s)
        self._block_s = sim.block_size / sim.sample_rate_hz

    @property
    def gear_ratio(self) -> float:
        """The reducer's ratio."""
        return self.sim.gear_ratio

    def set(self, command: BenchCommand) -> None:
        """The latest setpoints (they apply from the next block)."""
        self.command = command

    def next_block(self) -> BenchBlock:
        """Simulate the next block with the latest setpoints."""
        c = self.command
        w = max(-self.max_input_speed_rad_s, min(self.max_input_speed_rad_s,
                                                 c.drive_velocity_rad_s))
        seg: DriveSegment | TorqueSegment | OutputPositionSegment
        if w != 0.0 and math.isfinite(w):
            load = -c.load_value if c.load_mode == 'effort' else 0.0
            seg = DriveSegment(speed_rpm=w / RAD_S_PER_RPM, duration_s=self._block_s,
                               load_nm=load)
        elif c.load_mode == 'position':
            seg = OutputPositionSegment(position_rad=c.load_value, duration_s=self._block_s)
        else:
            seg = TorqueSegment(torque_nm=c.load_value, duration_s=self._block_s)
        return self.sim.hold(seg)
