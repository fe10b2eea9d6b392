"""``rv-te selfcal``: calibrate an output scale from its read heads or by reversal.

Two ways to tell the encoder's error from the reducer's (DESIGN.md s.7, issue 36):

* ``rv-te selfcal heads BAG``: a bench whose output scale has several read heads (BenchInfo
  names their angles). The differences between heads hold the scale's error and no reducer
  TE; its harmonics are estimated (with their uncertainty) for the orders the head layout
  observes: for N equally spaced heads every order but the multiples of N.
* ``rv-te selfcal reversal BAG1 BAG2 --index-deg 0 180``: a one-head bench, two (or more)
  sessions of the same unit with the scale re-mounted on its shaft at the stated index
  angles (the readings zeroed to the shaft angle in each). The scale's error moves with
  the scale, the reducer's stays with the output: both are separated at every order the
  index makes observable (180 deg: odd orders; 120 deg: all but multiples of 3).

Either writes an encoder calibration file (scale serial, date, method, harmonics with
uncertainty, the orders left undetermined, validity) that ``rv-te analyze --calibration``,
``rv-te identify --calibration`` and the TE node (``encoder_out_calibration``) apply.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.cli.argtypes import int_between, positive_float
from rv_te_bench.core.units import rad_to_arcsec, rad_to_deg
from rv_te_bench.errors import BagError, RvTeError, TeConfigError
from rv_te_bench.safe_yaml import one_line

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.core.selfcal import HarmonicEstimate
    from sim.bench_info import BenchInfoData

EXAMPLES = """\
examples:
  rv-te selfcal heads bags/four_heads --out cal/RING-42_heads.yaml
                        the scale error from the differences of its 4 heads
  rv-te selfcal reversal bags/run_0deg bags/run_180deg --index-deg 0 180 \\
      --out cal/RING-42.yaml --serial RING-42
                        one head, scale re-mounted at 180 deg: scale and reducer separated
  rv-te analyze bags/later_run --calibration cal/RING-42.yaml
                        a later session with the calibration applied

exit codes: 0 ok, 1 failed (one ERROR: line on stderr), 2 bad usage
"""


def register(subparsers: Subparsers) -> None:
    """Add the ``selfcal`` subcommand."""
    p = subparsers.add_parser(
        'selfcal', help='calibrate the output scale: from its read heads, or by reversal',
        description=__doc__.split('\n\n', 1)[1] if __doc__ else None, epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('method', choices=('heads', 'reversal'),
                   help='heads: one bag of a scale with several heads; reversal: two or '
                        'more bags with the scale at different index angles')
    p.add_argument('bags', nargs='+', help='bag folders or .mcap files')
    p.add_argument('--index-deg', type=float, nargs='+', default=None, metavar='DEG',
                   help='reversal: the scale\'s index angle on its shaft in each bag [deg], '
                        'one per bag (e.g. 0 180)')
    p.add_argument('--out', type=Path, default=None, metavar='FILE',
                   help='write the calibration file here (not overwritten)')
    p.add_argument('--serial', default=None,
                   help="the scale's serial number (default: BenchInfo's "
                        'encoder_out_scale_serial; required when the bags do not state it)')
    p.add_argument('--max-order', type=int_between(1, 256), default=32, metavar='K',
                   help='highest harmonic of the scale revolution estimated')
    p.add_argument('--valid-days', type=positive_float, default=365.0, metavar='D',
                   help='the calibration is valid this many days')
    p.add_argument('--mounting', default='',
                   help='the mounting it holds for (order 1 is its eccentricity)')
    p.add_argument('--plot', type=Path, default=None, metavar='PNG',
                   help='draw the scale error found (and, for reversal, the reducer\'s '
                        'lines) to this PNG')
    p.add_argument('--json', action='store_true', help='one JSON document on stdout')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 ok, 1 one ``ERROR:`` line."""
    try:
        return _run(args)
    except (RvTeError, FileExistsError, OSError) as exc:
        print(f'ERROR: {one_line(exc)}', file=sys.stderr)
        return 1


def _info(bag: str) -> BenchInfoData:
    from rv_te_bench.io.bag_reader import read_bench_info

    info = read_bench_info(bag)
    if info is None:
        msg = f'{bag}: no BenchInfo in the bag: the gear ratio and the scale are not known'
        raise BagError(msg)
    return info


def _serial(args: argparse.Namespace, infos: list[BenchInfoData]) -> str:
    stated = {i.encoder_out_scale_serial for i in infos} - {''}
    if len(stated) > 1:
        msg = (f'the bags name different output scales {sorted(stated)}: a calibration is '
               'of one scale')
        raise TeConfigError(msg)
    if args.serial is not None:
        if stated and args.serial not in stated:
            msg = (f'--serial {args.serial!r} differs from the scale the bags state '
                   f'({stated.pop()!r})')
            raise TeConfigError(msg)
        return str(args.serial)
    if not stated:
        msg = ('the bags do not state the output scale\'s serial number '
               '(encoders.output.serial): give --serial')
        raise TeConfigError(msg)
    return stated.pop()


def _blocks(bag: str) -> Any:
    """Encoder blocks one by one (batches unpacked), with a progress line per 1000."""
    from rv_te_bench.core.stream_records import EncoderBatch
    from rv_te_bench.io.bag_reader import read_encoder_batches

    n = 0
    for item in read_encoder_batches(bag):
        if isinstance(item, EncoderBatch):
            n += item.n_blocks
            yield item
        else:
            n += 1
            yield item
        if n and n % 1000 == 0:
            print(f'{bag}: {n} blocks read', file=sys.stderr)


def _heads(args: argparse.Namespace) -> tuple[HarmonicEstimate, dict[str, Any]]:
    from rv_te_bench.core.heads import HeadLayout
    from rv_te_bench.core.selfcal import HeadSelfCalibration

    if len(args.bags) != 1:
        msg = f'selfcal heads takes one bag, got {len(args.bags)}'
        raise TeConfigError(msg)
    bag = args.bags[0]
    info = _info(bag)
    angles = info.encoder_out_head_angles_rad
    if len(angles) < 2:
        msg = (f'{bag}: BenchInfo states {len(angles) or 1} read head on the output scale: '
               'self-calibration needs two or more (else: rv-te selfcal reversal)')
        raise TeConfigError(msg)
    layout = HeadLayout.of(angles)
    cal = HeadSelfCalibration(layout, max_order=args.max_order)
    used = skipped = 0
    for item in _blocks(bag):
        ids = tuple(item.out_head_ids)
        if ids != layout.head_ids:      # a block without every head: left out, counted
            skipped += item.n_blocks if hasattr(item, 'n_blocks') else 1
            continue
        cal.add(item.theta_out_heads_rad)
        used += item.n_blocks if hasattr(item, 'n_blocks') else 1
    est = cal.result()
    return est, {'bag': str(bag), 'blocks_used': used, 'blocks_without_every_head': skipped,
                 'revolutions': cal.revolutions, 'info': info}


def _reversal(args: argparse.Namespace) -> tuple[HarmonicEstimate, dict[str, Any]]:
    from rv_te_bench.core.selfcal import ReversalFold, reversal_separation

    if len(args.bags) < 2:
        msg = 'selfcal reversal needs two or more bags (the scale at different indices)'
        raise TeConfigError(msg)
    if args.index_deg is None or len(args.index_deg) != len(args.bags):
        got = 0 if args.index_deg is None else len(args.index_deg)
        msg = (f'--index-deg needs one angle per bag ({len(args.bags)}), got {got}: the '
               'scale\'s index on its shaft in each session')
        raise TeConfigError(msg)
    sessions, infos = [], []
    for bag, index in zip(args.bags, args.index_deg, strict=True):
        info = _info(bag)
        infos.append(info)
        fold = ReversalFold(gear_ratio=info.gear_ratio, max_order=args.max_order)
        for item in _blocks(bag):
            fold.add(item.theta_in_rad, item.theta_out_rad)
        sessions.append(fold.session(math.radians(index), str(bag)))
    ratios = {round(i.gear_ratio, 9) for i in infos}
    if len(ratios) > 1:
        msg = f'the bags are of different reducers (gear ratios {sorted(ratios)})'
        raise TeConfigError(msg)
    res = reversal_separation(sessions)
    return res.scale, {'bags': [str(b) for b in args.bags], 'indices_deg': args.index_deg,
                       'reducer': res.reducer.to_plain(), 'reducer_estimate': res.reducer,
                       'infos': infos}


def _run(args: argparse.Namespace) -> int:
    from rv_te_bench.core.encoder_calibration import calibration_from_estimate
    from rv_te_bench.io.calibration_file import write_encoder_calibration

    if args.out is not None and args.out.exists():
        msg = f'Output path {args.out} exists already, not overwriting'
        raise FileExistsError(msg)
    if args.method == 'heads':
        est, extra = _heads(args)
        infos = [extra.pop('info')]
    else:
        if args.index_deg is not None and len(args.index_deg) == len(args.bags) \
                and len(set(args.index_deg)) < 2:
            msg = f'--index-deg {args.index_deg} are all the same angle: nothing to separate'
            raise TeConfigError(msg)
        est, extra = _reversal(args)
        infos = extra.pop('infos')
    serial = _serial(args, infos)
    today = dt.datetime.now(tz=dt.UTC).date()
    cal = calibration_from_estimate(
        est, scale_serial=serial, date=today.isoformat(),
        valid_until=(today + dt.timedelta(days=args.valid_days)).isoformat(),
        mounting=args.mounting, encoder_model=infos[0].encoder_out_model,
        source=', '.join(str(b) for b in args.bags))
    if args.out is not None:
        write_encoder_calibration(args.out, cal)
        print(f'calibration written: {args.out}', file=sys.stderr)
    reducer = extra.pop('reducer_estimate', None)
    if args.plot is not None:
        _plot(args.plot, est, reducer, cal.describe())
        print(f'plot written: {args.plot}', file=sys.stderr)
    if args.json:
        print(json.dumps({'calibration': cal.to_plain(), 'estimate': est.to_plain(),
                          **{k: v for k, v in extra.items() if k != 'info'}},
                         indent=2, default=str))
        return 0
    print(cal.describe())
    print(f'{"order":>5} {"amplitude [arcsec]":>19} {"phase [deg]":>12} {"u [arcsec]":>11}')
    for h in cal.harmonics:
        print(f'{h.order:>5} {float(rad_to_arcsec(h.amplitude_rad)):>19.4f} '
              f'{float(rad_to_deg(h.phase_rad)):>12.2f} {float(rad_to_arcsec(h.u_rad)):>11.4f}')
    if cal.undetermined_orders:
        print(f'not determined (ambiguous with the reducer): orders '
              f'{", ".join(map(str, cal.undetermined_orders))}')
    if reducer is not None:
        print('reducer TE separated (shaft angle of the first session):')
        for k, c, u, ok in zip(reducer.orders.tolist(), reducer.c_rad.tolist(),
                               reducer.u_rad.tolist(), reducer.observable.tolist(),
                               strict=True):
            if ok and k <= 4:
                print(f'{k:>5} {float(rad_to_arcsec(abs(c))):>19.4f} '
                      f'{float(rad_to_deg(np.angle(c * 1j))):>12.2f} '
                      f'{float(rad_to_arcsec(u)):>11.4f}')
    return 0


def _plot(path: Path, est: HarmonicEstimate, reducer: HarmonicEstimate | None,
          title: str) -> None:
    import matplotlib as mpl

    mpl.use('Agg')
    import matplotlib.pyplot as plt

    u = np.linspace(0.0, 2 * math.pi, 2000)
    fig, axes = plt.subplots(1, 2 if reducer is not None else 1, figsize=(11, 4),
                             squeeze=False)
    ax = axes[0, 0]
    ax.plot(np.degrees(u), rad_to_arcsec(est.error_rad(u)), lw=1.2)
    ax.set_xlabel('scale angle [deg]')
    ax.set_ylabel('scale error [arcsec]')
    ax.set_title('scale error (observable orders)')
    ax.grid(alpha=0.3)
    if reducer is not None:
        ok = reducer.observable
        ax2 = axes[0, 1]
        ax2.bar(reducer.orders[ok] - 0.2, rad_to_arcsec(np.abs(est.c_rad[ok])), 0.4,
                label='scale')
        ax2.bar(reducer.orders[ok] + 0.2, rad_to_arcsec(np.abs(reducer.c_rad[ok])), 0.4,
                label='reducer')
        ax2.set_xlabel('order (per output revolution)')
        ax2.set_ylabel('amplitude [arcsec]')
        ax2.set_yscale('log')
        ax2.legend()
        ax2.set_title('separated by reversal')
    fig.suptitle(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
