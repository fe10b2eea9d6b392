"""The measurement-file options of ``rv-te import``, shared with ``rv-te test --from``."""

from __future__ import annotations

import argparse
import datetime as dt
from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import DataImportError

if TYPE_CHECKING:
    from pathlib import Path

    from rv_te_bench.io.bench_description import BenchDescription
    from rv_te_bench.io.importers import ImportOptions
    from rv_te_bench.io.unit_serial import SerialChoice

__all__ = ['add_file_arguments', 'import_options', 'with_unit_serial']


def add_file_arguments(g: Any) -> None:
    """How to read a DAQ file or a JointState bag (a parser or an argument group)."""
    g.add_argument('--format', choices=('csv', 'tdms', 'mdf', 'bag'),
                   help='file format (default: from the suffix; a folder, .mcap or .db3 is a '
                        'rosbag2 bag of sensor_msgs/JointState)')
    g.add_argument('--theta-in', metavar='COL', help='input-angle column / channel (name, '
                   'group/channel for TDMS, 0-based CSV index, or the JointState joint name)')
    g.add_argument('--theta-out', metavar='COL', help='output-angle column / channel')
    g.add_argument('--theta-out-heads', metavar='COL,COL,...', default='',
                   help='one column / channel (or JointState joint) per read head of the '
                   'output scale, head 0 first, comma-separated (the bench description '
                   'states their angles: encoders.output.heads_deg); head 0 is the output '
                   'angle')
    g.add_argument('--torque', metavar='COL', help='output-torque column / channel (x the '
                   "bench's torque_sensor.scale_nm_per_unit = N m)")
    g.add_argument('--torque-in', metavar='COL', help='input-torque column / channel (x the '
                   "bench's loss_channels.torque_in.scale_nm_per_unit = N m; issue 38)")
    g.add_argument('--temperature', metavar='COL', help='case-temperature column / channel '
                   '[degC] (issue 38)')
    g.add_argument('--time', metavar='COL', help='time column / channel (default: the '
                   "file's own time base, else --rate, else the bench's sample_rate_hz); for a "
                   'JointState bag: the topic, when it has several')
    g.add_argument('--time-unit', choices=('s', 'ms', 'us', 'ns', 'min', 'h'),
                   help='unit of the --time column (default: from the format, the column '
                        "name (t_ms, 'time [s]') or the channel's unit; never assumed)")
    g.add_argument('--rate', type=float, metavar='HZ', help='fixed sample rate [Hz] (no time '
                   'column)')
    units = ('rad', 'deg', 'arcmin', 'arcsec', 'counts', 'rev')
    g.add_argument('--unit-in', choices=units, help="input-angle unit (default: the file's "
                   'unit, else rad)')
    g.add_argument('--unit-out', choices=units, help='output-angle unit (likewise)')
    g.add_argument('--counts-per-rev-in', type=int, metavar='N', help='input counts per rev '
                   "for --unit-in counts (default: the bench's encoders.input.counts_per_rev)")
    g.add_argument('--counts-per-rev-out', type=int, metavar='N',
                   help='output counts per rev for --unit-out counts')
    g.add_argument('--no-header', action='store_true', help='CSV: no header line (columns by '
                   'index)')
    g.add_argument('--delimiter', help='CSV delimiter (default: sniffed from the first line)')
    g.add_argument('--decimal', choices=('.', ','), default='.',
                   help="CSV decimal mark: ',' for a decimal-comma export (1,5;2,25: common "
                        "European locales; columns then by ';' or tab) (default: '.')")
    g.add_argument('--no-unwrap', action='store_true', help='keep both angles as recorded '
                   '(multi-turn counters)')
    g.add_argument('--unwrap-in', action=argparse.BooleanOptionalAction, default=None,
                   help='the input angle is single-turn: unwrap it (also across drop-outs, '
                        'from the speed); --no-unwrap-in: a multi-turn counter, kept as '
                        'recorded (default: single-turn unless it spans more than a turn)')
    g.add_argument('--unwrap-out', action=argparse.BooleanOptionalAction, default=None,
                   help='the output angle is single-turn (likewise)')
    g.add_argument('--start-utc', metavar='ISO', help='absolute time of the first sample, '
                   "e.g. 2026-11-24T09:30:00Z (default: the file's, else its modification "
                   'time)')
    g.add_argument('--chunk-samples', type=int, default=100_000, metavar='N',
                   help='samples read at a time (memory is proportional)')
    g.add_argument('--compression', choices=['zstd-fast', 'zstd', 'lz4', 'none'],
                   default='zstd-fast',
                   help="the bag's chunk compression: zstd-fast (zstd level -5: 0.77 of the "
                        'raw size, the fastest to write and to read back), zstd (level 1, as '
                        'the recorder: 0.69, 3x the CPU to write, 5x to read), lz4 (0.85), '
                        'none (1.0) (default: zstd-fast; sizes for float64 encoder data)')
    g.add_argument('--serial-pattern', metavar='REGEX', default=None,
                   help='where the unit serial is in the file name when neither --serial nor '
                        'the bench description gives it: the group named serial, else the '
                        "first group (default: 'SN' + letters, digits, dashes with a digit: "
                        'SN-2026-0042_cw.csv -> SN-2026-0042)')


def with_unit_serial(desc: BenchDescription, args: argparse.Namespace, path: Path, *,
                     choice: SerialChoice | None = None,
                     ) -> tuple[BenchDescription, SerialChoice]:
    """The description with the unit's serial: ``choice`` when given, else ``--serial``, its
    own, else the file name's (:func:`rv_te_bench.io.unit_serial.choose_serial`); and where
    the serial came from (stated in the bag's metadata as ``unit_serial_source``)."""
    from dataclasses import replace

    from rv_te_bench.io.unit_serial import choose_serial

    uut = desc.unit_under_test
    if choice is None:
        choice = choose_serial(getattr(args, 'serial', None), bench_serial=uut.serial,
                               bench_origin=desc.origin, path=path,
                               pattern=args.serial_pattern)
    uut = replace(uut, serial=choice.serial, serial_source=choice.source if choice.serial
                  else '')
    return replace(desc, unit_under_test=uut), choice


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
    # integer arithmetic (a float timestamp would round the nanoseconds)
    return (when - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)) // dt.timedelta(microseconds=1) \
        * 1000



def import_options(args: argparse.Namespace) -> ImportOptions:
    """The :class:`ImportOptions` of the parsed arguments (contradictions: usage error)."""
    from rv_te_bench.io.importers import ImportOptions

    turns = {}
    for role in ('in', 'out'):
        flag = getattr(args, f'unwrap_{role}')
        if args.no_unwrap and flag:
            args._parser.error(f'--no-unwrap and --unwrap-{role} contradict each other: '
                               'give one')
        turns[role] = ('multi' if args.no_unwrap or flag is False else
                       'single' if flag else 'auto')
    return ImportOptions(
        theta_in=args.theta_in, theta_out=args.theta_out, torque=args.torque, time=args.time,
        torque_in=getattr(args, 'torque_in', None),
        temperature=getattr(args, 'temperature', None),
        rate_hz=args.rate, time_unit=args.time_unit, unit_in=args.unit_in,
        unit_out=args.unit_out, counts_per_rev_in=args.counts_per_rev_in,
        counts_per_rev_out=args.counts_per_rev_out, turns_in=turns['in'],
        turns_out=turns['out'], start_ns=_start_ns(args.start_utc),
        chunk_samples=args.chunk_samples, delimiter=args.delimiter,
        theta_out_heads=tuple(c.strip() for c in args.theta_out_heads.split(',') if c.strip()),
        decimal=args.decimal, compression=getattr(args, 'compression', 'zstd-fast'))
