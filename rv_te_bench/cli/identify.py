"""``rv-te identify BAG``: eccentricities of a 2K-V unit from a recorded TE session.

Reads the encoder blocks and the BenchInfo of a rosbag2/MCAP bag, forms the TE of Eq. 22
(TE = theta_out - theta_in / i, i from BenchInfo), fits the Wang 2020 Eqs 1-8 model and
prints what one record can tell: the output-wheel eccentricity and the two pair
eccentricities; with the part magnitudes of the preset (or ``--set``, e.g. from runout
inspection) it splits them into theta_p1, theta_p2, theta_g and recommends re-assembly
phases (Eq. 21). The output angle is taken as recorded: zero must be the assembly
reference (t0). Best with one whole output revolution or more.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np

from rv_te_bench.cli.optimize_phases import (
    ProgressBar,
    add_search_arguments,
    check_search_arguments,
    format_result,
    load_wang_params,
)

EXAMPLES = """\
examples:
  rv-te identify out/session_bag                      identify and recommend re-assembly
  rv-te identify out/session_bag --json --no-recommend
  rv-te identify bag.mcap --set eccentricity.e_p1_m=1.2e-5 --set eccentricity.e_g_m=8e-6
"""


def register(subparsers: Any) -> None:  # noqa: ANN401 - argparse's private type
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
    p.add_argument('--seed', type=int, default=0, help='seed of the random fit starts')
    p.add_argument('--no-recommend', action='store_true', help='identify only')
    add_search_arguments(p)
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=run)


def load_record(path: str, topic: str | None = None) -> tuple[np.ndarray, np.ndarray,
                                                                dict[str, Any]]:
    """(theta_in_rad, theta_out_rad, bench info) of a bag, blocks in sequence order.

    Raises:
        BagError: Not a bag, unreadable, no encoder topic.
        TeInputError: No encoder samples, or no BenchInfo with a gear ratio.
    """
    from rv_te_bench.errors import TeInputError  # noqa: PLC0415
    from rv_te_bench.io.bag_reader import read_bench_info, read_encoder_blocks  # noqa: PLC0415

    info = read_bench_info(path)
    blocks = sorted(read_encoder_blocks(path, topic), key=lambda b: b.seq)
    if not blocks or sum(len(b.theta_in_rad) for b in blocks) == 0:
        msg = f'{path}: the bag holds no encoder samples'
        raise TeInputError(msg)
    if info is None or not info.get('gear_ratio'):
        msg = f'{path}: no BenchInfo with a gear ratio (needed for the TE of Eq. 22)'
        raise TeInputError(msg)
    theta_in = np.concatenate([np.asarray(b.theta_in_rad, dtype=np.float64) for b in blocks])
    theta_out = np.concatenate([np.asarray(b.theta_out_rad, dtype=np.float64)
                                for b in blocks])
    return theta_in, theta_out, info


def _text(idf: Any) -> str:  # noqa: ANN401
    from sim.units import rad_to_arcsec, rad_to_deg  # noqa: PLC0415

    lines = [f'{"quantity":<10} {"e_um":>8} {"phase_deg":>10}']
    for key, ph in (('e_ot', 'theta_ot'), ('pair1', 'pair1'), ('pair2', 'pair2')):
        lines.append(f'{key:<10} {idf.e_m[key] * 1e6:8.3f} '
                     f'{float(rad_to_deg(idf.phases_rad[ph])):10.2f}')
    if idf.split_resolved:
        for key, ph in (('e_p1', 'theta_p1'), ('e_p2', 'theta_p2'), ('e_g', 'theta_g')):
            lines.append(f'{key:<10} {idf.assumed_e_m[key] * 1e6:8.3f} '
                         f'{float(rad_to_deg(idf.phases_rad[ph])):10.2f}  (magnitude given)')
    lines += ['', f'residual rms {float(rad_to_arcsec(idf.residual_rms_rad)):.3f}", '
                  f'pair contact {idf.contact_fraction[0]:.2f} / {idf.contact_fraction[1]:.2f}, '
                  f'{idf.output_revolutions:.2f} output revolutions, {idf.n_samples} samples']
    if idf.split_resolved and not idf.labels_resolved:
        lines.append('note: planets of nearly equal eccentricity: pair labels ambiguous')
    if idf.output_revolutions < 1.0:
        lines.append('note: less than one output revolution: e_ot is poorly determined')
    return '\n'.join(lines)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 ok, 1 domain error (one ``ERROR:`` line on stderr)."""
    from rv_te_bench.core.identify import (  # noqa: PLC0415
        identify_eccentricities,
        recommend_reassembly,
    )
    from rv_te_bench.core.te import transmission_error_rad  # noqa: PLC0415
    from rv_te_bench.errors import RvTeError  # noqa: PLC0415
    from sim.errors import SimError  # noqa: PLC0415

    bar = None
    rec = None
    try:
        check_search_arguments(args)
        theta_in, theta_out, info = load_record(args.bag, args.topic)
        from sim.bench import overrides_from_parameters_yaml  # noqa: PLC0415

        # the bench's own overrides (recorded in BenchInfo) first, then --set
        recorded = ([] if args.preset else
                    overrides_from_parameters_yaml(str(info.get('parameters_yaml', ''))))
        preset, params = load_wang_params(args.preset or str(info.get('preset', '')),
                                          [*recorded, *args.overrides])
        te = transmission_error_rad(theta_in, theta_out, gear_ratio=float(info['gear_ratio']))
        idf = identify_eccentricities(theta_out, te, params,
                                      rng=np.random.default_rng(args.seed))
        if not args.no_recommend:
            bar = None if args.quiet else ProgressBar('re-assembly grid')
            rec = recommend_reassembly(idf, params, step_deg=args.step_deg,
                                       refine=args.refine,
                                       refine_tol_deg=args.refine_tol_deg, progress=bar)
    except (SimError, RvTeError) as exc:
        if bar is not None:
            bar.close()
        print(f'ERROR: {exc}', file=sys.stderr)
        return 1
    if bar is not None:
        bar.close()
    if args.json:
        out: dict[str, Any] = {'bag': str(args.bag), 'preset': preset.name,
                               'identification': idf.to_json_dict()}
        if rec is not None:
            out['reassembly'] = rec.to_json_dict()
            out['advice'] = rec.to_advice(
                preset.name, method='identified-assembly-phases').to_json_dict()
        print(json.dumps(out, indent=2))
    else:
        print(f'Eccentricities identified from {args.bag} (preset {preset.name})\n')
        print(_text(idf))
        if rec is not None:
            print()
            print(format_result(rec, 'Recommended re-assembly (turn each part from the '
                                     'identified to the recommended phase)'))
    return 0
