"""Judging a plan's steps from data measured elsewhere (``rv-te test PLAN --from ...``).

A recorded session or an imported DAQ file has no step markers. Each step's parts are
found in the data (:func:`rv_te_bench.core.segments.find_runs`), or taken from the step's
``time_ranges_s``:

* a TE step's direction: the first unused run at or after the previous step's data (else
  anywhere) turning in that direction (input speed sign: ccw turns the output
  positively) at the step's speed within ``speed_tolerance`` and against its load within
  ``load_tolerance``, long enough for ``settle_s`` and the step's whole revolutions;
* a sweep point: likewise, per speed and load, in the step's direction;
* a hysteresis position: a run with the input locked over which the torque goes beyond
  half the rated torque both ways.

The data of each part then goes through the same result code as a live step
(:func:`rv_te_bench.acceptance._results.step_result`) and the same tolerance evaluation.
A part that is not in the data gets one line saying what is missing (and what the
record has instead), its metrics are NaN with that line, and the step is not judged:
never a number read from the wrong data.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.acceptance._loss_finders import LOSS_FINDERS
from rv_te_bench.acceptance._results import step_result
from rv_te_bench.acceptance._segments import SegmentData
from rv_te_bench.acceptance.plan import DIRECTIONS, HysteresisStep, SweepStep, TeStep
from rv_te_bench.acceptance.runner import build_report
from rv_te_bench.core.hysteresis_measured import torque_noise_nm
from rv_te_bench.core.segments import RAD_S_PER_RPM, Run, RunSettings, find_runs
from rv_te_bench.errors import AcceptanceError

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.acceptance.plan import Step, TestPlan
    from rv_te_bench.acceptance.tolerance import Measured, ToleranceProfile
    from rv_te_bench.core.segments import MeasuredRecord

__all__ = ['FINDERS', 'JudgeSettings', 'judge_record']


#: Samples a cut part keeps off its run's end (the run finder's edges are good to ~2).
_EDGE = 3


@dataclass(frozen=True)
class JudgeSettings:
    """How a record's parts are matched to the plan's steps.

    Attributes:
        speed_tolerance: Relative deviation of a run's input speed from the step's (> 0).
        load_tolerance: Relative deviation of a run's load from the step's (> 0); never
            tighter than 1 % of the plan's largest load, 0.5 N m or 4 torque noise sigmas.
        window_s: Stretch compared before and after each sample to find runs [s].
    """

    speed_tolerance: float = 0.02
    load_tolerance: float = 0.05
    window_s: float = 0.02

    def __post_init__(self) -> None:
        """Validate (AcceptanceError names the setting)."""
        for name in ('speed_tolerance', 'load_tolerance', 'window_s'):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 < v < 1.0):
                msg = f'{name} must lie in (0, 1), got {v!r}'
                raise AcceptanceError(msg)


def _plan_loads(plan: TestPlan) -> list[float]:
    loads = {0.0}
    for s in plan.steps:   # TE, sweep and the whole-reducer steps' loads
        if isinstance(s, HysteresisStep):
            continue
        load = getattr(s, 'load_nm', None)
        if isinstance(load, float):
            loads.add(load)
        loads.update(getattr(s, 'loads_nm', ()))
    return sorted(loads)


class _Finder:
    """Finds each step's parts in the record, in plan order."""

    def __init__(self, plan: TestPlan, record: MeasuredRecord, settings: JudgeSettings) -> None:
        self.record = record
        self.settings = settings
        self.info = record.info
        tq = record.torque_out_nm
        self.torque_ok = tq is not None and bool(np.all(np.isfinite(tq)))
        self.noise = torque_noise_nm(tq) if tq is not None and self.torque_ok else 0.0
        loads = _plan_loads(plan)
        gaps = [b - a for a, b in itertools.pairwise(loads)]
        self.max_load = max(loads)
        resolution = max(0.25 * min(gaps) if gaps else 1.0, 8.0 * self.noise
                         * math.sqrt(2.0 / max(1.0, settings.window_s * self.info.sample_rate_hz)),
                         0.5)
        run_settings = RunSettings(window_s=settings.window_s,
                                   speed_tolerance=settings.speed_tolerance,
                                   load_resolution_nm=resolution, min_duration_s=0.05)
        self.runs = find_runs(record.time_s, record.theta_in_rad,
                              tq if self.torque_ok else None, run_settings,
                              breaks=record.breaks)
        self.used: set[int] = set()
        self.cursor_s = -math.inf
        self.cut_at: dict[int, int] = {}   # run -> its first sample not yet taken
        self.used_ramps: set[int] = set()   # first samples of the torque ramps taken
        self._ramps: dict[str, list[tuple[int, int, int]]] = {}

    def ramp_episodes(self, channel: str, find: Callable[[], list[tuple[int, int, int]]],
                      ) -> list[tuple[int, int, int]]:
        """The torque ramps of ``channel`` in the record (found once by ``find``)."""
        if channel not in self._ramps:
            self._ramps[channel] = find()
        return self._ramps[channel]

    # -- helpers ----------------------------------------------------------------------
    def _data(self, start: int, stop: int, role: str, label: dict[str, Any], note: str = '',
              found: dict[str, Any] | None = None) -> SegmentData:
        r = self.record
        tq = r.torque_out_nm[start:stop] if r.torque_out_nm is not None else np.zeros(0)
        if note == '' and tq.size and not np.all(np.isfinite(tq)):
            note = (f'{int(np.count_nonzero(~np.isfinite(tq)))} samples of this part have '
                    'no torque value')
        t_in, temp = (np.zeros(0) if a is None else a[start:stop]
                      for a in (r.torque_in_nm, r.temp_case_degc))
        return SegmentData(role=role, label=label, theta_in_rad=r.theta_in_rad[start:stop],
                           theta_out_rad=r.theta_out_rad[start:stop], torque_out_nm=tq,
                           torque_in_nm=t_in, temp_case_degc=temp,
                           time_s=r.time_s[start:stop], note=note, found=found or {})

    data = _data

    def _take(self, k: int) -> Run:
        self.used.add(k)
        run = self.runs[k]
        self.cursor_s = max(self.cursor_s, run.t_end_s)
        return run

    def _load_ok(self, run: Run, load_nm: float) -> bool:
        tol = max(self.settings.load_tolerance * load_nm, 0.01 * self.max_load, 0.5,
                  4.0 * self.noise)
        return abs(abs(run.load_nm) - load_nm) <= tol

    def _range(self, t0: float, t1: float) -> tuple[int, int, str]:
        t = self.record.time_s
        a, b = int(np.searchsorted(t, t0)), int(np.searchsorted(t, t1, side='right'))
        if b - a < 2:
            return a, b, (f'the time range [{t0:g}, {t1:g}] s holds no data (the record '
                          f'spans 0..{float(t[-1]):.6g} s)')
        inside = [int(x) for x in self.record.breaks if a < int(x) < b]
        if inside:
            return a, b, (f'the time range [{t0:g}, {t1:g}] s holds a break (drop-out or '
                          f'lost block) at {float(t[inside[0]]):.6g} s')
        return a, b, ''

    def _describe(self, want_locked: bool) -> str:
        runs = [r for r in self.runs if r.locked == want_locked and r.duration_s >= 0.5]
        if not runs:
            return 'the record has none' if want_locked else \
                'the record has no run of constant speed of 0.5 s or more'
        parts = [f'{("ccw" if r.speed_rad_s > 0 else "cw")} {abs(r.speed_rpm):.5g} rpm '
                 + (f'/ {abs(r.load_nm):.4g} N m ' if math.isfinite(r.load_nm) else '')
                 + f'({r.duration_s:.3g} s at {r.t_start_s:.4g} s)' for r in runs[:6]]
        more = f' and {len(runs) - 6} more' if len(runs) > 6 else ''
        return 'the record has ' + ', '.join(parts) + more

    # -- drives ----------------------------------------------------------------------------
    def drive(self, step: TeStep | SweepStep, direction: str, speed_rpm: float, load_nm: float,
              span: tuple[float, float] | None, role: str) -> SegmentData:
        label = {'direction': direction, 'speed_rpm': speed_rpm, 'load_nm': load_nm,
                 'settle_s': step.settle_s}
        if span is not None:
            a, b, note = self._range(*span)
            return self._data(a, b, role, label, note, {'from_plan_time_range_s': list(span)})
        rev_s = self.info.gear_ratio * 60.0 / speed_rpm
        need_s = step.settle_s + step.revolutions * rev_s
        return self.run_for(direction, speed_rpm, load_nm, need_s, role, label,
                            f'settle {step.settle_s:g} s + {step.revolutions} output '
                            'revolution(s)')

    def run_for(self, direction: str, speed_rpm: float, load_nm: float, need_s: float,
                role: str, label: dict[str, Any], what: str, *,
                cut_s: float | None = None) -> SegmentData:
        """The first unused run at or after the previous part (else anywhere) in
        ``direction`` at ``speed_rpm`` against ``load_nm`` (the settings' tolerances)
        lasting ``need_s`` (``what`` says of what); its data cut to ``cut_s`` from its start
        (None: the whole run), or a part with the note of what the record has instead. A
        run cut is left to later parts from where the cut ended (a warm-up run straight
        into a life test's run at the same speed and load is one run in the data). A cut
        part may be a few samples shorter than ``need_s`` and ends _EDGE samples before the
        run's end: the run's edges are found to a few samples (the finder's window), and
        its last samples may belong to what follows."""
        slack = 1.5 if cut_s is None else 1.5 + 2 * _EDGE
        sign = DIRECTIONS[direction]
        t = self.record.time_s
        if load_nm > 0 and not self.torque_ok:
            return self._data(0, 0, role, label, f'the step runs against {load_nm:g} N m but '
                              'the record has no torque channel to find or check the load')
        cands = []
        for k, r in enumerate(self.runs):
            if k in self.used or r.locked or r.speed_rad_s * sign <= 0:
                continue
            if abs(abs(r.speed_rpm) - speed_rpm) > self.settings.speed_tolerance * speed_rpm:
                continue
            if self.torque_ok and not self._load_ok(r, load_nm):
                continue
            a = self.cut_at.get(k, r.start)
            if r.t_end_s - float(t[a]) + slack / self.info.sample_rate_hz < need_s:
                continue
            cands.append(k)
        after = [k for k in cands if float(t[self.cut_at.get(k, self.runs[k].start)])
                 >= self.cursor_s]
        best = after[0] if after else cands[0] if cands else None
        if best is None:
            load = f' against {load_nm:g} N m' if self.torque_ok else ''
            note = (f'no {direction} run at {speed_rpm:g} rpm (+-'
                    f'{100 * self.settings.speed_tolerance:g} %){load} of at least '
                    f'{need_s:.4g} s ({what}) in the record: {self._describe(False)}')
            return self._data(0, 0, role, label, note)
        r = self.runs[best]
        a = self.cut_at.get(best, r.start)
        stop = r.stop if cut_s is None else min(
            r.stop - _EDGE, a + round(cut_s * self.info.sample_rate_hz))
        if stop >= r.stop - round(0.05 * self.info.sample_rate_hz):
            self._take(best)          # what is left is too short to be a part
        else:
            self.cut_at[best] = stop
            self.cursor_s = max(self.cursor_s, float(t[stop - 1]))
        found = {'found_t_start_s': float(t[a]), 'found_t_end_s': float(t[stop - 1]),
                 'found_speed_rpm': abs(r.speed_rpm),
                 'found_load_nm': abs(r.load_nm) if math.isfinite(r.load_nm) else None}
        return self._data(a, stop, role, label, found=found)

    # -- hysteresis --------------------------------------------------------------------------
    def locked(self, step: HysteresisStep) -> list[SegmentData]:
        tr = step.rated_torque_nm
        label = [{'position': p} for p in range(step.positions)]
        if self.record.torque_out_nm is None:
            note = ('no torque channel in the record: a hysteresis curve needs the output '
                    'torque (a CSV/TDMS/MDF torque column: --torque; a JointState effort: '
                    '--torque JOINT; the bench\'s torque topic: --torque-topic)')
            return [self._data(0, 0, 'cycle', lb, note) for lb in label]
        if step.time_ranges_s:
            out = []
            for lb, span in zip(label, step.time_ranges_s, strict=True):
                a, b, note = self._range(*span)
                out.append(self._data(a, b, 'cycle', lb, note,
                                      {'from_plan_time_range_s': list(span)}))
            return out
        tq = self.record.torque_out_nm

        def reaches(a: int, b: int) -> bool:
            seg = tq[a:b]
            seg = seg[np.isfinite(seg)]
            return seg.size > 0 and float(seg.max()) >= 0.5 * tr and float(seg.min()) <= -0.5 * tr

        cands = [k for k, r in enumerate(self.runs)
                 if k not in self.used and r.locked and reaches(r.start, r.stop)]
        after = [k for k in cands if self.runs[k].t_start_s >= self.cursor_s]
        chosen = (after if len(after) >= step.positions else cands)[:step.positions]
        if len(chosen) < step.positions:
            note = self._why_no_cycle(step, len(chosen))
            return [self._data(0, 0, 'cycle', lb, note) for lb in label]
        out = []
        for lb, k in zip(label, chosen, strict=True):
            r = self._take(k)
            out.append(self._data(r.start, r.stop, 'cycle', lb, found={
                'found_t_start_s': r.t_start_s, 'found_t_end_s': r.t_end_s}))
        return out

    def _why_no_cycle(self, step: HysteresisStep, have: int) -> str:
        tr = step.rated_torque_nm
        tq = self.record.torque_out_nm
        assert tq is not None
        w = self.record.theta_in_rad
        t = self.record.time_s
        big = np.flatnonzero(np.isfinite(tq) & (np.abs(tq) >= 0.5 * tr))
        want = (f'{step.positions} load cycle(s) to +-{tr:g} N m with the input locked '
                f'(one per position); found {have}')
        if big.size == 0:
            fin = tq[np.isfinite(tq)]
            lo, hi = (float(fin.min()), float(fin.max())) if fin.size else (math.nan, math.nan)
            return f'{want}: the applied torque only reaches {-lo:+.4g} / {-hi:+.4g} N m'
        # where the torque is large but the input turns: not locked
        k = int(big[0])
        a, b = max(0, k - 50), min(w.size, k + 50)
        speed = abs(float((w[b - 1] - w[a]) / max(t[b - 1] - t[a], 1e-12))) / RAD_S_PER_RPM
        if speed >= 0.01:
            return (f'{want}: the input is not locked while the torque is applied (input '
                    f'speed {speed:.3g} rpm at {float(t[k]):.4g} s)')
        return f'{want}: no locked stretch holds a whole cycle both ways'


def _te_parts(finder: _Finder, step: TeStep) -> list[SegmentData]:
    spans = {d: (t0, t1) for d, t0, t1 in step.time_ranges_s}
    return [finder.drive(step, d, step.speed_rpm, step.load_nm, spans.get(d), 'te')
            for d in step.directions]


def _sweep_parts(finder: _Finder, step: SweepStep) -> list[SegmentData]:
    points = [(s, ld) for s in step.speeds_rpm for ld in step.loads_nm]
    spans: list[tuple[float, float] | None] = list(step.time_ranges_s) or [None] * len(points)
    return [finder.drive(step, step.direction, s, ld, span, 'sweep')
            for (s, ld), span in zip(points, spans, strict=True)]


def _hysteresis_parts(finder: _Finder, step: HysteresisStep) -> list[SegmentData]:
    return finder.locked(step)


def _no_parts(_finder: _Finder, _step: Step) -> list[SegmentData]:
    return []   # an operator step leaves no data to find


#: Step kind -> how its parts are found in a measured record (see plan._KINDS). The step
#: is Any: each finder takes the step class of its key's kind, which the table cannot say.
FINDERS: dict[str, Callable[[_Finder, Any], list[SegmentData]]] = {
    'te': _te_parts, 'sweep': _sweep_parts, 'hysteresis': _hysteresis_parts,
    'operator': _no_parts, **LOSS_FINDERS}


def _step_segments(finder: _Finder, step: Step) -> list[SegmentData]:
    return FINDERS[step.kind](finder, step)


def judge_record(plan: TestPlan, profile: ToleranceProfile, record: MeasuredRecord, *,
                 serial: str, operator: str, conditions: dict[str, Any] | None = None,
                 settings: JudgeSettings | None = None) -> dict[str, Any]:
    """The unit record of ``plan`` judged from ``record`` (as :func:`build_report`).

    Args:
        plan, profile: The validated plan and tolerance profile.
        record: The measured record (:func:`rv_te_bench.io.measured_record.read_measured_record`).
        serial, operator: The unit's identity.
        conditions: Test conditions for the record.
        settings: Matching tolerances (default :class:`JudgeSettings`).

    Returns:
        The report, with ``source`` (where the data came from, where each step was found)
        and the date of the record's first sample.
    """
    finder = _Finder(plan, record, settings or JudgeSettings())
    results: list[tuple[list[Measured], dict[str, Any]]] = []
    found = []
    for step in plan.steps:
        segs = _step_segments(finder, step)
        measured, details = step_result(step, record.info, segs)
        notes = sorted({m.note for m in measured if m.note})
        if notes:
            details['not_judged'] = '; '.join(notes)
        results.append((measured, details))
        found.append({'step': step.name, 'parts': [
            {**s.label, **s.found, **({'note': s.note} if s.note else {})} for s in segs]})
    report = build_report(plan=plan, profile=profile, info=record.info, serial=serial,
                          operator=operator, results=results, conditions=conditions,
                          started_utc=record.start_utc)
    report['source'] = {'route': 'recorded', 'from': record.source,
                        'samples': record.samples,
                        'duration_s': float(record.time_s[-1]) if record.samples else 0.0,
                        'breaks': int(record.breaks.size), 'torque_from': record.torque_from,
                        'channels_from': record.channels_from,
                        'steps': found}
    return report
