"""Command-line options of the read heads and the encoder calibration (issue 36), shared by
``rv-te analyze`` and ``rv-te identify``."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rv_te_bench.core.angle_fold import FoldedTe
    from rv_te_bench.core.encoder_attribution import OncePerRevNote
    from rv_te_bench.core.encoder_calibration import EncoderCalibration
    from rv_te_bench.core.head_combine import HeadCombiner
    from sim.bench_info import BenchInfoData


def add_heads_arguments(p: argparse.ArgumentParser) -> None:
    """``--heads`` and ``--calibration``."""
    p.add_argument('--heads', choices=('average', 'head0'), default='average',
                   help="a scale with several read heads (the bag's BenchInfo): their mean "
                        '(equal-division averaging: every scale harmonic not a multiple of '
                        'their number cancels) or head 0 alone')
    p.add_argument('--calibration', metavar='FILE', default=None,
                   help='encoder calibration of the output scale (rv-te selfcal) to take off '
                        "its readings; its scale serial must be the bag's. Without it, the "
                        "calibration the session's TE node applied live (te/encoder_heads in "
                        'the bag) is applied, so the offline TE is the live one')
    p.add_argument('--no-session-calibration', action='store_true',
                   help="do not apply the calibration the session's TE node applied (the "
                        'uncalibrated readings)')


def load_calibration(args: argparse.Namespace) -> EncoderCalibration | None:
    """The ``--calibration`` file, read and checked (kept on ``args.calibration_record``).

    Raises:
        EncoderCalibrationError: Unreadable or invalid (one line).
    """
    from rv_te_bench.io.calibration_file import load_encoder_calibration

    cal = None if args.calibration is None else load_encoder_calibration(args.calibration)
    args.calibration_record = cal
    return cal


def heads_combiner(args: argparse.Namespace, info: BenchInfoData | None) -> HeadCombiner | None:
    """The head combination ``--heads`` / ``--calibration`` ask for on this bag.

    Raises:
        EncoderCalibrationError: A calibration for another scale, expired, or for a bag
            without BenchInfo (no serial to check).
        HeadLayoutError: BenchInfo's heads cannot be averaged.
    """
    from rv_te_bench.core.head_combine import HeadCombiner
    from rv_te_bench.errors import EncoderCalibrationError
    from rv_te_bench.io.session_heads import choose_calibration

    cal = load_calibration(args)
    if info is None:
        if cal is not None:
            msg = (f'{args.bag}: no BenchInfo, so the scale serial of the calibration '
                   f'({cal.scale_serial!r}) cannot be checked: not applied')
            raise EncoderCalibrationError(msg)
        return None
    cal, source, problems = choose_calibration(
        args.bag, info, cal, from_session=not args.no_session_calibration)
    args.calibration_record, args.calibration_source = cal, source
    for text in problems:
        print(f'WARNING: {args.bag}: {text}', file=sys.stderr)
    if source == 'session':
        print(f"NOTE: {args.bag}: the calibration the session's TE node applied is applied "
              f'({cal.describe()}); --no-session-calibration leaves it out',  # type: ignore[union-attr]
              file=sys.stderr)
    return HeadCombiner(info, mode=args.heads, calibration_out=cal)


def encoder_note(info: BenchInfoData | None, combiner: HeadCombiner | None,
                 calibration: EncoderCalibration | None, folded: FoldedTe) -> OncePerRevNote:
    """What the output encoder could put on the once-per-revolution line of the fold."""
    from rv_te_bench.core.bench_uncertainty import default_encoder_errors
    from rv_te_bench.core.encoder_attribution import line_amplitude_rad, once_per_rev_note

    scale = None if combiner is None else combiner.scales['out']
    return once_per_rev_note(
        line_rad=line_amplitude_rad(folded.phi_rad, folded.te_rad),
        eccentricity_m=0.0 if info is None else info.encoder_out_scale_eccentricity_m,
        diameter_m=0.0 if info is None else info.encoder_out_scale_diameter_m,
        error_model=(None if info is None or not info.encoder_out_model
                     else default_encoder_errors(info.encoder_out_model,
                                                 info.encoder_out_resolution_rad)),
        layout=scale.layout if scale is not None and scale.mode == 'average' else None,
        calibration=calibration)
