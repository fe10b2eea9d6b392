"""``rv-te identify BAG``: eccentricities of a 2K-V unit from a recorded TE session.

Streams the encoder blocks of a rosbag2/MCAP bag (an MCAP chunk at a time, memory
independent of the length), forms the TE of Wang 2020 Eq. 22 (TE = theta_out - theta_in / i)
and folds it onto one output revolution of the kinematic output angle theta_in / i (zero = the
assembly reference t0); fits the Wang 2020 Eqs 1-8 model and prints what one TE record can
tell: the pair sums Q1, Q2 and the output-wheel eccentricity E (up to their label swap),
with 1-sigma errors and the fit quality. The split into theta_p1, theta_p2, theta_g needs
the part magnitudes e_p1, e_p2, e_g: the preset's values unless given (``--set``, from
runout inspection); then it recommends re-assembly phases (Wang 2020 Eq. 21), unless the model
explains too little of the TE (``--min-explained``). A damaged bag is read up to the damage
and the result marked PARTIAL, as ``rv-te analyze`` does.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.cli._heads import add_heads_arguments, encoder_note, heads_combiner
from rv_te_bench.cli._progress import ProgressBar
from rv_te_bench.cli.argtypes import nonnegative_int, positive_float
from rv_te_bench.cli.optimize_phases import (
    add_search_arguments,
    check_search_arguments,
    format_result,
    load_wang_params,
)
from rv_te_bench.errors import BagError, BenchInfoError, CompensationError, RvTeError, TeInputError
from rv_te_bench.safe_yaml import one_line
from sim.errors import SimError
from sim.units import rad_to_deg

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.core.angle_fold import FoldedTe
    from rv_te_bench.core.head_combine import HeadCombiner
    from rv_te_bench.core.identify import Identification
    from rv_te_bench.core.phases import EccentricGeometry
    from rv_te_bench.core.stream_records import GapEvent
    from sim.bench_info import BenchInfoData
    from sim.presets import Preset

EXAMPLES = """\
examples:
  rv-te identify out/session_bag                      identify and recommend re-assembly
  rv-te identify out/session_bag --json --no-recommend
  rv-te identify bag.mcap --set eccentricity.e_p1_m=1.2e-5 --set eccentricity.e_g_m=8e-6
                                                      part magnitudes measured on the parts
  rv-te identify real.mcap --preset wang2020-2kv --ratio 79
                                                      a bag without (readable) BenchInfo

exit codes: 0 ok (partial results are marked PARTIAL; withheld advice is not an error),
1 failed (one ERROR: line on stderr), 2 bad usage
"""

#: Preset keys of the part magnitudes that split the pair sums.
MAGNITUDE_KEYS = ('eccentricity.e_p1_m', 'eccentricity.e_p2_m', 'eccentricity.e_g_m')


def register(subparsers: Subparsers) -> None:
    """Add the ``identify`` subcommand."""
    p = subparsers.add_parser(
        'identify', help='identify 2K-V eccentricities from a bag; recommend re-assembly',
        description=__doc__.split('\n\n', 1)[1] if __doc__ else None, epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bag', help='bag folder or .mcap file with EncoderBlock messages')
    p.add_argument('--topic', default=None, help='EncoderBlock topic (default: the only one)')
    p.add_argument('--preset', default=None,
                   help="preset (default: the bag's BenchInfo preset)")
    p.add_argument('--set', dest='overrides', action='append', default=[],
                   metavar='KEY=VALUE', help='override a preset value, e.g. part magnitudes')
    p.add_argument('--ratio', type=positive_float, metavar='I', default=None,
                   help="overall gear ratio i (default: BenchInfo, else the preset's)")
    p.add_argument('--crank-per-output', type=positive_float, metavar='C', default=None,
                   help="absolute crank revs per output rev (default: the preset's, 25 for "
                        'the Wang 2020 2K-V)')
    p.add_argument('--seed', type=nonnegative_int, default=0,
                   help='seed of the random fit starts (integer >= 0)')
    p.add_argument('--min-explained', type=float, default=None, metavar='F',
                   help='share of the TE variance the model must explain for re-assembly '
                        'advice (default 0.99)')
    p.add_argument('--no-recommend', action='store_true', help='identify only')
    add_heads_arguments(p)
    add_search_arguments(p)
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=run)


@dataclass
class BagRecord:
    """What streaming a bag left: the folded TE and what the reading met.

    Attributes:
        folded: The TE folded onto one output revolution.
        blocks: Encoder blocks read.
        partial: Part of the bag could not be read.
        problems: Read problems (one line each).
        skipped_samples: Non-finite or malformed samples left out.
        gaps: Breaks in the block stream (seq jumps with their time and length, time going
            backwards), as ``rv-te analyze`` reports them.
    """

    folded: FoldedTe
    blocks: int = 0
    partial: bool = False
    problems: list[str] = field(default_factory=list)
    skipped_samples: int = 0
    gaps: list[GapEvent] = field(default_factory=list)


def fold_bag(path: str, topic: str | None, gear_ratio: float, *,
             progress: Callable[[int, int], None] | None = None,
             combiner: HeadCombiner | None = None) -> BagRecord:
    """Stream a bag's encoder blocks into an :class:`AngleFold` (phi = theta_in / i).

    Reads with ``strict=False``: a damaged part ends the read, what came before is kept
    and the record is marked partial. With ``combiner`` the output angle is formed from
    the read heads (and a calibration) first (:mod:`rv_te_bench.core.head_combine`).

    Raises:
        BagError: Not a bag, no encoder topic, or no block readable.
    """
    from rv_te_bench.core.angle_fold import AngleFold
    from rv_te_bench.core.head_combine import WindowBreak, combine_stream
    from rv_te_bench.core.seq_gaps import SeqGapWatch
    from rv_te_bench.core.stream_records import EncoderBatch
    from rv_te_bench.io.bag_reader import (
        read_encoder_batches,
        summarize_problems,
    )

    fold = AngleFold()
    watch = SeqGapWatch()
    stream = read_encoder_batches(path, topic, strict=False)
    blocks = samples = malformed = 0
    extra: list[str] = []
    items = stream if combiner is None else combine_stream(stream, combiner)
    try:
        for item in items:
            if isinstance(item, WindowBreak):   # the fold needs no window: nothing to do
                continue
            if isinstance(item, EncoderBatch):
                blocks += item.n_blocks
                th_in, th_out = item.theta_in_rad, item.theta_out_rad
                starts = np.asarray(item.starts, dtype=np.intp)
                offs = np.asarray(item.time_offset_s, dtype=np.float64)
                stamp = np.asarray(item.stamp_s, dtype=np.float64)
                watch.add(item.seq, stamp + offs[starts[:-1]], stamp + offs[starts[1:] - 1],
                          np.asarray(item.sample_rate_hz, dtype=np.float64))
            else:
                blocks += 1
                th_in = np.asarray(item.theta_in_rad, dtype=np.float64)
                th_out = np.asarray(item.theta_out_rad, dtype=np.float64)
                if th_in.shape != th_out.shape:
                    malformed += max(th_in.size, th_out.size)
                    continue
                offs = np.asarray(item.time_offset_s, dtype=np.float64)
                if offs.size == th_in.size and th_in.size and isinstance(item.seq, int) \
                        and isinstance(item.stamp_s, int | float):
                    watch.add(np.array([item.seq]), np.array([item.stamp_s + offs[0]]),
                              np.array([item.stamp_s + offs[-1]]),
                              np.array([float(item.sample_rate_hz)]))
            samples += th_in.size
            fold.add_encoders(th_in, th_out, gear_ratio=gear_ratio)
            if progress is not None:
                progress(blocks, samples)
    except BagError as exc:   # e.g. the topic changes type further on: keep what came before
        extra.append(str(exc))
    problems = [*stream.problems, *extra]
    if blocks == 0:
        detail = summarize_problems(problems) or 'the encoder topic holds no messages'
        msg = f'{path}: no encoder block could be read ({detail})'
        raise BagError(msg)
    return BagRecord(folded=fold.result(), blocks=blocks,
                     partial=bool(problems) or stream.partial, problems=problems,
                     skipped_samples=fold.skipped + malformed, gaps=watch.gaps)


def _bench_info(args: argparse.Namespace) -> tuple[BenchInfoData | None, str | None]:
    """(BenchInfo, problem): a damaged BenchInfo is a problem only without the flags."""
    from rv_te_bench.io.bag_reader import read_bench_info

    try:
        return read_bench_info(args.bag), None
    except BenchInfoError as exc:   # readable messages, damaged BenchInfo: the hint helps
        if args.preset is None:
            msg = (f'{str(exc).rstrip(".")}; give --preset (and --ratio if the bench ran '
                   'another ratio) to identify without it')
            raise BagError(msg) from None
        del exc   # the damaged chunk is reported again by the encoder read
        return None, (f'no readable BenchInfo: preset {args.preset} and '
                      f'{"--ratio" if args.ratio else "its ratio"} used instead')


def _setup(args: argparse.Namespace, info: BenchInfoData | None,
           ) -> tuple[Preset, EccentricGeometry, float, str]:
    """(preset, params, gear ratio, source of the part magnitudes)."""
    from rv_te_bench.core.phases import EccentricGeometry
    from rv_te_bench.io.bench_record import overrides_from_parameters_yaml

    if args.preset is None and info is None:
        msg = (f'{args.bag}: no BenchInfo in the bag: give --preset (and --ratio if the bench '
               "ran another ratio than the preset's)")
        raise TeInputError(msg)
    # the bench's own overrides (recorded in BenchInfo) first, then --set
    recorded = ([] if args.preset or info is None else
                overrides_from_parameters_yaml(info.parameters_yaml))
    name = args.preset if args.preset else ('' if info is None else info.preset)
    preset, wang = load_wang_params(name, [*recorded, *args.overrides])
    ratio = args.ratio or (info.gear_ratio if info is not None and info.gear_ratio
                           else float(wang.kinematics.gear_ratio))
    params = EccentricGeometry.from_params(wang)
    if args.crank_per_output is not None:
        params = replace(params, crank_order=math.copysign(args.crank_per_output,
                                                           params.crank_order))
    keys = {o.split('=', 1)[0].strip() for o in args.overrides}
    rec_keys = {o.split('=', 1)[0].strip() for o in recorded}
    if keys & set(MAGNITUDE_KEYS):
        source = 'given with --set'
    elif rec_keys & set(MAGNITUDE_KEYS):
        source = "the bench's preset overrides recorded in BenchInfo (a simulated unit)"
    else:
        source = f'preset {preset.name} values, assumed, not measured on this unit'
    return preset, params, ratio, source


def _deg(x: float) -> float:
    return float(rad_to_deg(x))


def _text(idf: Identification, source: str) -> str:
    from rv_te_bench.core.identify import OBSERVABILITY

    head = f'  {"quantity":<34} {"e [um]":>8} {"1s [um]":>8} {"phase [deg]":>11} {"1s [deg]":>8}'
    lines = ['identified from the TE record (' + OBSERVABILITY['identified_from_te'][3] + '):',
             head]
    rows = (('Q1 = e_p1 + e_g  (pair-1 sum)', 'pair1', 'pair1', None),
            ('Q2 = e_p2 - e_g  (pair-2 sum)', 'pair2', 'pair2', None),
            ('E  = e_ot  (output wheel)', 'e_ot', 'theta_ot', 'theta_ot'))
    for label, key, ph, sph in rows:
        sig_deg = (_deg(idf.sigma_rad[sph]) if sph else
                   _deg(idf.sigma_m[key] / idf.e_m[key] / math.sqrt(2)) if idf.e_m[key] else
                   math.nan)
        lines.append(f'  {label:<34} {idf.e_m[key] * 1e6:8.3f} {idf.sigma_m[key] * 1e6:8.4f} '
                     f'{_deg(idf.phases_rad[ph]):11.2f} {sig_deg:8.3f}')
    fit = idf.fit
    lines.append(f'  {fit.describe()}')
    lines.append(f'  pair contact {idf.contact_fraction[0]:.2f} / {idf.contact_fraction[1]:.2f}, '
                 f'{idf.output_revolutions:.2f} output revolutions, {idf.n_samples} samples')
    lines += ['', 'needs the part magnitudes (one TE record cannot separate planet and '
                  'revolution eccentricity):']
    if idf.split_resolved:
        lines.append(f'  magnitudes: {source}')
        for key, ph in (('e_p1', 'theta_p1'), ('e_p2', 'theta_p2'), ('e_g', 'theta_g')):
            lines.append(f'  {key:<6} {idf.assumed_e_m[key] * 1e6:8.3f} um (given)  {ph:<9} '
                         f'{_deg(idf.phases_rad[ph]):8.2f} deg  (1s {_deg(idf.sigma_rad[ph]):.3f})')
        lines.append(f'  split misfit {idf.split_residual_m * 1e6:.3f} um; a 1 % error of Q1/Q2 '
                     f'turns these phases by <= {idf.split_deg_per_pct:.2f} deg, 1 um of '
                     f'magnitude error by <= {idf.split_deg_per_um:.2f} deg'
                     + ('' if idf.split_well_posed else ' (NOT well posed)'))
    else:
        lines.append('  not split (no part magnitudes)')
    lines += [f'note: {n}' for n in idf.notes()]
    return '\n'.join(lines)


class _Progress:
    """A progress line on stderr every 2 s while the bag is read."""

    def __init__(self, name: str) -> None:
        self._clock = time.monotonic
        self._t0 = self._clock()
        self._next = 2.0
        self._name = name

    def __call__(self, blocks: int, samples: int) -> None:
        dt = self._clock() - self._t0
        if dt >= self._next:
            self._next = dt + 2.0
            print(f'{self._name}: {blocks} blocks, {samples / 1e6:.2f} M samples read',
                  file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 ok, 1 domain error (one ``ERROR:`` line on stderr)."""
    try:
        return _run(args)
    except BrokenPipeError:
        # stdout closed early (``rv-te identify bag | head -1``): not a failure
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


def _run(args: argparse.Namespace) -> int:
    from rv_te_bench.allocator import tune_for_batch_work
    from rv_te_bench.core.identify import (
        MIN_EXPLAINED_FRACTION,
        identify_folded,
        recommend_reassembly,
    )

    tune_for_batch_work()
    bar = None
    rec = None
    withheld = None
    try:
        check_search_arguments(args)
        min_explained = (MIN_EXPLAINED_FRACTION if args.min_explained is None
                         else args.min_explained)
        if not (math.isfinite(min_explained) and 0.0 <= min_explained <= 1.0):
            msg = f'--min-explained must be between 0 and 1, got {args.min_explained!r}'
            raise CompensationError(msg)
        info, info_problem = _bench_info(args)
        preset, params, ratio, source = _setup(args, info)
        combiner = heads_combiner(args, info)
        record = fold_bag(args.bag, args.topic, ratio,
                          progress=None if args.quiet else _Progress(str(args.bag)),
                          combiner=combiner)
        if info_problem:
            record.problems.insert(0, info_problem)
            record.partial = True
        idf = identify_folded(record.folded, params, rng=np.random.default_rng(args.seed))
        note = encoder_note(info, combiner, args.calibration_record, record.folded)
        idf = replace(idf, fit=replace(idf.fit, min_explained_fraction=min_explained))
        if not args.no_recommend:
            if idf.fit.acceptable:
                bar = None if args.quiet else ProgressBar('re-assembly grid')
                rec = recommend_reassembly(idf, params, step_deg=args.step_deg,
                                           refine=args.refine,
                                           refine_tol_deg=args.refine_tol_deg, progress=bar)
            else:
                withheld = (f're-assembly advice withheld: the model explains '
                            f'{100 * idf.fit.explained_fraction:.2f} % of the TE variance, '
                            f'below {100 * min_explained:g} % (--min-explained)')
    except (SimError, RvTeError) as exc:
        if bar is not None:
            bar.close()
        print(f'ERROR: {one_line(exc)}', file=sys.stderr)
        return 1
    if bar is not None:
        bar.close()
    from rv_te_bench.io.bag_reader import summarize_problems

    if record.partial:
        print(f'PARTIAL: {args.bag}: {record.blocks} blocks read; part of the bag is '
              f'unreadable: {summarize_problems(record.problems)}', file=sys.stderr)
    if record.skipped_samples:
        print(f'WARNING: {args.bag}: {record.skipped_samples} non-finite or malformed samples '
              'left out', file=sys.stderr)
    if record.gaps:
        print(f'WARNING: {args.bag}: {len(record.gaps)} gap(s) in the encoder stream (the TE '
              'is folded from the data on both sides)', file=sys.stderr)
        for g in record.gaps[:10]:
            print(f'  {g.kind} at seq {g.seq}: {g.detail}', file=sys.stderr)
        if len(record.gaps) > 10:
            print(f'  ... {len(record.gaps) - 10} more (see --json)', file=sys.stderr)
    if args.json:
        out: dict[str, Any] = {
            'bag': str(args.bag), 'preset': preset.name, 'partial': record.partial,
            'problems': record.problems, 'blocks_read': record.blocks,
            'skipped_samples': record.skipped_samples,
            'gaps': [{'kind': g.kind, 'seq': g.seq, 'detail': g.detail,
                      'at_s': g.at_s, 'missing_s': g.missing_s, 't_before_s': g.t_before_s,
                      't_after_s': g.t_after_s} for g in record.gaps],
            'gear_ratio': ratio,
            'part_magnitudes_source': source, 'identification': idf.to_json_dict(),
            'advice_withheld': withheld,
            'encoder': {'heads': None if combiner is None else combiner.report(),
                        'calibration_source': getattr(args, 'calibration_source', ''),
                        'once_per_rev': note.to_plain()},
            'advice_encoder_flag': note.text() if note.comparable and not note.separated
            else ''}
        if rec is not None:
            out['reassembly'] = rec.to_json_dict()
            out['advice'] = rec.to_advice(
                preset.name, method='identified-assembly-phases').to_json_dict()
        print(json.dumps(out, indent=2))
        return 0
    flag = '  [PARTIAL]' if record.partial else ''
    print(f'Eccentricities identified from {args.bag} (preset {preset.name}, i = {ratio:.6g})'
          f'{flag}\n')
    print(_text(idf, source))
    print(f'\n{note.text()}')
    if rec is not None and note.comparable and not note.separated:
        print('FLAG: the re-assembly advice below rests on the once-per-revolution line, '
              'which the output encoder could produce in part (see above)')
    if rec is not None:
        print()
        print(format_result(rec, 'Recommended re-assembly (turn each part from the '
                                 'identified to the recommended phase)'))
    elif withheld is not None:
        print(f'\n{withheld}')
    return 0
