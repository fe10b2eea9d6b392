"""Acceptance test plans: YAML files validated before anything starts.

A plan (docs/ACCEPTANCE.md)::

    plan: rv-80e-acceptance             # name (required)
    description: ...                    # optional
    tolerance: rv-80e-101               # a shipped profile name or a path (optional: the
                                        #   profile named after the bench's preset)
    steps:
      - {name: te, kind: te, speed_rpm: 1500, load_nm: 0, directions: [ccw, cw],
         revolutions: 1, settle_s: 0.5}
      - {name: hysteresis, kind: hysteresis, rated_torque_nm: 784, method: torque_steps,
         step_fraction: 0.1, dwell_s: 0.2, lost_motion_fraction: 0.03,
         rigidity: {K: [0.5, 1.0]}, preload: true, positions: 3,
         reposition_speed_rpm: 300}
      - {name: sweep, kind: sweep, speeds_rpm: [500, 1500], loads_nm: [0, 200],
         direction: ccw, revolutions: 1, settle_s: 0.5}

``positions``: the hysteresis cycle is measured at this many output positions, evenly spaced
over one revolution (the output turned on at ``reposition_speed_rpm`` input between them);
the unit's lost motion and backlash are the largest, its rigidity the smallest.

``kind: operator`` steps (``{name: mount, kind: operator, instruction: "mount the unit",
timeout_s: 600}``) wait for the operator's acknowledgement on a real bench (the action's
feedback shows the instruction; the ``test/acknowledge`` service or ``rv-te ack`` answers);
no acknowledgement within ``timeout_s`` aborts the test. They measure nothing.

``safety`` (optional, top level): limits the sequencer checks on every sample read back
from a real bench, besides the bench description's ``limits``: ``max_input_speed_rpm``,
``max_output_torque_nm`` (default: 1.25 x the largest speed / torque the plan commands),
``stale_joint_state_s`` (no joint state for this long aborts the step; default 1),
``reach_timeout_s`` (a setpoint not reached within this aborts; default 10).

``time_ranges_s`` (optional, used only when a recorded or imported record is judged,
``rv-te test --from``): where in the record each part of the step is, in seconds from the
record's first sample, instead of finding it from the data: a TE step maps each direction
to ``[start, end]`` (``{ccw: [12.0, 18.5], cw: [20.0, 26.5]}``), a sweep lists one
``[start, end]`` per point (speeds x loads, in that order), a hysteresis step one per
position.

Directions: ``ccw`` turns the output positively (REP-103, counter-clockwise seen from the
output flange), ``cw`` negatively. Loads resist the motion (magnitudes). Every bad key or
value raises :class:`PlanError` naming the file, the step and the rule.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

from rv_te_bench.acceptance._fields import Fields
from rv_te_bench.acceptance._files import parse_yaml_text, read_source, shipped
from rv_te_bench.acceptance.loss_steps import (
    LOSS_KINDS,
    BackDrivingStep,
    EfficiencyStep,
    LifeStep,
    NoLoadStep,
    StartingTorqueStep,
    TemperatureRiseStep,
)
from rv_te_bench.core.hysteresis import HysteresisConfig, RigidityRegion
from rv_te_bench.errors import PlanError, TeConfigError

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = [
    'DIRECTIONS',
    'STEP_KINDS',
    'HysteresisStep',
    'OperatorStep',
    'PlanPlain',
    'PlanSafety',
    'Step',
    'SweepStep',
    'TeStep',
    'TestPlan',
    'load_plan',
    'parse_plan',
    'parse_yaml_text',
    'shipped_plans',
]

#: Direction name -> sign of the output rotation.
DIRECTIONS = {'ccw': 1, 'cw': -1}
_MAX_STEPS = 100
#: Upper bounds of a step (a plan runs on a real bench: nothing unbounded): input speed
#: [rpm], output torque [N m] (robot reducers are rated well below 1e5 N m), whole output
#: revolutions per direction or point, settle time [s].
MAX_SPEED_RPM = 1e5
MAX_TORQUE_NM = 1e6
MAX_REVOLUTIONS = 100
MAX_SETTLE_S = 600.0


@dataclass(frozen=True)
class TeStep:
    """TE over whole output revolutions in each direction (SI units)."""

    name: str
    speed_rpm: float
    load_nm: float = 0.0
    directions: tuple[str, ...] = ('ccw', 'cw')
    revolutions: int = 1
    settle_s: float = 0.5
    time_ranges_s: tuple[tuple[str, float, float], ...] = ()
    kind: str = 'te'


@dataclass(frozen=True)
class HysteresisStep:
    """Input locked, output loaded 0 -> +T_R -> 0 -> -T_R -> 0 (SI units)."""

    name: str
    rated_torque_nm: float
    method: str = 'torque_steps'
    step_fraction: float = 0.1
    dwell_s: float = 0.2
    output_speed_rad_s: float = 2.0e-4
    lost_motion_fraction: float = 0.03
    rigidity: tuple[tuple[str, float, float], ...] = (('K', 0.5, 1.0),)
    preload: bool = True
    positions: int = 1
    reposition_speed_rpm: float = 300.0
    time_ranges_s: tuple[tuple[float, float], ...] = ()
    kind: str = 'hysteresis'

    def config(self) -> HysteresisConfig:
        """The curve-reading settings of this step."""
        return HysteresisConfig(
            rated_torque_nm=self.rated_torque_nm, lost_motion_fraction=self.lost_motion_fraction,
            rigidity_regions=tuple(RigidityRegion(*r) for r in self.rigidity))


@dataclass(frozen=True)
class SweepStep:
    """TE at every combination of speeds and loads in one direction (a table)."""

    name: str
    speeds_rpm: tuple[float, ...]
    loads_nm: tuple[float, ...] = (0.0,)
    direction: str = 'ccw'
    revolutions: int = 1
    settle_s: float = 0.5
    time_ranges_s: tuple[tuple[float, float], ...] = ()
    kind: str = 'sweep'


@dataclass(frozen=True)
class OperatorStep:
    """Wait for the operator (mount the unit, lock the input shaft); measures nothing."""

    name: str
    instruction: str
    timeout_s: float = 600.0
    kind: str = 'operator'


Step = (TeStep | HysteresisStep | SweepStep | OperatorStep | EfficiencyStep | NoLoadStep
        | StartingTorqueStep | BackDrivingStep | TemperatureRiseStep | LifeStep)


@dataclass(frozen=True)
class PlanSafety:
    """The plan's safety limits for a real bench (SI-ish units as named; NaN: not given)."""

    max_input_speed_rpm: float = math.nan
    max_output_torque_nm: float = math.nan
    stale_joint_state_s: float = 1.0
    reach_timeout_s: float = 10.0


class PlanPlain(TypedDict):
    """:meth:`TestPlan.to_plain`: the plan as validated (safety NaN -> None; each step its
    fields, which depend on its kind)."""

    plan: str
    description: str
    tolerance: str
    safety: dict[str, float | None]
    steps: list[dict[str, Any]]


@dataclass(frozen=True)
class TestPlan:
    """A validated plan."""

    __test__ = False   # not a pytest class

    name: str
    steps: tuple[Step, ...]
    description: str = ''
    tolerance: str = ''
    safety: PlanSafety = field(default_factory=PlanSafety)
    origin: str = field(default='<plan>', compare=False)

    def to_plain(self) -> PlanPlain:
        """The plan as validated (SI units), for records."""
        return {'plan': self.name, 'description': self.description,
                'tolerance': self.tolerance,
                'safety': {k: (None if isinstance(v, float) and math.isnan(v) else v)
                           for k, v in asdict(self.safety).items()},
                'steps': [{k: (list(v) if isinstance(v, tuple) else v)
                           for k, v in asdict(s).items()} for s in self.steps]}


def _te_step(f: Fields, name: str) -> TeStep:
    dirs = f.data.pop('directions', ['ccw', 'cw'])
    if not isinstance(dirs, list) or not dirs or len(set(map(str, dirs))) != len(dirs) or \
            not all(d in DIRECTIONS for d in dirs):
        f.fail('directions', f'must be a list of distinct directions from {list(DIRECTIONS)}',
               dirs)
    ranges = f.data.pop('time_ranges_s', {})
    if not isinstance(ranges, dict) or not set(map(str, ranges)) <= set(dirs):
        f.fail('time_ranges_s', f'must map directions of the step ({", ".join(dirs)}) to '
               '[start, end] in seconds', ranges)
    spans = tuple((str(d), *f.span(f'time_ranges_s.{d}', r)) for d, r in ranges.items())
    return TeStep(name=name,
                  speed_rpm=f.num('speed_rpm', lo=0.0, lo_open=True, hi=MAX_SPEED_RPM),
                  load_nm=f.num('load_nm', 0.0, lo=0.0, hi=MAX_TORQUE_NM),
                  directions=tuple(dirs),
                  revolutions=f.integer('revolutions', 1, lo=1, hi=MAX_REVOLUTIONS),
                  settle_s=f.num('settle_s', 0.5, lo=0.0, hi=MAX_SETTLE_S), time_ranges_s=spans)


def _hysteresis_step(f: Fields, name: str) -> HysteresisStep:
    rig = f.data.pop('rigidity', {'K': [0.5, 1.0]})
    if not isinstance(rig, dict) or not rig:
        f.fail('rigidity', 'must map region names to [lo, hi] fractions of the rated torque',
               rig)
    regions = []
    for rname, span in rig.items():
        if not isinstance(span, list) or len(span) != 2:
            f.fail(f'rigidity.{rname}', 'must be [lo, hi] (fractions of the rated torque)',
                   span)
        regions.append((str(rname), *span))
    step = HysteresisStep(
        name=name, rated_torque_nm=f.num('rated_torque_nm', lo=0.0, lo_open=True,
                                         hi=MAX_TORQUE_NM),
        method=f.text('method', 'torque_steps', choices=('torque_steps', 'constant_speed')),
        step_fraction=f.num('step_fraction', 0.1, lo=0.0, lo_open=True, hi=0.5),
        dwell_s=f.num('dwell_s', 0.2, lo=0.0, lo_open=True, hi=60.0),
        output_speed_rad_s=f.num('output_speed_rad_s', 2.0e-4, lo=0.0, lo_open=True, hi=0.1),
        lost_motion_fraction=f.num('lost_motion_fraction', 0.03, lo=0.0, lo_open=True, hi=0.5),
        rigidity=tuple(regions), preload=f.flag('preload', True),
        positions=f.integer('positions', 1, lo=1),
        reposition_speed_rpm=f.num('reposition_speed_rpm', 300.0, lo=0.0, lo_open=True,
                                   hi=MAX_SPEED_RPM))
    step = dataclasses.replace(step, time_ranges_s=f.spans('time_ranges_s', step.positions,
                                                           'position'))
    if step.positions > 36:
        f.fail('positions', 'must be <= 36', step.positions)
    try:
        step.config()
    except TeConfigError as exc:
        f.fail('rigidity', str(exc))
    return step


def _sweep_step(f: Fields, name: str) -> SweepStep:
    step = SweepStep(name=name,
                     speeds_rpm=f.numbers('speeds_rpm', lo=0.0, hi=MAX_SPEED_RPM, nonzero=True),
                     loads_nm=f.numbers('loads_nm', [0.0], lo=0.0, hi=MAX_TORQUE_NM),
                     direction=f.text('direction', 'ccw', choices=tuple(DIRECTIONS)),
                     revolutions=f.integer('revolutions', 1, lo=1, hi=MAX_REVOLUTIONS),
                     settle_s=f.num('settle_s', 0.5, lo=0.0, hi=MAX_SETTLE_S))
    n = len(step.speeds_rpm) * len(step.loads_nm)
    return dataclasses.replace(step, time_ranges_s=f.spans(
        'time_ranges_s', n, 'sweep point (speeds x loads)'))


def _operator_step(f: Fields, name: str) -> OperatorStep:
    text = f.text('instruction')
    if len(text) > 500:
        f.fail('instruction', 'must be at most 500 characters', text[:40] + '...')
    return OperatorStep(name=name, instruction=text,
                        timeout_s=f.num('timeout_s', 600.0, lo=0.0, lo_open=True, hi=86400.0))


#: Step kind -> parser. A new kind (issue 38) adds its dataclass and parser here, its
#: program to runner.PROGRAMS, its result to _results.RESULTS and how recorded data is cut
#: for it to recorded.FINDERS (tests/acceptance/test_kinds.py checks they agree).
_KINDS: dict[str, Callable[[Fields, str], Step]] = {
    'te': _te_step, 'hysteresis': _hysteresis_step, 'sweep': _sweep_step,
    'operator': _operator_step, **LOSS_KINDS}
STEP_KINDS = tuple(_KINDS)


def _safety(top: Fields) -> PlanSafety:
    raw = top.data.pop('safety', {})
    f = Fields(raw if raw is not None else {}, f'{top.where}: safety')
    out = PlanSafety(
        max_input_speed_rpm=f.num('max_input_speed_rpm', math.inf, lo=0.0, lo_open=True)
        if 'max_input_speed_rpm' in f.data else math.nan,
        max_output_torque_nm=f.num('max_output_torque_nm', math.inf, lo=0.0, lo_open=True)
        if 'max_output_torque_nm' in f.data else math.nan,
        stale_joint_state_s=f.num('stale_joint_state_s', 1.0, lo=0.0, lo_open=True, hi=3600.0),
        reach_timeout_s=f.num('reach_timeout_s', 10.0, lo=0.0, lo_open=True, hi=3600.0))
    f.done()
    return out


def parse_plan(data: Any, origin: str = '<plan>') -> TestPlan:
    """Validate a plan mapping (parsed YAML).

    Raises:
        PlanError: Anything wrong, named (file, step, key, rule, value).
    """
    if isinstance(data, dict) and 'plan' not in data and 'steps' not in data:
        msg = (f'{origin}: is not a test plan (it has neither a "plan" nor a "steps" key; '
               'nothing of it is shown)')
        raise PlanError(msg)
    top = Fields(data, origin)
    name = top.text('plan')
    from rv_te_bench.store.records import FIELD_MAX_CHARS
    if len(name) > FIELD_MAX_CHARS['plan']:   # the results store keeps 128 (issue #21)
        top.fail('plan', f'is {len(name)} characters, the results store keeps at most '
                 f"{FIELD_MAX_CHARS['plan']}", name[:40] + '...')
    description = str(top.data.pop('description', '') or '')
    tolerance = top.text('tolerance', '')if 'tolerance' in top.data else ''
    safety = _safety(top)
    steps_raw = top.data.pop('steps', None)
    top.done()
    if not isinstance(steps_raw, list) or not steps_raw or len(steps_raw) > _MAX_STEPS:
        top.fail('steps', f'must be a list of 1..{_MAX_STEPS} steps', steps_raw)
    steps: list[Step] = []
    names: set[str] = set()
    for j, raw in enumerate(steps_raw):
        f = Fields(raw, f'{origin}: step {j}')
        kind = f.text('kind', choices=tuple(_KINDS))
        sname = f.text('name', f'{kind}-{j}')
        if sname in names:
            f.fail('name', 'must be unique in the plan', sname)
        names.add(sname)
        f.where = f'{origin}: step {j} ({sname!r})'
        steps.append(_KINDS[kind](f, sname))
        f.done()
    return TestPlan(name=name, steps=tuple(steps), description=description,
                    tolerance=tolerance, safety=safety, origin=origin)


def shipped_plans() -> list[str]:
    """Names of the plans shipped in ``rv_te_bench/acceptance/plans``."""
    return shipped('plans')


def load_plan(name_or_path: str | Path) -> tuple[TestPlan, str]:
    """Load a plan file (or a shipped plan by name); returns it and its text.

    Raises:
        PlanError: Missing or unreadable file, bad YAML, invalid plan.
    """
    text, origin = read_source(name_or_path, folder='plans', what='test plan', error=PlanError)
    return parse_plan(parse_yaml_text(text, origin, PlanError), origin), text
