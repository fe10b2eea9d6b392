"""Running a plan step by step: bench programs out, encoder data in, metrics and verdicts.

No ROS here: the ``test_sequencer`` node drives each step's program through a bench's
setpoints (:mod:`rv_te_bench.acceptance.driver`; a plan with whole-reducer steps: sends it
to the simulated bench's ``bench/run_program``) and feeds :class:`StepRunner` from
``bench/encoders``; :func:`run_plan_offline` feeds it straight
from :class:`sim.program.ProgramSimulator` (same numbers, no middleware).

Programs per step (SI units; docs/ACCEPTANCE.md):

* ``te``: one drive segment per direction, ``settle_s`` plus the whole output revolutions
  (plus 2 % and two samples), against the load with the sign that resists the motion; the
  first ``settle_s`` of each segment is not analysed.
* ``sweep``: one drive segment per (speed, load), in the step's direction.
* ``hysteresis``: with ``preload`` first 0 -> -T_R -> 0 (so that the first loading starts on
  a known flank; not analysed), then 0 -> +T_R -> 0 -> -T_R -> 0: equal torque steps of
  ``step_fraction`` T_R held ``dwell_s`` each, plus every torque the metrics read
  (+-lost-motion torque, the rigidity points), or constant-speed loading at
  ``output_speed_rad_s`` between the torque limits.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.acceptance._results import step_result
from rv_te_bench.acceptance._segments import SegmentData
from rv_te_bench.acceptance.loss_steps import LOSS_PROGRAMS
from rv_te_bench.acceptance.plan import (
    DIRECTIONS,
    HysteresisStep,
    OperatorStep,
    SweepStep,
    TeStep,
)
from rv_te_bench.acceptance.tolerance import evaluate
from rv_te_bench.core.te import output_phase_and_te
from rv_te_bench.errors import AcceptanceError
from sim.errors import ModelInputError
from sim.program import program_from_plain

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.acceptance.plan import Step, TestPlan
    from rv_te_bench.acceptance.tolerance import Measured, MetricVerdictJson, ToleranceProfile
    from rv_te_bench.core.bench_uncertainty import BenchUncertainty
    from sim.bench import BenchBlock
    from sim.bench_info import BenchInfoData
    from sim.program import ProgramSimulator

__all__ = ['PROGRAMS', 'SEGMENT_DECIDED', 'StepRunner', 'build_report', 'reanalyse',
           'run_plan_offline', 'running_verdicts']


def _fin(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass(eq=False)
class _Segment:
    plain: dict[str, Any]
    role: str                     # 'te' | 'sweep' | 'preload' | 'cycle'
    label: dict[str, Any] = field(default_factory=dict)
    chunks: list[tuple[np.ndarray, ...]] = field(default_factory=list)
    extra: list[tuple[np.ndarray, ...]] = field(default_factory=list)
    samples: int = 0
    blocks: int = 0
    expected_blocks: int = -1      # from the bench's answer; -1: not known


class StepRunner:
    """One step: its bench program, the data of its segments, its metrics.

    Args:
        step: The plan step.
        info: The bench's record (its ``BenchInfo``).
        uncertainty: The bench's error model for the metrics' budgets (default: the
            data-sheet values of the BenchInfo encoder models).
    """

    def __init__(self, step: Step, info: BenchInfoData, *,
                 uncertainty: BenchUncertainty | None = None) -> None:
        """Build the step's program."""
        self.step = step
        self.info = info
        self.uncertainty = uncertainty
        self.segments: list[_Segment] = []
        self.live_name = 'te_pp_rad'
        self._live = (math.inf, -math.inf)
        self._notes: dict[int, str] = {}
        PROGRAMS[step.kind](self, step)

    # -- programs -----------------------------------------------------------------------------
    def add_segment(self, plain: dict[str, Any], role: str, label: dict[str, Any]) -> None:
        """Append a bench segment (``sim.program`` plain form) with its role and label."""
        self.segments.append(_Segment(plain, role, dict(label)))

    def add_drive(self, speed_rpm: float, load_nm: float, sign: int, revs: int,
                  settle_s: float, role: str, label: dict[str, Any]) -> None:
        """A drive segment of ``settle_s`` plus ``revs`` whole output revolutions (+2 %)."""
        self._drive(speed_rpm, load_nm, sign, revs, settle_s, role, label)

    def _drive(self, speed_rpm: float, load_nm: float, sign: int, revs: int, settle_s: float,
               role: str, label: dict[str, Any]) -> None:
        rev_s = self.info.gear_ratio * 60.0 / speed_rpm
        duration = settle_s + revs * rev_s * 1.02 + 2.0 / self.info.sample_rate_hz
        self.segments.append(_Segment(
            {'kind': 'drive', 'speed_rpm': sign * speed_rpm, 'duration_s': duration,
             'load_nm': sign * load_nm}, role, {**label, 'settle_s': settle_s}))

    def _hysteresis(self, step: HysteresisStep) -> None:
        for pos in range(step.positions):
            if pos > 0:   # turn the output on by 1/positions of a revolution, then lock
                # in whole blocks (the bench's unit of time): the speed is lowered a little
                block_s = self.info.block_size / self.info.sample_rate_hz
                move_s = self.info.gear_ratio * 60.0 / step.reposition_speed_rpm / step.positions
                duration = math.ceil(move_s / block_s - 1e-9) * block_s
                self.segments.append(_Segment(
                    {'kind': 'drive', 'speed_rpm': step.reposition_speed_rpm * move_s / duration,
                     'duration_s': duration}, 'reposition', {'position': pos}))
            self._cycle(step, pos)

    def _cycle(self, step: HysteresisStep, pos: int) -> None:
        tr = step.rated_torque_nm
        label = {'position': pos}
        if step.method == 'torque_steps':
            cfg = step.config()
            n = round(1.0 / step.step_fraction)
            fr = sorted({round(k / n, 12) for k in range(n + 1)}
                        | {round(abs(p) / tr, 12) for p in cfg.torque_points_nm()})
            up = [f * tr for f in fr]
            if step.preload:
                for t in [-0.5 * tr, -tr, -0.5 * tr, 0.0]:
                    self._torque(t, step.dwell_s, 'preload', label)
            seq = up + up[-2::-1] + [-t for t in up[1:]] + [-t for t in up[-2::-1]]
            for t in seq:
                self._torque(t, step.dwell_s, 'cycle', label)
        else:
            w = step.output_speed_rad_s
            moves = ((-1, -tr, 'preload'), (1, 0.0, 'preload')) if step.preload else ()
            for sign, target, role in (*moves, (1, tr, 'cycle'), (-1, -tr, 'cycle'),
                                       (1, 0.0, 'cycle')):
                self.segments.append(_Segment({'kind': 'output_speed', 'speed_rad_s': sign * w,
                                               'target_torque_nm': target}, role, dict(label)))

    def _torque(self, t: float, dwell: float, role: str, label: dict[str, Any]) -> None:
        self.segments.append(_Segment({'kind': 'torque', 'torque_nm': t, 'duration_s': dwell},
                                      role, dict(label)))

    def program(self) -> list[dict[str, Any]]:
        """The bench program (plain segments, for ``sim.program.program_from_plain``)."""
        return [s.plain for s in self.segments]

    def expect(self, segment_blocks: list[int] | tuple[int, ...]) -> None:
        """The blocks the bench will send per segment (a segment short of them is reported
        incomplete and its metrics not measured, rather than read across the hole)."""
        if len(segment_blocks) != len(self.segments):
            msg = (f'the bench planned {len(segment_blocks)} segments for a program of '
                   f'{len(self.segments)}')
            raise AcceptanceError(msg)
        for seg, n in zip(self.segments, segment_blocks, strict=True):
            seg.expected_blocks = int(n)

    def _incomplete(self, segs: list[_Segment]) -> str:
        bad = [(i, s) for i, s in enumerate(self.segments) if s in segs
               and s.expected_blocks >= 0 and s.blocks < s.expected_blocks]
        if not bad:
            return ''
        missing = sum(s.expected_blocks - s.blocks for _, s in bad)
        return (f'{missing} block(s) of {len(bad)} segment(s) missing (first: segment '
                f'{bad[0][0]}); not analysed')

    # -- data -----------------------------------------------------------------------------------
    def feed(self, segment: int, theta_in_rad: np.ndarray, theta_out_rad: np.ndarray,
             torque_out_nm: np.ndarray, torque_in_nm: np.ndarray | None = None,
             temp_case_degc: np.ndarray | None = None) -> float:
        """Take one block of segment ``segment``; return the live metric (SI). The input
        torque and case temperature (None: the bench has no such channel) are kept for
        the steps that need them."""
        seg = self.segments[segment]
        arrays = tuple(np.asarray(a, dtype=np.float64) for a in
                       (theta_in_rad, theta_out_rad, torque_out_nm))
        seg.chunks.append(arrays)
        seg.extra.append(tuple(np.zeros(0) if a is None else np.asarray(a, dtype=np.float64)
                               for a in (torque_in_nm, temp_case_degc)))
        seg.samples += arrays[0].size
        seg.blocks += 1
        if self.live_name == 'torque_nm':
            return float(-arrays[2][-1]) if arrays[2].size else math.nan
        settle = round(seg.label.get('settle_s', 0.0) * self.info.sample_rate_hz)
        skip = max(0, settle - (seg.samples - arrays[0].size))
        if skip < arrays[0].size:
            _, te = output_phase_and_te(arrays[0][skip:], arrays[1][skip:],
                                        gear_ratio=self.info.gear_ratio, check=False)
            lo, hi = self._live
            self._live = (min(lo, float(te.min())), max(hi, float(te.max())))
        lo, hi = self._live
        return hi - lo if hi >= lo else math.nan

    def next_segment(self) -> None:
        """The live value restarts (a new direction or sweep point)."""
        self._live = (math.inf, -math.inf)

    def _cat(self, seg: _Segment) -> tuple[np.ndarray, ...]:
        if not seg.chunks:
            return (np.zeros(0),) * 3
        return tuple(np.concatenate([c[j] for c in seg.chunks]) for j in range(3))

    # -- results ----------------------------------------------------------------------------------
    def segment_data(self) -> list[SegmentData]:
        """The data of every segment, with a note where blocks are missing."""
        return [self._segment_data(i) for i in range(len(self.segments))]

    def _segment_data(self, i: int) -> SegmentData:
        seg = self.segments[i]
        th_in, th_out, torque = self._cat(seg)
        t_in, temp = ((np.concatenate([e[0] for e in seg.extra]),
                       np.concatenate([e[1] for e in seg.extra])) if seg.extra
                      else (np.zeros(0), np.zeros(0)))
        return SegmentData(role=seg.role, label=seg.label, theta_in_rad=th_in,
                           theta_out_rad=th_out, torque_out_nm=torque,
                           torque_in_nm=t_in, temp_case_degc=temp,
                           note=self._notes.get(i) or self._incomplete([seg]))

    def segment_metrics(self, i: int) -> list[Measured]:
        """The metrics segment ``i`` decides once it is complete: a TE step's direction or
        a sweep point is its own segment (the same value :meth:`result` gives it); a
        hysteresis step's metrics need its whole cycle, so they come with :meth:`result`."""
        if self.step.kind not in SEGMENT_DECIDED:
            return []
        return step_result(self.step, self.info, [self._segment_data(i)])[0]

    def mark(self, segment: int, note: str) -> None:
        """Segment ``segment`` cannot be analysed, for the reason ``note`` (data lost)."""
        self._notes.setdefault(segment, note)

    def result(self) -> tuple[list[Measured], dict[str, Any]]:
        """Metrics (SI) and the details the report shows."""
        return step_result(self.step, self.info, self.segment_data(), self.uncertainty)


def _te_program(r: StepRunner, step: TeStep) -> None:
    for d in step.directions:
        r.add_drive(step.speed_rpm, step.load_nm, DIRECTIONS[d], step.revolutions,
                    step.settle_s, 'te', {'direction': d, 'speed_rpm': step.speed_rpm,
                                          'load_nm': step.load_nm})


def _sweep_program(r: StepRunner, step: SweepStep) -> None:
    for s in step.speeds_rpm:
        for load in step.loads_nm:
            r.add_drive(s, load, DIRECTIONS[step.direction], step.revolutions, step.settle_s,
                        'sweep', {'direction': step.direction, 'speed_rpm': s,
                                  'load_nm': load})


def _hysteresis_program(r: StepRunner, step: HysteresisStep) -> None:
    r.live_name = 'torque_nm'
    r._hysteresis(step)


def _operator_program(r: StepRunner, _step: OperatorStep) -> None:
    r.live_name = 'waiting_s'   # no bench program: the sequencer waits for the operator


#: Step kinds whose segments each decide their own metric (a direction, a sweep point).
SEGMENT_DECIDED = frozenset({'te', 'sweep'})


def running_verdicts(measured: list[Measured], profile: ToleranceProfile,
                     ) -> tuple[list[MetricVerdictJson], str]:
    """The metrics decided so far against their limits, while a test runs.

    Returns the rows (as the final report's ``metrics``; a limit not measured yet is
    'pending') and what is decided of the unit's verdict: 'fail' as soon as a metric is out
    of its limit (later steps cannot undo it), else 'running'. Sweep points are not
    judged (as in :func:`build_report`).
    """
    verdicts, _, _ = evaluate([m for m in measured if not m.name.startswith('sweep:')],
                              profile)
    rows = [v.to_json_dict() for v in verdicts]
    for r in rows:
        if r['verdict'] == 'not_measured':
            r['verdict'] = 'pending'
    return rows, 'fail' if any(r['verdict'] == 'fail' for r in rows) else 'running'


#: Step kind -> the builder of its bench program (see plan._KINDS for a new kind). The step
#: is Any: each builder takes the step class of its key's kind, which the table cannot say.
PROGRAMS: dict[str, Callable[[StepRunner, Any], None]] = {
    'te': _te_program, 'sweep': _sweep_program, 'hysteresis': _hysteresis_program,
    'operator': _operator_program, **LOSS_PROGRAMS}


def build_report(*, plan: TestPlan, profile: ToleranceProfile, info: BenchInfoData,
                 serial: str, operator: str, results: list[tuple[list[Measured], dict[str, Any]]],
                 conditions: dict[str, Any] | None = None, started_utc: str = '',
                 status: str = 'completed', why: str = '') -> dict[str, Any]:
    """The unit's record: identity, bench, conditions, verdicts, per-step details (SI).

    ``status`` other than 'completed' (cancelled, aborted, error) makes the verdict that
    status; ``why`` (the abort's reason) is added to its reason.
    """
    measured = [m for res in results for m in res[0] if not m.name.startswith('sweep:')]
    verdicts, verdict, reason = evaluate(measured, profile)
    if status != 'completed':
        verdict, reason = status, f'{status} after {len(results)} of {len(plan.steps)} steps'
        if why:
            reason += f': {why}'
    steps = []
    for step, (ms, details) in zip(plan.steps, results, strict=False):
        steps.append({'name': step.name, 'kind': step.kind,
                      'metrics': [{'name': m.name, 'unit': m.unit, 'value': _fin(m.value),
                                   'u95': _fin(m.u95)} for m in ms], **details})
    return {
        'unit': {'serial': serial, 'operator': operator,
                 'date_utc': started_utc or dt.datetime.now(dt.UTC).isoformat(timespec='seconds')},
        'bench': {'bench_id': info.bench_id, 'preset': info.preset, 'gear_ratio': info.gear_ratio,
                  'sample_rate_hz': info.sample_rate_hz, 'encoder_in': info.encoder_in_model,
                  'encoder_out': info.encoder_out_model,
                  'encoder_out_resolution_rad': info.encoder_out_resolution_rad,
                  'reducer_type': info.reducer_type, 'crank_per_input': info.crank_per_input,
                  'mesh_orders': list(info.mesh_orders), 'mesh_labels': list(info.mesh_labels),
                  'encoder_in_scale_serial': info.encoder_in_scale_serial,
                  'encoder_out_scale_serial': info.encoder_out_scale_serial},
        'conditions': dict(conditions or {}),
        'plan': plan.to_plain(), 'tolerance': profile.to_plain(),
        'verdict': verdict, 'reason': reason,
        'metrics': [v.to_json_dict() for v in verdicts],
        'steps': steps,
    }


def run_plan_offline(plan: TestPlan, profile: ToleranceProfile, *, serial: str, operator: str,
                     sim: ProgramSimulator, info: BenchInfoData | None = None,
                     conditions: dict[str, Any] | None = None,
                     on_feedback: Callable[[int, str, float, str, float], None] | None = None,
                     on_block: Callable[[BenchBlock], None] | None = None,
                     uncertainty: BenchUncertainty | None = None,
                     ) -> dict[str, Any]:
    """Run every step on a :class:`sim.program.ProgramSimulator` (no ROS) and report.

    Args:
        plan, profile: The validated plan and tolerance profile.
        serial, operator: Unit identity.
        sim: The simulated bench.
        info: Its record (ratio, rate, lines); None: ``sim.info``.
        conditions: Extra test conditions for the record.
        on_feedback: Called per block with (step index, step name, step progress, live
            metric name, live value).
        on_block: Called with every block the bench produced (a recording of the run).
        uncertainty: The bench's error model (default: the data sheets of its encoders).

    Raises:
        AcceptanceError: A step's program is refused by the bench.
    """
    started = dt.datetime.now(dt.UTC).isoformat(timespec='seconds')
    info = sim.info if info is None else info
    results = []
    for j, step in enumerate(plan.steps):
        runner = StepRunner(step, info, uncertainty=uncertainty)
        if not runner.program():          # an operator step: nobody to wait for offline
            measured, details = runner.result()
            results.append((measured, {**details, 'acknowledged': 'not needed (offline)'}))
            continue
        try:
            total = sim.load(program_from_plain(runner.program()))
        except ModelInputError as exc:
            msg = f'step {step.name!r}: the bench refused its program: {exc}'
            raise AcceptanceError(msg) from None
        runner.expect(sim.segment_blocks)
        done, last_seg = 0, 0
        while sim.running:
            block, seg = sim.next_block()
            if on_block is not None:
                on_block(block)
            if seg != last_seg:
                runner.next_segment()
                last_seg = seg
            live = runner.feed(seg, block.theta_in_rad, block.theta_out_rad, block.torque_out_nm,
                               block.torque_in_nm, block.temp_case_degc)
            done += 1
            if on_feedback is not None:
                on_feedback(j, step.name, done / total, runner.live_name, live)
        results.append(runner.result())
    return build_report(plan=plan, profile=profile, info=info, serial=serial, operator=operator,
                        results=results, conditions=conditions, started_utc=started)


def reanalyse(*, plan: TestPlan, profile: ToleranceProfile, info: BenchInfoData,
              steps: list[dict[str, Any]],
              blocks: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray,
                                      np.ndarray | None, np.ndarray | None]],
              serial: str, operator: str, conditions: dict[str, Any] | None = None,
              started_utc: str = '', status: str = 'completed',
              times: dict[int, np.ndarray] | None = None,
              uncertainty: BenchUncertainty | None = None) -> dict[str, Any]:
    """The unit record computed again from recorded blocks (a session bag).

    Args:
        plan, profile, info: As in the live run.
        steps: The recorded steps (``step_index``, ``state``, ``first_seq``,
            ``segment_blocks``); only finished ones are analysed, in plan order.
        blocks: seq -> (theta_in_rad, theta_out_rad, torque_out_nm, torque_in_nm,
            temp_case_degc); the last two None where the bench had no such channel.
        serial, operator, conditions, started_utc: The unit's identity and conditions.
        times: seq -> sample times [s], for steps recorded with time ranges
            (``segments_s`` in their result: driven by setpoints).
        status: 'completed', or how the recorded test ended ('cancelled', 'error').
        uncertainty: The bench's error model (default: the data sheets of its encoders).

    Raises:
        AcceptanceError: The recorded steps do not follow the plan, or carry no segment
            block counts.
    """
    results = []
    for n, s in enumerate(x for x in steps if x['state'] == 'finished'):
        if s['step_index'] != n or n >= len(plan.steps):
            msg = (f'recorded step {s["step_index"]} ({s.get("step_name", "?")!r}) does not '
                   f'follow the plan (expected step {n})')
            raise AcceptanceError(msg)
        if plan.steps[n].kind == 'operator':
            results.append(StepRunner(plan.steps[n], info).result())
            continue
        runner = StepRunner(plan.steps[n], info, uncertainty=uncertainty)
        spans = _recorded_spans(s)
        if spans:     # driven by setpoints: each segment is a time range on the bench clock
            _feed_by_time(runner, s, spans, blocks, times or {})
            results.append(runner.result())
            continue
        if not s['segment_blocks']:
            msg = (f'recorded step {n} has no segment block counts nor time ranges (recorded '
                   'before they were recorded): it cannot be analysed again')
            raise AcceptanceError(msg)
        runner.expect(s['segment_blocks'])
        ends = np.cumsum(s['segment_blocks'])
        last = -1
        for k in range(int(ends[-1])):
            block = blocks.get(int(s['first_seq']) + k)
            if block is None:
                continue
            seg = int(np.searchsorted(ends, k, side='right'))
            if seg != last:
                runner.next_segment()
                last = seg
            runner.feed(seg, *block)
        results.append(runner.result())
    return build_report(plan=plan, profile=profile, info=info, serial=serial, operator=operator,
                        results=results, conditions=conditions, started_utc=started_utc,
                        status=status)


def _recorded_spans(step: dict[str, Any]) -> list[tuple[float, float]]:
    """The segments' time ranges a setpoint-driven step recorded (empty: none)."""
    import yaml

    try:
        res = yaml.safe_load(step.get('result_yaml') or '') or {}
    except yaml.YAMLError:
        return []
    spans = res.get('segments_s') if isinstance(res, dict) else None
    if not isinstance(spans, list):
        return []
    return [(float(a), float(b)) for a, b in spans]


def _feed_by_time(runner: StepRunner, step: dict[str, Any], spans: list[tuple[float, float]],
                  blocks: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray,
                                          np.ndarray | None, np.ndarray | None]],
                  times: dict[int, np.ndarray]) -> None:
    """The step's blocks cut into its segments by their recorded time ranges, as live.

    A block of the step missing from the bag leaves a hole from the last sample before it
    to the first sample after it (the step's start and end where there is none): every
    segment whose time range reaches into that hole is marked, and so not measured across
    it; a hole between two segments (the bench moving to the next setpoint) costs none."""
    lo = np.array([a for a, _ in spans])
    hi = np.array([b for _, b in spans])
    last = -1
    prev_end = -math.inf
    missing: int | None = None     # the first missing block of the hole not yet marked
    for seq in range(int(step['first_seq']), int(step['last_seq']) + 1):
        block, t = blocks.get(seq), times.get(seq)
        if block is None or t is None:
            missing = seq if missing is None else missing
            continue
        if missing is not None:
            _mark_hole(runner, lo, hi, prev_end, float(t[0]), missing)
            missing = None
        prev_end = float(t[-1])
        for i in np.flatnonzero((hi >= t[0]) & (lo <= t[-1])):
            keep = (t >= lo[i]) & (t <= hi[i])
            if not keep.any():
                continue
            if i != last:
                runner.next_segment()
                last = int(i)
            tq = block[2][keep] if block[2].size else block[2]
            extra = [None if x is None or np.asarray(x).size != t.size else np.asarray(x)[keep]
                     for x in (block[3] if len(block) > 3 else None,
                               block[4] if len(block) > 4 else None)]
            runner.feed(int(i), block[0][keep], block[1][keep], tq, *extra)
    if missing is not None:
        _mark_hole(runner, lo, hi, prev_end, math.inf, missing)


def _mark_hole(runner: StepRunner, lo: np.ndarray, hi: np.ndarray, after_s: float,
               before_s: float, seq: int) -> None:
    """Mark the segments reaching into the hole between ``after_s`` and ``before_s``."""
    for i in np.flatnonzero((hi > after_s) & (lo < before_s)):
        runner.mark(int(i), f'block {seq} of the step is not in the bag')

