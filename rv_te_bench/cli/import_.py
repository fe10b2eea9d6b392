"""``rv-te import FILE --bench BENCH.yaml --out BAG``: a DAQ measurement file -> a session bag."""

from __future__ import annotations

import argparse
import json
import sys
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from rv_te_bench.cli._import_args import add_file_arguments, import_options, with_unit_serial
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
  rv-te import heads.csv --bench bench4.yaml --out bags/run_heads --time t_s \\
      --theta-in theta_in_rad --theta-out-heads out_h0,out_h1,out_h2,out_h3
                        four read heads on the output scale (bench4.yaml: heads_deg):
                        one column per head, head 0 first; rv-te analyze averages them
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
    p.add_argument('--serial', default=None, metavar='SERIAL',
                   help="the unit's serial (default: the bench description's "
                        'unit_under_test.serial, else the file name, see --serial-pattern)')
    add_file_arguments(p)
    p.add_argument('--json', action='store_true', help='summary as JSON on stdout')
    p.add_argument('--write-bench-example', type=Path, metavar='FILE',
                   help='write the example bench description to FILE and stop')
    p.set_defaults(func=run, _parser=p)


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
    from rv_te_bench.io.importers import import_file

    desc, serial = with_unit_serial(load_bench_description(args.bench), args, args.file)
    options = import_options(args)
    try:
        summary = import_file(args.file, desc, args.out, options=options, fmt=args.format,
                              header=not args.no_header,
                              on_note=lambda line: print(f'note: {line}', file=sys.stderr))
    except DataImportError as exc:
        raise DataImportError(f'{exc}; nothing written') from None
    if args.json:
        print(json.dumps({**summary.to_json_dict(), 'unit_serial': serial.serial,
                          'unit_serial_source': serial.source}, indent=2))
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
    print(f'  {serial.describe()}')
    print(f'  next: rv-te analyze {" ".join(s.segments) if s.segments else s.bag}')
    return 0
