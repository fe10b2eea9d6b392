"""``rv-te compensate PRESET --te-arcmin X [--set key=value ...] [--json]``.

Hu 2020 tooth-profile compensation: assigns the measured TE to the pin radius, the shifting
modification and the cumulative circumference error (Hu 2020 Eq. 27, Table 6 structure) and prints
the tooth contact analysis before and after (pins in mesh, F_max, delta_max).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

from rv_te_bench.errors import CompensationError, RvTeError
from rv_te_bench.safe_yaml import one_line
from sim.errors import SimError
from sim.units import arcmin_to_rad, rad_to_arcmin

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.core.advice import Advice

EXAMPLES = """\
examples:
  rv-te compensate hu2020-rv --te-arcmin 1.4559
  rv-te compensate hu2020-rv --te-arcmin 1.4559 --scale table6      Table 6 scale
  rv-te compensate rv-80e-101 --te-arcmin 1.552 --fraction 0.5 --json
  rv-te compensate hu2020-rv --te-arcmin 1.2 --set tca.torque_nm=784
"""


def register(subparsers: Subparsers) -> None:
    """Add the ``compensate`` subcommand."""
    p = subparsers.add_parser(
        'compensate', help='tooth-profile TE compensation of an RV reducer (Hu 2020)',
        description='Assign a measured TE to the factors with negative error sensitivity '
                    '(pin radius, shifting modification, cumulative circumference error; '
                    'Hu 2020 Eq. 27) and show the tooth contact analysis before and after.',
        epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('preset', help='preset name (model hu2020-rv) or path to a preset TOML file')
    p.add_argument('--te-arcmin', type=float, required=True,
                   help='measured total TE (peak-to-peak over a period) [arcmin]')
    p.add_argument('--fraction', type=float, default=1.0,
                   help='part of the TE to compensate, in (0, 1] (default 1)')
    p.add_argument('--scale', choices=('eq27', 'table6'), default='eq27',
                   help='eq27: Hu 2020 Eq. 27 as written (default); table6: scaled to Table 6')
    p.add_argument('--set', dest='overrides', action='append', default=[], metavar='KEY=VALUE',
                   help='override a preset value (repeatable)')
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=run)


def _text(advice: Advice) -> str:
    lines = [f'preset {advice.preset}: tooth-profile compensation (Hu 2020 Eq. 27, '
             f'scale {advice.details["scale"]})',
             f'  TE before {rad_to_arcmin(advice.te_before_rad):.4f} arcmin, predicted after '
             f'{rad_to_arcmin(advice.te_after_rad):.4f} arcmin '
             f'(load reversing between +-{advice.details["torque_nm"]:g} N m: '
             f'elastic part {rad_to_arcmin(advice.details["elastic_pp_before_rad"]):.4f} -> '
             f'{rad_to_arcmin(advice.details["elastic_pp_after_rad"]):.4f} arcmin, geometric '
             f'part {rad_to_arcmin(advice.details["geometric_part_rad"]):.4f} arcmin removed '
             'by the linear model as far as --fraction says)',
             f'  {"factor":<52} {"symbol":<14} {"S_j":>8} {"now mm":>10} {"new mm":>10}']
    for m in advice.modifications:
        lines.append(f'  {m.factor:<52} {m.symbol:<14} {m.sensitivity_index:>8.4f} '
                     f'{m.current_value * 1e3:>10.4f} {m.recommended_value * 1e3:>10.4f}')
    d = advice.details
    lines.append(f"  K1' {d['k1_prime_before']:.5f} -> {d['k1_prime_after']:.5f}")
    for label, key in (('before', 'tca_before'), ('after ', 'tca_after')):
        t = d[key]
        lines.append(f"  TCA {label}: {t['pins_in_mesh']:>2} pins in mesh "
                     f"({t['mesh_from_deg']:.0f}..{t['mesh_to_deg']:.0f} deg), "
                     f"F_max {t['f_max_n']:.1f} N, delta_max {t['delta_max_m'] * 1e3:.4f} mm")
    lines.append("  Table 6 / Hu 2020 Eq. 27 scale for the paper's TE: "
                 f"{d['table6_over_eq27']:.2f} (see --scale)")
    return '\n'.join(lines)


def run(args: argparse.Namespace) -> int:
    """Compute and print the advice; 0 ok, 1 on a domain error (one ERROR line).

    Everything is computed before anything is printed, so a failure writes nothing to
    stdout.
    """
    from rv_te_bench.core.tooth_compensation import compensate_preset
    from sim.presets import load_preset

    try:
        te = args.te_arcmin
        if not (math.isfinite(te) and te > 0):
            msg = f'--te-arcmin must be a finite value > 0, got {te!r}'
            raise CompensationError(msg)
        preset = load_preset(args.preset, args.overrides)
        if preset.model != 'hu2020-rv':
            msg = (f'preset {preset.name!r} has model {preset.model!r}; tooth-profile '
                   'compensation needs a hu2020-rv preset')
            raise CompensationError(msg)
        advice = compensate_preset(preset, float(arcmin_to_rad(te)), fraction=args.fraction,
                                   scale=args.scale)
        out = (json.dumps(advice.to_json_dict(), indent=2) if args.json
               else _text(advice))
    except (RvTeError, SimError) as exc:
        print(f'ERROR: {one_line(exc)}', file=sys.stderr)
        return 1
    print(out)
    return 0
