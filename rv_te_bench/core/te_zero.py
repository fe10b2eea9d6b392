"""The zero of the TE: encoder zeros, the first sample, whole output turns (issue 33).

TE = theta_out - theta_in / i (Wang 2020 Eq. 22) is defined up to a constant: two shaft
encoders are never zeroed to the reducer. An output encoder mounted 123.4 deg off gives a
TE 123.4 deg (7404 arcmin) off; a single-turn absolute encoder that starts at 359.998 deg
gives a TE a whole output turn off. The peak-to-peak and the order lines do not see the
constant; the mean and the amplitude (max |TE|) are nothing but the constant. So the TE is
referred to a stated zero before any statistic is taken, and the report names it:

* ``'encoders'``: the encoder zeros the bench declares (a bench description's
  ``encoders.*.zero_offset_deg`` from a zeroing step, or a simulated bench, whose encoders
  read the model's shaft angles), then whole output turns removed (wrap-aware: 359.998 deg
  is -0.002 deg);
* ``'first-sample'``: the TE at the first clean sample is removed (TE starts at 0), for a
  bench whose zeros nobody declared;
* ``'auto'`` (the default): ``'encoders'`` when the bench declares its zeros, else
  ``'first-sample'``.

Applied where the samples come in (:class:`TeZero` shifts ``theta_out_rad`` of each block or
batch by one constant, latched at the first clean sample), so the windows, the cumulative
statistics, the trace and the folds downstream all see the same referred TE; the output
angle reference of the spectra (theta_in / i) is unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal, TypeAlias, TypedDict

import numpy as np

from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData, check_block
from rv_te_bench.core.units import rad_to_arcmin, rad_to_deg
from rv_te_bench.errors import TeConfigError

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator

    from rv_te_bench.core.head_combine import WindowBreak

__all__ = ['SIMULATED_ZERO_SOURCE', 'TE_ZERO_MODES', 'EncoderZero', 'TeReference',
           'TeReferenceJson', 'TeZero',
           'TeZeroMode', 'encoder_zero_from_record', 'wrap_turn_rad']

TeZeroMode: TypeAlias = Literal['auto', 'first-sample', 'encoders']
TE_ZERO_MODES: tuple[str, ...] = ('auto', 'first-sample', 'encoders')

_TWO_PI = 2.0 * math.pi

#: The zero a simulated bench declares (its encoders read the model's shaft angles).
SIMULATED_ZERO_SOURCE = "the simulated bench (encoders read the model's shaft angles)"


def wrap_turn_rad(x_rad: float) -> float:
    """An angle wrapped to [-pi, pi) [rad]: 359.998 deg -> -0.002 deg.

    Examples:
        >>> round(math.degrees(wrap_turn_rad(math.radians(359.998))), 9)
        -0.002
        >>> round(math.degrees(wrap_turn_rad(math.radians(-123.4))), 9)
        -123.4
    """
    return (float(x_rad) + math.pi) % _TWO_PI - math.pi


@dataclass(frozen=True)
class EncoderZero:
    """Encoder zeros a bench declares: the readings at the reducer's zero position.

    TE = (theta_out - output_rad) - (theta_in - input_rad) / i.

    Attributes:
        input_rad: Input encoder reading at the reducer's zero [rad].
        output_rad: Output encoder reading at the reducer's zero [rad].
        source: Where the zeros come from, for the report (e.g. the bench description).
    """

    input_rad: float = 0.0
    output_rad: float = 0.0
    source: str = ''

    def __post_init__(self) -> None:
        """Validate (finite offsets)."""
        for name in ('input_rad', 'output_rad'):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                msg = f'encoder zero {name} must be a finite number [rad], got {v!r}'
                raise TeConfigError(msg)
            object.__setattr__(self, name, float(v))


def encoder_zero_from_record(record: object) -> EncoderZero | None:
    """The encoder zeros a bench record declares (``BenchInfo.parameters_yaml`` parsed).

    * ``encoder_zero: {input_rad, output_rad, source}``: declared (a bench description with
      ``zero_offset_deg``, or a simulated bench);
    * no such key but ``bench.te_mode`` (the settings of a simulated bench, recorded before
      the key existed): the simulator's encoders read the model's shaft angles, zeros 0;
    * else None (nobody declared the zeros). A malformed ``encoder_zero`` is None as well.

    Examples:
        >>> encoder_zero_from_record({'encoder_zero': {'input_rad': 0.0, 'output_rad': 1.0,
        ...                                            'source': 'a zeroing step'}})
        EncoderZero(input_rad=0.0, output_rad=1.0, source='a zeroing step')
        >>> encoder_zero_from_record({'bench': {'source': 'bench description'}}) is None
        True
    """
    if not isinstance(record, dict):
        return None
    z = record.get('encoder_zero')
    if isinstance(z, dict):
        try:
            return EncoderZero(input_rad=z.get('input_rad', 0.0),
                               output_rad=z.get('output_rad', 0.0),
                               source=str(z.get('source') or 'the bench record'))
        except TeConfigError:
            return None
    bench = record.get('bench')
    if isinstance(bench, dict) and 'te_mode' in bench:
        return EncoderZero(source=SIMULATED_ZERO_SOURCE)
    return None


class TeReferenceJson(TypedDict):
    """The JSON of :class:`TeReference` (units in the keys)."""

    method: Literal['encoders', 'first-sample']
    source: str
    removed_rad: float
    whole_output_turns: int
    removed_within_turn_rad: float
    removed_within_turn_deg: float
    removed_within_turn_arcmin: float
    first_te_rad: float
    first_te_arcmin: float
    text: str


@dataclass(frozen=True)
class TeReference:
    """The zero the TE was referred to (what the report states).

    Attributes:
        method: ``'encoders'`` (declared encoder zeros, whole output turns removed) or
            ``'first-sample'`` (the TE at the first clean sample removed).
        removed_rad: The constant subtracted from the raw TE [rad] (whole turns included).
        whole_turns: Whole output turns in ``removed_rad``.
        source: Where the zeros come from (``'encoders'``), or the first sample's seq.
        first_te_rad: The TE at the first clean sample after the removal [rad] (0 for
            ``'first-sample'``).
    """

    method: Literal['encoders', 'first-sample']
    removed_rad: float
    whole_turns: int
    source: str
    first_te_rad: float = 0.0

    @property
    def removed_within_turn_rad(self) -> float:
        """The removed constant without its whole output turns, in [-pi, pi) [rad]."""
        return wrap_turn_rad(self.removed_rad)

    def describe(self) -> str:
        """One line for people (report, terminal)."""
        turns = (f' and {self.whole_turns:+d} whole output turn(s)' if self.whole_turns
                 else '')
        within = self.removed_within_turn_rad
        if self.method == 'first-sample':
            return (f'TE referred to its first clean sample ({self.source}): '
                    f'{rad_to_deg(within):+.6f} deg ({rad_to_arcmin(within):+.3f} arcmin)'
                    f'{turns} removed; the encoders\' zeros were not declared, so mean and '
                    'amplitude are relative to that sample')
        return (f'TE referred to the encoder zeros of {self.source}'
                + (f' ({rad_to_arcmin(within):+.3f} arcmin' + (f'{turns}' if turns else '')
                   + ' removed)' if self.removed_rad else '')
                + f'; TE at the first sample {rad_to_arcmin(self.first_te_rad):+.4f} arcmin')

    def to_json_dict(self) -> TeReferenceJson:
        """JSON (units in the keys)."""
        within = self.removed_within_turn_rad
        return {'method': self.method, 'source': self.source,
                'removed_rad': self.removed_rad, 'whole_output_turns': self.whole_turns,
                'removed_within_turn_rad': within,
                'removed_within_turn_deg': float(rad_to_deg(within)),
                'removed_within_turn_arcmin': float(rad_to_arcmin(within)),
                'first_te_rad': self.first_te_rad,
                'first_te_arcmin': float(rad_to_arcmin(self.first_te_rad)),
                'text': self.describe()}


class TeZero:
    """Refers the TE of a block stream to one zero (latched at the first clean sample).

    Args:
        mode: ``'auto'``, ``'first-sample'`` or ``'encoders'`` (module docstring).
        gear_ratio: Overall ratio i (> 0).
        declared: The bench's declared encoder zeros, or None when it declares none.

    ``'encoders'`` without declared zeros uses the encoders' own zeros (0, 0) and says so.

    Raises:
        TeConfigError: An unknown mode or a ratio that is not finite and > 0.

    Examples:
        An output encoder that starts at 359.998 deg on a zeroed input:

        >>> z = TeZero('encoders', gear_ratio=79.0, declared=None)
        >>> b = EncoderBlockData(0, 0.0, 1e3, np.array([0.0, 1e-3]), np.array([0.0, 0.079]),
        ...                      np.radians([359.998, 359.999]))
        >>> round(math.degrees(float(z.apply(b).theta_out_rad[0])), 9)
        -0.002
        >>> z.reference.whole_turns
        1
    """

    def __init__(self, mode: str, *, gear_ratio: float, declared: EncoderZero | None) -> None:
        if mode not in TE_ZERO_MODES:
            msg = f'TE zero mode must be one of {", ".join(TE_ZERO_MODES)}, got {mode!r}'
            raise TeConfigError(msg)
        if not (isinstance(gear_ratio, int | float) and math.isfinite(gear_ratio)
                and gear_ratio > 0):
            msg = f'gear_ratio must be finite and > 0, got {gear_ratio!r}'
            raise TeConfigError(msg)
        self.mode = mode
        self.method: Literal['encoders', 'first-sample'] = (
            'encoders' if mode == 'encoders' or (mode == 'auto' and declared is not None)
            else 'first-sample')
        self.declared = declared if declared is not None else EncoderZero(
            source="the encoders' own zeros (none declared)")
        self.gear_ratio = float(gear_ratio)
        self.reference: TeReference | None = None
        self._shift = 0.0

    def _latch(self, seq: int, th_in: np.ndarray, th_out: np.ndarray) -> bool:
        ok = np.isfinite(th_in) & np.isfinite(th_out)
        if not ok.any():
            return False
        k = int(np.argmax(ok))
        raw = float(th_out[k]) - float(th_in[k]) / self.gear_ratio
        if self.method == 'first-sample':
            shift, first = raw, 0.0
            source = f'block seq {seq}, sample {k}'
        else:
            d = self.declared
            base = d.output_rad - d.input_rad / self.gear_ratio
            shift = base + _TWO_PI * round((raw - base) / _TWO_PI)
            first = raw - shift
            source = d.source
        self._shift = shift
        self.reference = TeReference(method=self.method, removed_rad=shift,
                                     whole_turns=round((shift - wrap_turn_rad(shift))
                                                       / _TWO_PI),
                                     source=source, first_te_rad=first)
        return True

    def apply(self, block: EncoderBlockData) -> EncoderBlockData:
        """The block with its output angles referred to the zero (a malformed block is
        returned as it is: the analyzer counts it)."""
        if self.reference is None:
            clean = check_block(block)
            if not isinstance(clean, tuple) or not self._latch(block.seq, clean[2], clean[3]):
                return block
        if self._shift == 0.0:
            return block
        try:
            th_out = np.asarray(block.theta_out_rad, dtype=np.float64) - self._shift
        except (TypeError, ValueError):
            return block
        return replace(block, theta_out_rad=th_out)

    def apply_batch(self, batch: EncoderBatch) -> EncoderBatch:
        """As :meth:`apply` for a batch of consecutive blocks."""
        first = 0   # blocks before the one latched on stay as they are (as in apply)
        if self.reference is None:
            for k in range(batch.n_blocks):
                blk = batch.block(k)
                clean = check_block(blk)
                if isinstance(clean, tuple) and self._latch(blk.seq, clean[2], clean[3]):
                    first = int(batch.starts[k])
                    break
            if self.reference is None:
                return batch
        if self._shift == 0.0:
            return batch
        th_out = np.array(batch.theta_out_rad, dtype=np.float64)
        th_out[first:] -= self._shift
        return replace(batch, theta_out_rad=th_out)

    def stream(self, items: Iterable[EncoderBlockData | EncoderBatch | WindowBreak],
               ) -> Iterator[EncoderBlockData | EncoderBatch | WindowBreak]:
        """Apply to each block or batch of an iterable, lazily (anything else, such as a
        head combination's ``WindowBreak`` marker, is passed on unchanged)."""
        for item in items:
            if isinstance(item, EncoderBatch):
                yield self.apply_batch(item)
            elif isinstance(item, EncoderBlockData):
                yield self.apply(item)
            else:
                yield item
