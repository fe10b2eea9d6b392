"""Lost motion, backlash and rigidity of a measured record without a plan (``rv-te analyze``).

A record with a torque channel and stretches with the input locked (a hysteresis test
measured on any bench, imported or recorded) is read the way a plan's hysteresis step is
read from it (:mod:`rv_te_bench.acceptance.recorded`): the same locked stretches, the same
reading of dwells or samples and the same catalogue definitions (lost motion at
+-``lost_motion_fraction`` x T_R on the centre line, backlash where both branches cross
zero torque, rigidity K as the smaller secant over 0.5-1.0 T_R), cycles averaged with their
spread. What a plan would state is taken from the record, and the report says so:

* T_R: given (``rated_torque_nm``), else the record's largest held torque (the dwell means
  of a torque-step test; the smoothed peak of a constant-speed one);
* the method: torque steps when held torques (dwells) cover at least half of a locked
  stretch and the output turns mostly between them (under a quarter of its travel within
  them), else constant speed;
* a torque-step test's dwell: the median dwell found (a held torque counts from 30 % of
  it on, as in a plan); torque resolution: a quarter of the lost-motion torque.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.acceptance._results import step_result
from rv_te_bench.acceptance.plan import HysteresisStep, parse_plan
from rv_te_bench.acceptance.recorded import JudgeSettings, _Finder
from rv_te_bench.core.hysteresis_measured import find_dwells, torque_noise_nm
from rv_te_bench.errors import AcceptanceError, PlanError, TeInputError

if TYPE_CHECKING:
    from rv_te_bench.core.segments import MeasuredRecord

__all__ = ['record_hysteresis']

#: A locked stretch is a load cycle when its smoothed torque goes beyond this part of the
#: largest torque of the locked stretches, both ways.
_BOTH_WAYS = 0.5
#: ... and the output may turn through the held torques by at most this part of its travel.
_MOVING_SHARE = 0.25
#: Torque resolutions tried for the held torques, as parts of the largest torque.
_RESOLUTIONS = (0.005, 0.01, 0.02, 0.04)
#: Held torques must cover this part of a stretch for the torque-step reading.
_DWELL_SHARE = 0.5


def _smooth(x: np.ndarray, k: int) -> np.ndarray:
    if x.size < k or k <= 1:
        return x
    return np.convolve(x, np.ones(k) / k, mode='valid')


def _stub(rated: float, **kw: Any) -> HysteresisStep:
    step = {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': float(rated), **kw}
    plan = parse_plan({'plan': 'analyze', 'steps': [step]}, 'hysteresis read from the record')
    hs = plan.steps[0]
    assert isinstance(hs, HysteresisStep)
    return hs


def record_hysteresis(record: MeasuredRecord, *, rated_torque_nm: float | None = None,
                      ) -> dict[str, Any] | None:
    """The hysteresis metrics of ``record`` (see the module docstring).

    Returns:
        None when the record has no locked stretch loaded both ways; else a dict with
        ``metrics`` (name -> value, SI; NaN where not read), ``spread`` (sample standard
        deviation over the cycles), ``rated_torque_nm`` and ``rated_from``, ``method``,
        ``positions``, ``cycles``, ``torque_noise_nm``, ``note`` (what could not be read,
        or ''), and ``details`` (the step's curve as the unit report draws it).

    Raises:
        AcceptanceError: ``rated_torque_nm`` not finite and > 0.
    """
    if rated_torque_nm is not None and not (math.isfinite(rated_torque_nm)
                                            and rated_torque_nm > 0):
        msg = f'the rated torque must be finite and > 0 N m, got {rated_torque_nm!r}'
        raise AcceptanceError(msg)
    tq = record.torque_out_nm
    if tq is None or not np.all(np.isfinite(tq)) or record.samples < 50:
        return None
    finder = _Finder(parse_plan({'plan': 'analyze', 'steps': [
        {'kind': 'hysteresis', 'name': 'h', 'rated_torque_nm': 1.0}]}, 'analyze'),
        record, JudgeSettings())
    fs = record.info.sample_rate_hz
    k = max(1, round(0.025 * fs))
    locked = [r for r in finder.runs if r.locked and r.stop - r.start >= 5 * k]
    if not locked:
        return None
    peaks = [(float(np.max(s)), float(np.min(s)))
             for s in (_smooth(tq[r.start:r.stop], k) for r in locked)]
    big = max(max(hi, -lo) for hi, lo in peaks)
    if not big > 0:
        return None
    cycles = [r for r, (hi, lo) in zip(locked, peaks, strict=True)
              if hi >= _BOTH_WAYS * big and -lo >= _BOTH_WAYS * big]
    if not cycles:
        return None
    noise = torque_noise_nm(tq)
    held: list[np.ndarray] = []
    lengths: list[np.ndarray] = []
    share: list[float] = []
    moving: list[float] = []
    for r in cycles:
        seg = tq[r.start:r.stop]
        d = None
        for part in _RESOLUTIONS:    # the finest step the torque noise lets tell apart
            try:
                d = find_dwells(seg, np.zeros(seg.size), min_samples=max(5, round(0.05 * fs)),
                                resolution_nm=max(0.5, part * big), noise_nm=noise)
                break
            except TeInputError:
                continue
        if d is None:
            share.append(0.0)
            continue
        held.append(np.asarray(d.torque_nm))
        lengths.append(np.asarray(d.stop) - np.asarray(d.start))
        share.append(float(np.sum(lengths[-1])) / seg.size)
        # a held torque holds the angle too: the output turns while the torque ramps. A
        # constant-speed loading (the output turned steadily) has torque plateaus in the
        # play that look held, but the angle moves through them.
        ang = _smooth(record.theta_out_rad[r.start:r.stop]
                      - record.theta_in_rad[r.start:r.stop] / record.info.gear_ratio, k)
        dang = np.abs(np.diff(ang))
        total = float(np.sum(dang))
        inside = sum(float(np.sum(dang[a:max(a, b - k)]))
                     for a, b in zip(d.start, d.stop, strict=True))
        moving.append(inside / total if total > 0 else 1.0)
    steps = bool(held) and min(share) >= _DWELL_SHARE and max(moving) < _MOVING_SHARE \
        and sum(h.size for h in held) >= 8
    kw: dict[str, Any] = {'positions': len(cycles)}
    if steps:
        levels = np.abs(np.concatenate(held))
        rated = float(np.max(levels))
        kw['method'] = 'torque_steps'
        kw['dwell_s'] = min(60.0, float(np.median(np.concatenate(lengths))) / fs)
        # the reading's torque resolution is a quarter of the smallest gap between the
        # step grid and the lost-motion torques: with the coarsest grid, a quarter of
        # lost_motion_fraction x T_R (what a plan of steps >= 4 % of T_R reads with too)
        kw['step_fraction'] = 0.5
        rated_from = "the record's largest held torque"
    else:
        kw['method'] = 'constant_speed'
        rated = big
        rated_from = "the record's largest torque (smoothed over 25 ms)"
    if rated_torque_nm is not None:
        rated, rated_from = float(rated_torque_nm), 'given'
    try:
        step = _stub(rated, **kw)
    except PlanError as exc:   # a setting taken from the record out of a plan's range
        msg = f'the hysteresis read from the record: {exc}'
        raise AcceptanceError(msg) from None
    measured, details = step_result(step, record.info, finder.locked(step))
    notes = sorted({m.note for m in measured if m.note})
    positions = details.get('positions', [])
    return {'metrics': {m.name: m.value for m in measured},
            'spread': positions[details.get('shown_position', 0)].get('spread', {})
            if positions else {},
            'rated_torque_nm': rated, 'rated_from': rated_from, 'method': step.method,
            'positions': step.positions, 'cycles': [p.get('cycles', 0) for p in positions],
            'torque_noise_nm': noise, 'lost_motion_torque_nm': step.lost_motion_fraction * rated,
            'note': '; '.join(notes), 'details': details}
