"""JointState samples in, EncoderBlock-shaped blocks and reported gaps out (no rclpy).

A real bench in ROS 2 reads its encoders through a ros2_control hardware interface, and
``joint_state_broadcaster`` publishes ``sensor_msgs/JointState``: usually one sample per
message, header stamp in nanoseconds, joint names, positions and efforts.
:class:`JointStateAssembler` turns that stream into the blocks the TE core analyses
(:class:`JointStateBlock`, the fields of ``rv_te_msgs/EncoderBlock``):

* **Sample times** are the header stamps (never arrival times). A block's ``stamp_ns`` is
  its first sample's stamp, ``time_offset_s`` the exact offsets from it.
* **Joints in one message or in separate messages.** A message holding both joints is one
  sample. Messages holding one of them are paired by stamp: an input and an output position
  whose stamps differ by at most ``pairing_tolerance_s`` form one sample (at the input
  joint's stamp). Reordering between the two joints' messages is tolerated up to
  ``max_unpaired`` samples; a half that cannot be paired is a missing joint.
* **Positions** are ``position * scale`` with scale 1 (``position_unit='rad'``) or
  2 pi / ``counts_per_rev_*`` (``'counts'``, raw counters). With ``wrap_*`` (single-turn
  absolute encoders reading [0, 2 pi) or [-pi, pi)) the scaled angle is unwrapped into a
  continuous multi-turn angle; this needs less than half a turn between two accepted
  samples (also across a gap). Both directions of rotation work alike.
* **Effort** of the output joint times ``effort_scale`` is the output torque [N m]
  (``effort_scale = 0``: no torque; a message without effort gives NaN torque).
* The per-sample path is scalar Python kept short (the common message has one sample);
  scaling, unwrapping and the time offsets are numpy, once per block.

**Gaps.** A stamp more than 1.5 sample periods after the last accepted one
(``'stamp_jump'``), a stamp not after it (``'stamp_backwards'``), a joint that did not come
(``'missing_joint'``) or a non-finite position (``'non_finite'``) closes the current block
(published short) and becomes a :class:`JointStateGap` with its reason, the stamps of the
good samples on both sides, the samples dropped and the samples the stamps say are missing.
Problems in a row before the next good sample make one gap.

Why a **skipped sequence number**: after a gap the next block's ``seq`` is one more than
contiguous (seq counts from 0 over the session and is contiguous otherwise). The TE
core (:mod:`rv_te_bench.core.stream`) trusts the DAQ clock and does *not* treat a forward
time jump between consecutive seqs as a gap, so contiguous seqs across a gap would splice
the stretches silently in the TE node, and in ``rv-te analyze`` of a recorded bag. A seq
jump is what every consumer already understands: the TE node and the offline analysis
close the open window as partial (``seq_jump``), and the recorder's bag keeps the evidence
without a new message type. The assembler's own :class:`JointStateGap` (reason, stamps,
counts) is what the adapter node logs and puts in its diagnostics. A gap before the first
accepted sample skips no seq (there is nothing to splice onto).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from rv_te_bench.errors import TeConfigError

if TYPE_CHECKING:
    from collections.abc import Sequence

    from rv_te_bench.core.stream_records import EncoderBlockData

__all__ = [
    'STAMP_JUMP_PERIODS',
    'GapReason',
    'JointStateAssembler',
    'JointStateBlock',
    'JointStateConfig',
    'JointStateGap',
]

PositionUnit = Literal['rad', 'counts']
GapReason = Literal['stamp_jump', 'stamp_backwards', 'missing_joint', 'non_finite']

#: A stamp further than this many sample periods after the last accepted one is a gap.
STAMP_JUMP_PERIODS = 1.5
_TWO_PI = 2.0 * math.pi
_MAX_LAYOUTS = 64   # distinct name lists remembered (name -> index lookups)
_EMPTY = np.empty(0, dtype=np.float64)
_EMPTY.setflags(write=False)
_NOTHING: tuple[()] = ()


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, kw_only=True)
class JointStateConfig:
    """How a JointState stream maps onto encoder blocks (SI units).

    Attributes:
        input_joint: Joint name of the input-shaft encoder.
        output_joint: Joint name of the output-shaft encoder.
        sample_rate_hz: Expected sample rate of the stamps [Hz] (> 0): gaps are stamp steps
            above 1.5 periods; also the ``sample_rate_hz`` of the blocks.
        block_size: Samples per block (>= 1); blocks closed by a gap are shorter.
        position_unit: ``'rad'`` or ``'counts'`` (raw counters, see ``counts_per_rev_*``).
        counts_per_rev_in: Input encoder counts per revolution [1/rev] (> 0) with
            ``'counts'``; 0 with ``'rad'``.
        counts_per_rev_out: Output encoder counts per revolution, likewise.
        wrap_in: The input position is single-turn (wraps at 2 pi after scaling): unwrap it.
        wrap_out: The output position is single-turn: unwrap it.
        effort_scale: Output torque [N m] per unit of the output joint's effort; 0 = no
            torque in the blocks.
        input_effort_scale: Input-shaft torque [N m] per unit of the input (drive) joint's
            effort (the bench's torque-in channel, issue 38); 0 = no input torque.
        pairing_tolerance_s: Joints in separate messages: largest stamp difference [s] of
            one sample's input and output positions (>= 0, below half a sample period).
        max_unpaired: Samples one joint may run ahead of the other (reordering) before its
            oldest unpaired half counts as a missing joint (>= 1).
        output_head_joints: Joint names of the output scale's further read heads (heads
            1..N-1; head 0 is ``output_joint``), read from the output joint's message
            (issue 36); a head absent from a message, or not finite, is left out of that
            sample's block (the block is kept).
    """

    input_joint: str
    output_joint: str
    sample_rate_hz: float
    block_size: int = 100
    position_unit: PositionUnit = 'rad'
    counts_per_rev_in: float = 0.0
    counts_per_rev_out: float = 0.0
    wrap_in: bool = False
    wrap_out: bool = False
    effort_scale: float = 0.0
    input_effort_scale: float = 0.0
    pairing_tolerance_s: float = 0.0
    max_unpaired: int = 64
    output_head_joints: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        """Check every field; the message names the field and the value."""
        for name in ('input_joint', 'output_joint'):
            value = getattr(self, name)
            if not isinstance(value, str) or not value:
                msg = f'{name} must be a non-empty joint name, got {value!r}'
                raise TeConfigError(msg)
        if self.input_joint == self.output_joint:
            msg = (f'input_joint and output_joint must differ, both are '
                   f'{self.input_joint!r}')
            raise TeConfigError(msg)
        heads = tuple(self.output_head_joints)
        object.__setattr__(self, 'output_head_joints', heads)
        names = [self.input_joint, self.output_joint, *heads]
        if len(heads) > 15 or not all(isinstance(h, str) and h for h in heads) \
                or len(set(names)) != len(names):
            msg = (f'output_head_joints must be at most 15 different joint names, none the '
                   f'input or output joint, got {list(heads)!r}')
            raise TeConfigError(msg)
        rate = self.sample_rate_hz
        if isinstance(rate, bool) or not isinstance(rate, int | float) \
                or not (math.isfinite(rate) and rate > 0):
            msg = f'sample_rate_hz must be finite and > 0, got {rate!r}'
            raise TeConfigError(msg)
        for name, least in (('block_size', 1), ('max_unpaired', 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                msg = f'{name} must be an integer >= {least}, got {value!r}'
                raise TeConfigError(msg)
        if self.position_unit not in ('rad', 'counts'):
            msg = f"position_unit must be 'rad' or 'counts', got {self.position_unit!r}"
            raise TeConfigError(msg)
        for name in ('counts_per_rev_in', 'counts_per_rev_out'):
            cpr = getattr(self, name)
            if self.position_unit == 'counts' and not (
                    isinstance(cpr, int | float) and math.isfinite(cpr) and cpr > 0):
                msg = f"{name} must be finite and > 0 with position_unit 'counts', got {cpr!r}"
                raise TeConfigError(msg)
            if self.position_unit == 'rad' and cpr != 0:
                msg = (f"{name} is for position_unit 'counts'; with 'rad' it must be 0, "
                       f'got {cpr!r}')
                raise TeConfigError(msg)
        for name in ('wrap_in', 'wrap_out'):
            if not isinstance(getattr(self, name), bool):
                msg = f'{name} must be a bool, got {getattr(self, name)!r}'
                raise TeConfigError(msg)
        if not (isinstance(self.effort_scale, int | float)
                and math.isfinite(self.effort_scale)):
            msg = f'effort_scale must be finite, got {self.effort_scale!r}'
            raise TeConfigError(msg)
        if not (isinstance(self.input_effort_scale, int | float)
                and math.isfinite(self.input_effort_scale)):
            msg = f'input_effort_scale must be finite, got {self.input_effort_scale!r}'
            raise TeConfigError(msg)
        tol = self.pairing_tolerance_s
        half = 0.5 / rate
        if not (isinstance(tol, int | float) and math.isfinite(tol) and 0 <= tol < half):
            msg = (f'pairing_tolerance_s must be >= 0 and below half a sample period '
                   f'({half:.6g} s at {rate:g} Hz), got {tol!r}')
            raise TeConfigError(msg)

    @property
    def scale_in_rad(self) -> float:
        """Radians per unit of the input joint's position."""
        return 1.0 if self.position_unit == 'rad' else _TWO_PI / self.counts_per_rev_in

    @property
    def scale_out_rad(self) -> float:
        """Radians per unit of the output joint's position."""
        return 1.0 if self.position_unit == 'rad' else _TWO_PI / self.counts_per_rev_out


@dataclass(frozen=True)
class JointStateBlock:
    """One block assembled from JointState samples (the fields of ``EncoderBlock``).

    Attributes:
        seq: Block number, from 0 over the session; one number is skipped after a gap.
        stamp_ns: Stamp of the first sample [ns].
        sample_rate_hz: The configured sample rate [Hz].
        time_offset_s: Sample stamps minus ``stamp_ns`` [s] (first is 0), read-only.
        theta_in_rad: Input-shaft angle, scaled and unwrapped [rad], read-only.
        theta_out_rad: Output-shaft angle, scaled and unwrapped [rad], read-only.
        torque_out_nm: Output torque [N m] (empty without ``effort_scale``), read-only.
        out_head_ids: The output heads present in the whole block (head 0 first), or ()
            without further heads.
        theta_out_heads_rad: Their readings, (heads, n) [rad], unwrapped beside head 0.
        torque_in_nm: Input-shaft torque [N m] from the drive joint's effort (empty
            without ``input_effort_scale``), read-only.
    """

    seq: int
    stamp_ns: int
    sample_rate_hz: float
    time_offset_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_out_nm: np.ndarray = field(default_factory=lambda: _EMPTY)
    out_head_ids: tuple[int, ...] = ()
    theta_out_heads_rad: np.ndarray = field(default_factory=lambda: _EMPTY)
    torque_in_nm: np.ndarray = field(default_factory=lambda: _EMPTY)

    @property
    def stamp_s(self) -> float:
        """``stamp_ns`` in seconds."""
        return self.stamp_ns * 1e-9

    def to_encoder_block_data(self) -> EncoderBlockData:
        """The TE core's block (what a TE node makes of the published EncoderBlock)."""
        from rv_te_bench.core.stream_records import EncoderBlockData

        if self.out_head_ids:
            return EncoderBlockData(self.seq, self.stamp_s, self.sample_rate_hz,
                                    self.time_offset_s, self.theta_in_rad, self.theta_out_rad,
                                    self.torque_out_nm, out_head_ids=self.out_head_ids,
                                    theta_out_heads_rad=self.theta_out_heads_rad)
        return EncoderBlockData(self.seq, self.stamp_s, self.sample_rate_hz,
                                self.time_offset_s, self.theta_in_rad, self.theta_out_rad,
                                self.torque_out_nm)


@dataclass(frozen=True)
class JointStateGap:
    """A reported break in the JointState stream.

    Attributes:
        reason: What broke it first: ``'stamp_jump'``, ``'stamp_backwards'``,
            ``'missing_joint'`` or ``'non_finite'``.
        stamp_before_ns: Stamp of the last accepted sample before it (None: at the start).
        stamp_after_ns: Stamp of the first accepted sample after it (None: the stream
            ended in the gap).
        samples_dropped: Samples received but not used (missing joint, non-finite).
        samples_missing: Samples the stamps say never came:
            ``round((after - before) * rate) - 1 - samples_dropped``, at least 0 (0 when a
            side is unknown or the stamp went backwards).
        seq_after: ``seq`` of the block after the gap (the skipped number is one less).
        detail: One line for the log.
    """

    reason: GapReason
    stamp_before_ns: int | None
    stamp_after_ns: int | None
    samples_dropped: int
    samples_missing: int
    seq_after: int
    detail: str


@dataclass(slots=True)
class _OpenGap:
    reason: GapReason
    stamp_before_ns: int | None
    dropped: int
    detail: str


class JointStateAssembler:
    """Streams JointState samples into :class:`JointStateBlock` s and :class:`JointStateGap` s.

    Never raises on bad data: every problem becomes a gap. Memory is bounded by one block
    and ``max_unpaired`` halves per joint.

    Examples:
        >>> cfg = JointStateConfig(input_joint='in', output_joint='out',
        ...                        sample_rate_hz=1000.0, block_size=2)
        >>> asm = JointStateAssembler(cfg)
        >>> asm.push(0, ['in', 'out'], [0.0, 0.0])
        ()
        >>> (block,) = asm.push(1_000_000, ['in', 'out'], [0.1, 0.001])
        >>> block.seq, block.time_offset_s.tolist(), block.theta_in_rad.tolist()
        (0, [0.0, 0.001], [0.0, 0.1])
        >>> (gap,) = asm.push(5_000_000, ['in', 'out'], [0.5, 0.005])
        >>> gap.reason, gap.samples_missing, gap.seq_after
        ('stamp_jump', 3, 2)
    """

    def __init__(self, config: JointStateConfig) -> None:
        """Start a session (seq 0) with ``config``."""
        self._cfg = config
        self._in_name = config.input_joint
        self._out_name = config.output_joint
        self._period_ns = 1e9 / config.sample_rate_hz
        self._jump_ns = STAMP_JUMP_PERIODS * self._period_ns
        self._tol_ns = config.pairing_tolerance_s * 1e9
        self._use_effort = config.effort_scale != 0.0
        self._use_effort_in = config.input_effort_scale != 0.0
        self._eff_in: list[float] = []
        self._head_names = config.output_head_joints
        self._layouts: dict[tuple[str, ...], tuple[int, int]] = {}
        self._head_index: dict[tuple[str, ...], tuple[int, ...]] = {}
        self._heads: list[tuple[float, ...]] = []   # further heads per sample of the block
        # the open block
        self._t: list[int] = []
        self._in: list[float] = []
        self._out: list[float] = []
        self._eff: list[float] = []
        # halves of samples waiting for their other joint: (stamp_ns, position, effort)
        self._half_in: deque[tuple[int, float, float, tuple[float, ...]]] = deque()
        self._half_out: deque[tuple[int, float, float, tuple[float, ...]]] = deque()
        self._last_ns: int | None = None          # last accepted sample's stamp
        self._next_seq = 0
        # unwrap state: last scaled (wrapped) reading and the turns added to it [rad]
        self._prev_in = math.nan
        self._prev_out = math.nan
        self._off_in = 0.0
        self._off_out = 0.0
        self._gap: _OpenGap | None = None
        self.counters: dict[str, int] = dict.fromkeys(
            ('messages', 'samples', 'blocks', 'gaps', 'samples_dropped', 'ignored_messages',
             'stamp_jump', 'stamp_backwards', 'missing_joint', 'non_finite',
             'blocks_head_missing'), 0)

    @property
    def config(self) -> JointStateConfig:
        """The configuration."""
        return self._cfg

    @property
    def pending_samples(self) -> int:
        """Samples in the open block."""
        return len(self._t)

    @property
    def has_samples(self) -> bool:
        """True once a sample of both joints was accepted (its joints arrive)."""
        return bool(self._t) or self.counters['samples'] > 0

    @property
    def names_seen(self) -> tuple[str, ...]:
        """The joint names the messages carried (sorted; the last 64 name lists)."""
        return tuple(sorted({n for key in self._layouts for n in key}))

    # -- the per-message path --------------------------------------------------------------
    def push(self, stamp_ns: int, names: Sequence[str], positions: Sequence[float],
             efforts: Sequence[float] = ()) -> tuple[JointStateBlock | JointStateGap, ...]:
        """Take one JointState message (one sample of one or both joints).

        Args:
            stamp_ns: Header stamp [ns].
            names: Joint names of the message.
            positions: Positions, same order as ``names`` (rad or counts).
            efforts: Efforts, same order (may be empty).

        Returns:
            The blocks and gaps this message completed, in stream order (usually none).
        """
        self.counters['messages'] += 1
        key = tuple(names)
        layout = self._layouts.get(key)
        if layout is None:
            layout = self._layout(key)
        i_in, i_out = layout
        if i_in < 0 and i_out < 0:
            self.counters['ignored_messages'] += 1   # none of our joints (another device)
            return _NOTHING
        out: list[JointStateBlock | JointStateGap] = []
        p_in = self._value(positions, i_in)
        p_out = self._value(positions, i_out)
        e_val = self._value(efforts, i_out) if self._use_effort else math.nan
        e_out = math.nan if e_val is None else e_val   # no effort value: torque unknown
        e_in = math.nan
        if self._use_effort_in:
            e_v = self._value(efforts, i_in)
            e_in = math.nan if e_v is None else e_v
        heads = self._head_values(key, positions) if self._head_names and p_out is not None \
            else ()
        if p_in is not None and p_out is not None and not self._half_in \
                and not self._half_out:
            self._sample(int(stamp_ns), p_in, p_out, e_out, out, heads, e_in)
            return tuple(out) if out else _NOTHING
        if p_in is not None:
            self._half_in.append((int(stamp_ns), p_in, e_in, ()))
        if p_out is not None:
            self._half_out.append((int(stamp_ns), p_out, e_out, heads))
        if p_in is None and p_out is None:   # named but no position value: missing joint
            self._problem('missing_joint', int(stamp_ns), out,
                          f'no position for {self._in_name!r}/{self._out_name!r}')
        self._pair(out)
        return tuple(out) if out else _NOTHING

    def _layout(self, key: tuple[str, ...]) -> tuple[int, int]:
        if len(self._layouts) >= _MAX_LAYOUTS:
            self._layouts.clear()
        try:
            i_in = key.index(self._in_name)
        except ValueError:
            i_in = -1
        try:
            i_out = key.index(self._out_name)
        except ValueError:
            i_out = -1
        self._layouts[key] = (i_in, i_out)
        return i_in, i_out

    def _head_values(self, key: tuple[str, ...], positions: Sequence[float],
                     ) -> tuple[float, ...]:
        """The further heads' positions of a message (NaN for a head it lacks)."""
        idx = self._head_index.get(key)
        if idx is None:
            if len(self._head_index) >= _MAX_LAYOUTS:
                self._head_index.clear()
            idx = self._head_index[key] = tuple(
                key.index(h) if h in key else -1 for h in self._head_names)
        vals = (self._value(positions, i) for i in idx)
        return tuple(math.nan if v is None else v for v in vals)

    @staticmethod
    def _value(values: Sequence[float], i: int) -> float | None:
        if i < 0:
            return None
        try:
            return float(values[i])
        except (IndexError, TypeError, ValueError):
            return None

    def _pair(self, out: list[JointStateBlock | JointStateGap]) -> None:
        """Match queued halves by stamp; unmatched ones are missing joints."""
        hin, hout, tol = self._half_in, self._half_out, self._tol_ns
        while hin and hout:
            a, b = hin[0], hout[0]
            if abs(a[0] - b[0]) <= tol:
                hin.popleft()
                hout.popleft()
                self._sample(a[0], a[1], b[1], b[2], out, b[3], a[2])
            elif a[0] < b[0]:
                hin.popleft()
                self._problem('missing_joint', a[0], out,
                              f'no {self._out_name!r} within the pairing tolerance')
            else:
                hout.popleft()
                self._problem('missing_joint', b[0], out,
                              f'no {self._in_name!r} within the pairing tolerance')
        for q, other in ((hin, self._out_name), (hout, self._in_name)):
            while len(q) > self._cfg.max_unpaired:
                t = q.popleft()[0]
                self._problem('missing_joint', t, out,
                              f'no {other!r} for {self._cfg.max_unpaired} samples')

    def _sample(self, t: int, p_in: float, p_out: float, e_out: float,
                out: list[JointStateBlock | JointStateGap],
                heads: tuple[float, ...] = (), e_in: float = math.nan) -> None:
        if not (math.isfinite(p_in) and math.isfinite(p_out)):
            self._problem('non_finite', t, out, f'position {p_in!r}/{p_out!r} at {t} ns')
            return
        last = self._last_ns
        if last is not None:
            dt = t - last
            if dt <= 0:
                self._problem('stamp_backwards', t, out,
                              f'stamp {t} ns is not after the last accepted {last} ns',
                              dropped=0)
            elif dt > self._jump_ns and self._gap is None:   # (else: the open gap's extent)
                self._problem('stamp_jump', t, out,
                              f'stamp step {dt * 1e-9:.6g} s > {STAMP_JUMP_PERIODS} periods '
                              f'({self._period_ns * 1e-9:.6g} s)', dropped=0)
        if self._gap is not None:
            self._close_gap(t, out)
        self._last_ns = t
        self._t.append(t)
        self._in.append(p_in)
        self._out.append(p_out)
        if self._use_effort:
            self._eff.append(e_out)
        if self._use_effort_in:
            self._eff_in.append(e_in)
        if self._head_names:
            self._heads.append(heads or (math.nan,) * len(self._head_names))
        if len(self._t) >= self._cfg.block_size:
            out.append(self._close_block())

    # -- gaps ------------------------------------------------------------------------------
    def _problem(self, reason: GapReason, t: int, out: list[JointStateBlock | JointStateGap],
                 detail: str, *, dropped: int = 1) -> None:
        self.counters[reason] += 1
        self.counters['samples_dropped'] += dropped
        if self._gap is None:
            if self._t:
                out.append(self._close_block())
            self._gap = _OpenGap(reason, self._last_ns, dropped, detail)
        else:
            self._gap.dropped += dropped

    def _close_gap(self, t_after: int | None,
                   out: list[JointStateBlock | JointStateGap]) -> None:
        gap, self._gap = self._gap, None
        assert gap is not None
        before = gap.stamp_before_ns
        if before is not None and t_after is not None:
            self._next_seq += 1   # the skipped seq: every consumer sees the break
        missing = 0
        if before is not None and t_after is not None and t_after > before:
            steps = round((t_after - before) / self._period_ns)
            missing = max(0, steps - 1 - gap.dropped)
        self.counters['gaps'] += 1
        out.append(JointStateGap(gap.reason, before, t_after, gap.dropped, missing,
                                 self._next_seq, gap.detail))

    # -- blocks ----------------------------------------------------------------------------
    def _close_block(self) -> JointStateBlock:
        """The open block, scaled and unwrapped (numpy, once per block)."""
        t = np.array(self._t, dtype=np.int64)
        cfg = self._cfg
        th_in = np.array(self._in, dtype=np.float64)
        th_out = np.array(self._out, dtype=np.float64)
        if cfg.position_unit == 'counts':
            th_in *= cfg.scale_in_rad
            th_out *= cfg.scale_out_rad
        if cfg.wrap_in:
            th_in, self._prev_in, self._off_in = _unwrap(th_in, self._prev_in, self._off_in)
        if cfg.wrap_out:
            th_out, self._prev_out, self._off_out = _unwrap(th_out, self._prev_out,
                                                            self._off_out)
        torque = (np.array(self._eff, dtype=np.float64) * self._cfg.effort_scale
                  if self._use_effort else _EMPTY)
        heads: dict[str, object] = {}
        if self._head_names:
            raw = np.array(self._heads, dtype=np.float64).T        # (heads - 1, n)
            if cfg.position_unit == 'counts':
                raw *= cfg.scale_out_rad
            raw_out = np.array(self._out, dtype=np.float64) * (
                cfg.scale_out_rad if cfg.position_unit == 'counts' else 1.0)
            # a head reads the same shaft within arcseconds: its turn is head 0's
            rows = th_out[None, :] + (np.mod(raw - raw_out[None, :] + math.pi, _TWO_PI)
                                      - math.pi)
            keep = [j + 1 for j in range(rows.shape[0]) if np.isfinite(rows[j]).all()]
            heads = {'out_head_ids': (0, *keep), 'theta_out_heads_rad': _readonly(
                np.vstack([th_out[None, :], rows[[k - 1 for k in keep]]]))}
            self.counters['blocks_head_missing'] += int(len(keep) < rows.shape[0])
            self._heads = []
        if self._use_effort_in:
            heads['torque_in_nm'] = _readonly(np.array(self._eff_in, dtype=np.float64)
                                              * cfg.input_effort_scale)
            self._eff_in = []
        block = JointStateBlock(
            self._next_seq, int(t[0]), float(self._cfg.sample_rate_hz),
            _readonly((t - t[0]).astype(np.float64) * 1e-9), _readonly(th_in),
            _readonly(th_out), _readonly(torque) if self._use_effort else _EMPTY,
            **heads)  # type: ignore[arg-type]
        self._next_seq += 1
        self.counters['blocks'] += 1
        self.counters['samples'] += len(self._t)
        self._t = []
        self._in = []
        self._out = []
        self._eff = []
        return block

    def flush(self) -> tuple[JointStateBlock, ...]:
        """Close the open block early (the stream paused); an open gap stays open."""
        return (self._close_block(),) if self._t else ()

    def finish(self) -> tuple[JointStateBlock | JointStateGap, ...]:
        """End of the stream: unpaired halves are missing joints; the open block and gap."""
        out: list[JointStateBlock | JointStateGap] = []
        for q, other in ((self._half_in, self._out_name), (self._half_out, self._in_name)):
            while q:
                self._problem('missing_joint', q.popleft()[0], out,
                              f'no {other!r} before the end of the stream')
        if self._t:
            out.append(self._close_block())
        if self._gap is not None:
            self._close_gap(None, out)
        return tuple(out)


def _unwrap(x: np.ndarray, prev: float, offset: float) -> tuple[np.ndarray, float, float]:
    """Continue unwrapping wrapped angles ``x`` after reading ``prev`` (offset carried).

    Returns:
        (unwrapped angles, last wrapped reading, offset [rad] of the last sample).
    """
    last = float(x[-1])
    steps = np.diff(x, prepend=x[0] if math.isnan(prev) else prev)
    turns = np.cumsum(np.round(steps / _TWO_PI))
    x -= _TWO_PI * turns
    x += offset
    return x, last, offset - _TWO_PI * float(turns[-1])
