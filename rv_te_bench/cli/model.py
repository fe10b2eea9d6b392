"""``rv-te model PRESET``: run a preset's TE model over whole output revolutions, print stats.

The input turns at a constant speed (``--rpm``, default the preset's
``drive.input_speed_rpm`` or 300 rpm); the load is constant or sinusoidal
(``--load-nm T --load-hz F``, F a number or ``crank`` / ``mesh`` for the crank (f_w) or
last-stage mesh frequency, as in Wang 2020 Figs 7, 11, 12). The model is fed in blocks,
the way the bench does. Statistics follow the papers: peak-to-peak, amplitude (max |TE|),
mean and standard deviation, in arcmin.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.cli.argtypes import positive_float
from rv_te_bench.errors import RvTeError, TeConfigError
from rv_te_bench.safe_yaml import one_line
from sim.errors import SimError
from sim.units import ARCMIN_PER_RAD

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from sim.presets import Preset

EXAMPLES = """\
examples:
  rv-te model wang2020-2kv                             NLTE of one output revolution
  rv-te model wang2020-2kv --kind ste --load-nm 300    static TE under 300 N m (Wang 2020 Eq. 18)
  rv-te model wang2020-2kv --kind dte --load-nm 30 --load-hz crank --plot out/dte.png
  rv-te model wang2020-2kv --phases-deg=-70,120,110,40 --json   optimised phases (Wang 2020 Eq. 21)
  rv-te model wang2020-2kv --kind dte --load-nm 300 --dte-start unloaded
                                                       DTE with the start-up transient
  rv-te model wang2020-2kv --kind dte --load-nm 300 --dte-start table4
                                                       Wang 2020 Table 4's DTE reading
  rv-te model wang2020-2kv --set mesh.stiffness_n_m=9e7 --kind ste --csv out/ste.csv
  rv-te model hu2020-rv --kind elastic --load-nm 1094 --load-hz 0.5
                                                       geometric + elastic TE (Hu 2020 TCA)
"""

# mode used when --kind is not given
DEFAULT_KIND = {'wang2020-2kv': 'nlte', 'hu2020-rv': 'geometric', 'li2023-rv': 'dte'}
#: (model, kind) whose TE does not depend on the load: the output shows no load for them.
LOAD_FREE_KINDS = {
    ('wang2020-2kv', 'nlte'): 'no-load TE of Wang 2020 Eqs 1-8',
    ('hu2020-rv', 'geometric'): 'geometric TE of Hu 2020 (load and speed do not enter)',
}
PHASE_KEYS = ('eccentricity.theta_p1_0_deg', 'eccentricity.theta_p2_0_deg',
              'eccentricity.theta_g_0_deg', 'eccentricity.theta_ot_0_deg')
BLOCK = 100_000
#: ``--dte-start`` values: the model's starts and 'table4' (Wang 2020 Table 4's DTE reading).
DTE_START_CHOICES = ('loaded', 'unloaded', 'unloaded-step', 'table4')
MAX_SAMPLES = 50_000_000


def _phases(text: str) -> tuple[float, float, float, float]:
    parts = [p for p in text.replace(' ', '').split(',') if p]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        msg = f'--phases-deg {text!r}: expected four numbers P1,P2,G,OT [deg]'
        raise argparse.ArgumentTypeError(msg) from None
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        msg = f'--phases-deg {text!r}: expected four finite numbers P1,P2,G,OT [deg]'
        raise argparse.ArgumentTypeError(msg)
    return values  # type: ignore[return-value]


def _load_hz(text: str) -> float | str:
    if text in {'crank', 'mesh'}:
        return text
    try:
        value = float(text)
    except ValueError:
        msg = f'--load-hz {text!r}: expected a frequency [Hz] >= 0, "crank" or "mesh"'
        raise argparse.ArgumentTypeError(msg) from None
    if not (math.isfinite(value) and value >= 0):
        msg = f'--load-hz {text!r}: must be finite and >= 0'
        raise argparse.ArgumentTypeError(msg)
    return value


def register(subparsers: Subparsers) -> None:
    """Add the ``model`` subcommand."""
    p = subparsers.add_parser(
        'model', help="run a preset's TE model (NLTE / STE / DTE) and print statistics",
        description=__doc__.split('\n\n', 1)[1] if __doc__ else None, epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('preset', help='preset name or path to a preset TOML file')
    p.add_argument('--kind', default=None,
                   help='model mode: nlte | ste | dte for 2K-V presets (default: nlte); '
                        'geometric | elastic for hu2020-rv (default: geometric); dte for '
                        'li2023-rv')
    p.add_argument('--load-nm', type=float, default=None, metavar='T',
                   help="load torque amplitude [N m] (default: preset drive.load_nm or 0)")
    p.add_argument('--load-hz', type=_load_hz, default=None, metavar='F',
                   help='sinusoidal load frequency [Hz], "crank" or "mesh"; 0 = constant '
                        '(default: preset drive.load_hz or 0)')
    p.add_argument('--phases-deg', type=_phases, default=None, metavar='P1,P2,G,OT',
                   help='eccentricity phases theta_p1, theta_p2, theta_g, theta_ot [deg] '
                        '(Wang 2020 Table 2 / Wang 2020 Eq. 21)')
    p.add_argument('--dte-start', choices=DTE_START_CHOICES, default=None,
                   help="2K-V DTE start (sets solver.dte_start): 'loaded' (the preset's "
                        "default) starts in equilibrium under the load; 'unloaded' from the "
                        "unloaded contact state at the first sample with the load as a step "
                        "(the start-up transient and TE = 0 in the statistics); "
                        "'unloaded-step' the same one sample interval before the first sample "
                        "(the record begins after the first step); 'table4' is "
                        "'unloaded-step' with m_e 5 kg and damping ratio 0.3, the reading of "
                        "Wang 2020 Table 4's DTE rows (docs/DESIGN_NOTES.md 'Paper vs suite'; "
                        '--set still overrides m_e and C_g)')
    p.add_argument('--revolutions', type=positive_float, default=1.0, metavar='N',
                   help='output revolutions to simulate (default 1; revolutions x output '
                        f'period x sample rate <= {MAX_SAMPLES:.0e} samples)')
    p.add_argument('--rpm', type=positive_float, default=None, metavar='R',
                   help='input speed [rpm] (default: preset drive.input_speed_rpm or 300)')
    p.add_argument('--sample-rate-hz', type=positive_float, default=10_000.0, metavar='F',
                   help='output sampling rate [Hz] (default 10000)')
    p.add_argument('--set', dest='overrides', action='append', default=[], metavar='KEY=VALUE',
                   help='override a preset value (repeatable)')
    p.add_argument('--json', action='store_true', help='machine-readable statistics')
    p.add_argument('--csv', type=Path, default=None, metavar='FILE',
                   help='write t_s, theta_in_rad, load_nm, te_rad, te_arcmin per sample '
                        '("-": to standard output, the statistics then go to standard error)')
    p.add_argument('--plot', type=Path, default=None, metavar='FILE.png',
                   help='save a plot of the TE curve (matplotlib, Agg)')
    p.add_argument('--force', action='store_true', help='overwrite existing --csv/--plot files')
    p.set_defaults(func=run)


def _float_or(preset: Preset, key: str, default: float) -> float:
    value = preset.get(key, default)
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) \
        else default


def simulate(args: argparse.Namespace) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Run the model as ``args`` say; return (statistics, per-sample columns).

    Raises:
        SimError: Bad preset, override or model input.
        RvTeError: Too many samples requested.
    """
    from sim.kinematics import kinematics_from_preset
    from sim.models import build_te_model
    from sim.presets import load_preset
    from sim.wang2020 import TABLE4_DTE_START

    overrides: list[str] = []
    if args.dte_start == 'table4':      # the reading's m_e and C_g; --set may change them
        overrides += [f'{k}={v}' for k, v in TABLE4_DTE_START.items()]
    overrides += list(args.overrides)
    if args.phases_deg is not None:
        overrides += [f'{k}={v!r}' for k, v in zip(PHASE_KEYS, args.phases_deg, strict=True)]
    if args.dte_start is not None:
        start = TABLE4_DTE_START['solver.dte_start'] if args.dte_start == 'table4' \
            else args.dte_start
        overrides.append(f'solver.dte_start={start}')
    preset = load_preset(args.preset, overrides)
    kind = args.kind or DEFAULT_KIND.get(preset.model, 'nlte')
    if args.dte_start is not None and (preset.model, kind) != ('wang2020-2kv', 'dte'):
        msg = f'--dte-start applies to the wang2020-2kv DTE only, not {preset.model} {kind}'
        raise TeConfigError(msg)
    kin = kinematics_from_preset(preset)
    model = build_te_model(preset, kind)

    rpm = args.rpm if args.rpm is not None else _float_or(preset, 'drive.input_speed_rpm', 300.0)
    f_in = rpm / 60.0
    freqs = kin.frequencies(f_in)
    load_nm = args.load_nm if args.load_nm is not None else _float_or(preset, 'drive.load_nm', 0.0)
    load_hz_arg = args.load_hz if args.load_hz is not None else _float_or(
        preset, 'drive.load_hz', 0.0)
    if load_hz_arg == 'crank':
        load_hz = freqs['crank_hz']
    elif load_hz_arg == 'mesh':
        load_hz = freqs[f'mesh_stage{len(kin.mesh_orders_out)}_hz']
    else:
        load_hz = float(load_hz_arg)
    if not math.isfinite(load_nm):
        msg = f'--load-nm {load_nm!r} must be finite'
        raise TeConfigError(msg)
    load_free = LOAD_FREE_KINDS.get((preset.model, kind))
    if load_free and (args.load_nm is not None or args.load_hz is not None):
        print(f'WARNING: --load-nm/--load-hz have no effect: {kind} is the {load_free}',
              file=sys.stderr)

    fs = float(args.sample_rate_hz)
    period_s = kin.output_period_s(f_in)
    duration_s = args.revolutions * period_s
    n = round(duration_s * fs)
    if n < 2 or n > MAX_SAMPLES:
        msg = (f'--revolutions {args.revolutions:g} at --sample-rate-hz {fs:g} give {n} '
               f'samples; need 2..{MAX_SAMPLES}')
        raise TeConfigError(msg)
    t = np.arange(n) / fs
    omega = 2.0 * math.pi * f_in
    theta_in = omega * t
    load = (load_nm * np.sin(2.0 * math.pi * load_hz * t) if load_hz > 0
            else np.full(n, load_nm))
    te = np.empty(n)
    start = time.perf_counter()
    for s0 in range(0, n, BLOCK):
        sl = slice(s0, min(n, s0 + BLOCK))
        te[sl] = model.te_rad(t[sl], theta_in[sl], np.full(sl.stop - sl.start, omega), load[sl])
    elapsed = time.perf_counter() - start

    te_arcmin = te * ARCMIN_PER_RAD
    amp = np.abs(np.fft.rfft(te_arcmin - te_arcmin.mean())) * 2.0 / n
    freq = np.fft.rfftfreq(n, 1.0 / fs)
    k_peak = int(np.argmax(amp[1:]) + 1) if n > 2 else 0
    stats: dict[str, Any] = {
        'preset': preset.name, 'model': preset.model, 'kind': kind,
        'te_pp_arcmin': float(np.ptp(te_arcmin)),
        'te_amplitude_arcmin': float(np.max(np.abs(te_arcmin))),
        'te_mean_arcmin': float(np.mean(te_arcmin)),
        'te_std_arcmin': float(np.std(te_arcmin)),
        'spectrum_peak_hz': float(freq[k_peak]),
        'spectrum_peak_arcmin': float(amp[k_peak]),
        'gear_ratio': kin.gear_ratio,
        'input_speed_rpm': rpm,
        'output_period_s': period_s,
        'crank_hz': freqs['crank_hz'],
        'crank_rel_hz': freqs['crank_rel_hz'],
        **{k: v for k, v in freqs.items() if k.startswith('mesh_')},
        # a load the model does not use is not shown as if it had been applied
        'load_nm': None if load_free else load_nm, 'load_hz': None if load_free else load_hz,
        'load_applied': not load_free,
        **_dte_settings(preset, kind),
        'revolutions': args.revolutions, 'duration_s': n / fs,
        'sample_rate_hz': fs, 'n_samples': n,
        'compute_s': elapsed, 'real_time_factor': (n / fs) / elapsed if elapsed > 0 else math.inf,
    }
    columns = {'t_s': t, 'theta_in_rad': theta_in, 'load_nm': load, 'te_rad': te,
               'te_arcmin': te_arcmin}
    if load_free:
        del columns['load_nm']
    return stats, columns


def _dte_settings(preset: Preset, kind: str) -> dict[str, Any]:
    """The 2K-V DTE's start and the Wang 2020 Eq. 19 values its transient depends on."""
    if (preset.model, kind) != ('wang2020-2kv', 'dte'):
        return {}
    return {'dte_start': preset.get('solver.dte_start', 'loaded'),
            'equivalent_mass_kg': float(preset['mesh.equivalent_mass_kg']),
            'mesh_damping_n_s_m': float(preset['mesh.damping_n_s_m'])}


def _check_out(path: Path, force: bool) -> None:
    if path.exists() and not force:
        msg = f'output path {str(path)!r} exists already (use --force to overwrite)'
        raise TeConfigError(msg)
    path.parent.mkdir(parents=True, exist_ok=True)


def _write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    from rv_te_bench.io.files import write_atomic

    data = np.column_stack(list(columns.values()))
    buf = io.BytesIO()
    np.savetxt(buf, data, delimiter=',', header=','.join(columns), comments='', fmt='%.12g')
    write_atomic(path, buf.getvalue())   # a full disk leaves no cut file


def _plot(path: Path, stats: dict[str, Any], columns: dict[str, np.ndarray]) -> None:
    import matplotlib as mpl

    from rv_te_bench.io.files import write_atomic

    mpl.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(columns['t_s'], columns['te_arcmin'], lw=0.6)
    ax.axhline(stats['te_mean_arcmin'], color='k', lw=0.5, ls='--')
    ax.set_xlabel('time [s]')
    ax.set_ylabel('TE [arcmin]')
    ax.set_title(f"{stats['preset']} {stats['kind'].upper()}: p-p {stats['te_pp_arcmin']:.3f}', "
                 f"amplitude {stats['te_amplitude_arcmin']:.3f}', "
                 f"mean {stats['te_mean_arcmin']:.3f}'")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    try:
        fig.savefig(buf, dpi=120, format=path.suffix[1:].lower() or None)
    finally:
        plt.close(fig)
    write_atomic(path, buf.getvalue())   # a full disk leaves no 0-byte image


def _check_plot_format(path: Path) -> None:
    """--plot FILE must name an image format matplotlib writes (checked before the work)."""
    from matplotlib.backend_bases import FigureCanvasBase

    kinds = FigureCanvasBase.get_supported_filetypes()
    suffix = path.suffix.lower().lstrip('.')
    if suffix not in kinds:
        msg = (f'--plot {path}: {("." + suffix) if suffix else "no file extension"} is not an '
               f'image format matplotlib writes; use one of '
               f'{", ".join("." + k for k in sorted(kinds))}')
        raise RvTeError(msg)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 ok, 1 domain error (one ``ERROR:`` line on stderr)."""
    try:
        to_stdout = args.csv is not None and str(args.csv) == '-'
        for path in (None if to_stdout else args.csv, args.plot):
            if path is not None:
                _check_out(path, args.force)
        if args.plot is not None:
            _check_plot_format(args.plot)
        stats, columns = simulate(args)
        if to_stdout:
            data = np.column_stack(list(columns.values()))
            print(','.join(columns))
            np.savetxt(sys.stdout, data, delimiter=',', fmt='%.12g')
            sys.stdout.flush()
        elif args.csv is not None:
            _write_csv(args.csv, columns)
        if args.plot is not None:
            _plot(args.plot, stats, columns)
    except (SimError, RvTeError) as exc:
        print(f'ERROR: {one_line(exc)}', file=sys.stderr)
        return 1
    out = sys.stderr if to_stdout else sys.stdout   # stdout holds the CSV
    if args.json:
        print(json.dumps(stats, indent=2), file=out)
    else:
        width = max(len(k) for k in stats)
        for key, value in stats.items():
            text = (f'{value:.6g}' if isinstance(value, float) else
                    'not used by this model' if value is None else str(value))
            print(f'{key:<{width}}  {text}', file=out)
    return 0
