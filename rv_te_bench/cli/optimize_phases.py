"""``rv-te optimize-phases PRESET``: Wang 2020 Eq. 21 assembly-phase optimisation.

Minimises S = max |NLTE| over one output revolution over the four eccentricity phases
(theta_p1, theta_p2, theta_g, theta_ot) on the grid [-180:STEP:180] deg (the paper: 10 deg,
37^4 = 1,874,161 combinations, a few seconds), optionally refined below the grid step, and
prints the optimum with the Table 4 rows (NLTE and STE at 30/100/300 N m, before and
after). A progress bar goes to stderr; results to stdout.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

from rv_te_bench.cli._progress import ProgressBar
from rv_te_bench.errors import CompensationError, RvTeError
from rv_te_bench.safe_yaml import one_line
from sim.errors import PresetError, SimError
from sim.units import rad_to_arcmin, rad_to_deg

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.core.phases import PhaseOptimisation
    from sim.presets import Preset
    from sim.wang2020 import Wang2kvParams

EXAMPLES = """\
examples:
  rv-te optimize-phases wang2020-2kv                    paper grid: [-70, 120, 110, 40] deg
  rv-te optimize-phases wang2020-2kv --refine --json    refine below 10 deg, JSON output
  rv-te optimize-phases wang2020-2kv --step-deg 20 --set eccentricity.e_p2_m=1.5e-5
"""


def _loads(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(p) for p in text.split(',') if p.strip())
    except ValueError:
        msg = f'--loads-nm {text!r}: expected comma-separated torques [N m]'
        raise argparse.ArgumentTypeError(msg) from None
    return values


def register(subparsers: Subparsers) -> None:
    """Add the ``optimize-phases`` subcommand."""
    p = subparsers.add_parser(
        'optimize-phases', help='Wang 2020 Eq. 21: assembly phases minimising max |NLTE|',
        description=__doc__.split('\n\n', 1)[1] if __doc__ else None, epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_search_arguments(p)
    p.add_argument('preset', help='a wang2020-2kv preset name or TOML path')
    p.add_argument('--loads-nm', type=_loads, default=(30.0, 100.0, 300.0), metavar='T1,T2',
                   help='loads for the STE rows [N m] (default 30,100,300)')
    p.add_argument('--set', dest='overrides', action='append', default=[],
                   metavar='KEY=VALUE', help='override a preset value (repeatable)')
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=run)


def add_search_arguments(p: argparse.ArgumentParser) -> None:
    """Grid options shared with ``rv-te identify``."""
    p.add_argument('--step-deg', type=float, default=10.0, metavar='S',
                   help='grid step [deg] for every phase (default 10, as in the paper)')
    p.add_argument('--refine', action='store_true',
                   help='refine the best grid point with finer local grids')
    p.add_argument('--refine-tol-deg', type=float, default=0.5, metavar='T',
                   help='final local grid step [deg] with --refine (default 0.5)')
    p.add_argument('--quiet', action='store_true', help='no progress bar')


#: Largest phase grid the CLI runs (step 4 deg: 91^4 = 6.9e7); finer phases come from
#: --refine, which searches locally.
MAX_GRID_COMBINATIONS = 7e7


def check_search_arguments(args: argparse.Namespace) -> None:
    """Validate the grid options before any work (so that errors come as one line).

    Raises:
        CompensationError: A non-finite or non-positive step or tolerance, step > 180.
    """
    if not (math.isfinite(args.step_deg) and 0 < args.step_deg <= 180):
        msg = f'--step-deg must be finite, > 0 and <= 180, got {args.step_deg!r}'
        raise CompensationError(msg)
    if not (math.isfinite(args.refine_tol_deg) and args.refine_tol_deg > 0):
        msg = f'--refine-tol-deg must be finite and > 0, got {args.refine_tol_deg!r}'
        raise CompensationError(msg)
    n_axis = math.floor(360.0 / args.step_deg) + 1
    if n_axis**4 > MAX_GRID_COMBINATIONS:
        msg = (f'--step-deg {args.step_deg:g} makes a grid of {n_axis}^4 = {n_axis**4:.3g} '
               f'combinations (at most {MAX_GRID_COMBINATIONS:.0e}); use a coarser step with '
               '--refine for finer phases')
        raise CompensationError(msg)


def load_wang_params(name: str, overrides: list[str]) -> tuple[Preset, Wang2kvParams]:
    """(preset, Wang2kvParams) of a wang2020-2kv preset.

    Raises:
        PresetError: Unknown preset, bad override, or a preset of another model.
    """
    from sim.presets import load_preset
    from sim.wang2020 import Wang2kvParams

    preset = load_preset(name, overrides)
    if preset.model != 'wang2020-2kv':
        msg = (f'preset {preset.name!r} is a {preset.model!r} preset; assembly phases need a '
               'wang2020-2kv preset')
        raise PresetError(msg)
    return preset, Wang2kvParams.from_preset(preset)


def format_result(result: PhaseOptimisation, title: str) -> str:
    """Text report of a PhaseOptimisation (degrees and arcmin)."""
    from rv_te_bench.core.phases import PHASE_NAMES

    lines = [title, '', f'{"phase":<10} {"before_deg":>11} {"after_deg":>10}']
    for name, b, a in zip(PHASE_NAMES, result.phases_before_rad, result.phases_after_rad,
                          strict=True):
        lines.append(f'{name:<10} {float(rad_to_deg(b)):11.2f} {float(rad_to_deg(a)):10.2f}')
    before = float(rad_to_arcmin(result.objective_before_rad))
    after = float(rad_to_arcmin(result.objective_after_rad))
    lines += ['', f"max|NLTE| (Wang 2020 Eq. 21): {before:.4f}' -> {after:.4f}' "
                  f'({100 * result.reduction:.1f} % less)',
              f'grid step {float(rad_to_deg(result.grid_step_rad)):g} deg, '
              f'{result.n_combinations:,} combinations, refined: {result.refined}, '
              f'{result.elapsed_s:.1f} s', '',
              f'{"case":<12} {"when":<7} {"pp_arcmin":>10} {"amp_arcmin":>11} '
              f'{"std_arcmin":>11} {"mean_arcmin":>12}']
    for row in result.table_rows():
        lines.append(f'{row["case"]:<12} {row["when"]:<7} {row["te_pp_arcmin"]:10.4f} '
                     f'{row["te_amplitude_arcmin"]:11.4f} {row["te_std_arcmin"]:11.4f} '
                     f'{row["te_mean_arcmin"]:12.4f}')
    return '\n'.join(lines)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 ok, 1 domain error (one ``ERROR:`` line on stderr)."""
    from rv_te_bench.core.phases import optimise_phases

    bar = None
    try:
        check_search_arguments(args)
        preset, params = load_wang_params(args.preset, list(args.overrides))
        bar = None if args.quiet else ProgressBar('grid search')
        result = optimise_phases(params, step_deg=args.step_deg, refine=args.refine,
                                 refine_tol_deg=args.refine_tol_deg, loads_nm=args.loads_nm,
                                 progress=bar)
    except (SimError, RvTeError) as exc:
        if bar is not None:
            bar.close()
        print(f'ERROR: {one_line(exc)}', file=sys.stderr)
        return 1
    if bar is not None:
        bar.close()
    advice = result.to_advice(preset.name)
    if args.json:
        out = {'preset': preset.name, **result.to_json_dict(), 'advice': advice.to_json_dict()}
        print(json.dumps(out, indent=2))
    else:
        print(format_result(result, f'Assembly phases for {preset.name} (Wang 2020 Eq. 21)'))
    return 0
