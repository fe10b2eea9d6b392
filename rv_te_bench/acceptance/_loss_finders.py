"""Where the whole-reducer steps (issue 38) lie in a measured record (``rv-te test PLAN
--from ...``): the parts :mod:`rv_te_bench.acceptance._loss_results` judges, found in the
data as :mod:`rv_te_bench.acceptance.recorded` finds TE and sweep parts.

* efficiency point, no-load speed: a run in the step's direction at the speed (and load;
  0 for no-load) lasting ``settle_s + measure_s``, cut to that length from its start (what
  the live bench records for the point);
* temperature rise: such a run lasting at least ``2 window_s``, cut to ``max_duration_s``;
* life checkpoint ``k``: in order, the run at the step's speed and load (``run_s``), the
  TE run at ``te_speed_rpm`` without load (settle + one output revolution), the no-load
  run at ``no_load_speed_rpm``;
* starting / back-driving ramp: a stretch where the input (output) torque rises from zero
  with one sign to its largest value right before it is released, the shaft standing still
  over its first half (a drive under load turns; a hysteresis half-cycle peaks in its
  middle); its direction is the sign of the torque that drives the shaft (input torque
  positive, output torque negative in the bench convention: ccw).

A part the data does not hold gets one line saying what is missing; the step is then not
judged. The record's input torque and case temperature come from ``bench/channels``, a
DAQ file's columns or the bench's own topics (:mod:`rv_te_bench.io.measured_record`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from rv_te_bench.acceptance._segments import SegmentData
from rv_te_bench.core.hysteresis_measured import torque_noise_nm

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.acceptance.loss_steps import (
        BackDrivingStep,
        EfficiencyStep,
        LifeStep,
        NoLoadStep,
        StartingTorqueStep,
        TemperatureRiseStep,
    )
    from rv_te_bench.core.segments import MeasuredRecord
    from sim.bench_info import BenchInfoData

__all__ = ['LOSS_FINDERS']

#: Samples below the detection level tolerated inside one ramp.
_RAMP_GAP = 5
#: A ramp's largest torque lies in its last part (1 - this): it is released at its top.
_PEAK_AT = 0.9


class PartFinder(Protocol):
    """What the finders here use of :class:`rv_te_bench.acceptance.recorded._Finder`."""

    record: MeasuredRecord
    info: BenchInfoData
    cursor_s: float
    used_ramps: set[int]

    def run_for(self, direction: str, speed_rpm: float, load_nm: float, need_s: float,
                role: str, label: dict[str, Any], what: str, *,
                cut_s: float | None = None) -> SegmentData:
        """The part of the record that is such a run (or one saying what is missing)."""

    def data(self, start: int, stop: int, role: str, label: dict[str, Any], note: str = '',
             found: dict[str, Any] | None = None) -> SegmentData:
        """The part ``start:stop`` of the record."""

    def ramp_episodes(self, channel: str, find: Callable[[], list[tuple[int, int, int]]],
                      ) -> list[tuple[int, int, int]]:
        """The torque ramps of ``channel`` in the record (found once by ``find``)."""


def _lab(direction: str, speed_rpm: float, load_nm: float, settle_s: float,
         **extra: Any) -> dict[str, Any]:
    return {'direction': direction, 'speed_rpm': speed_rpm, 'load_nm': load_nm,
            'settle_s': settle_s, **extra}


def _efficiency(finder: PartFinder, step: EfficiencyStep) -> list[SegmentData]:
    need = step.settle_s + step.measure_s
    return [finder.run_for(step.direction, s, ld, need, 'efficiency',
                           _lab(step.direction, s, ld, step.settle_s),
                           f'settle {step.settle_s:g} s + measure {step.measure_s:g} s',
                           cut_s=need)
            for s in step.speeds_rpm for ld in step.loads_nm]


def _no_load(finder: PartFinder, step: NoLoadStep) -> list[SegmentData]:
    need = step.settle_s + step.measure_s
    return [finder.run_for(step.direction, s, 0.0, need, 'no_load',
                           _lab(step.direction, s, 0.0, step.settle_s),
                           f'settle {step.settle_s:g} s + measure {step.measure_s:g} s',
                           cut_s=need)
            for s in step.speeds_rpm]


def _temperature(finder: PartFinder, step: TemperatureRiseStep) -> list[SegmentData]:
    return [finder.run_for(step.direction, step.speed_rpm, step.load_nm, 2.0 * step.window_s,
                           'temperature', _lab(step.direction, step.speed_rpm, step.load_nm,
                                               0.0),
                           f'two rate windows of {step.window_s:g} s',
                           cut_s=step.max_duration_s)]


def _life(finder: PartFinder, step: LifeStep) -> list[SegmentData]:
    d = step.direction
    rev_s = finder.info.gear_ratio * 60.0 / step.te_speed_rpm
    te_s = step.settle_s + rev_s * 1.02 + 2.0 / finder.info.sample_rate_hz
    nl_s = step.settle_s + step.measure_s
    out = []
    for k in range(step.checkpoints):
        out += [finder.run_for(d, step.speed_rpm, step.load_nm, step.run_s, 'life_run',
                               _lab(d, step.speed_rpm, step.load_nm, 0.0, checkpoint=k),
                               f'checkpoint {k}: run {step.run_s:g} s', cut_s=step.run_s),
                finder.run_for(d, step.te_speed_rpm, 0.0, te_s - 2.0 / finder.info.sample_rate_hz,
                               'life_te', _lab(d, step.te_speed_rpm, 0.0, step.settle_s,
                                               checkpoint=k),
                               f'checkpoint {k}: TE over one output revolution', cut_s=te_s),
                finder.run_for(d, step.no_load_speed_rpm, 0.0, nl_s, 'life_no_load',
                               _lab(d, step.no_load_speed_rpm, 0.0, step.settle_s,
                                    checkpoint=k),
                               f'checkpoint {k}: no-load torque', cut_s=nl_s)]
    return out


def _episodes(torque: np.ndarray, angle: np.ndarray, breaks: np.ndarray,
              threshold_rad: float) -> list[tuple[int, int, int]]:
    """(start, stop, sign) of each torque ramp in the record (see the module docstring);
    start backs up over the ramp's part below the detection level."""
    fin = np.isfinite(torque)
    if not np.any(fin):
        return []
    mag = np.abs(np.where(fin, torque, 0.0))
    level = max(8.0 * torque_noise_nm(torque[fin]), 1e-3 * float(np.quantile(mag[fin], 0.999)),
                1e-9)
    above = np.r_[False, mag > level, False]
    edges = np.flatnonzero(np.diff(above.astype(np.int8)))
    starts, stops = list(edges[0::2]), list(edges[1::2])
    merged: list[list[int]] = []
    for a, b in zip(starts, stops, strict=True):
        cut = any(merged and merged[-1][1] <= int(x) <= a for x in breaks)
        if merged and a - merged[-1][1] <= _RAMP_GAP and not cut:
            merged[-1][1] = int(b)
        else:
            merged.append([int(a), int(b)])
    out = []
    prev_end = 0
    for a, b in merged:
        seg = torque[a:b]
        sign = int(np.sign(np.nanmedian(seg)))
        if b - a < 5 or sign == 0 or np.any(np.sign(seg[np.isfinite(seg)]) == -sign):
            prev_end = b
            continue
        m = a + int(np.nanargmax(np.abs(seg)))
        half = a + (m - a) // 2
        if m < a + _PEAK_AT * (b - a) - 1 or abs(angle[half] - angle[a]) > threshold_rad:
            prev_end = b
            continue
        x = np.arange(a, m + 1, dtype=np.float64)
        rate = float(np.polyfit(x, np.abs(torque[a:m + 1]), 1)[0]) if m - a >= 2 else 0.0
        back = math.ceil(1.5 * level / rate) + 2 if rate > 0 else 0
        lo = max(prev_end, a - back, *[int(x) for x in breaks if int(x) <= a])
        out.append((lo, min(b + _RAMP_GAP, angle.size), sign))
        prev_end = b
    return out


def _ramps(channel: str,
           ) -> Callable[[PartFinder, StartingTorqueStep | BackDrivingStep], list[SegmentData]]:
    def find(finder: PartFinder, step: StartingTorqueStep | BackDrivingStep,
             ) -> list[SegmentData]:
        r = finder.record
        torque = r.torque_in_nm if channel == 'torque_in' else r.torque_out_nm
        angle = r.theta_in_rad if channel == 'torque_in' else r.theta_out_rad
        what = 'input' if channel == 'torque_in' else 'output'
        labels = [{'direction': d, 'shaft': what} for d in step.directions]
        if torque is None:
            note = (f'no {what} torque channel in the record: a {step.kind} step needs it '
                    '(bench/channels, a DAQ file column or the bench\'s torque topic)')
            return [finder.data(0, 0, 'ramp', lb, note) for lb in labels]
        eps = finder.ramp_episodes(channel, lambda: _episodes(
            torque, angle, r.breaks, step.threshold_rad))
        drive = 1 if channel == 'torque_in' else -1   # sign of the torque that turns it ccw
        out = []
        for lb in labels:
            want = drive * (1 if lb['direction'] == 'ccw' else -1)
            cands = [e for e in eps if e[2] == want and e[0] not in finder.used_ramps]
            t = r.time_s
            after = [e for e in cands if t[e[0]] >= finder.cursor_s]
            e = after[0] if after else cands[0] if cands else None
            if e is None:
                taken = sum(1 for x in eps if x[0] in finder.used_ramps)
                note = (f'no {lb["direction"]} {what} torque ramp (rising from zero to its '
                        f'release, the {what} shaft still over its first half) in the record: '
                        f'it has {len(eps)} such ramp(s), {taken} taken by earlier parts')
                out.append(finder.data(0, 0, 'ramp', lb, note))
                continue
            finder.used_ramps.add(e[0])
            finder.cursor_s = max(finder.cursor_s, float(t[e[1] - 1]))
            out.append(finder.data(e[0], e[1], 'ramp', lb, '', {
                'found_t_start_s': float(t[e[0]]), 'found_t_end_s': float(t[e[1] - 1])}))
        return out
    return find


#: Step kind -> how its parts are found in a measured record (recorded.FINDERS takes these).
#: The step is Any: each finder takes the step class of its key's kind, which a table
#: indexed by kind cannot say.
LOSS_FINDERS: dict[str, Callable[[PartFinder, Any], list[SegmentData]]] = {
    'efficiency': _efficiency, 'no_load': _no_load, 'temperature_rise': _temperature,
    'life': _life, 'starting_torque': _ramps('torque_in'), 'back_driving': _ramps('torque_out')}
