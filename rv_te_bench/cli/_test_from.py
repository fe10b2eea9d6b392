"""``rv-te test PLAN --from BAG|FILE``: a plan judged from data measured elsewhere (no ROS).

* BAG: a bag of the suite's messages (``bench/info`` + ``bench/encoders``: a recorded
  session, an import) is judged as it is; a bag of ``sensor_msgs/JointState`` (what a
  ros2_control bench records) is first imported with its bench description (``--bench``,
  ``--theta-in/--theta-out`` joints, ``--torque JOINT`` for the effort of that joint).
* FILE: a DAQ file (CSV, NI TDMS, ASAM MDF4) is imported with its bench description
  through ``rv-te import``'s readers into ``<out-dir>/<serial>_<time>/bag`` and judged.

The torque can also come from the bench's own torque topic in the bag (``--torque-topic``;
``geometry_msgs/WrenchStamped``, ``std_msgs/Float64`` or a JointState effort). The verdict
table, the unit report, the JSON and the results-store record are the live test's.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.cli._import_args import add_file_arguments, import_options, with_unit_serial
from rv_te_bench.errors import AcceptanceError, BagError

if TYPE_CHECKING:
    from rv_te_bench.acceptance import TestPlan, ToleranceProfile
    from rv_te_bench.io.unit_serial import SerialChoice

__all__ = ['add_from_arguments', 'run_from']


def add_from_arguments(p: argparse.ArgumentParser) -> None:
    """The ``--from`` option and how to read what it names."""
    g = p.add_argument_group(
        'data measured elsewhere (--from): a session bag, a JointState bag or a DAQ file')
    g.add_argument('--from', dest='from_path', type=Path, default=None, metavar='BAG|FILE',
                   help='judge the plan from this record instead of running it: a bag of '
                        'bench/encoders (a recorded session, an import), a JointState bag, '
                        'or a CSV / TDMS / MDF4 file (with --bench)')
    g.add_argument('--bench', type=Path, metavar='BENCH.yaml', default=None,
                   help='bench description of a DAQ file or JointState bag (rv-te import '
                        '--write-bench-example)')
    add_file_arguments(g)
    g.add_argument('--torque-topic', metavar='TOPIC', default=None,
                   help="the bench's torque topic in the bag (WrenchStamped, Float64 or "
                        'JointState), instead of the torque in the encoder blocks')
    g.add_argument('--torque-axis', choices=('x', 'y', 'z'), default='z',
                   help='WrenchStamped component along the output axis')
    g.add_argument('--torque-joint', default='', metavar='JOINT',
                   help='JointState torque topic: the joint whose effort is the torque')
    g.add_argument('--torque-scale', type=float, default=1.0, metavar='X',
                   help='torque topic value x X = torque_out_nm [N m] (bench convention: '
                        'positive resists positive rotation)')
    g.add_argument('--torque-in-topic', metavar='TOPIC', default=None,
                   help="the bench's input-torque topic in the bag (WrenchStamped, Float64 or "
                        'JointState; --torque-axis, x --torque-in-scale), instead of '
                        'bench/channels')
    g.add_argument('--torque-in-scale', type=float, default=1.0, metavar='X',
                   help='input-torque topic value x X = torque_in_nm [N m] (positive drives '
                        'the input positively)')
    g.add_argument('--temperature-topic', metavar='TOPIC', default=None,
                   help="the bench's case-temperature topic in the bag (sensor_msgs/"
                        'Temperature or Float64, degC), instead of bench/channels')
    g.add_argument('--speed-tolerance', type=float, default=0.02, metavar='FRACTION',
                   help="a run's input speed may differ from the step's by this much")
    g.add_argument('--load-tolerance', type=float, default=0.05, metavar='FRACTION',
                   help="a run's load may differ from the step's by this much")


def _has_encoder_blocks(path: Path) -> bool:
    from rv_te_bench.io.bag_reader import bag_topics
    from rv_te_bench.io.msgdefs import ENCODER_BLOCK

    try:
        topics = bag_topics(path)
    except BagError:
        return False
    return any(t.get('type') == ENCODER_BLOCK for t in topics.values())


def _serial(args: argparse.Namespace) -> SerialChoice:
    """The unit's serial: --serial, the bench description's, a suite bag's own (its metadata),
    else the file name's; where it came from.

    Raises:
        AcceptanceError: None of them gives one.
    """
    from rv_te_bench.io.unit_serial import choose_serial

    src = Path(args.from_path)
    bench_serial, origin = '', ''
    if not args.serial and args.bench is not None:
        from rv_te_bench.io.bench_description import load_bench_description

        desc = load_bench_description(args.bench)
        bench_serial, origin = desc.unit_under_test.serial, desc.origin
    choice = choose_serial(args.serial, bench_serial=bench_serial, bench_origin=origin)
    if not choice.serial and src.exists() and _has_encoder_blocks(src):
        from rv_te_bench.io.unit_serial import SerialChoice
        from rv_te_bench.report.analysis import session_info

        in_bag = session_info(src).unit_serial
        if in_bag:
            choice = SerialChoice(in_bag, f"the bag's metadata ({src})")
    if not choice.serial:
        choice = choose_serial(None, path=src, pattern=args.serial_pattern)
    if not choice.serial:
        msg = (f'no unit serial: give --serial ({choice.source}; --serial-pattern REGEX '
               'finds it in another file name)')
        raise AcceptanceError(msg)
    return choice


def _bag_for(args: argparse.Namespace, out_dir: Path) -> tuple[Path, str]:
    """The bag to judge: ``--from`` itself, or the import of the file or JointState bag."""
    from rv_te_bench.io.importers import detect_format, import_file

    src = Path(args.from_path)
    if not src.exists():
        msg = f'--from {src}: no such file or folder'
        raise AcceptanceError(msg)
    fmt = args.format or detect_format(src)
    if fmt == 'bag' and _has_encoder_blocks(src):
        return src, 'bag'
    if args.bench is None:
        what = 'a JointState bag' if fmt == 'bag' else f'a {fmt.upper()} file'
        msg = (f'--from {src} is {what}: give its bench description with --bench BENCH.yaml '
               '(rv-te import --write-bench-example BENCH.yaml writes one to edit)')
        raise AcceptanceError(msg)
    from rv_te_bench.io.bench_description import load_bench_description

    desc, _ = with_unit_serial(load_bench_description(args.bench), args, src,
                               choice=args.serial_choice)
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = import_file(src, desc, out_dir / 'bag', options=import_options(args), fmt=fmt,
                          header=not args.no_header,
                          on_note=lambda line: print(f'note: {line}', file=sys.stderr))
    if len(summary.segments) > 1:
        msg = (f'the import split {src} into {len(summary.segments)} bags (the turns of a '
               'single-turn angle are ambiguous across a drop-out): judge each with --from '
               f'{", ".join(summary.segments)}')
        raise AcceptanceError(msg)
    print(f'imported {src} -> {summary.bag} ({summary.samples} samples, '
          f'{summary.duration_s:.3f} s; torque: {"yes" if summary.torque else "no"})',
          file=sys.stderr)
    return Path(summary.bag), fmt


def run_from(args: argparse.Namespace, plan: TestPlan, plan_text: str, tol_text: str,
             conditions: dict[str, Any]) -> int:
    """Judge, report, record (and keep ``judged.json`` for ``rv-te unit-report``); 0 pass,
    3 fail, 1 error or not judged."""
    from rv_te_bench.acceptance import load_tolerance, parse_tolerance
    from rv_te_bench.acceptance._files import parse_yaml_text
    from rv_te_bench.acceptance.recorded import JudgeSettings, judge_record
    from rv_te_bench.cli._judged import write_judged
    from rv_te_bench.cli._test_report import record_in_store, show_report, verdict_exit
    from rv_te_bench.errors import ToleranceError
    from rv_te_bench.io.measured_record import TorqueTopic, read_measured_record

    settings = JudgeSettings(speed_tolerance=args.speed_tolerance,
                             load_tolerance=args.load_tolerance)
    stamp = datetime.now(UTC).strftime('%Y%m%dT%H%M%SZ')
    given = args.serial
    args.serial_choice = _serial(args)
    args.serial = args.serial_choice.serial
    safe_serial = ''.join(c if c.isalnum() or c in '-_.' else '_' for c in args.serial)
    out_dir = Path(args.out_dir) / f'{safe_serial}_{stamp}'
    bag, fmt = _bag_for(args, out_dir)
    if not given:   # where the serial came from (--serial needs no word)
        print(args.serial_choice.describe(), file=sys.stderr)
    torque = None
    if args.torque_topic:
        torque = TorqueTopic(topic=args.torque_topic, axis=args.torque_axis,
                             joint=args.torque_joint, scale=args.torque_scale)
    torque_in = temperature = None
    if args.torque_in_topic:
        torque_in = TorqueTopic(topic=args.torque_in_topic, axis=args.torque_axis,
                                joint=args.torque_joint, scale=args.torque_in_scale)
    if args.temperature_topic:   # a case sensor is read at a few Hz: 10 s between readings
        temperature = TorqueTopic(topic=args.temperature_topic, max_gap_s=10.0)
    # a JointState bag imported: the bench's other topics stay in the original bag
    topics_from = Path(args.from_path) if fmt == 'bag' and bag != Path(args.from_path) \
        else None
    record = read_measured_record(bag, torque=torque, torque_in=torque_in,
                                  temperature=temperature, topics_from=topics_from)
    profile: ToleranceProfile
    if tol_text:
        profile = parse_tolerance(parse_yaml_text(tol_text, 'tolerance', ToleranceError),
                                  'tolerance')
    elif record.info.preset:
        profile, tol_text = load_tolerance(record.info.preset)
    else:
        msg = ('no tolerance profile: the plan names none and the bench has no preset; give '
               '--tolerance FILE')
        raise AcceptanceError(msg)
    print(f'judging plan {plan.name!r} from {bag} ({record.samples} samples, '
          f'{float(record.time_s[-1]):.3f} s, {record.breaks.size} break(s); torque: '
          f'{record.torque_from}; input torque and case temperature: '
          f'{record.channels_from})', file=sys.stderr)
    report = judge_record(plan, profile, record, serial=args.serial, operator=args.operator,
                          conditions=conditions, settings=settings)
    report['source']['imported_from'] = str(args.from_path) if fmt != 'bag' or \
        bag != Path(args.from_path) else ''
    report['bench']['bag'] = str(bag)
    for step in report['steps']:
        if step.get('not_judged'):
            print(f"step {step['name']!r} not judged: {step['not_judged']}", file=sys.stderr)
    report_dir = Path(args.report) if args.report else out_dir / 'report'
    show_report(report, report_dir, as_json=args.json, pdf=args.pdf)
    judged = write_judged(out_dir, bag=bag, plan_text=plan_text, tolerance_text=tol_text,
                          torque=None if torque is None else {
                              'topic': torque.topic, 'axis': torque.axis,
                              'joint': torque.joint, 'scale': torque.scale},
                          settings={'speed_tolerance': settings.speed_tolerance,
                                    'load_tolerance': settings.load_tolerance},
                          report=report, channel_topics={
                              k: dataclasses.asdict(v) for k, v in (('torque_in', torque_in),
                                                                    ('temperature', temperature))
                              if v is not None}, topics_bag=topics_from)
    print(f'judged record: {judged} (rv-te unit-report {out_dir} judges it again)',
          file=sys.stderr)
    record_in_store(args, report, bag, beside_bag=bag == Path(args.from_path))
    return verdict_exit(report['verdict'], args.serial, report['reason'], report,
                        as_json=args.json)
