"""Bench programs: the segments an acceptance test drives the simulated bench through.

A program is a sequence of segments, each a whole number of blocks (its duration rounded up),
run on one sample clock that continues across segments and programs:

* :class:`DriveSegment`: the input turns at ``speed_rpm`` (signed: negative turns the output
  backwards) against a constant load (bench convention: a positive ``load_nm`` resists
  positive rotation). The TE is the preset's TE model (reset at the start of the segment, so
  a dynamic model starts at static equilibrium), plus, for backwards rotation, the change of
  flank a kinematic model does not know about: the free play of the torsion model
  (:mod:`sim.torsion`; Wang 2020 Eq. 9 at the output angle for the 2K-V). The Wang 2020 'ste'
  and 'dte' modes put a negative load on the tooth backs themselves and get no offset.
* :class:`TorqueSegment`: the input is locked where the last segment left it and a torque
  (applied to the output, positive in the positive sense) is held: the equal-torque-step
  method of the hysteresis test.
* :class:`OutputSpeedSegment`: the input locked, the output turned at a constant speed by the
  loader until the measured torque reaches ``target_torque_nm`` (a servo with a torque
  limit), then held for ``hold_s``: the constant-speed method.

Samples carry ``torque_out_nm`` in the bench's load convention (``-applied torque`` in the
locked segments), like every EncoderBlock.

With ``losses`` set (:class:`sim.loss_bench.LossConfig`) the blocks also carry the loss
channels (input torque, both transducers, case temperature): a drive segment runs the loss
model at its speed and load; a locked segment dissipates nothing (the input is held, the
output moves quasi-statically), so the case cools towards the ambient, the input transducer
reads the reaction ``torque_out / i`` and the output transducer the segment's own reading.
The case temperature carries over from segment to segment and program to program.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from sim._checks import Rule, real_number
from sim.bench import BenchBlock, bench_info_of, loss_fields, read_heads
from sim.bench_info import DEFAULT_SAMPLE_RATE_HZ
from sim.encoders import EncoderSpec, SimulatedEncoder, encoder_preset
from sim.errors import ModelInputError
from sim.loss_bench import LossChannels, LossConfig
from sim.models import build_te_model
from sim.presets import load_preset
from sim.torsion import torsion_curve
from sim.units import RAD_S_PER_RPM

if TYPE_CHECKING:
    from sim.bench_info import BenchInfoData
    from sim.presets import Preset
    from sim.torsion import TorsionCurve

__all__ = [
    'SEGMENT_KINDS',
    'DriveSegment',
    'OutputPositionSegment',
    'OutputSpeedSegment',
    'ProgramSimulator',
    'Segment',
    'TorqueRampSegment',
    'TorqueSegment',
    'program_from_plain',
    'program_to_plain',
]


def _num(seg: str, name: str, value: object, rule: Rule = '') -> float:
    return real_number(f'{seg}: {name}', value, rule)


@dataclass(frozen=True)
class DriveSegment:
    """Input driven at a constant speed against a constant load.

    Attributes:
        speed_rpm: Input speed [rpm], non-zero (negative: backwards).
        duration_s: Length [s], > 0.
        load_nm: Load torque [N m], bench convention (positive resists positive rotation).
    """

    kind: ClassVar[str] = 'drive'
    speed_rpm: float
    duration_s: float
    load_nm: float = 0.0

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field)."""
        rules: tuple[tuple[str, Rule], ...] = (
            ('speed_rpm', '!=0'), ('duration_s', '>0'), ('load_nm', ''))
        for name, rule in rules:
            object.__setattr__(self, name, _num('drive segment', name, getattr(self, name), rule))


@dataclass(frozen=True)
class TorqueSegment:
    """Input locked, a torque held on the output.

    Attributes:
        torque_nm: Torque applied to the output [N m] (positive twists it positively).
        duration_s: Dwell [s], > 0.
    """

    kind: ClassVar[str] = 'torque'
    torque_nm: float
    duration_s: float

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field)."""
        rules: tuple[tuple[str, Rule], ...] = (('torque_nm', ''), ('duration_s', '>0'))
        for name, rule in rules:
            object.__setattr__(self, name, _num('torque segment', name, getattr(self, name),
                                                rule))


@dataclass(frozen=True)
class OutputSpeedSegment:
    """Input locked, output turned at a constant speed until the torque reaches a target.

    Attributes:
        speed_rad_s: Output speed [rad/s], non-zero; its sign is the direction.
        target_torque_nm: Applied torque at which the loader stops [N m]; it must lie ahead
            (above the present torque when turning forwards, below when backwards).
        hold_s: Time held at the target afterwards [s], >= 0.
    """

    kind: ClassVar[str] = 'output_speed'
    speed_rad_s: float
    target_torque_nm: float
    hold_s: float = 0.0

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field)."""
        rules: tuple[tuple[str, Rule], ...] = (
            ('speed_rad_s', '!=0'), ('target_torque_nm', ''), ('hold_s', '>=0'))
        for name, rule in rules:
            object.__setattr__(self, name, _num('output_speed segment', name,
                                                getattr(self, name), rule))


@dataclass(frozen=True)
class OutputPositionSegment:
    """Input locked, the output moved to a position by a position-controlled loader.

    The loader reaches the position by the end of the segment's first block (linearly)
    and holds it; the torque is the elastic torque plus friction in the direction of the
    motion, and stays at its last value while the output stands still (stick).

    Attributes:
        position_rad: The output shaft angle commanded [rad], as the output encoder reads it.
        duration_s: Length [s], > 0.
    """

    kind: ClassVar[str] = 'output_position'
    position_rad: float
    duration_s: float

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field)."""
        rules: tuple[tuple[str, Rule], ...] = (('position_rad', ''), ('duration_s', '>0'))
        for name, rule in rules:
            object.__setattr__(self, name, _num('output_position segment', name,
                                                getattr(self, name), rule))


@dataclass(frozen=True)
class TorqueRampSegment:
    """A quasi-static torque ramp until the shaft turns (needs the loss model).

    ``shaft='input'``: the drive ramps the input torque, the output free and unloaded (the
    starting torque); ``'output'``: the loader ramps the output torque, the input free (the
    back-driving torque). The shaft holds until the breakaway torque of
    :mod:`sim.losses`, then turns (:mod:`sim.breakaway`); the controller releases the
    torque when the shaft has turned ``stop_angle_rad`` and the shaft stops there.

    Attributes:
        shaft: ``'input'`` or ``'output'``.
        ramp_rate_nm_s: Ramp rate [N m/s], non-zero; its sign is the direction.
        max_torque_nm: The ramp ends here [N m], > 0 (duration ``max / |rate|``).
        stop_angle_rad: Shaft travel at which the torque is released [rad], > 0.
    """

    kind: ClassVar[str] = 'torque_ramp'
    shaft: str
    ramp_rate_nm_s: float
    max_torque_nm: float
    stop_angle_rad: float = 0.01

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field)."""
        if self.shaft not in ('input', 'output'):
            msg = f"torque_ramp segment: shaft must be 'input' or 'output', got {self.shaft!r}"
            raise ModelInputError(msg)
        rules: tuple[tuple[str, Rule], ...] = (('ramp_rate_nm_s', '!=0'),
                                               ('max_torque_nm', '>0'),
                                               ('stop_angle_rad', '>0'))
        for name, rule in rules:
            object.__setattr__(self, name, _num('torque_ramp segment', name,
                                                getattr(self, name), rule))

    @property
    def duration_s(self) -> float:
        """max_torque_nm / |ramp_rate_nm_s|."""
        return self.max_torque_nm / abs(self.ramp_rate_nm_s)


Segment = (DriveSegment | TorqueSegment | OutputSpeedSegment | OutputPositionSegment
           | TorqueRampSegment)
SEGMENT_KINDS: dict[str, type[Segment]] = {c.kind: c for c in (DriveSegment, TorqueSegment,
                                                      OutputSpeedSegment,
                                                      OutputPositionSegment,
                                                      TorqueRampSegment)}


def program_from_plain(items: Any) -> tuple[Segment, ...]:
    """Segments from a list of ``{kind: ..., field: value}`` dicts (a YAML program).

    Raises:
        ModelInputError: Not a non-empty list, unknown kind or field, bad value (the message
            names the segment number).
    """
    if not isinstance(items, list | tuple) or not items:
        msg = f'a bench program must be a non-empty list of segments, got {type(items).__name__}'
        raise ModelInputError(msg)
    out: list[Segment] = []
    for n, item in enumerate(items):
        if not isinstance(item, dict) or 'kind' not in item:
            msg = f'segment {n}: must be a mapping with a "kind", got {item!r}'
            raise ModelInputError(msg)
        cls = SEGMENT_KINDS.get(item['kind'])
        if cls is None:
            msg = f'segment {n}: kind {item["kind"]!r} unknown; known: {", ".join(SEGMENT_KINDS)}'
            raise ModelInputError(msg)
        fields = {k: v for k, v in item.items() if k != 'kind'}
        allowed = set(cls.__dataclass_fields__)
        if unknown := sorted(set(fields) - allowed):
            msg = f'segment {n} ({cls.kind}): unknown field(s) {unknown}; allowed {sorted(allowed)}'
            raise ModelInputError(msg)
        try:
            out.append(cls(**fields))
        except TypeError as exc:
            msg = f'segment {n} ({cls.kind}): {exc}'
            raise ModelInputError(msg) from None
        except ModelInputError as exc:
            msg = f'segment {n}: {exc}'
            raise ModelInputError(msg) from None
    return tuple(out)


def program_to_plain(program: tuple[Segment, ...]) -> list[dict[str, Any]]:
    """The inverse of :func:`program_from_plain`."""
    return [{'kind': s.kind, **asdict(s)} for s in program]


@dataclass(frozen=True)
class _Planned:
    segment: Segment
    first_block: int
    blocks: int


class ProgramSimulator:
    """Runs bench programs block by block (same seed, same data).

    Args:
        preset: Preset name or TOML path.
        overrides: Preset overrides ``key=value``.
        te_mode: TE model mode of the drive segments.
        encoder_in, encoder_out: Encoder preset names or specs.
        sample_rate_hz: DAQ rate [Hz], > 0.
        block_size: Samples per block, >= 1.
        seed: Encoder noise seed, >= 0.
        preset_obj: Use this preset instead of loading ``preset`` (overrides still applied).
        daq_skew_s: Output channel latched this much after the input channel [s].
        torque_zero_nm: Zero error of the torque sensor [N m]: it reads the true torque
            plus this (a torque step holds the *reading* at the commanded value).
        torque_gain_error: Relative sensitivity error of the torque sensor (reading =
            true x (1 + error) + zero).
        bench_id: Bench identifier of :attr:`info`.
        losses: Simulate the losses, torque transducers and case temperature; None
            (default): the blocks carry no loss channels and draw nothing more.

    Raises:
        PresetError, ModelInputError: Bad preset, mode or settings.
    """

    def __init__(self, *, preset: str, overrides: tuple[str, ...] = (), te_mode: str = 'nlte',
                 encoder_in: str | EncoderSpec = 'heidenhain-ron886',
                 encoder_out: str | EncoderSpec = 'heidenhain-ron886',
                 sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ, block_size: int = 100,
                 seed: int = 0, preset_obj: Preset | None = None, daq_skew_s: float = 0.0,
                 torque_zero_nm: float = 0.0, torque_gain_error: float = 0.0,
                 bench_id: str = 'bench', losses: LossConfig | None = None) -> None:
        """Build the model, the torsion characteristic's source and the encoders."""
        self.preset = (load_preset(preset, list(overrides)) if preset_obj is None
                       else preset_obj.with_overrides(list(overrides)))
        self.te_mode = te_mode
        self.model = build_te_model(self.preset, te_mode)
        self.gear_ratio = float(self.model.kinematics.gear_ratio)
        self.sample_rate_hz = _num('bench', 'sample_rate_hz', sample_rate_hz, '>0')
        if isinstance(block_size, bool) or not isinstance(block_size, int) or block_size < 1:
            msg = f'block_size must be an integer >= 1, got {block_size!r}'
            raise ModelInputError(msg)
        self.block_size = block_size
        self.daq_skew_s = _num('bench', 'daq_skew_s', daq_skew_s)
        self.torque_zero_nm = _num('bench', 'torque_zero_nm', torque_zero_nm)
        self.torque_gain_error = _num('bench', 'torque_gain_error', torque_gain_error)
        if abs(self.torque_gain_error) >= 0.5:
            msg = f'torque_gain_error must lie within +-0.5, got {torque_gain_error!r}'
            raise ModelInputError(msg)
        specs = [e if isinstance(e, EncoderSpec) else encoder_preset(e)
                 for e in (encoder_in, encoder_out)]
        self._settings = {'bench_id': bench_id, 'preset': preset, 'overrides': list(overrides),
                          'te_mode': te_mode, 'encoder_in': specs[0].to_plain(),
                          'encoder_out': specs[1].to_plain(),
                          'sample_rate_hz': self.sample_rate_hz, 'block_size': block_size,
                          'seed': seed}
        if losses is not None and not isinstance(losses, LossConfig):
            msg = f'losses must be a LossConfig or None, got {losses!r}'
            raise ModelInputError(msg)
        if losses is not None:
            self._settings['losses'] = losses.to_plain()
        self._specs = (specs[0], specs[1])
        self._info: BenchInfoData | None = None
        rng = np.random.default_rng(seed)
        rng_in, rng_out = rng.spawn(2)
        self._enc_in = SimulatedEncoder(specs[0], rng_in)
        self._enc_out = SimulatedEncoder(specs[1], rng_out)
        self.losses: LossChannels | None = None if losses is None else LossChannels(
            self.preset, losses, rng.spawn(1)[0], self.sample_rate_hz)
        if self.losses is not None:   # the transducers' ranges and classes, for the record
            self._settings['loss_channels'] = self.losses.describe()['sensors']
        self._offsets = np.arange(block_size, dtype=np.float64) / self.sample_rate_hz
        self._offsets.setflags(write=False)
        self._curves: dict[float, TorsionCurve] = {}
        self.seq = 0                 # next block number (continues across programs)
        self.theta_in_rad = 0.0      # input angle now
        self.torsion_rad: float | None = None   # output torsion angle when locked
        self._plan: list[_Planned] = []
        self._block_in_program = 0
        self._seg_index = -1
        self._last_true_torque_nm = 0.0   # a position-held output keeps its torque (stick)
        self._holding = False             # running commands block by block (hold())
        #: (curve, (phi0, true torque, samples), angles) of the last held-torque block
        self._held: tuple[TorsionCurve, tuple[float, float, int], np.ndarray] | None = None

    @property
    def info(self) -> BenchInfoData:
        """What this bench's ``bench/info`` says (the acceptance runner's bench record)."""
        if self._info is None:
            self._info = bench_info_of(
                bench_id=str(self._settings['bench_id']), preset=self.preset,
                kinematics=self.model.kinematics, encoder_in=self._specs[0],
                encoder_out=self._specs[1], sample_rate_hz=self.sample_rate_hz,
                block_size=self.block_size, settings=self._settings)
        return self._info

    # -- planning ---------------------------------------------------------------------------
    def curve(self, theta_in_rad: float) -> TorsionCurve:
        """The torsion characteristic at a locked input angle (cached)."""
        key = round(float(theta_in_rad), 12)
        if key not in self._curves:
            if len(self._curves) > 64:
                self._curves.clear()
            self._curves[key] = torsion_curve(self.preset, key)
        return self._curves[key]

    def _blocks(self, duration_s: float) -> int:
        return max(1, math.ceil(duration_s * self.sample_rate_hz / self.block_size - 1e-9))

    def load(self, program: tuple[Segment, ...]) -> int:
        """Queue a program (replacing what is left of one); return its number of blocks."""
        self._holding = False
        plan: list[_Planned] = []
        first = 0
        theta, phi = self.theta_in_rad, self.torsion_rad
        for seg in program:
            if isinstance(seg, DriveSegment):
                duration = seg.duration_s
                theta += seg.speed_rpm * RAD_S_PER_RPM * self._blocks(duration) \
                    * self.block_size / self.sample_rate_hz
                phi = None
            elif isinstance(seg, TorqueRampSegment):
                duration = seg.duration_s
                theta += self._ramp_travel_in(seg)
                phi = None
            else:
                curve = self.curve(theta)
                phi = self._rest_angle(curve, phi)
                if isinstance(seg, TorqueSegment):
                    duration = seg.duration_s
                    phi = float(curve.angle_under_torque([self._true_torque(seg.torque_nm)],
                                                         phi)[0])
                elif isinstance(seg, OutputPositionSegment):
                    duration = seg.duration_s
                    phi = seg.position_rad - theta / self.gear_ratio
                else:
                    direction = 1 if seg.speed_rad_s > 0 else -1
                    start_t = float(curve.torque_under_motion([phi], direction)[0])
                    if direction * (seg.target_torque_nm - start_t) <= 0:
                        msg = (f'output_speed segment: target torque {seg.target_torque_nm} '
                               f'N m is not ahead of the present {start_t:.6g} N m when '
                               f'turning {"forwards" if direction > 0 else "backwards"}')
                        raise ModelInputError(msg)
                    target = curve.angle_at_torque(self._true_torque(seg.target_torque_nm),
                                                   direction)
                    duration = abs(target - phi) / abs(seg.speed_rad_s) + seg.hold_s
                    phi = target
            n = self._blocks(duration)
            plan.append(_Planned(seg, first, n))
            first += n
        self._plan = plan
        self._block_in_program = 0
        self._seg_index = -1
        return first

    def _ramp_friction(self, seg: TorqueRampSegment) -> tuple[float, float, float]:
        if self.losses is None:
            msg = ('torque_ramp segment: needs the loss model and torque transducers '
                   '(ProgramSimulator(losses=...))')
            raise ModelInputError(msg)
        from sim.breakaway import shaft_friction

        return shaft_friction(self.losses.model, seg.shaft)

    def _ramp_travel_in(self, seg: TorqueRampSegment) -> float:
        """Input travel a ramp segment ends with [rad]."""
        ts = self._ramp_friction(seg)[0]
        if not ts < seg.max_torque_nm:
            return 0.0
        sign = 1.0 if seg.ramp_rate_nm_s > 0 else -1.0
        return sign * seg.stop_angle_rad * (self.gear_ratio if seg.shaft == 'output' else 1.0)

    @property
    def segment_blocks(self) -> tuple[int, ...]:
        """Blocks of each segment of the loaded program, in order."""
        return tuple(p.blocks for p in self._plan)

    @staticmethod
    def _rest_angle(curve: TorsionCurve, phi: float | None) -> float:
        """Torsion angle when the input is locked after driving: on the drive flank."""
        if phi is not None:
            return phi
        return curve.centre_rad - 0.5 * curve.backlash_rad

    # -- running ----------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """True while blocks of the loaded program are left."""
        return bool(self._plan) and self._block_in_program < self._plan[-1].first_block \
            + self._plan[-1].blocks

    def stop(self) -> None:
        """Drop what is left of the program."""
        self._plan = []
        self._block_in_program = 0
        self._holding = False

    def hold(self, segment: Segment) -> BenchBlock:
        """One block of ``segment``, continuing it when it is the segment of the last block
        run this way (a command held: the dynamic model is not restarted), else starting it
        (a new command). What a bench driven by setpoints does, block by block.

        Raises:
            ModelInputError: An output-speed segment (position commands move the output here).
        """
        if isinstance(segment, OutputSpeedSegment):
            msg = 'hold() takes drive, torque and output_position segments'
            raise ModelInputError(msg)
        last = self._plan[-1] if len(self._plan) == 1 else None
        if last is not None and self._holding and last.segment == segment \
                and self._block_in_program == last.blocks:
            self._plan[-1] = _Planned(segment, 0, last.blocks + 1)
        else:
            self._plan = [_Planned(segment, 0, 1)]
            self._block_in_program = 0
            self._seg_index = -1
            self._holding = True
        block, _ = self.next_block()
        return block

    def segment_of_block(self, k: int) -> int:
        """Index of the segment that block ``k`` of the program belongs to."""
        i = self._seg_index
        for j in (i, i + 1):   # the segment of the last block, or the next one
            if 0 <= j < len(self._plan):
                p = self._plan[j]
                if p.first_block <= k < p.first_block + p.blocks:
                    return j
        for i, p in enumerate(self._plan):
            if p.first_block <= k < p.first_block + p.blocks:
                return i
        msg = f'block {k} is not in the program'
        raise ModelInputError(msg)

    def next_block(self) -> tuple[BenchBlock, int]:
        """Simulate the next block of the program; returns it and its segment index.

        Raises:
            ModelInputError: No program is running.
        """
        if not self.running:
            msg = 'no bench program is running'
            raise ModelInputError(msg)
        k = self._block_in_program
        i = self.segment_of_block(k)
        planned = self._plan[i]
        t = (self.seq * self.block_size) / self.sample_rate_hz + self._offsets
        if i != self._seg_index:
            self._seg_index = i
            self._seg_t0 = float(t[0])
            self._seg_theta0 = self.theta_in_rad
            self._seg_phi0 = self.torsion_rad
            if isinstance(planned.segment, DriveSegment):
                self.model.reset()
        seg = planned.segment
        ramp_in: np.ndarray | None = None
        if isinstance(seg, DriveSegment):
            theta_in, te, torque = self._drive(seg, t)
        elif isinstance(seg, TorqueRampSegment):
            theta_in, te, torque, ramp_in = self._ramp(seg, t)
        else:
            theta_in, te, torque = self._locked(seg, t)
        extra: dict[str, np.ndarray] = {}
        if self.losses is not None:
            if ramp_in is not None:
                lb = self.losses.block(t, np.zeros_like(t), torque, torque_in_true_nm=ramp_in)
            elif isinstance(seg, DriveSegment):
                lb = self.losses.block(t, np.full_like(t, seg.speed_rpm * RAD_S_PER_RPM),
                                       torque)
            else:
                lb = self.losses.block(t, np.zeros_like(t), torque,
                                       torque_out_reading_nm=torque)
            extra = loss_fields(lb)
        theta_out = theta_in / self.gear_ratio + te
        if self.daq_skew_s and isinstance(seg, DriveSegment):
            from sim.bench import skewed_reading

            theta_out_read = skewed_reading(theta_out, seg.speed_rpm * RAD_S_PER_RPM
                                            / self.gear_ratio, te, t, self.daq_skew_s)
        else:
            theta_out_read = theta_out
        ro = self._readonly
        read_in, heads_in = read_heads(self._enc_in, theta_in)
        read_out, heads_out = read_heads(self._enc_out, theta_out_read)
        block = BenchBlock(
            seq=self.seq, t0_s=float(t[0]), time_offset_s=self._offsets,
            theta_in_rad=read_in, theta_out_rad=read_out,
            torque_out_nm=ro(torque), te_true_rad=ro(te), theta_in_true_rad=ro(theta_in),
            theta_out_true_rad=ro(theta_out), theta_in_heads_rad=heads_in,
            theta_out_heads_rad=heads_out, **extra)
        self.seq += 1
        self._block_in_program += 1
        return block, i

    @staticmethod
    def _readonly(a: np.ndarray) -> np.ndarray:
        a = np.array(a, dtype=np.float64)
        a.setflags(write=False)
        return a

    def _drive(self, seg: DriveSegment, t: np.ndarray) -> tuple[np.ndarray, ...]:
        omega = seg.speed_rpm * RAD_S_PER_RPM
        theta_in = self._seg_theta0 + omega * (t - self._seg_t0)
        load = np.full_like(t, seg.load_nm)
        te = np.asarray(self.model.te_rad(t, theta_in, np.full_like(t, omega), load),
                        dtype=np.float64)
        if omega < 0:
            te = te + self._reverse_offset(theta_in)
        self.theta_in_rad = float(self._seg_theta0 + omega * (t[-1] + 1.0 / self.sample_rate_hz
                                                            - self._seg_t0))
        self.torsion_rad = None
        self._last_true_torque_nm = 0.0
        return theta_in, te, load

    def _ramp(self, seg: TorqueRampSegment, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """A torque ramp block: input angle, TE (0), output load, input torque."""
        from sim.breakaway import ramp_angle_rad

        ts, tk, j = self._ramp_friction(seg)
        rate = abs(seg.ramp_rate_nm_s)
        sign = 1.0 if seg.ramp_rate_nm_s > 0 else -1.0
        tr = t - self._seg_t0
        angle = ramp_angle_rad(tr, ts, tk, j, rate)
        stopped = angle >= seg.stop_angle_rad
        angle = np.minimum(angle, seg.stop_angle_rad)
        applied = np.where(stopped, 0.0, np.minimum(rate * tr, seg.max_torque_nm)) * sign
        scale = self.gear_ratio if seg.shaft == 'output' else 1.0
        theta_in = self._seg_theta0 + sign * angle * scale
        self.theta_in_rad = float(theta_in[-1])
        self.torsion_rad = None
        self._last_true_torque_nm = 0.0
        zeros = np.zeros_like(t)
        if seg.shaft == 'input':
            return theta_in, zeros, zeros, applied
        return theta_in, zeros, -applied, zeros

    def _reverse_offset(self, theta_in: np.ndarray) -> np.ndarray | float:
        """Flank change when turning backwards (see the module docstring)."""
        if self.preset.model == 'wang2020-2kv':
            if self.te_mode in {'ste', 'dte'}:
                return 0.0
            from sim import wang2020

            params = wang2020.Wang2kvParams.from_preset(self.preset)
            return wang2020.backlash_rad(theta_in / self.gear_ratio, params)
        return self.curve(0.0).backlash_rad

    def _locked(self, seg: TorqueSegment | OutputSpeedSegment | OutputPositionSegment,
                t: np.ndarray) -> tuple[np.ndarray, ...]:
        theta = self._seg_theta0
        curve = self.curve(theta)
        phi0 = self._rest_angle(curve, self._seg_phi0)
        if isinstance(seg, TorqueSegment):
            true = np.full_like(t, self._true_torque(seg.torque_nm))
            # every block of a held torque gives the same angles: computed once
            key = (phi0, float(true[0]), t.size)
            if self._held is None or self._held[0] is not curve or self._held[1] != key:
                self._held = (curve, key, curve.angle_under_torque(true, phi0))
            phi = self._held[2].copy()
        elif isinstance(seg, OutputPositionSegment):
            target = seg.position_rad - theta / self.gear_ratio
            # where the output was at the start of this block: reached by the end of the
            # segment's first block, linearly
            start = phi0
            first = float(t[0]) <= self._seg_t0 + 0.5 / self.sample_rate_hz
            frac = (np.arange(1, t.size + 1) / t.size) if first else np.ones(t.size)
            phi = start + (target - start) * frac if first else np.full_like(t, target)
            if first and target != start:
                true = curve.torque_under_motion(phi, 1 if target > start else -1)
            else:
                true = np.full_like(t, self._last_true_torque_nm)
        else:
            direction = 1 if seg.speed_rad_s > 0 else -1
            target = curve.angle_at_torque(self._true_torque(seg.target_torque_nm), direction)
            phi = phi0 + seg.speed_rad_s * (t - self._seg_t0)
            phi = np.minimum(phi, target) if direction > 0 else np.maximum(phi, target)
            true = curve.torque_under_motion(phi, direction)
        self.torsion_rad = float(phi[-1])
        self.theta_in_rad = theta
        self._last_true_torque_nm = float(true[-1])
        reading = true * (1.0 + self.torque_gain_error) + self.torque_zero_nm
        if isinstance(seg, TorqueSegment):
            reading = np.full_like(t, seg.torque_nm)   # the loader holds the reading
        return np.full_like(t, theta), phi, -reading

    def _true_torque(self, reading_nm: float) -> float:
        """The torque applied when the sensor reads ``reading_nm``."""
        return (reading_nm - self.torque_zero_nm) / (1.0 + self.torque_gain_error)

    def __repr__(self) -> str:
        """Short description."""
        return (f'ProgramSimulator({self.preset.name!r}, {self.te_mode!r}, '
                f'{self.sample_rate_hz:g} Hz x {self.block_size})')
