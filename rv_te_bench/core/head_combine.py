"""Each block's shaft angles formed from its read heads, and a scale calibration applied.

The one place where a session (the TE node, ``rv-te analyze``, ``rv-te identify``, the
compensation node) turns the heads of an ``EncoderBlock`` into the angle its TE uses:

* the bench's record (:class:`~sim.bench_info.BenchInfoData`) says where each scale's heads
  sit; :class:`HeadCombiner` takes their weighted mean (:class:`~.heads.HeadLayout`:
  equal-division averaging, which cancels every scale harmonic not a multiple of N);
* an :class:`~.encoder_calibration.EncoderCalibration` of a scale, checked against the
  scale's serial in the record, is taken off each head's reading first (at the head's angle
  and the scale's index), and with it the orders the heads alone leave;
* a block that lacks a head (a read head fault, a DAQ channel lost) is combined from the
  heads it has when they still cancel the once-per-revolution error (else from head 0 with
  the calibration, else head 0 as it is) and reported as a :class:`HeadEvent`: the scale
  error left differs there, so the caller closes the window it is in (no spectrum mixes two
  head sets); no sample is dropped.

``mode='head0'`` uses head 0 alone (with the calibration when given): the one-head view of
the same session, for comparison.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Literal, TypedDict

import numpy as np

from rv_te_bench.core.heads import HeadLayout
from rv_te_bench.errors import EncoderCalibrationError, HeadLayoutError, TeConfigError

if TYPE_CHECKING:
    import datetime as _dt
    from collections.abc import Iterable, Iterator

    from rv_te_bench.core.encoder_calibration import CalibrationFile, EncoderCalibration
    from rv_te_bench.core.heads import HeadLayoutJson
    from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData
    from sim.bench_info import BenchInfoData

__all__ = ['HEAD_MODES', 'MAX_EVENTS_KEPT', 'HeadCombiner', 'HeadEvent', 'ScaleHeads',
           'ScaleHeadsJson', 'WindowBreak', 'combine_stream']

HeadMode = Literal['average', 'head0']
HEAD_MODES: tuple[str, ...] = ('average', 'head0')
_SIDES = ('in', 'out')
#: Head events a combiner keeps for the report (all are counted).
MAX_EVENTS_KEPT = 100


@dataclass(frozen=True)
class HeadEvent:
    """A block whose heads differ from the scale's full set.

    Attributes:
        seq: The block.
        side: ``'in'`` or ``'out'``.
        missing: Head numbers absent from the block.
        used: Head numbers its angle was formed from.
        detail: One line for people.
    """

    seq: int
    side: str
    missing: tuple[int, ...]
    used: tuple[int, ...]
    detail: str


@dataclass(frozen=True)
class WindowBreak:
    """Marker in a block stream: the read heads forming the angle change here; the TE core
    closes its open window (:meth:`StreamingTeAnalyzer.split_window`) before what follows.

    Attributes:
        seq: The first block after the change.
        detail: Why, for people.
    """

    seq: int
    detail: str


class ScaleHeadsJson(TypedDict):
    """The JSON of :class:`ScaleHeads` (what is done to one shaft's heads)."""

    mode: HeadMode
    n_heads: int
    layout: HeadLayoutJson | None
    calibration: CalibrationFile | None
    index_rad: float
    description: str


@dataclass(frozen=True)
class ScaleHeads:
    """How one shaft's angle is formed.

    Attributes:
        layout: The scale's heads (None: one head, nothing to combine).
        calibration: The scale's calibration taken off each reading (None: none).
        index_rad: The scale's index on its shaft [rad].
        mode: ``'average'`` or ``'head0'``.
        n_heads: Heads the bench states for the scale.
        angles_rad: Their angles (head number = index) [rad].
    """

    layout: HeadLayout | None
    calibration: EncoderCalibration | None
    index_rad: float
    mode: HeadMode
    n_heads: int = 1
    angles_rad: tuple[float, ...] = (0.0,)

    @property
    def active(self) -> bool:
        """Whether anything is done to the shaft's readings."""
        return self.calibration is not None or (
            self.layout is not None and self.mode == 'average')

    def describe(self) -> str:
        """One line for people."""
        parts = []
        if self.mode == 'head0' and self.n_heads > 1:
            parts.append(f'head 0 of {self.n_heads} alone (mode head0)')
        elif self.layout is None:
            parts.append('one read head')
        else:
            parts.append(self.layout.describe())
        if self.calibration is not None:
            parts.append(f'calibration applied: {self.calibration.describe()}')
        return '; '.join(parts)

    def to_plain(self) -> ScaleHeadsJson:
        """JSON-friendly."""
        return {'mode': self.mode, 'n_heads': self.n_heads,
                'layout': None if self.layout is None else self.layout.to_plain(),
                'calibration': (None if self.calibration is None
                                else self.calibration.to_plain()),
                'index_rad': self.index_rad, 'description': self.describe()}


class HeadCombiner:
    """Forms blocks' shaft angles from their heads (see the module docstring).

    Args:
        info: The bench's record (head angles, scale serials and indices).
        mode: ``'average'`` (mean of the heads) or ``'head0'``.
        calibration_out: Calibration of the output scale (None: none).
        calibration_in: Calibration of the input scale.

    Raises:
        HeadLayoutError: The record's head angles cannot be averaged (names them).
        EncoderCalibrationError: A calibration of another scale, or expired.
        TeConfigError: An unknown mode.
    """

    def __init__(self, info: BenchInfoData, *, mode: str = 'average',
                 calibration_out: EncoderCalibration | None = None,
                 calibration_in: EncoderCalibration | None = None,
                 when: _dt.date | None = None) -> None:
        """See the class docstring (``when``: the day the readings were taken, for the
        calibrations' validity; None: today)."""
        if mode not in HEAD_MODES:
            msg = f'heads mode must be one of {list(HEAD_MODES)}, got {mode!r}'
            raise TeConfigError(msg)
        scales = {}
        for side, cal in (('in', calibration_in), ('out', calibration_out)):
            angles = tuple(getattr(info, f'encoder_{side}_head_angles_rad'))
            try:   # head 0 alone needs no averaging: any layout will do
                layout = (HeadLayout.of(angles) if len(angles) > 1 and mode == 'average'
                          else None)
            except HeadLayoutError as exc:
                msg = f'the bench\'s {side}put scale: {exc}'
                raise HeadLayoutError(msg) from None
            if cal is not None:
                cal.check_for(getattr(info, f'encoder_{side}_scale_serial'), when=when)
            scales[side] = ScaleHeads(layout, cal, float(getattr(
                info, f'encoder_{side}_scale_index_rad')), mode,  # type: ignore[arg-type]
                max(1, len(angles)), tuple(float(a) for a in angles) or (0.0,))
        self.scales: dict[str, ScaleHeads] = scales
        self.counters = {'blocks': 0, 'blocks_head_missing': 0}
        self.events: list[HeadEvent] = []      # the first MAX_EVENTS_KEPT
        self._subsets: dict[tuple[str, tuple[int, ...]], HeadLayout | None] = {}

    @property
    def active(self) -> bool:
        """Whether any shaft's readings are changed (else blocks pass unchanged)."""
        return any(s.active for s in self.scales.values())

    def describe(self) -> dict[str, ScaleHeadsJson]:
        """What is done to each shaft, JSON-friendly (report, bag metadata)."""
        return {f'{side}put': s.to_plain() for side, s in self.scales.items()}

    def report(self) -> dict[str, Any]:
        """:meth:`describe` with the counters and the events kept (for the report)."""
        return {**self.describe(), 'counters': dict(self.counters),
                'events': [e.detail for e in self.events]}

    def _subset(self, side: str, ids: tuple[int, ...]) -> HeadLayout | None:
        key = (side, ids)
        if key not in self._subsets:
            layout = self.scales[side].layout
            try:
                self._subsets[key] = (layout.subset(ids) if layout is not None and len(ids) > 1
                                      else None)
            except HeadLayoutError:
                self._subsets[key] = None
        return self._subsets[key]

    def _shaft(self, side: str, seq: int, primary: np.ndarray, ids: tuple[int, ...],
               heads: np.ndarray) -> tuple[np.ndarray, HeadEvent | None]:
        scale = self.scales[side]
        if not scale.active:
            return primary, None
        layout = scale.layout
        cal = scale.calibration
        want = layout.head_ids if layout is not None else (0,)
        have = ids if ids else (0,)                       # no heads sent: theta is head 0
        rows = heads if ids else primary[None, :]
        angle_of = dict(enumerate(scale.angles_rad))      # head number -> its angle [rad]

        def corrected(r: np.ndarray, h: int) -> np.ndarray:
            if cal is None:
                return r
            return cal.correct(r, head_angle_rad=angle_of.get(h, 0.0),
                               index_rad=scale.index_rad)

        if scale.mode == 'head0' or layout is None:
            pick = have.index(0) if 0 in have else 0
            event = None if 0 in have else HeadEvent(
                seq, side, (0,), (have[pick],), f'block seq {seq}: {side}put head 0 missing: '
                f'head {have[pick]} used')
            return corrected(rows[pick], have[pick]), event
        rows = np.vstack([corrected(r, h) for h, r in zip(have, rows, strict=True)])
        if have == want:
            return layout.combine(rows), None
        missing = tuple(h for h in want if h not in have)
        sub = self._subset(side, have)
        if sub is not None:
            order = [have.index(h) for h in sub.head_ids]
            out = sub.combine(rows[order])
            used = sub.head_ids
            how = (f'mean of heads {list(used)} (weights {[round(w, 3) for w in sub.weights]})')
        else:
            pick = have.index(0) if 0 in have else 0
            out = rows[pick]
            used = (have[pick],)
            how = (f'head {have[pick]} alone' + (' with the calibration' if cal else
                                                  ': the scale error is not averaged out'))
        event = HeadEvent(seq, side, missing, used,
                          f'block seq {seq}: {side}put head(s) {list(missing)} missing; '
                          f'angle from the {how}')
        return out, event

    def block(self, b: EncoderBlockData) -> tuple[EncoderBlockData, list[HeadEvent]]:
        """The block with its shaft angles formed from its heads, and its events.

        A malformed head field (rows that do not fit the block) is left for the TE core to
        count: the block passes with its primary readings and an event naming it.
        """
        self.counters['blocks'] += 1
        if not self.active:
            return b, []
        events: list[HeadEvent] = []
        values: dict[str, np.ndarray] = {}
        for side in _SIDES:
            primary = np.asarray(getattr(b, f'theta_{side}_rad'), dtype=np.float64)
            ids = tuple(int(i) for i in getattr(b, f'{side}_head_ids'))
            heads = np.asarray(getattr(b, f'theta_{side}_heads_rad'), dtype=np.float64)
            if ids and heads.shape != (len(ids), primary.size):
                events.append(HeadEvent(b.seq, side, (), (), (
                    f'block seq {b.seq}: {side}put heads malformed ({len(ids)} ids, readings '
                    f'of shape {heads.shape} for {primary.size} samples); head 0 used')))
                ids, heads = (), heads[:0]
            out, event = self._shaft(side, b.seq, primary, ids, heads)
            values[f'theta_{side}_rad'] = out
            if event is not None:
                events.append(event)
        if events:
            self.counters['blocks_head_missing'] += 1
            self.events.extend(events[:max(0, MAX_EVENTS_KEPT - len(self.events))])
        return replace(b, theta_in_rad=values['theta_in_rad'],
                       theta_out_rad=values['theta_out_rad']), events

    def batch(self, b: EncoderBatch) -> EncoderBatch:
        """A batch (every block with the same heads, as the bag reader makes them) with its
        shaft angles formed; a batch missing heads is split by the caller into blocks."""
        self.counters['blocks'] += int(b.n_blocks)
        if not self.active:
            return b
        values = {}
        for side in _SIDES:
            primary = getattr(b, f'theta_{side}_rad')
            ids = tuple(int(i) for i in getattr(b, f'{side}_head_ids'))
            heads = getattr(b, f'theta_{side}_heads_rad')
            out, event = self._shaft(side, int(b.seq[0]), primary, ids, heads)
            if event is not None:
                msg = 'HeadCombiner.batch takes batches with every head (use block())'
                raise EncoderCalibrationError(msg)
            values[f'theta_{side}_rad'] = out
        return replace(b, theta_in_rad=values['theta_in_rad'],
                       theta_out_rad=values['theta_out_rad'])

    def batch_complete(self, b: EncoderBatch) -> bool:
        """Whether every block of the batch carries every head it needs of both scales
        (head 0 in mode head0: ``theta_*_rad`` is head 0 when it is there)."""
        for side in _SIDES:
            scale = self.scales[side]
            if not scale.active:
                continue
            ids = tuple(int(i) for i in getattr(b, f'{side}_head_ids'))
            if scale.layout is None:
                if ids and 0 not in ids:
                    return False
            elif ids != scale.layout.head_ids:
                return False
        return True


def combine_stream(items: Iterable[EncoderBlockData | EncoderBatch], combiner: HeadCombiner,
                   ) -> Iterator[EncoderBlockData | EncoderBatch | WindowBreak]:
    """The items of a bag reader with their angles formed from the heads, and a
    :class:`WindowBreak` wherever the set of heads used changes (both ways)."""
    from rv_te_bench.core.stream_records import EncoderBatch

    if not combiner.active:
        yield from items
        return
    used: str | tuple[tuple[str, tuple[int, ...]], ...] | None = None   # 'all': every head
    for item in items:
        if isinstance(item, EncoderBatch) and combiner.batch_complete(item):
            if used not in (None, 'all'):
                yield WindowBreak(int(item.seq[0]), 'every head back')
            used = 'all'
            yield combiner.batch(item)
            continue
        blocks = ([item.block(k) for k in range(item.n_blocks)]
                  if isinstance(item, EncoderBatch) else [item])
        for block in blocks:
            out, events = combiner.block(block)
            now = 'all' if not events else tuple((e.side, e.used) for e in events)
            if used is not None and now != used:
                yield WindowBreak(int(block.seq), events[0].detail if events
                                  else 'every head back')
            used = now
            yield out
