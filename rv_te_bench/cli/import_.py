"""``rv-te import FILE --bench BENCH.yaml --out BAG``: a DAQ measurement file -> a session bag."""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from rv_te_bench.errors import DataImportError

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers

EXAMPLES = """\
examples:
  rv-te import run.csv --bench bench.yaml --out bags/run_csv --time t_s \\
      --theta-in theta_in_rad --theta-out theta_out_rad
                        CSV with a time column [s] and angles in rad
  rv-te import run_deg.csv --bench bench.yaml --out bags/run_deg --no-header \\
      --rate 2000 --theta-in 1 --theta-out 2 --unit-in deg --unit-out deg
                        no header: columns by 0-based index, fixed rate, degrees
  rv-te import run.tdms --bench bench.yaml --out bags/run_tdms \\
      --theta-in encoders/theta_in --theta-out encoders/theta_out
                        NI TDMS: group/channel, time from the waveform properties
  rv-te import run.mf4 --bench bench.yaml --out bags/run_mdf \\
      --theta-in theta_in --theta-out theta_out
                        ASAM MDF4: time from the channel group's master channel
  rv-te import joint_states_bag --bench bench.yaml --out bags/run_js
                        rosbag2 bag (MCAP or sqlite3) of sensor_msgs/JointState; joints
                        from the bench description (joints: input, output) or --theta-in
  rv-te import --write-bench-example my_bench.yaml
                        write the example bench description to edit

Then analyse the bag as any session: rv-te analyze bags/run_csv --report out/run_csv.

Drop-outs: a time step of more than 1.5 sample periods, time going backwards, or a
non-finite (empty, nan) time or angle ends the block there and skips one block number, as
a live bench's lost blocks do: analyze, identify, the report and the TE node on replay
show it as a gap with its time and length, and no window holding it counts as complete.
Each drop-out is listed (note lines; "gaps" in --json).

Angles: a single-turn encoder (--unwrap-in / --unwrap-out) is unwrapped where it steps by
more than half a turn between two samples, and across a drop-out by the whole turns the
speed before and after predict; when that is ambiguous the record is split there and the
rest goes to OUT_seg2, ... (reported). A multi-turn counter (--no-unwrap-in /
--no-unwrap-out; --no-unwrap for both) is kept as recorded. Default: single-turn unless
the channel's readings span more than one turn.
Time: the unit comes from --time-unit, the format (TDMS timestamps, JointState stamps,
an MDF master channel), the column name (t_ms, "time [min]") or the channel's unit;
otherwise the import is refused. Integer epoch nanoseconds are read without rounding and
give the start time.
The bag is written beside --out under a hidden name and renamed when complete: a bad file
leaves nothing behind. TDMS and MDF need the extra: pip install "rv-te-bench[daq]".
"""


def register(subparsers: Subparsers) -> None:
    """Add the ``import`` subcommand."""
    p = subparsers.add_parser(
        'import', help='convert a DAQ measurement file (CSV, NI TDMS, ASAM MDF4) or a '
                       'JointState bag into a session bag',
        description='Convert a measurement file of a real bench into a rosbag2/MCAP bag of '
                    'BenchInfo + EncoderBlock messages that analyze, identify, replay and the '
                    'report take as any session.',
        epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('file', nargs='?', type=Path, help='the measurement file')
    p.add_argument('--bench', type=Path, metavar='BENCH.yaml',
                   help='bench description (rv-te import --write-bench-example bench.yaml)')
    p.add_argument('--out', type=Path, metavar='BAG', help='bag folder to create (must not exist)')
    p.add_argument('--format', choices=('csv', 'tdms', 'mdf', 'bag'),
                   help='file format (default: from the suffix; a folder, .mcap or .db3 is a '
                        'rosbag2 bag of sensor_msgs/JointState)')
    p.add_argument('--theta-in', metavar='COL', help='input-angle column / channel (name, '
                   'group/channel for TDMS, 0-based CSV index, or the JointState joint name)')
    p.add_argument('--theta-out', metavar='COL', help='output-angle column / channel')
    p.add_argument('--torque', metavar='COL', help='output-torque column / channel (x the '
                   "bench's torque_sensor.scale_nm_per_unit = N m)")
    p.add_argument('--time', metavar='COL', help='time column / channel (default: the '
                   "file's own time base, else --rate, else the bench's sample_rate_hz); for a "
                   'JointState bag: the topic, when it has several')
    p.add_argument('--time-unit', choices=('s', 'ms', 'us', 'ns', 'min', 'h'),
                   help='unit of the --time column (default: from the format, the column '
                        "name (t_ms, 'time [s]') or the channel's unit; never assumed)")
    p.add_argument('--rate', type=float, metavar='HZ', help='fixed sample rate [Hz] (no time '
                   'column)')
    units = ('rad', 'deg', 'arcmin', 'arcsec', 'counts', 'rev')
    p.add_argument('--unit-in', choices=units, help="input-angle unit (default: the file's "
                   'unit, else rad)')
    p.add_argument('--unit-out', choices=units, help='output-angle unit (likewise)')
    p.add_argument('--counts-per-rev-in', type=int, metavar='N', help='input counts per rev '
                   "for --unit-in counts (default: the bench's encoders.input.counts_per_rev)")
    p.add_argument('--counts-per-rev-out', type=int, metavar='N',
                   help='output counts per rev for --unit-out counts')
    p.add_argument('--no-header', action='store_true', help='CSV: no header line (columns by '
                   'index)')
    p.add_argument('--delimiter', help='CSV delimiter (default: sniffed from the first line)')
    p.add_argument('--no-unwrap', action='store_true', help='keep both angles as recorded '
                   '(multi-turn counters)')
    p.add_argument('--unwrap-in', action=argparse.BooleanOptionalAction, default=None,
                   help='the input angle is single-turn: unwrap it (also across drop-outs, '
                        'from the speed); --no-unwrap-in: a multi-turn counter, kept as '
                        'recorded (default: single-turn unless it spans more than a turn)')
    p.add_argument('--unwrap-out', action=argparse.BooleanOptionalAction, default=None,
                   help='the output angle is single-turn (likewise)')
    p.add_argument('--start-utc', metavar='ISO', help='absolute time of the first sample, '
                   "e.g. 2026-11-24T09:30:00Z (default: the file's, else its modification "
                   'time)')
    p.add_argument('--chunk-samples', type=int, default=100_000, metavar='N',
                   help='samples read at a time (memory is proportional)')
    p.add_argument('--json', action='store_true', help='summary as JSON on stdout')
    p.add_argument('--write-bench-example', type=Path, metavar='FILE',
                   help='write the example bench description to FILE and stop')
    p.set_defaults(func=run, _parser=p)


def _start_ns(text: str | None) -> int | None:
    if text is None:
        return None
    try:
        when = dt.datetime.fromisoformat(text.replace('Z', '+00:00'))
    except ValueError:
        msg = f'--start-utc {text!r} is not an ISO 8601 time (2026-11-24T09:30:00Z)'
        raise DataImportError(msg) from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=dt.UTC)
    return round(when.timestamp() * 1e9)


def _write_example(path: Path) -> int:
    from rv_te_bench.io.files import write_atomic

    if path.exists():
        print(f'ERROR: {path} exists already, not overwriting', file=sys.stderr)
        return 1
    text = resources.files('rv_te_bench').joinpath(
        'launch', 'bench_description_example.yaml').read_text('utf-8')
    write_atomic(path, text)
    print(f'wrote {path} (edit it: bench_id, preset or reducer, encoders, unit under test)')
    return 0


def run(args: argparse.Namespace) -> int:
    """Import the file; 0 on success, 1 on a bad file (one ``ERROR:`` line)."""
    if args.write_bench_example is not None:
        return _write_example(args.write_bench_example)
    missing = [f for f, v in (('FILE', args.file), ('--bench', args.bench),
                              ('--out', args.out)) if v is None]
    if missing:
        args._parser.error(f'{", ".join(missing)} required')
    from rv_te_bench.io.bench_description import load_bench_description
    from rv_te_bench.io.importers import ImportOptions, import_file

    desc = load_bench_description(args.bench)
    turns = {}
    for role in ('in', 'out'):
        flag = getattr(args, f'unwrap_{role}')
        if args.no_unwrap and flag:
            args._parser.error(f'--no-unwrap and --unwrap-{role} contradict each other: '
                               'give one')
        turns[role] = ('multi' if args.no_unwrap or flag is False else
                       'single' if flag else 'auto')
    options = ImportOptions(
        theta_in=args.theta_in, theta_out=args.theta_out, torque=args.torque, time=args.time,
        rate_hz=args.rate, time_unit=args.time_unit, unit_in=args.unit_in,
        unit_out=args.unit_out, counts_per_rev_in=args.counts_per_rev_in,
        counts_per_rev_out=args.counts_per_rev_out, turns_in=turns['in'],
        turns_out=turns['out'],
        start_ns=_start_ns(args.start_utc), chunk_samples=args.chunk_samples,
        delimiter=args.delimiter)
    try:
        summary = import_file(args.file, desc, args.out, options=options, fmt=args.format,
                              header=not args.no_header,
                              on_note=lambda line: print(f'note: {line}', file=sys.stderr))
    except DataImportError as exc:
        raise DataImportError(f'{exc}; nothing written') from None
    if args.json:
        print(json.dumps(summary.to_json_dict(), indent=2))
        return 0
    s = summary
    print(f'{s.bag}: {s.samples} samples in {s.blocks} blocks, {s.duration_s:.3f} s at '
          f'{s.sample_rate_hz:g} Hz (rate from {s.rate_from}), start {s.start_utc} '
          f'(from {s.start_from})')
    print(f'  angles: input in {s.unit_in}, output in {s.unit_out}; unwrapped turns: input '
          f'{s.wraps_in}, output {s.wraps_out}; torque: {"yes" if s.torque else "no"}')
    if s.gaps_total:
        print(f'  drop-outs: {s.gaps_total} ({s.samples_dropped} samples dropped), each a gap '
              'in the bag (listed above)')
    if len(s.segments) > 1:
        print(f'  segments: {len(s.segments)} bags: {", ".join(s.segments)}')
    print(f'  next: rv-te analyze {" ".join(s.segments) if s.segments else s.bag}')
    return 0
