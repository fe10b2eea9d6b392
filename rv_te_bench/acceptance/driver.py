"""Driving a step's bench program through setpoints, as a ros2_control bench takes them.

A step's program (:meth:`~rv_te_bench.acceptance.runner.StepRunner.program`: drive,
torque and constant-speed segments) becomes setpoints of two forward command controllers,
the drive joint's velocity and the load joint's effort or position
(:class:`Setpoint`), and the samples read back are cut into the segments' data. Nothing
here knows ROS: the ``test_sequencer`` node publishes the setpoints and feeds the blocks
read back (through ``joint_states`` and the JointState adapter), a test feeds
:class:`sim.commanded.CommandedBench` directly, and both run the same code.

Each segment starts with its setpoint and waits until the bench *has reached* it (the
input speed within ``speed_tolerance`` of a drive's, the input stopped and the torque
within ``torque_tolerance_nm`` of a held one, each over the whole ``window_s``: the mean
of the window and the means of both its halves, so that a speed or torque passing through
the target - a stop from a higher speed averaged with the standstill after it - is not
taken for reached), then runs for its duration counted on the
samples' own clock; the samples in between are the transition, in no segment's data. A
constant-speed segment moves the load joint's position setpoint at the segment's speed from
where the output stands until the torque read back reaches its target, then holds the
position for ``hold_s``.

Safety, on every sample read back: the input speed (from consecutive input angles) and the
torque applied to the output against :class:`SafetyLimits`; a setpoint not reached within
``reach_timeout_s``. Any of these ends the step with its reason (:attr:`Update.abort`) and
the zero setpoint (drive stopped, load effort 0). Staleness (no sample for a while) and
operator interrupts are the caller's, on its own clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import AcceptanceError

if TYPE_CHECKING:
    import numpy.typing as npt

    from rv_te_bench.acceptance.plan import TestPlan

__all__ = ['ZERO', 'DriverSettings', 'ProgramDriver', 'SafetyLimits', 'Setpoint', 'Update',
           'plan_limits']

RAD_S_PER_RPM = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class Setpoint:
    """What the two forward command controllers get (SI, joint senses).

    Attributes:
        drive_velocity_rad_s: Drive (input) joint velocity [rad/s].
        load_mode: ``'effort'`` or ``'position'``: which load controller gets ``load_value``.
        load_value: Load joint effort (torque applied to the output, positive twists it
            positively) [N m] or load joint position (output angle) [rad].
    """

    drive_velocity_rad_s: float
    load_mode: str
    load_value: float


#: Drive stopped, no load: what every end, abort and cancel commands.
ZERO = Setpoint(0.0, 'effort', 0.0)


@dataclass(frozen=True)
class SafetyLimits:
    """Limits checked on every sample read back (SI).

    Attributes:
        max_input_speed_rad_s: |input speed| allowed [rad/s] (> 0).
        max_output_torque_nm: |torque applied to the output| allowed [N m] (> 0).
        stale_timeout_s: No sample read back for this long (the caller's clock) aborts [s].
        speed_source, torque_source: Where each limit comes from, for the messages.
    """

    max_input_speed_rad_s: float
    max_output_torque_nm: float
    stale_timeout_s: float = 1.0
    speed_source: str = ''
    torque_source: str = ''

    def __post_init__(self) -> None:
        """Validate (AcceptanceError names the limit)."""
        for name in ('max_input_speed_rad_s', 'max_output_torque_nm', 'stale_timeout_s'):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (
                    math.isfinite(v) and v > 0):
                msg = f'safety limit {name} must be finite and > 0, got {v!r}'
                raise AcceptanceError(msg)

    def check(self, t_s: np.ndarray, theta_in_rad: np.ndarray, applied_nm: np.ndarray | None,
              previous: tuple[float, float] | None) -> str:
        """'' when every sample is within the limits, else the first breach in words.

        Args:
            t_s, theta_in_rad: Sample times and input angles of a block.
            applied_nm: Torque applied to the output per sample (None: no channel).
            previous: (time, input angle) of the sample before the block (None: the first).
        """
        if applied_nm is not None and applied_nm.size:
            over = np.flatnonzero(~(np.abs(applied_nm) <= self.max_output_torque_nm))
            if over.size:
                k = int(over[0])
                return (f'output torque {applied_nm[k]:+.6g} N m beyond the limit '
                        f'+-{self.max_output_torque_nm:.6g} N m ({self.torque_source}) at '
                        f'{t_s[k]:.4f} s')
        t, th = t_s, theta_in_rad
        if previous is not None:
            t, th = np.r_[previous[0], t], np.r_[previous[1], th]
        if t.size >= 2:
            dt = np.diff(t)
            speed = np.abs(np.diff(th)) / np.where(dt > 0, dt, np.inf)
            over = np.flatnonzero(~(speed <= self.max_input_speed_rad_s))
            if over.size:
                k = int(over[0])
                return (f'input speed {speed[k] / RAD_S_PER_RPM:.6g} rpm beyond the limit '
                        f'{self.max_input_speed_rad_s / RAD_S_PER_RPM:.6g} rpm '
                        f'({self.speed_source}) at {t[k + 1]:.4f} s')
        return ''


@dataclass(frozen=True)
class DriverSettings:
    """How setpoints are judged reached (SI).

    Attributes:
        speed_tolerance: A drive speed is reached within this fraction (> 0).
        lock_speed_rad_s: The input counts as stopped below this speed [rad/s].
        torque_tolerance_nm: A held torque is reached within this [N m] (> 0).
        window_s: Speeds and torques are averaged over this (and over each half of it)
            before comparing [s].
        reach_timeout_s: A setpoint not reached within this aborts the step [s].
    """

    speed_tolerance: float = 0.02
    lock_speed_rad_s: float = 0.01 * RAD_S_PER_RPM
    torque_tolerance_nm: float = 1.0
    window_s: float = 0.02
    reach_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        """Validate (AcceptanceError names the setting)."""
        for name in ('speed_tolerance', 'lock_speed_rad_s', 'torque_tolerance_nm', 'window_s',
                     'reach_timeout_s'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                msg = f'{name} must be finite and > 0, got {v!r}'
                raise AcceptanceError(msg)


@dataclass(frozen=True)
class Update:
    """What one block read back gives.

    Attributes:
        setpoint: A new setpoint to send now (None: keep the last one).
        parts: (segment index, start, stop) slices of the block that belong to segments.
        finished: The program is done (the zero setpoint is in ``setpoint``).
        abort: Why the step ends early ('' when it does not); ``setpoint`` is then ZERO.
    """

    setpoint: Setpoint | None = None
    parts: list[tuple[int, int, int]] = field(default_factory=list)
    finished: bool = False
    abort: str = ''


class ProgramDriver:
    """Runs one step's program through setpoints (see the module docstring).

    Args:
        program: The plain segments (``{'kind': 'drive', ...}``) of the step.
        limits: The safety limits.
        settings: Reach criteria.
        sample_rate_hz: The bench's sample rate [Hz] (windows in samples).

    Raises:
        AcceptanceError: A segment of an unknown kind.
    """

    def __init__(self, program: list[dict[str, Any]], *, limits: SafetyLimits,
                 settings: DriverSettings, sample_rate_hz: float) -> None:
        """Check the program; nothing is commanded before :meth:`start`."""
        for j, seg in enumerate(program):
            if seg.get('kind') not in ('drive', 'torque', 'output_speed'):
                msg = f'segment {j}: kind {seg.get("kind")!r} cannot be driven by setpoints'
                raise AcceptanceError(msg)
        self.program = program
        self.limits = limits
        self.settings = settings
        self.window = max(2, round(settings.window_s * sample_rate_hz))
        self.period_s = 1.0 / sample_rate_hz
        self.index = -1
        self.reached_at: float | None = None    # bench time the current segment started
        self.commanded_at: float | None = None  # bench time its setpoint was sent
        self.boundaries: list[tuple[float, float]] = []   # (start, end) per finished segment
        self._tail_t = np.zeros(0)
        self._tail_in = np.zeros(0)
        self._tail_out = np.zeros(0)
        self._tail_tq = np.zeros(0)
        self._position0 = math.nan
        self._hold_until: float | None = None
        self._done = False

    # -- setpoints --------------------------------------------------------------------------
    def _setpoint(self, seg: dict[str, Any], t: float | None) -> Setpoint:
        if seg['kind'] == 'drive':
            return Setpoint(seg['speed_rpm'] * RAD_S_PER_RPM, 'effort',
                            -float(seg.get('load_nm', 0.0)))
        if seg['kind'] == 'torque':
            return Setpoint(0.0, 'effort', float(seg['torque_nm']))
        # output speed: the position moves from where the output stands
        if t is None or self.reached_at is None or not math.isfinite(self._position0):
            return Setpoint(0.0, 'position', self._position0) if math.isfinite(
                self._position0) else Setpoint(0.0, 'effort', 0.0)
        return Setpoint(0.0, 'position', self._position0
                        + float(seg['speed_rad_s']) * (t - self.reached_at))

    def start(self) -> Setpoint:
        """The first segment's setpoint (sent by the caller now)."""
        self.index = 0
        return self._setpoint(self.program[0], None)

    @property
    def segment(self) -> dict[str, Any]:
        """The current segment."""
        return self.program[self.index]

    # -- read back ---------------------------------------------------------------------------
    def push(self, t_s: npt.ArrayLike, theta_in_rad: npt.ArrayLike, theta_out_rad: npt.ArrayLike,
             applied_nm: npt.ArrayLike | None) -> Update:
        """One block read back: safety, progress, the samples' segments, the next setpoint.

        Args:
            t_s: Sample times on the bench's clock [s].
            theta_in_rad, theta_out_rad: Encoder angles [rad].
            applied_nm: Torque applied to the output [N m] (None: no torque channel).
        """
        t = np.asarray(t_s, dtype=np.float64)
        th_in = np.asarray(theta_in_rad, dtype=np.float64)
        th_out = np.asarray(theta_out_rad, dtype=np.float64)
        tq = None if applied_nm is None else np.asarray(applied_nm, dtype=np.float64)
        if self._done or t.size == 0:
            return Update(finished=self._done)
        prev = (float(self._tail_t[-1]), float(self._tail_in[-1])) if self._tail_t.size \
            else None
        breach = self.limits.check(t, th_in, tq, prev)
        if breach:
            self._done = True
            return Update(setpoint=ZERO, abort=breach)
        if self.commanded_at is None:
            self.commanded_at = float(t[0])
        parts: list[tuple[int, int, int]] = []
        setpoint: Setpoint | None = None
        k = 0
        while k < t.size and not self._done:
            seg = self.segment
            if self.reached_at is None:
                r = self._reach(seg, t, th_in, th_out, tq, k)
                if r < 0:
                    since = float(t[0]) if self.commanded_at is None else self.commanded_at
                    waited = float(t[-1]) - since
                    if waited > self.settings.reach_timeout_s:
                        self._done = True
                        return Update(setpoint=ZERO, parts=parts, abort=self._not_reached(
                            seg, waited, t, th_in, tq))
                    break
                k = r
                self.reached_at = float(t[k])
                if seg['kind'] == 'output_speed':
                    self._position0 = float(th_out[k])
            end = self._segment_end(seg, t, tq, k)
            if end is None:                    # the segment goes on past this block
                parts.append((self.index, k, t.size))
                if seg['kind'] == 'output_speed':
                    setpoint = self._setpoint(seg, float(t[-1]))
                break
            if end > k:
                parts.append((self.index, k, end))
            # the segment's last sample: in this block, or (its end time fell between two
            # blocks) the previous block's last
            last_t = float(t[end - 1]) if end > 0 else float(self._tail_t[-1])
            self.boundaries.append((self.reached_at, last_t))
            k = end
            self.index += 1
            self.reached_at = None
            if self.index >= len(self.program):
                self._done = True
                setpoint = ZERO
                break
            self.commanded_at = float(t[min(k, t.size - 1)])
            nxt = self.segment
            if nxt['kind'] == 'output_speed':
                self._position0 = float(th_out[min(k, t.size - 1)])
            setpoint = self._setpoint(nxt, None)
        self._keep_tail(t, th_in, th_out, tq)
        return Update(setpoint=setpoint, parts=parts, finished=self._done)

    def _keep_tail(self, t: np.ndarray, th_in: np.ndarray, th_out: np.ndarray,
                   tq: np.ndarray | None) -> None:
        w = self.window
        self._tail_t = np.r_[self._tail_t, t][-w:]
        self._tail_in = np.r_[self._tail_in, th_in][-w:]
        self._tail_out = np.r_[self._tail_out, th_out][-w:]
        self._tail_tq = np.r_[self._tail_tq, tq if tq is not None else np.full(t.size, np.nan)
                              ][-w:]

    def _windowed(self, t: np.ndarray, x: np.ndarray, tail: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, int]:
        """(times, values) with the previous block's tail in front, and the tail's length."""
        n = min(tail.size, self._tail_t.size)
        return np.r_[self._tail_t[-n:] if n else np.zeros(0), t], \
            np.r_[tail[-n:] if n else np.zeros(0), x], n

    def _reach(self, seg: dict[str, Any], t: np.ndarray, th_in: np.ndarray,
               th_out: np.ndarray, tq: np.ndarray | None, k0: int) -> int:
        """Index of the first sample at or after k0 where the setpoint is reached, -1 if none
        in the block."""
        w = self.window
        tt, ww, n = self._windowed(t, th_in, self._tail_in)
        idx = np.arange(k0, t.size) + n          # positions in the extended arrays
        ok = idx >= w
        j = idx[ok]
        if j.size == 0:
            return -1
        # the window's mean speed and its halves' (a window across a change of speed has
        # a mean anywhere between the two speeds; its halves differ then)
        h = j - w // 2
        speeds = [(ww[b] - ww[a]) / (tt[b] - tt[a])
                  for a, b in ((j - w, j), (j - w, h), (h, j))]
        s = self.settings
        if seg['kind'] == 'drive':
            target = seg['speed_rpm'] * RAD_S_PER_RPM
            good = _all_near(speeds, target, s.speed_tolerance * abs(target))
            load = -float(seg.get('load_nm', 0.0))
            if tq is not None and load != 0.0:
                good &= self._torque_near(t, tq, j - n, load)
        else:
            good = _all_near(speeds, 0.0, s.lock_speed_rad_s)
            if seg['kind'] == 'torque':
                if tq is None:
                    return -1
                good &= self._torque_near(t, tq, j - n, float(seg['torque_nm']))
        hit = np.flatnonzero(good)
        return int(j[hit[0]] - n) if hit.size else -1

    def _torque_near(self, t: np.ndarray, tq: np.ndarray, k: np.ndarray,
                     target: float) -> np.ndarray:
        """Where the mean torque of the window ending at samples k, and of each of its
        halves, is within the tolerance of target."""
        w = self.window
        _, xx, n = self._windowed(t, tq, self._tail_tq)
        c = np.r_[0.0, np.cumsum(np.nan_to_num(xx))]
        j = k + n + 1                       # exclusive ends in the extended arrays
        lo = np.maximum(j - w, 0)
        mid = lo + np.maximum((j - lo) // 2, 1)   # the halves [lo, mid) and [mid, j)
        full = (c[j] - c[lo]) / (j - lo)
        second = np.where(j > mid, (c[j] - c[mid]) / np.maximum(j - mid, 1), full)
        means = [full, (c[mid] - c[lo]) / (mid - lo), second]
        return _all_near(means, target, self.settings.torque_tolerance_nm)

    def _segment_end(self, seg: dict[str, Any], t: np.ndarray, tq: np.ndarray | None,
                     k: int) -> int | None:
        """End (exclusive index) of the current segment within the block, None if later."""
        assert self.reached_at is not None
        if seg['kind'] != 'output_speed':
            end_t = self.reached_at + float(seg['duration_s'])
            past = np.flatnonzero(t[k:] >= end_t - 0.5 * self.period_s)
            return k + int(past[0]) if past.size else None
        if tq is None:
            return None
        direction = 1.0 if seg['speed_rad_s'] > 0 else -1.0
        target = float(seg['target_torque_nm'])
        if self._hold_until is None:
            hit = np.flatnonzero(direction * (tq[k:] - target) >= 0)
            if not hit.size:
                return None
            h = k + int(hit[0])
            self._hold_until = float(t[h]) + float(seg.get('hold_s', 0.0))
            k = h
        past = np.flatnonzero(t[k:] >= self._hold_until)
        if not past.size:
            return None
        self._hold_until = None
        return k + int(past[0]) + 1

    def _not_reached(self, seg: dict[str, Any], waited: float, t: np.ndarray,
                     th_in: np.ndarray, tq: np.ndarray | None) -> str:
        speed = float((th_in[-1] - th_in[0]) / max(t[-1] - t[0], 1e-12)) / RAD_S_PER_RPM \
            if t.size > 1 else math.nan
        now = f'input {speed:.4g} rpm' + (f', torque {float(np.mean(tq)):+.4g} N m'
                                          if tq is not None and tq.size else '')
        if seg['kind'] == 'drive':
            want = f'{seg["speed_rpm"]:g} rpm against {seg.get("load_nm", 0.0):g} N m'
        elif seg['kind'] == 'torque':
            want = f'{seg["torque_nm"]:g} N m with the input stopped'
        else:
            want = 'the input stopped'
        return (f'setpoint not reached within {self.settings.reach_timeout_s:g} s (segment '
                f'{self.index}: {want}; read back: {now}) after {waited:.3g} s')


def plan_limits(plan: TestPlan, *, bench_max_input_speed_rpm: float = math.nan,
                bench_max_output_torque_nm: float = math.nan, bench_origin: str = 'bench',
                margin: float = 1.25) -> SafetyLimits:
    """The safety limits of a plan on a bench: the smallest of the plan's ``safety``, the
    bench description's ``limits`` and ``margin`` x the largest speed and torque the plan
    commands.

    Raises:
        AcceptanceError: A step commands more than the plan's or the bench's limit (named),
            before anything moves.
    """
    from rv_te_bench.acceptance.plan import HysteresisStep, SweepStep, TeStep

    speed, torque, what_speed, what_torque = 0.0, 0.0, '', ''
    for st in plan.steps:
        cands: list[tuple[float, float]] = []
        if isinstance(st, TeStep):
            cands = [(st.speed_rpm, st.load_nm)]
        elif isinstance(st, SweepStep):
            cands = [(s, ld) for s in st.speeds_rpm for ld in st.loads_nm]
        elif isinstance(st, HysteresisStep):
            cands = [(st.reposition_speed_rpm if st.positions > 1 else 0.0,
                      st.rated_torque_nm)]
        elif st.kind != 'operator':   # whole-reducer steps: their speeds and loads
            from rv_te_bench.acceptance.preflight import step_speeds_rpm

            loads = [float(getattr(st, 'load_nm', 0.0)), *getattr(st, 'loads_nm', ())]
            cands = [(max(step_speeds_rpm(st), default=0.0), max(loads))]
        for s, t in cands:
            if s > speed:
                speed, what_speed = s, st.name
            if t > torque:
                torque, what_torque = t, st.name
    sources_s = [(margin * speed, f'{margin:g} x the plan\'s {speed:g} rpm')]
    sources_t = [(margin * torque, f'{margin:g} x the plan\'s {torque:g} N m')]
    for value, name, src in ((plan.safety.max_input_speed_rpm, 'speed', 'the plan\'s safety'),
                             (bench_max_input_speed_rpm, 'speed', bench_origin),
                             (plan.safety.max_output_torque_nm, 'torque', 'the plan\'s safety'),
                             (bench_max_output_torque_nm, 'torque', bench_origin)):
        if not math.isfinite(value):
            continue
        if name == 'speed':
            if speed > value:
                msg = (f'step {what_speed!r} commands {speed:g} rpm, above the limit '
                       f'{value:g} rpm of {src}')
                raise AcceptanceError(msg)
            sources_s.append((value, src))
        else:
            if torque > value:
                msg = (f'step {what_torque!r} commands {torque:g} N m, above the limit '
                       f'{value:g} N m of {src}')
                raise AcceptanceError(msg)
            sources_t.append((value, src))
    s_lim = min((x for x in sources_s if x[0] > 0), default=(1.0, 'no drive step'))
    t_lim = min((x for x in sources_t if x[0] > 0), default=(1.0, 'no load step'))
    return SafetyLimits(max_input_speed_rad_s=s_lim[0] * RAD_S_PER_RPM,
                        max_output_torque_nm=t_lim[0],
                        stale_timeout_s=plan.safety.stale_joint_state_s,
                        speed_source=s_lim[1], torque_source=t_lim[1])


def _all_near(values: list[np.ndarray], target: float, tolerance: float
              ) -> npt.NDArray[np.bool_]:
    """Where every one of ``values`` (equal-shaped arrays) is within ``tolerance`` of
    ``target``."""
    ok = np.ones(values[0].shape, dtype=bool)
    for v in values:
        ok &= np.abs(v - target) <= tolerance
    return ok
