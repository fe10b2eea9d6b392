"""``rv-te test PLAN --sim PRESET``: the plan on the simulated bench in this process (no
ROS), with its loss channels (input and output torque transducers, case temperature), as
fast as the machine computes it. The route for the whole-reducer steps (issue 38): the
ROS bench's EncoderBlock carries no input torque or temperature.
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rv_te_bench.acceptance.plan import TestPlan

__all__ = ['add_offline_arguments', 'loss_steps_in', 'run_offline', 'sim_preflight']


def add_offline_arguments(p: argparse.ArgumentParser) -> None:
    """``--sim`` and ``--sim-without``."""
    g = p.add_argument_group('simulated bench in this process (--sim; no ROS)')
    g.add_argument('--sim', default=None, metavar='PRESET',
                   help='run the plan on a simulated bench of this preset with torque '
                        'transducers and a case temperature sensor, in this process')
    g.add_argument('--sim-without', action='append', default=[], choices=('torque',
                                                                          'temperature'),
                   help='the simulated bench lacks these transducers (repeatable)')


def loss_steps_in(plan: TestPlan) -> list[str]:
    """Names of the plan's whole-reducer steps (issue 38 kinds)."""
    from rv_te_bench.acceptance.loss_steps import LOSS_KINDS

    return [s.name for s in plan.steps if s.kind in LOSS_KINDS]


def sim_preflight(plan: TestPlan, preset_name: str, overrides: list[str],
                  channels: set[str]) -> Any:
    """The preset (validated) after the plan passed the bench checks (one-line errors)."""
    from rv_te_bench.acceptance.preflight import check_plan
    from sim.kinematics import kinematics_from_preset
    from sim.presets import load_preset

    preset = load_preset(preset_name, overrides)
    rated = preset.section('rating').get('max_output_speed_rpm')
    ratio = float(kinematics_from_preset(preset).gear_ratio)
    check_plan(plan, channels=channels,
               max_input_speed_rpm=float(rated) * ratio if rated else float('inf'),
               bench=f'the simulated bench ({preset_name})')
    return preset


def run_offline(args: argparse.Namespace, plan: TestPlan, tol_text: str,
                conditions: dict[str, Any]) -> int:
    """Validate against the bench, run, report; 0 pass, 3 fail, 1 otherwise."""
    from rv_te_bench.acceptance import load_tolerance, parse_tolerance, run_plan_offline
    from rv_te_bench.acceptance._files import parse_yaml_text
    from rv_te_bench.cli._test_report import DEFAULT_TE_MODE, show_report, verdict_exit
    from rv_te_bench.errors import ToleranceError
    from sim.loss_bench import LossConfig
    from sim.program import ProgramSimulator

    channels = {'torque_out'}
    if 'torque' not in args.sim_without:
        channels |= {'torque_in', 'torque_out'}
    else:
        channels.discard('torque_out')
    if 'temperature' not in args.sim_without:
        channels.add('temperature')
    preset = sim_preflight(plan, args.sim, list(args.set), channels)
    if tol_text:
        profile = parse_tolerance(parse_yaml_text(tol_text, 'tolerance', ToleranceError))
    else:
        profile = load_tolerance(preset.name)[0]
    mode = args.te_mode or DEFAULT_TE_MODE.get(preset.model, 'nlte')
    sim = ProgramSimulator(preset=args.sim, overrides=tuple(args.set), te_mode=mode,
                           encoder_in=args.encoder, encoder_out=args.encoder,
                           sample_rate_hz=args.sample_rate_hz, seed=int(args.seed),
                           bench_id=f'sim-{args.sim}',
                           losses=LossConfig() if channels - {'torque_out'} else None)
    state = {'step': -1, 'last': 0.0}

    def progress(j: int, name: str, frac: float, _live: str, _value: float) -> None:
        now = time.monotonic()
        if j != state['step'] or now - state['last'] > 2.0:
            state['step'], state['last'] = j, now
            print(f'step {j + 1}/{len(plan.steps)} {name}: {100 * frac:5.1f} %',
                  file=sys.stderr, flush=True)

    stamp = datetime.now(UTC).strftime('%Y%m%dT%H%M%SZ')
    safe = ''.join(c if c.isalnum() or c in '-_.' else '_' for c in args.serial)
    report_dir = Path(args.report) if args.report else Path(args.out_dir) / f'{safe}_{stamp}' \
        / 'report'
    report = run_plan_offline(plan, profile, serial=args.serial, operator=args.operator,
                              sim=sim, conditions={**conditions, 'route': 'offline simulated '
                                                   'bench (--sim)'}, on_feedback=progress)
    show_report(report, report_dir, as_json=args.json, pdf=args.pdf)
    return verdict_exit(report['verdict'], args.serial, report['reason'], report,
                        as_json=args.json)
