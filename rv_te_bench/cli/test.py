"""``rv-te test``: run an acceptance test plan on a unit and give its verdict.

The client of the ``test_sequencer``'s ``run_test_plan`` action: it validates the plan and
the tolerance profile, sends them with the unit's serial and the operator, shows the
progress, prints the verdict table and writes the unit report (HTML + JSON + PNG).
Exit code: 0 the unit passes, 3 it fails, 4 indeterminate (the tolerance profile's guarded
decision rule could not prove conformance or non-conformance: a value and its U straddle a
limit), 1 error, cancelled (Ctrl-C cancels the test and stops the bench) or not judged
(recorded data that lacks what a step needs).

Without ``--launch`` it talks to a running session (a ros2_control bench's forward command
controllers and ``joint_states``, the ``joint_state_adapter``, a ``test_sequencer`` and a
recorder); with ``--launch PRESET`` it starts a simulated one
itself (bench, test_sequencer, recorder; the bag lands in ``--out-dir``). With ``--from
BAG|FILE`` nothing runs: the plan is judged from a recorded session, a JointState bag or a
DAQ file imported with its bench description (``--bench``), the steps found in the data.

Usage examples:
  rv-te test li2023-rv --serial LI-0001 --operator kim --launch li2023-rv
  rv-te test rv-80e --serial RV80E-0042 --operator kim --launch rv-80e-101
  rv-te test my_plan.yaml --serial SN7 --operator kim --tolerance my_limits.yaml
  rv-te test rv-80e --serial SN8 --operator kim --launch hu2020-rv \\
      --set torsion.clearance_rad=4e-4 --condition ambient_temperature_c=23
  rv-te test li2023-rv --serial LI-0002 --operator kim --from bags/li_session
  rv-te test li2023-rv --serial LI-0003 --operator kim --from li_run.csv --bench li_bench.yaml \\
      --time t_s --theta-in theta_in_rad --theta-out theta_out_rad --torque torque_nm
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import threading
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from rv_te_bench.cli._db import add_db_argument, check_record_text
from rv_te_bench.cli._test_report import (
    DEFAULT_TE_MODE,
    EXIT_FAIL,
    EXIT_INDETERMINATE,
    record_in_store,
    show_report,
    verdict_exit,
)
from rv_te_bench.cli.argtypes import float_between, nonempty_text
from rv_te_bench.safe_yaml import SMALL_TEXT_LIMITS, brief, load_yaml

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node
    from rv_te_msgs.action import RunTestPlan

    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.launch.session import Session, SessionSpec

__all__ = ['EXIT_FAIL', 'EXIT_INDETERMINATE', 'register', 'run']


def register(subparsers: Subparsers) -> None:
    """Add the ``test`` subcommand."""
    p = subparsers.add_parser(
        'test', help='run an acceptance test plan on a unit: verdict and unit report',
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('plan', help='test plan: a YAML file or a shipped plan name '
                                '(rv-80e, li2023-rv, wang2020-2kv)')
    p.add_argument('--serial', default=None, type=nonempty_text,
                   help='serial number of the unit under test (required, except with --from: '
                        "then by default the bench description's unit_under_test.serial, "
                        "the bag's, else the file name's, see --serial-pattern)")
    p.add_argument('--operator', required=True, type=nonempty_text, help='who runs the test')
    p.add_argument('--tolerance', default=None, metavar='FILE|NAME',
                   help="tolerance profile (default: the plan's, else the one shipped for "
                        "the bench's preset)")
    p.add_argument('--condition', action='append', default=[], metavar='KEY=VALUE',
                   help='a test condition for the record, e.g. ambient_temperature_c=23')
    p.add_argument('--namespace', default='/', help='namespace of the session')
    p.add_argument('--report', default=None, metavar='DIR',
                   help='where the unit report goes (default: <out-dir>/<serial>_<time>/)')
    p.add_argument('--pdf', action='store_true',
                   help='also print the report to report.pdf with headless Chromium (A4, to sign)')
    p.add_argument('--out-dir', default='out/tests', help='folder for sessions and reports')
    p.add_argument('--wait-s', type=float_between(0.1, 3600.0), default=20.0,
                   help='how long to wait for the test_sequencer [s], 0.1..3600')
    p.add_argument('--json', action='store_true', help='print the result as JSON on stdout')

    add_db_argument(p, mode='also')
    from rv_te_bench.cli._test_from import add_from_arguments
    from rv_te_bench.cli.dashboard import add_dashboard_arguments

    add_dashboard_arguments(p, flag=True)
    g = p.add_argument_group('simulated session (--launch)')
    g.add_argument('--launch', default=None, metavar='PRESET',
                   help='start a simulated bench of this preset, a test_sequencer and a '
                        'recorder, run the plan, stop them')
    g.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                   help='preset override of the simulated unit (e.g. torsion.clearance_rad=3e-4)')
    g.add_argument('--te-mode', default=None, help='TE model mode (default per model)')
    g.add_argument('--encoder', default='heidenhain-ron886', help='encoder preset, both shafts')
    g.add_argument('--sample-rate-hz', type=float_between(1.0, 1e6), default=1000.0,
                   help='encoder sample rate of the simulated bench [Hz], 1..1e6')
    g.add_argument('--auto-ack', action='store_true',
                   help="acknowledge the plan's operator steps at once (a simulated bench; "
                        'without it: Enter in this terminal, or rv-te ack)')
    g.add_argument('--speed-factor', type=float_between(0.0, 1000.0), default=2.0,
                   help='times faster than real time; 0 = as fast as the joint_states '
                        'readers keep up (2000 samples/s) (0..1000)')
    g.add_argument('--seed', type=int, default=1)
    g.add_argument('--bench-programs', action='store_true',
                   help='with --launch: run a plan with whole-reducer steps (efficiency, '
                        'no-load, starting and back-driving torque, temperature, life) as '
                        'the simulated bench\'s own programs (bench/run_program) instead of '
                        'through the ros2_control setpoints; needed for starting_torque and '
                        'back_driving, which the setpoint route has no input effort ramp for')
    add_from_arguments(p)
    from rv_te_bench.cli._test_offline import add_offline_arguments

    add_offline_arguments(p)
    p.set_defaults(func=run, _parser=p)


def _conditions(items: list[str]) -> dict[str, Any]:
    from rv_te_bench.errors import (
        AcceptanceError,
        YamlInputError,
        YamlLimitError,
    )

    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition('=')
        if not sep or not key.strip():
            msg = f'--condition {brief(item)} is not of the form key=value'
            raise AcceptanceError(msg)
        try:
            out[key.strip()] = load_yaml(text, origin=f'--condition {brief(item)}',
                                         limits=SMALL_TEXT_LIMITS)
        except YamlLimitError as exc:
            raise AcceptanceError(str(exc)) from None
        except YamlInputError:
            out[key.strip()] = text
    return out


def _session(args: argparse.Namespace, out_dir: Path) -> Session:
    """Start the simulated session of ``--launch`` (validated first)."""
    from rv_te_bench.launch.session import Session, SessionSpec
    from sim.presets import load_preset

    preset = load_preset(args.launch, list(args.set))   # a bad preset or --set: one line
    mode = args.te_mode or DEFAULT_TE_MODE.get(preset.model, 'nlte')
    from sim.program import ProgramSimulator

    ProgramSimulator(preset=args.launch, overrides=tuple(args.set), te_mode=mode,
                     encoder_in=args.encoder, encoder_out=args.encoder,
                     sample_rate_hz=args.sample_rate_hz)   # the model builds: mode is valid
    # with the live page, a TE node too: the page shows its windows and spectra
    if getattr(args, 'losses', False) and getattr(args, 'bench_programs', False):
        # asked for: the simulated bench runs the whole-reducer steps' programs itself
        # (bench/run_program, with their torque ramps), publishing bench/encoders and
        # bench/channels
        out_dir.mkdir(parents=True, exist_ok=True)
        nodes = ('recorder', 'bench', 'test_sequencer') + (
            ('te_node',) if getattr(args, 'dashboard', False) else ())
        spec = SessionSpec(
            nodes=nodes, namespace=args.namespace_norm,
            parameters={
                'bench': {'preset': args.launch, 'overrides': list(args.set), 'te_mode': mode,
                          'encoder_in': args.encoder, 'encoder_out': args.encoder,
                          'sample_rate_hz': float(args.sample_rate_hz), 'block_size': 100,
                          'seed': int(args.seed), 'time_mode': 'fast',
                          'speed_factor': float(args.speed_factor), 'commanded': True,
                          'losses': True},
                'recorder': {'output_dir': str(out_dir), 'bag_name': 'bag'},
                'test_sequencer': {'loss_route': 'programs'}})
    else:
        spec = simulated_session_spec(
            out_dir, preset=args.launch, overrides=list(args.set), te_mode=mode,
            encoder=args.encoder, sample_rate_hz=float(args.sample_rate_hz), seed=int(args.seed),
            speed_factor=float(args.speed_factor), namespace=args.namespace_norm,
            losses=bool(getattr(args, 'losses', False)),
            extra_nodes=('te_node',) if getattr(args, 'dashboard', False) else ())
    if getattr(args, 'dashboard', False):
        from rv_te_bench.cli.dashboard import wait_for_dashboard

        wait_for_dashboard(spec)
    log = (out_dir / 'session.log').open('wb')
    session = Session(spec, stdout=log)
    try:
        session.start()
    except BaseException:   # the nodes already started stop with it (and the log closes)
        session.stop()
        log.close()
        raise
    return session, log


#: Samples per block of the simulated ros2_control bench and of its adapter's blocks (20 ms
#: at 1 kHz: the sequencer sees a setpoint reached within a block).
SIM_BLOCK_SIZE = 20
SIM_JOINTS = ('input_joint', 'output_joint')


def simulated_session_spec(out_dir: Path, *, preset: str, overrides: list[str] | None = None,
                           te_mode: str, encoder: str = 'heidenhain-ron886',
                           sample_rate_hz: float = 1000.0, seed: int = 1,
                           speed_factor: float = 2.0, namespace: str = '',
                           extra_nodes: tuple[str, ...] = (),
                           losses: bool = False) -> SessionSpec:
    """The session of ``--launch``: a simulated ros2_control bench (setpoint topics in,
    joint_states out), the JointState adapter with the bench's description (written to
    ``out_dir``), the test_sequencer and the recorder (the bag: ``out_dir/bag``), as on a
    real bench. With ``losses`` the bench simulates the reducer's losses and serves the
    input torque as the drive joint's effort and the case temperature on a
    ``sensor_msgs/Temperature`` topic; the description's ``loss_channels`` state the
    transducers (the simulator's own), as a real bench's description does."""
    from rv_te_bench.launch.session import SessionSpec

    out_dir.mkdir(parents=True, exist_ok=True)
    desc = out_dir / 'bench_description.yaml'
    loss: dict[str, Any] = {}
    if losses:
        from sim.loss_bench import LossConfig
        from sim.program import ProgramSimulator

        sensors = ProgramSimulator(preset=preset, overrides=tuple(overrides or ()),
                                   te_mode=te_mode, sample_rate_hz=sample_rate_hz,
                                   losses=LossConfig()).losses.describe()['sensors']
        # the ranges and %-classes a description states (a Pt100's class is not one: 0)
        loss = {'loss_channels': {k: {kk: v[kk] for kk in ('model', 'full_scale',
                                                            'accuracy_class_pct')
                                      if kk in v and (kk == 'model' or v[kk] > 0)}
                                  for k, v in sensors.items()}}
    desc.write_text(yaml.safe_dump({
        'bench_id': 'bench0', 'preset': preset, 'preset_overrides': list(overrides or []),
        'sample_rate_hz': float(sample_rate_hz), 'block_size': SIM_BLOCK_SIZE,
        'encoders': {'input': {'model': encoder}, 'output': {'model': encoder}},
        # the load joint's effort is the torque applied to the output (the joint's sense,
        # as its effort setpoint): torque_out_nm (resisting positive rotation) = -effort
        'torque_sensor': {'present': True, 'model': 'simulated (exact)',
                          'scale_nm_per_unit': -1.0},
        'joints': {'input': SIM_JOINTS[0], 'output': SIM_JOINTS[1]},
        'metadata': {'bench': 'simulated ros2_control bench (rv-te test --launch)'},
        **loss}, sort_keys=False), encoding='utf-8')
    return SessionSpec(
        nodes=('recorder', 'bench', 'joint_state_adapter', 'test_sequencer', *extra_nodes),
        namespace=namespace,
        parameters={
            'bench': {'preset': preset, 'overrides': list(overrides or []), 'te_mode': te_mode,
                      'encoder_in': encoder, 'encoder_out': encoder,
                      'sample_rate_hz': float(sample_rate_hz), 'block_size': SIM_BLOCK_SIZE,
                      'seed': int(seed), 'time_mode': 'fast', 'speed_factor': float(speed_factor),
                      'ros2_control': True, 'joint_state_names': list(SIM_JOINTS),
                      'losses': bool(losses)},
            'joint_state_adapter': {'bench_description': str(desc)},
            'recorder': {'output_dir': str(out_dir), 'bag_name': 'bag'},
            'test_sequencer': {'bench_description': str(desc)}})


def run(args: argparse.Namespace) -> int:
    """Validate, (launch,) send the goal, follow it, report; 0 pass, 3 fail, 1 error."""
    from rv_te_bench.acceptance import load_plan, load_tolerance
    from rv_te_bench.launch.session import normalise_namespace

    check_record_text(args)   # before the test: the store would refuse it at the end
    plan, plan_text = load_plan(args.plan)
    tol_text = ''
    if args.tolerance:
        _, tol_text = load_tolerance(args.tolerance)
    elif plan.tolerance:
        base = Path(args.plan).parent if Path(args.plan).exists() else None
        _, tol_text = load_tolerance(plan.tolerance, relative_to=base)

    conditions = _conditions(args.condition)
    if args.serial is None and args.from_path is None:
        args._parser.error('the following arguments are required: --serial')
    if args.from_path is not None:
        if args.launch:
            args._parser.error('--from judges recorded data and --launch runs a simulated '
                               'bench: give one')
        from rv_te_bench.cli._test_from import run_from

        return run_from(args, plan, plan_text, tol_text, conditions)
    if getattr(args, 'sim', None):
        if args.launch:
            args._parser.error('--sim runs the simulated bench in this process and --launch '
                               'starts a ROS session: give one')
        from rv_te_bench.cli._test_offline import run_offline

        return run_offline(args, plan, tol_text, conditions)
    from rv_te_bench.cli._test_offline import loss_steps_in

    args.losses = bool(loss_steps_in(plan))
    if args.launch:   # the simulated bench has the loss channels when the plan needs them
        from rv_te_bench.cli._test_offline import sim_preflight

        ramps = [(j, s) for j, s in enumerate(plan.steps)
                 if s.kind in ('starting_torque', 'back_driving')]
        if ramps and not getattr(args, 'bench_programs', False):
            j, st = ramps[0]
            print(f'ERROR: step {j} ({st.name!r}, {st.kind}) needs a torque ramp, which the '
                  'ros2_control setpoint route does not command (no effort command interface '
                  'on the drive joint); add --bench-programs to run the plan as the simulated '
                  "bench's own programs; nothing was run", file=sys.stderr)
            return 1

        sim_preflight(plan, args.launch, list(args.set), {'torque_out'} | (
            {'torque_in', 'temperature'} if args.losses else set()))
    args.namespace_norm = normalise_namespace(args.namespace)
    stamp = datetime.now(UTC).strftime('%Y%m%dT%H%M%SZ')
    safe_serial = ''.join(c if c.isalnum() or c in '-_.' else '_' for c in args.serial)
    out_dir = Path(args.out_dir) / f'{safe_serial}_{stamp}'
    report_dir = Path(args.report) if args.report else out_dir / 'report'
    session = log = dash = None
    if getattr(args, 'dashboard', False):
        from rv_te_bench.cli.dashboard import EXIT_PORT_IN_USE, start_dashboard

        dash = start_dashboard(args, namespace=args.namespace_norm or '/',
                               source=f'rv-te test {args.serial}')
        if dash is None:
            return EXIT_PORT_IN_USE
    try:   # the page is stopped whatever happens from here, a session failing to start too
        if args.launch:
            session, log = _session(args, out_dir)
            print(f'session: bench {args.launch} (simulated), test_sequencer, recorder -> '
                  f'{out_dir / "bag"}', file=sys.stderr)
        result = _run_goal(args, plan_text, tol_text, yaml.safe_dump(conditions) if conditions
                           else '')
    finally:
        if session is not None:
            session.stop()
            log.close()
        if dash is not None:
            dash.model.set_state('finished (the test ended)')
            _linger(dash, args)
            dash.stop()
    if result is None:
        return 1
    verdict, reason, report_json = result
    report = json.loads(report_json) if report_json else None
    if report is not None:
        if args.launch:
            report['bench']['bag'] = str(out_dir / 'bag')
        show_report(report, report_dir, as_json=args.json, pdf=args.pdf)
        if args.launch:
            record_in_store(args, report, out_dir / 'bag')
    return verdict_exit(verdict, args.serial, reason, report, as_json=args.json)


def _linger(dash: Any, args: argparse.Namespace) -> None:
    """Keep serving a moment so that open tabs get the verdict (they keep it after)."""
    end = time.monotonic() + float(getattr(args, 'dashboard_linger_s', 1.0))
    while time.monotonic() < end:
        time.sleep(0.05)


class _Progress:
    """One line per step, a live line while it runs (a periodic line when not a tty)."""

    def __init__(self) -> None:
        self.step = -1
        self.last = 0.0
        self.tty = sys.stderr.isatty()
        #: An operator step waits for an acknowledgement (its instruction), set once per step.
        self.operator: str | None = None

    def __call__(self, fb: RunTestPlan.Feedback) -> None:
        from rv_te_bench.report.unit import format_live

        if fb.step_index != self.step:
            if self.tty and self.step >= 0:
                print(file=sys.stderr)
            self.step = fb.step_index
            print(f'step {fb.step_index + 1}/{fb.step_count} {fb.step_name} ({fb.step_kind})',
                  file=sys.stderr)
            if fb.step_kind == 'operator':
                self.operator = fb.message.removeprefix('waiting for the operator: ')
                return
        if fb.step_kind == 'operator':
            return
        now = time.monotonic()
        line = (f'  {100 * fb.step_progress:5.1f} % of the step, {100 * fb.plan_progress:5.1f} '
                f'% of the plan, {format_live(fb.live_metric, fb.live_value)}')
        if self.tty:
            print('\r' + line, end='', file=sys.stderr, flush=True)
        elif now - self.last > 2.0:
            self.last = now
            print(line, file=sys.stderr, flush=True)


class _OperatorAck:
    """Operator steps: the instruction on the terminal, the acknowledgement by Enter (a
    terminal), at once (``--auto-ack``), or from elsewhere (``rv-te ack``)."""

    def __init__(self, args: argparse.Namespace, node: Node, executor: Executor) -> None:
        self.auto = bool(getattr(args, 'auto_ack', False))
        self.node, self.executor = node, executor
        self.entered = threading.Event()
        self.waiting = False

    def poll(self, progress: _Progress) -> None:
        from rv_te_bench.cli.ack import acknowledge

        if progress.operator is not None:
            text, progress.operator = progress.operator, None
            self.waiting = True
            if self.auto:
                print(f'  operator: {text} (acknowledged automatically: --auto-ack)',
                      file=sys.stderr)
                self.entered.set()
            elif sys.stdin.isatty():
                print(f'  operator: {text}; press Enter when done (or run rv-te ack)',
                      file=sys.stderr, flush=True)
                self.entered.clear()
                threading.Thread(target=lambda: (sys.stdin.readline(), self.entered.set()),
                                 daemon=True).start()
            else:
                print(f'  operator: {text}; acknowledge with rv-te ack', file=sys.stderr,
                      flush=True)
        if self.waiting and self.entered.is_set():
            self.waiting = False
            self.entered.clear()
            _ok, message = acknowledge(self.node, self.executor, wait_s=5.0)
            print(f'  {message}', file=sys.stderr)


def _run_goal(args: argparse.Namespace, plan_text: str, tol_text: str,
              conditions: str) -> tuple[str, str, str] | None:
    """Send the goal and follow it; (verdict, reason, report_json), None on an error."""
    import rclpy
    from rclpy.action import ActionClient
    from rclpy.executors import SingleThreadedExecutor
    from rv_te_msgs.action import RunTestPlan

    from rv_te_bench.nodes.goal_client import TrackedGoal

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('rv_te_test_client', context=ctx,
                             namespace=args.namespace_norm or '/')
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    progress = _Progress()
    try:
        client = ActionClient(node, RunTestPlan, 'run_test_plan')
        deadline = time.monotonic() + args.wait_s
        while not client.server_is_ready():
            if time.monotonic() > deadline:
                print(f'ERROR: no test_sequencer answers run_test_plan in namespace '
                      f'{args.namespace_norm or "/"} within {args.wait_s:g} s (start a session '
                      'with a commanded bench, or use --launch PRESET)', file=sys.stderr)
                return None
            executor.spin_once(timeout_sec=0.1)
        goal = RunTestPlan.Goal(plan_yaml=plan_text, tolerance_yaml=tol_text,
                                serial=args.serial, operator_name=args.operator,
                                conditions_yaml=conditions)
        tracked = TrackedGoal(node, client, RunTestPlan, 'run_test_plan', goal,
                              feedback_callback=lambda m: progress(m.feedback))
        deadline = time.monotonic() + args.wait_s
        while not tracked.answered():   # (a reply the middleware lost: goal_client)
            if time.monotonic() > deadline:
                print(f'ERROR: the test_sequencer did not answer the goal within '
                      f'{args.wait_s:g} s (its reply lost, and the goal not on its status '
                      'topic)', file=sys.stderr)
                return None
            executor.spin_once(timeout_sec=0.1)
        handle = tracked.handle
        assert handle is not None
        if not handle.accepted:
            print(f'ERROR: the test_sequencer rejected the goal: {_busy_reason(node, executor)}',
                  file=sys.stderr)
            return None
        try:
            gone_since: float | None = None
            operator = _OperatorAck(args, node, executor)
            while not tracked.result_done():
                executor.spin_once(timeout_sec=0.1)
                operator.poll(progress)
                if client.server_is_ready():
                    gone_since = None
                    continue
                gone_since = gone_since or time.monotonic()
                if time.monotonic() - gone_since > args.wait_s:
                    print(f'ERROR: the test_sequencer went away during the test (no action '
                          f'server for {args.wait_s:g} s); the bench may still be running',
                          file=sys.stderr)
                    return None
        except KeyboardInterrupt:
            print('\ncancelling the test (the bench stops) ...', file=sys.stderr)
            cancel = handle.cancel_goal_async()
            end = time.monotonic() + 30.0
            done = False
            while not (cancel.done() and done) and time.monotonic() < end:
                executor.spin_once(timeout_sec=0.1)
                done = done or tracked.result_done()
            if not done:
                print('ERROR: the test_sequencer did not confirm the cancel', file=sys.stderr)
                return None
        if progress.tty and progress.step >= 0:
            print(file=sys.stderr)
        res = tracked.result()
        return res.verdict, res.reason, res.report_json
    finally:
        with contextlib.suppress(Exception):
            executor.shutdown()
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def _busy_reason(node: Node, executor: Executor) -> str:
    """Why a goal was rejected: the running test on the latched test/report."""
    from rv_te_msgs.msg import TestReport

    from rv_te_bench.nodes import qos

    got: list[Any] = []
    sub = node.create_subscription(TestReport, 'test/report', got.append, qos.LATCHED_QOS)
    end = time.monotonic() + 3.0
    while not got and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.1)
    quiet = time.monotonic() + 0.3     # the latched history holds several: take them all
    while time.monotonic() < min(quiet, end + 1.0):
        n = len(got)
        executor.spin_once(timeout_sec=0.05)
        if len(got) > n:
            quiet = time.monotonic() + 0.3
    node.destroy_subscription(sub)
    latest = max(got, key=lambda m: (m.header.stamp.sec, m.header.stamp.nanosec), default=None)
    if latest is not None and latest.verdict == 'running':
        r = latest
        return (f'it is busy with plan {r.plan_name!r} for unit {r.serial!r} (operator '
                f'{r.operator_name}); wait for it or cancel it')
    return 'it is busy with another test'


