"""The hysteresis curve as the page draws it: a loop of branches, not a cloud of points.

While a hysteresis step runs, the samples are reduced to one (applied torque, torsion angle)
point per :data:`POINT_S` of session time (the means over it: applied torque = -reaction
torque, angle = TE, since the input is held). Each point carries the branch it lies on:
+1 while the applied torque rises (loading towards +T_R, and back from -T_R), -1 while it
falls. The direction turns only once the torque has come back from its extreme by more than
:data:`TURN_FRACTION` of the largest |torque| so far, so the noise of a dwell does not split
a branch. The page bins each branch's points into its pixel columns of torque (min, max and
mean angle per column) and draws one line per branch with its envelope, which closes into
the measured loop.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ['MAX_POINTS', 'POINT_S', 'TURN_FRACTION', 'HysteresisLoop', 'branch_directions']

#: Curve points kept (one per POINT_S of session time: 500 s of a step).
MAX_POINTS = 50_000
#: Session time behind one curve point [s].
POINT_S = 0.01
#: The torque must come back from its extreme by this part of the largest |torque| seen
#: before the branch turns.
TURN_FRACTION = 0.02


def branch_directions(torque_nm: np.ndarray, state: dict[str, float]) -> np.ndarray:
    """+1 (rising) / -1 (falling) / 0 (not yet known) per point, continuing ``state``.

    ``state`` holds the direction so far, the extreme of the current branch and the largest
    |torque| seen; it is updated. The loop runs over the curve's points (one per 10 ms, a
    few per update), not over samples.
    """
    out = np.zeros(len(torque_nm), dtype=np.int8)
    direction, extreme, peak = state['direction'], state['extreme'], state['peak']
    for i, t in enumerate(torque_nm.tolist()):
        peak = max(peak, abs(t))
        turn = TURN_FRACTION * peak
        if direction == 0:
            if math.isnan(extreme):
                extreme = t
            elif abs(t - extreme) > turn:
                direction = 1 if t > extreme else -1
                extreme = t
        elif direction * (t - extreme) >= 0:
            extreme = t                       # further along the branch
        elif abs(t - extreme) > turn:
            direction, extreme = -direction, t
        out[i] = direction
    state.update(direction=direction, extreme=extreme, peak=peak)
    return out


class HysteresisLoop:
    """The points of the running hysteresis step (see the module docstring)."""

    def __init__(self) -> None:
        """No points yet."""
        self.epoch = 0
        self.clear()

    def clear(self) -> None:
        """A new step: no points, no direction (a new epoch: clients start over)."""
        self.epoch += 1
        self.points: list[tuple[float, float, int]] = []   # (torque [N m], angle [rad], ±1)
        self._next_s = -math.inf
        self._state: dict[str, float] = {'direction': 0, 'extreme': math.nan, 'peak': 0.0}

    def __len__(self) -> int:
        return len(self.points)

    def push(self, t_s: np.ndarray, angle_rad: np.ndarray, torque_out_nm: np.ndarray) -> None:
        """Samples of the step: one point per POINT_S of session time, with its branch."""
        slot = np.floor(t_s / POINT_S).astype(np.int64)
        if not len(slot):
            return
        cuts = np.flatnonzero(np.diff(slot)) + 1
        starts = np.concatenate(([0], cuts))
        counts = np.diff(np.concatenate((starts, [len(t_s)])))
        tq = np.add.reduceat(-torque_out_nm, starts) / counts   # applied torque = -reaction
        ang = np.add.reduceat(angle_rad, starts) / counts
        keep = (slot[starts] * POINT_S >= self._next_s) & np.isfinite(tq) & np.isfinite(ang)
        self._next_s = (slot[-1] + 1) * POINT_S
        tq, ang = tq[keep], ang[keep]
        room = max(MAX_POINTS - len(self.points), 0)
        tq, ang = tq[:room], ang[:room]
        way = branch_directions(tq, self._state)
        self.points.extend(zip(tq.tolist(), ang.tolist(), way.tolist(), strict=True))

    def since(self, cursor: tuple[int, int] | None) -> tuple[dict[str, Any], tuple[int, int]]:
        """The points a client with ``cursor`` (epoch, points it has) lacks, as
        [torque, angle, branch] rows from index ``from`` (0: a new step, start over), and
        its new cursor."""
        seen = cursor[1] if cursor is not None and cursor[0] == self.epoch else 0
        return ({'from': seen, 'points': [list(p) for p in self.points[seen:]]},
                (self.epoch, len(self.points)))
