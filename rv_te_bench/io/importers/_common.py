"""What every importer shares: options, raw chunks, units, the reader protocol.

A reader yields :class:`RawChunk` s (values as the file holds them, consecutive samples);
:mod:`._convert` turns them into SI and finds the drop-outs, :mod:`._turns` unwraps each
angle channel (also across a drop-out, or splits the record there), :mod:`._to_bag` writes
the blocks.

Time units are never assumed: a time column's unit comes from ``--time-unit``, the format
(TDMS timestamps, JointState stamps: ns; an MDF master channel: s), the column name
(``t_ms``, ``time [min]``, ``t (s)``) or the channel's unit property; otherwise the import
is refused in one line naming the column.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np

from rv_te_bench.errors import DataImportError

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator
    from pathlib import Path

__all__ = [
    'ANGLE_UNITS',
    'TIME_UNITS',
    'TURNS',
    'ImportOptions',
    'RawChunk',
    'angle_unit',
    'channel_roles',
    'head_roles',
    'stack_heads',
    'time_unit',
]

AngleUnit = Literal['rad', 'deg', 'arcmin', 'arcsec', 'counts', 'rev']
ANGLE_UNITS: tuple[str, ...] = ('rad', 'deg', 'arcmin', 'arcsec', 'counts', 'rev')
#: Spellings a file may state for an angle unit (TDMS ``unit_string``, MDF unit).
_UNIT_ALIASES = {
    'rad': 'rad', 'radian': 'rad', 'radians': 'rad',
    'deg': 'deg', 'degree': 'deg', 'degrees': 'deg', '\N{DEGREE SIGN}': 'deg',
    'arcmin': 'arcmin', "'": 'arcmin', 'arcsec': 'arcsec', '"': 'arcsec', 'as': 'arcsec',
    'counts': 'counts', 'count': 'counts', 'cnt': 'counts', 'inc': 'counts', 'rev': 'rev',
    'turn': 'rev', 'turns': 'rev', 'r': 'rev',
}
#: The sample rates a file may state or be given [Hz] (a DAQ of a TE bench: 1 Hz .. 10 MHz;
#: outside, the times of a long file would not fit a ROS 2 stamp, or it is a typo).
MIN_RATE_HZ = 1e-3
MAX_RATE_HZ = 1e8
#: Time unit -> seconds per unit.
TIME_UNITS = {'s': 1.0, 'ms': 1e-3, 'us': 1e-6, 'ns': 1e-9, 'min': 60.0, 'h': 3600.0}
#: Spellings of a time unit in a column name or a channel property.
_TIME_ALIASES = {
    's': 's', 'sec': 's', 'secs': 's', 'second': 's', 'seconds': 's',
    'ms': 'ms', 'msec': 'ms', 'millisecond': 'ms', 'milliseconds': 'ms',
    'us': 'us', '\N{MICRO SIGN}s': 'us', '\N{GREEK SMALL LETTER MU}s': 'us', 'usec': 'us',
    'microsecond': 'us', 'microseconds': 'us',
    'ns': 'ns', 'nsec': 'ns', 'nanosecond': 'ns', 'nanoseconds': 'ns',
    'min': 'min', 'mins': 'min', 'minute': 'min', 'minutes': 'min',
    'h': 'h', 'hr': 'h', 'hrs': 'h', 'hour': 'h', 'hours': 'h',
}
#: How an angle channel turns: ``auto`` (single-turn unless its readings span more than a
#: turn), ``single`` (a single-turn absolute encoder: unwrapped) or ``multi`` (a multi-turn
#: counter: kept as recorded).
TURNS = ('auto', 'single', 'multi')


def require_reader(module: str, what: str) -> object:
    """Import the optional ``module`` a format needs (the ``daq`` extra), or one line saying
    how to install it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        msg = (f'reading {what} needs the {module} library: pip install "rv-te-bench[daq]" '
               f'(or pip install {module})')
        raise DataImportError(msg) from None


def refuse_empty(path: Path) -> None:
    """One line for a file of 0 bytes (the libraries' own errors on it are obscure)."""
    if path.is_file() and path.stat().st_size == 0:
        msg = f'{path}: the file is empty'
        raise DataImportError(msg)


def channel_roles(path: Path, options: ImportOptions,
                  names: Callable[[], list[str]]) -> dict[str, str]:
    """The channels ``options`` names, by role (``in``, ``out``, ``torque``, ``time``), for a
    file of named channels (TDMS, MDF): the two angles have no default there.

    Raises:
        DataImportError: An angle channel is not named; the message lists the file's first
            20 channels (``names()``, called only then).
    """
    if options.theta_in is None or options.theta_out is None:
        msg = (f'{path}: name the angle channels with --theta-in and --theta-out '
               f'(channels: {", ".join(names()[:20])})')
        raise DataImportError(msg)
    roles = {'in': options.theta_in, 'out': options.theta_out, 'torque': options.torque,
             'time': options.time, **head_roles(options), **loss_roles(options)}
    return {r: spec for r, spec in roles.items() if spec is not None}


def loss_roles(options: ImportOptions) -> dict[str, str]:
    """The loss channels' roles (``torque_in``, ``temperature``) and their columns."""
    roles = {'torque_in': options.torque_in, 'temperature': options.temperature}
    return {r: spec for r, spec in roles.items() if spec is not None}


def stack_loss(cols: dict[str, np.ndarray], options: ImportOptions) -> np.ndarray | None:
    """The loss columns of a chunk as one (2, n) array (rows torque_in, temperature; NaN
    for a channel not given), or None when neither is."""
    if not loss_roles(options):
        return None
    n = cols['in'].size
    return np.vstack([np.asarray(cols[r], dtype=np.float64) if r in cols
                      else np.full(n, np.nan) for r in ('torque_in', 'temperature')])


def head_roles(options: ImportOptions) -> dict[str, str]:
    """The roles of the output scale's further heads (``out_h1``, ``out_h2``, ...: heads 1..N-1;
    head 0 is ``out``) and their columns / channels."""
    return {f'out_h{j}': spec for j, spec in enumerate(options.theta_out_heads[1:], start=1)}


def stack_heads(cols: dict[str, np.ndarray], options: ImportOptions) -> np.ndarray | None:
    """The further heads' columns of a chunk as one (N-1, n) array, or None."""
    names = list(head_roles(options))
    return np.vstack([cols[r] for r in names]) if names else None


def time_unit(text: str | None) -> str | None:
    """A time unit as a name or property states it -> a key of ``TIME_UNITS``, or None."""
    if not text:
        return None
    return _TIME_ALIASES.get(text.strip().lower())


def angle_unit(text: str | None) -> str | None:
    """A unit as a file states it -> one of ``ANGLE_UNITS``, None when unknown or empty."""
    if not text:
        return None
    return _UNIT_ALIASES.get(text.strip().lower())


#: ``--compression`` of an import -> (the bag's chunk compression, the zstd level).
#: Every MCAP reader reads each (rosbags, mcap + mcap-ros2-support; tested). Measured on the
#: bench's bag (benchmarks/README.md, Import): size against the raw records, CPU per sample
#: to compress / decompress: zstd-fast 0.77, 13 / 5 ns; zstd 0.69, 44 / 25 ns; lz4 0.85,
#: 24 / 6 ns; none 1.00, 0 / 0. zstd-fast (level -5) is the default: a quarter smaller than
#: none at a third of zstd's cost, and every later analysis of the bag decompresses it five
#: times faster than zstd level 1 (what the recorder writes, 11 % smaller).
COMPRESSIONS: dict[str, tuple[Literal['zstd', 'lz4', 'none'], int | None]] = {
    'zstd-fast': ('zstd', -5), 'zstd': ('zstd', 1), 'lz4': ('lz4', None),
    'none': ('none', None)}
DEFAULT_COMPRESSION = 'zstd-fast'


@dataclass(frozen=True, kw_only=True)
class ImportOptions:
    """How to read a measurement file (SI units; None: from the file or the bench).

    Attributes:
        theta_in: Input-angle column / channel: a name or (CSV) a 0-based index.
        theta_out: Output-angle column / channel.
        torque: Output-torque column / channel (recorded unit x the bench's scale = N m).
        time: Time column / channel; None: the file's own time base or ``rate_hz``.
        rate_hz: Fixed sample rate [Hz] (no time column).
        time_unit: Unit of the time column (a key of ``TIME_UNITS``); None: from the
            format, the column name or the channel's unit, else refused.
        unit_in: Unit of the input angle; None: the unit the file states, else rad.
        unit_out: Unit of the output angle, likewise.
        counts_per_rev_in: Counts per revolution of the input encoder (unit ``counts``).
        counts_per_rev_out: Counts per revolution of the output encoder.
        turns_in: How the input angle turns (``TURNS``): ``single`` unwraps it (within
            continuous data and across a drop-out from the speed before and after),
            ``multi`` keeps it as recorded, ``auto`` is single unless its readings span
            more than one turn.
        turns_out: How the output angle turns, likewise.
        start_ns: Absolute time of the first sample [ns since the epoch]; None: the file's.
        chunk_samples: Samples read at a time (memory is proportional to it).
        delimiter: CSV delimiter; None: sniffed from the header line.
        theta_out_heads: One column / channel per read head of the output scale, head 0
            first (issue 36; empty: one head): head 0 is the output angle (``theta_out``
            defaults to it), the others are unwrapped beside it in its unit; a missing value
            of a further head leaves that head out of its block (the block is not dropped).
        decimal: CSV decimal mark: ``'.'``, or ``','`` for a decimal-comma export (the
            delimiter is then ``;`` or a tab, never ``,``).
        torque_in: Input-torque column / channel (recorded unit x the bench's
            ``loss_channels.torque_in.scale_nm_per_unit`` = N m; issue 38).
        temperature: Case-temperature column / channel [degC].
        compression: The bag's chunk compression, a key of :data:`COMPRESSIONS`.
    """

    theta_in: str | None = None
    theta_out: str | None = None
    torque: str | None = None
    time: str | None = None
    rate_hz: float | None = None
    time_unit: str | None = None
    unit_in: str | None = None
    unit_out: str | None = None
    counts_per_rev_in: int | None = None
    counts_per_rev_out: int | None = None
    turns_in: str = 'auto'
    turns_out: str = 'auto'
    start_ns: int | None = None
    chunk_samples: int = 100_000
    delimiter: str | None = None
    theta_out_heads: tuple[str, ...] = ()
    decimal: str = '.'
    torque_in: str | None = None
    temperature: str | None = None
    compression: str = DEFAULT_COMPRESSION

    def __post_init__(self) -> None:
        """Validate (one line naming the option and the rule)."""
        if self.compression not in COMPRESSIONS:
            msg = (f'--compression must be one of {", ".join(COMPRESSIONS)}, got '
                   f'{self.compression!r}')
            raise DataImportError(msg)
        if self.decimal not in ('.', ','):
            msg = f"--decimal must be '.' or ',', got {self.decimal!r}"
            raise DataImportError(msg)
        if self.decimal == ',' and self.delimiter == ',':
            msg = ("--decimal , with --delimiter ',': a comma cannot be both; a decimal-comma "
                   "export separates its columns with ';' or a tab")
            raise DataImportError(msg)
        heads = tuple(str(h) for h in self.theta_out_heads)
        object.__setattr__(self, 'theta_out_heads', heads)
        if heads:
            if len(heads) < 2 or len(set(heads)) != len(heads) or len(heads) > 16:
                msg = (f'--theta-out-heads must name 2 to 16 different columns, one per read '
                       f'head (head 0 first), got {list(heads)}')
                raise DataImportError(msg)
            if self.theta_out is None:
                object.__setattr__(self, 'theta_out', heads[0])
            elif self.theta_out != heads[0]:
                msg = (f'--theta-out {self.theta_out!r} must be the first of --theta-out-heads '
                       f'(head 0), got {heads[0]!r}')
                raise DataImportError(msg)
        if self.rate_hz is not None and not (math.isfinite(self.rate_hz)
                                             and MIN_RATE_HZ <= self.rate_hz <= MAX_RATE_HZ):
            msg = (f'--rate must be between {MIN_RATE_HZ:g} and {MAX_RATE_HZ:g} Hz, got '
                   f'{self.rate_hz!r}')
            raise DataImportError(msg)
        if self.time is not None and self.rate_hz is not None:
            msg = 'give a time column (--time) or a fixed rate (--rate), not both'
            raise DataImportError(msg)
        if self.time_unit is not None and self.time_unit not in TIME_UNITS:
            msg = f'unknown time unit {self.time_unit!r}; known: {", ".join(TIME_UNITS)}'
            raise DataImportError(msg)
        for name in ('unit_in', 'unit_out'):
            u = getattr(self, name)
            if u is not None and u not in ANGLE_UNITS:
                msg = f'unknown angle unit {u!r} ({name}); known: {", ".join(ANGLE_UNITS)}'
                raise DataImportError(msg)
        for name in ('turns_in', 'turns_out'):
            if getattr(self, name) not in TURNS:
                msg = f'{name} must be one of {", ".join(TURNS)}, got {getattr(self, name)!r}'
                raise DataImportError(msg)
        for name in ('counts_per_rev_in', 'counts_per_rev_out'):
            c = getattr(self, name)
            if c is not None and (isinstance(c, bool) or not isinstance(c, int) or c < 1):
                msg = f'{name} must be an integer >= 1, got {c!r}'
                raise DataImportError(msg)
        if not 1 <= self.chunk_samples <= 100_000_000:
            msg = f'chunk_samples must be in [1, 1e8], got {self.chunk_samples!r}'
            raise DataImportError(msg)


@dataclass(frozen=True)
class RawChunk:
    """Consecutive samples as a file holds them (float64 arrays of one length).

    Attributes:
        first: Index of the first sample in the file (0-based, over the whole file).
        time: Time values in the time column's unit (float64, or int64 for exact integer
            stamps such as epoch nanoseconds), or None (fixed rate / file time base).
        theta_in: Input angle in the file's unit.
        theta_out: Output angle in the file's unit.
        torque: Torque in the recorded unit, or None.
        out_heads: The output scale's further heads (1..N-1) in the output's unit, shape
            (N-1, n), or None.
        loss: Input torque (recorded unit) and case temperature [degC], shape (2, n), NaN
            rows for a channel not given, or None (issue 38).
    """

    first: int
    time: np.ndarray | None
    theta_in: np.ndarray
    theta_out: np.ndarray
    torque: np.ndarray | None = None
    out_heads: np.ndarray | None = None
    loss: np.ndarray | None = None


class ImportReader(Protocol):
    """An opened importer (CSV, TDMS, MDF, JointState bag): what :func:`write_bag` reads."""

    path: Path
    origin: str
    labels: dict[str, str]
    declared_units: dict[str, str | None]
    has_time: bool
    time_unit: str | None    # fixed by the format (e.g. ns stamps), else None
    declared_rate_hz: float | None
    start_ns: int | None

    def locate(self, index: int) -> str:
        """Where sample ``index`` is in the file (for messages)."""
        ...

    def chunks(self) -> Iterator[RawChunk]:
        """The samples in file order."""
        ...

    def close(self) -> None:
        """Release the file."""
        ...
