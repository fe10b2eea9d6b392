"""Plan steps of the whole reducer test (issue 38): efficiency map, no-load running torque,
starting and back-driving torque, temperature rise, run-in / life checkpoints.

YAML (docs/LOSSES_TESTS.md; SI units unless the key says otherwise)::

  - {name: efficiency, kind: efficiency, speeds_rpm: [500, 1000, 2000],
     loads_nm: [196, 392, 588, 784], direction: ccw, settle_s: 1.0, measure_s: 2.0}
  - {name: no-load, kind: no_load, speeds_rpm: [500, 1000, 2000, 3000], settle_s: 1.0,
     measure_s: 2.0}
  - {name: starting, kind: starting_torque, directions: [ccw, cw], ramp_rate_nm_s: 0.2,
     max_torque_nm: 2.0, threshold_rad: 2.0e-4}
  - {name: back-driving, kind: back_driving, directions: [ccw], ramp_rate_nm_s: 20,
     max_torque_nm: 200, threshold_rad: 2.0e-5}
  - {name: warm-up, kind: temperature_rise, speed_rpm: 1500, load_nm: 392,
     rate_limit_k_per_min: 0.05, window_s: 120, max_duration_s: 3600}
  - {name: life, kind: life, checkpoints: 6, run_s: 60, speed_rpm: 1500, load_nm: 392,
     te_speed_rpm: 1500, no_load_speed_rpm: 1000, noise_rel: 0.02, growth_fraction: 0.1}

Each point of an efficiency or no-load step is one drive segment of ``settle_s`` (not
analysed) plus ``measure_s``. A ramp step ramps the torque at ``ramp_rate_nm_s`` up to
``max_torque_nm`` (the unit must turn below it) and the bench releases the torque when the
shaft has turned ``stop_angle_rad`` (default 10 x the detection threshold). A temperature
step runs ``max_duration_s`` (the analysis finds when the case settled). A life step runs
``checkpoints`` times: ``run_s`` at its speed and load, then one output revolution of TE
at ``te_speed_rpm`` and a no-load window at ``no_load_speed_rpm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.acceptance._fields import Fields
    from rv_te_bench.acceptance._segments import ProgramSink

__all__ = [
    'LOSS_KINDS',
    'LOSS_PROGRAMS',
    'BackDrivingStep',
    'EfficiencyStep',
    'LifeStep',
    'NoLoadStep',
    'StartingTorqueStep',
    'TemperatureRiseStep',
]

_DIRS = {'ccw': 1, 'cw': -1}
_MAX_SPEED_RPM = 1e5
_MAX_TORQUE_NM = 1e6


@dataclass(frozen=True)
class EfficiencyStep:
    """eta at every (speed, load), one direction."""

    name: str
    speeds_rpm: tuple[float, ...]
    loads_nm: tuple[float, ...]
    direction: str = 'ccw'
    settle_s: float = 1.0
    measure_s: float = 2.0
    kind: str = 'efficiency'


@dataclass(frozen=True)
class NoLoadStep:
    """Input torque at zero load at every speed."""

    name: str
    speeds_rpm: tuple[float, ...]
    direction: str = 'ccw'
    settle_s: float = 1.0
    measure_s: float = 2.0
    kind: str = 'no_load'


@dataclass(frozen=True)
class StartingTorqueStep:
    """Input torque ramp (output free) per direction until the input turns."""

    name: str
    ramp_rate_nm_s: float
    max_torque_nm: float
    threshold_rad: float
    directions: tuple[str, ...] = ('ccw', 'cw')
    stop_angle_rad: float = math.nan
    kind: str = 'starting_torque'


@dataclass(frozen=True)
class BackDrivingStep:
    """Output torque ramp (input free) per direction until the output turns."""

    name: str
    ramp_rate_nm_s: float
    max_torque_nm: float
    threshold_rad: float
    directions: tuple[str, ...] = ('ccw',)
    stop_angle_rad: float = math.nan
    kind: str = 'back_driving'


@dataclass(frozen=True)
class TemperatureRiseStep:
    """Run at one speed and load until the case settles (or max_duration_s)."""

    name: str
    speed_rpm: float
    load_nm: float = 0.0
    direction: str = 'ccw'
    rate_limit_k_per_min: float = 0.05
    window_s: float = 120.0
    max_duration_s: float = 3600.0
    kind: str = 'temperature_rise'


@dataclass(frozen=True)
class LifeStep:
    """Run-in / life test: checkpoints of TE, crank-order lines, no-load torque and
    temperature, with the growth detector on each tracked quantity."""

    name: str
    checkpoints: int
    run_s: float
    speed_rpm: float
    load_nm: float = 0.0
    direction: str = 'ccw'
    te_speed_rpm: float = 1500.0
    no_load_speed_rpm: float = 1000.0
    settle_s: float = 0.5
    measure_s: float = 2.0
    growth_fraction: float = 0.10
    noise_rel: float = 0.02
    baseline_checkpoints: int = 3
    threshold: float = 1.5
    kind: str = 'life'


def _directions(f: Fields, default: list[str]) -> tuple[str, ...]:
    dirs = f.data.pop('directions', default)
    if not isinstance(dirs, list) or not dirs or len(set(map(str, dirs))) != len(dirs) or \
            not all(d in _DIRS for d in dirs):
        f.fail('directions', f'must be a list of distinct directions from {list(_DIRS)}', dirs)
    return tuple(dirs)


def _window(f: Fields) -> tuple[float, float]:
    return (f.num('settle_s', 1.0, lo=0.0, hi=600.0),
            f.num('measure_s', 2.0, lo=0.0, lo_open=True, hi=3600.0))


def _efficiency(f: Fields, name: str) -> EfficiencyStep:
    speeds = f.numbers('speeds_rpm', lo=0.0, hi=_MAX_SPEED_RPM, nonzero=True)
    loads = f.numbers('loads_nm', lo=0.0, hi=_MAX_TORQUE_NM, nonzero=True)
    direction = f.text('direction', 'ccw', choices=tuple(_DIRS))
    settle, measure = _window(f)
    return EfficiencyStep(name, speeds, loads, direction, settle, measure)


def _no_load(f: Fields, name: str) -> NoLoadStep:
    speeds = f.numbers('speeds_rpm', lo=0.0, hi=_MAX_SPEED_RPM, nonzero=True)
    direction = f.text('direction', 'ccw', choices=tuple(_DIRS))
    settle, measure = _window(f)
    return NoLoadStep(name, speeds, direction, settle, measure)


def _ramp(cls: type[StartingTorqueStep | BackDrivingStep], default_dirs: list[str],
          ) -> Callable[[Fields, str], StartingTorqueStep | BackDrivingStep]:
    def parse(f: Fields, name: str) -> StartingTorqueStep | BackDrivingStep:
        rate = f.num('ramp_rate_nm_s', lo=0.0, lo_open=True, hi=_MAX_TORQUE_NM)
        top = f.num('max_torque_nm', lo=0.0, lo_open=True, hi=_MAX_TORQUE_NM)
        thr = f.num('threshold_rad', lo=0.0, lo_open=True, hi=0.1)
        stop = f.num('stop_angle_rad', 10.0 * thr, lo=0.0, lo_open=True, hi=1.0)
        if stop <= thr:
            f.fail('stop_angle_rad', f'must exceed threshold_rad ({thr:g})', stop)
        if top / rate > 3600.0:
            f.fail('max_torque_nm', 'over ramp_rate_nm_s must be at most 3600 s',
                   top / rate)
        return cls(name=name, ramp_rate_nm_s=rate, max_torque_nm=top, threshold_rad=thr,
                   directions=_directions(f, default_dirs), stop_angle_rad=stop)
    return parse


def _temperature(f: Fields, name: str) -> TemperatureRiseStep:
    step = TemperatureRiseStep(
        name=name, speed_rpm=f.num('speed_rpm', lo=0.0, lo_open=True, hi=_MAX_SPEED_RPM),
        load_nm=f.num('load_nm', 0.0, lo=0.0, hi=_MAX_TORQUE_NM),
        direction=f.text('direction', 'ccw', choices=tuple(_DIRS)),
        rate_limit_k_per_min=f.num('rate_limit_k_per_min', 0.05, lo=0.0, lo_open=True,
                                   hi=10.0),
        window_s=f.num('window_s', 120.0, lo=0.0, lo_open=True, hi=3600.0),
        max_duration_s=f.num('max_duration_s', 3600.0, lo=0.0, lo_open=True, hi=86400.0))
    if step.window_s * 2 > step.max_duration_s:
        f.fail('window_s', f'must be at most half of max_duration_s ({step.max_duration_s:g})',
               step.window_s)
    return step


def _life(f: Fields, name: str) -> LifeStep:
    step = LifeStep(
        name=name, checkpoints=f.integer('checkpoints', 6, lo=2, hi=1000),
        run_s=f.num('run_s', lo=0.0, lo_open=True, hi=86400.0),
        speed_rpm=f.num('speed_rpm', lo=0.0, lo_open=True, hi=_MAX_SPEED_RPM),
        load_nm=f.num('load_nm', 0.0, lo=0.0, hi=_MAX_TORQUE_NM),
        direction=f.text('direction', 'ccw', choices=tuple(_DIRS)),
        te_speed_rpm=f.num('te_speed_rpm', 1500.0, lo=0.0, lo_open=True, hi=_MAX_SPEED_RPM),
        no_load_speed_rpm=f.num('no_load_speed_rpm', 1000.0, lo=0.0, lo_open=True,
                                hi=_MAX_SPEED_RPM),
        settle_s=f.num('settle_s', 0.5, lo=0.0, hi=600.0),
        measure_s=f.num('measure_s', 2.0, lo=0.0, lo_open=True, hi=3600.0),
        growth_fraction=f.num('growth_fraction', 0.10, lo=0.0, lo_open=True, hi=10.0),
        noise_rel=f.num('noise_rel', 0.02, lo=0.0, lo_open=True, hi=1.0),
        baseline_checkpoints=f.integer('baseline_checkpoints', 3, lo=1, hi=100),
        threshold=f.num('threshold', 1.5, lo=0.0, lo_open=True, hi=100.0))
    if step.checkpoints <= step.baseline_checkpoints:
        f.fail('checkpoints', f'must exceed baseline_checkpoints '
               f'({step.baseline_checkpoints})', step.checkpoints)
    return step


#: A whole-reducer step.
LossStep = (EfficiencyStep | NoLoadStep | StartingTorqueStep | BackDrivingStep
            | TemperatureRiseStep | LifeStep)

#: kind -> parser (plan._KINDS takes these).
LOSS_KINDS: dict[str, Callable[[Fields, str], LossStep]] = {
    'efficiency': _efficiency, 'no_load': _no_load,
    'starting_torque': _ramp(StartingTorqueStep, ['ccw', 'cw']),
    'back_driving': _ramp(BackDrivingStep, ['ccw']),
    'temperature_rise': _temperature, 'life': _life}


# -- programs --------------------------------------------------------------------------------
def _timed(r: ProgramSink, speed_rpm: float, load_nm: float, sign: int, seconds: float,
           settle_s: float, role: str, label: dict[str, Any]) -> None:
    r.add_segment({'kind': 'drive', 'speed_rpm': sign * speed_rpm,
                   'duration_s': settle_s + seconds, 'load_nm': sign * load_nm},
                  role, {**label, 'settle_s': settle_s, 'speed_rpm': speed_rpm,
                         'load_nm': load_nm})


def _efficiency_program(r: ProgramSink, step: EfficiencyStep) -> None:
    for s in step.speeds_rpm:
        for load in step.loads_nm:
            _timed(r, s, load, _DIRS[step.direction], step.measure_s, step.settle_s,
                   'efficiency', {'direction': step.direction})


def _no_load_program(r: ProgramSink, step: NoLoadStep) -> None:
    for s in step.speeds_rpm:
        _timed(r, s, 0.0, _DIRS[step.direction], step.measure_s, step.settle_s, 'no_load',
               {'direction': step.direction})


def _ramp_program(shaft: str,
                  ) -> Callable[[ProgramSink, StartingTorqueStep | BackDrivingStep], None]:
    def build(r: ProgramSink, step: StartingTorqueStep | BackDrivingStep) -> None:
        r.live_name = 'torque_nm'
        for d in step.directions:
            r.add_segment({'kind': 'torque_ramp', 'shaft': shaft,
                           'ramp_rate_nm_s': _DIRS[d] * step.ramp_rate_nm_s,
                           'max_torque_nm': step.max_torque_nm,
                           'stop_angle_rad': step.stop_angle_rad},
                          'ramp', {'direction': d, 'shaft': shaft})
    return build


def _temperature_program(r: ProgramSink, step: TemperatureRiseStep) -> None:
    _timed(r, step.speed_rpm, step.load_nm, _DIRS[step.direction], step.max_duration_s, 0.0,
           'temperature', {'direction': step.direction})


def _life_program(r: ProgramSink, step: LifeStep) -> None:
    sign = _DIRS[step.direction]
    for k in range(step.checkpoints):
        lab = {'direction': step.direction, 'checkpoint': k}
        _timed(r, step.speed_rpm, step.load_nm, sign, step.run_s, 0.0, 'life_run', lab)
        r.add_drive(step.te_speed_rpm, 0.0, sign, 1, step.settle_s, 'life_te',
                    {**lab, 'speed_rpm': step.te_speed_rpm, 'load_nm': 0.0})
        _timed(r, step.no_load_speed_rpm, 0.0, sign, step.measure_s, step.settle_s,
               'life_no_load', lab)


#: kind -> bench program builder (runner.PROGRAMS takes these). The step is Any: each
#: builder takes the step class of its key's kind, which the table cannot say.
LOSS_PROGRAMS: dict[str, Callable[[ProgramSink, Any], None]] = {
    'efficiency': _efficiency_program, 'no_load': _no_load_program,
    'starting_torque': _ramp_program('input'),
    'back_driving': _ramp_program('output'),
    'temperature_rise': _temperature_program, 'life': _life_program}
