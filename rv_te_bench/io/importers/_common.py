"""What every importer shares: options, raw chunks, unit conversion, unwrapping, checks.

A reader yields :class:`RawChunk` s (values as the file holds them, consecutive samples);
:class:`ChunkConverter` turns each into SI (time since the first sample [s], angles [rad],
unwrapped across chunk boundaries, torque [N m]) and checks it, naming the file, the column
or channel and the row or sample of the first bad value.

Unwrapping (on by default): an angle that steps by more than half a turn between two
consecutive samples is taken to have wrapped at a full turn (a single-turn absolute encoder
reading in [0, 2 pi)), and a whole turn is added or taken away from there on, as
``numpy.unwrap`` does. This assumes each shaft turns less than half a revolution per sample
(input speed below ``30 * sample_rate_hz`` rpm), true of every TE bench; multi-turn data is
unchanged by it.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np

from rv_te_bench.errors import DataImportError
from sim.units import ARCMIN_PER_RAD, ARCSEC_PER_RAD

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator
    from pathlib import Path

__all__ = [
    'ANGLE_UNITS',
    'TIME_UNITS',
    'ChunkConverter',
    'ImportOptions',
    'RawChunk',
    'SiChunk',
    'angle_unit',
    'channel_roles',
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
TIME_UNITS = {'s': 1.0, 'ms': 1e-3, 'us': 1e-6, 'ns': 1e-9}
_TWO_PI = 2.0 * math.pi


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
             'time': options.time}
    return {r: spec for r, spec in roles.items() if spec is not None}


def angle_unit(text: str | None) -> str | None:
    """A unit as a file states it -> one of ``ANGLE_UNITS``, None when unknown or empty."""
    if not text:
        return None
    return _UNIT_ALIASES.get(text.strip().lower())


@dataclass(frozen=True, kw_only=True)
class ImportOptions:
    """How to read a measurement file (SI units; None: from the file or the bench).

    Attributes:
        theta_in: Input-angle column / channel: a name or (CSV) a 0-based index.
        theta_out: Output-angle column / channel.
        torque: Output-torque column / channel (recorded unit x the bench's scale = N m).
        time: Time column / channel; None: the file's own time base or ``rate_hz``.
        rate_hz: Fixed sample rate [Hz] (no time column).
        time_unit: Unit of the time column (``s``, ``ms``, ``us``, ``ns``).
        unit_in: Unit of the input angle; None: the unit the file states, else rad.
        unit_out: Unit of the output angle, likewise.
        counts_per_rev_in: Counts per revolution of the input encoder (unit ``counts``).
        counts_per_rev_out: Counts per revolution of the output encoder.
        unwrap: Unwrap angles that wrap at a full turn (module docstring).
        start_ns: Absolute time of the first sample [ns since the epoch]; None: the file's.
        chunk_samples: Samples read at a time (memory is proportional to it).
        delimiter: CSV delimiter; None: sniffed from the header line.
    """

    theta_in: str | None = None
    theta_out: str | None = None
    torque: str | None = None
    time: str | None = None
    rate_hz: float | None = None
    time_unit: str = 's'
    unit_in: str | None = None
    unit_out: str | None = None
    counts_per_rev_in: int | None = None
    counts_per_rev_out: int | None = None
    unwrap: bool = True
    start_ns: int | None = None
    chunk_samples: int = 100_000
    delimiter: str | None = None

    def __post_init__(self) -> None:
        """Validate (one line naming the option and the rule)."""
        if self.rate_hz is not None and not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            msg = f'--rate must be finite and > 0, got {self.rate_hz!r}'
            raise DataImportError(msg)
        if self.time is not None and self.rate_hz is not None:
            msg = 'give a time column (--time) or a fixed rate (--rate), not both'
            raise DataImportError(msg)
        if self.time_unit not in TIME_UNITS:
            msg = f'unknown time unit {self.time_unit!r}; known: {", ".join(TIME_UNITS)}'
            raise DataImportError(msg)
        for name in ('unit_in', 'unit_out'):
            u = getattr(self, name)
            if u is not None and u not in ANGLE_UNITS:
                msg = f'unknown angle unit {u!r} ({name}); known: {", ".join(ANGLE_UNITS)}'
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
        time: Time values in the time column's unit, or None (fixed rate / file time base).
        theta_in: Input angle in the file's unit.
        theta_out: Output angle in the file's unit.
        torque: Torque in the recorded unit, or None.
    """

    first: int
    time: np.ndarray | None
    theta_in: np.ndarray
    theta_out: np.ndarray
    torque: np.ndarray | None = None


class ImportReader(Protocol):
    """An opened importer (CSV, TDMS, MDF, JointState bag): what :func:`write_bag` reads."""

    path: Path
    origin: str
    labels: dict[str, str]
    declared_units: dict[str, str | None]
    has_time: bool
    time_unit: str
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


@dataclass(frozen=True)
class SiChunk:
    """Consecutive samples in SI: time since the first sample of the file [s], angles
    unwrapped [rad], torque [N m] (empty when none)."""

    t_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_out_nm: np.ndarray


def _to_rad_factor(unit: str, counts_per_rev: int | None, where: str) -> float:
    if unit == 'counts':
        if counts_per_rev is None:
            msg = (f'{where}: unit counts needs the counts per revolution (the bench '
                   'description encoders.*.counts_per_rev or --counts-per-rev-in/-out)')
            raise DataImportError(msg)
        return _TWO_PI / counts_per_rev
    return {'rad': 1.0, 'deg': math.pi / 180.0, 'arcmin': 1.0 / ARCMIN_PER_RAD,
            'arcsec': 1.0 / ARCSEC_PER_RAD, 'rev': _TWO_PI}[unit]


class _Unwrapper:
    """``numpy.unwrap`` (period 2 pi) carried across chunks; counts the wraps found."""

    def __init__(self) -> None:
        self.last: float | None = None
        self.offset = 0.0
        self.wraps = 0

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if x.size == 0:
            return x
        prev = x[0] if self.last is None else self.last
        d = np.diff(x, prepend=prev)
        dmod = np.mod(d + math.pi, _TWO_PI) - math.pi
        dmod[(dmod == -math.pi) & (d > 0)] = math.pi
        corr = dmod - d
        corr[np.abs(d) < math.pi] = 0.0
        n = int(np.count_nonzero(corr))
        self.last = float(x[-1])
        if n == 0:
            return x + self.offset if self.offset else x
        self.wraps += n
        out = x + (self.offset + np.cumsum(corr))
        self.offset = float(out[-1] - x[-1])
        return out


class ChunkConverter:
    """RawChunk -> SiChunk with every check of the importers (stateful across chunks).

    Args:
        origin: The file, for messages.
        labels: Column / channel name per role (``time``, ``in``, ``out``, ``torque``).
        locate: Sample index -> ``'row N'`` / ``'sample N'`` for messages.
        unit_in: Angle unit of the input column (one of ``ANGLE_UNITS``).
        unit_out: Angle unit of the output column.
        counts_per_rev_in: For unit ``counts``.
        counts_per_rev_out: For unit ``counts``.
        time_scale_s: Seconds per time-column unit (None: fixed rate).
        rate_hz: Fixed rate [Hz] when there is no time column.
        torque_scale_nm: Recorded torque x this = N m.
        unwrap: Unwrap angles (module docstring).
    """

    def __init__(self, *, origin: str, labels: dict[str, str],
                 locate: Callable[[int], str], unit_in: str, unit_out: str,
                 counts_per_rev_in: int | None, counts_per_rev_out: int | None,
                 time_scale_s: float | None, rate_hz: float | None,
                 torque_scale_nm: float, unwrap: bool) -> None:
        self.origin = origin
        self.labels = labels
        self.locate = locate
        self.k_in = _to_rad_factor(unit_in, counts_per_rev_in,
                                   f'{origin}: column {labels["in"]!r}')
        self.k_out = _to_rad_factor(unit_out, counts_per_rev_out,
                                    f'{origin}: column {labels["out"]!r}')
        self.time_scale_s = time_scale_s
        self.rate_hz = rate_hz
        self.torque_scale_nm = torque_scale_nm
        self.unwrap = unwrap
        self.unwrap_in = _Unwrapper()
        self.unwrap_out = _Unwrapper()
        self.t0: float | None = None        # first time value (file unit)
        self.t_last: float | None = None
        self.samples = 0

    def fail(self, role: str, index: int, what: str) -> None:
        """Raise one line naming the file, the column, the row or sample and the fault."""
        msg = f'{self.origin}: column {self.labels[role]!r}, {self.locate(index)}: {what}'
        raise DataImportError(msg)

    def _finite(self, role: str, first: int, x: np.ndarray) -> None:
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            self.fail(role, first + int(bad[0]), f'value {x[bad[0]]!r} is not finite')

    def __call__(self, raw: RawChunk) -> SiChunk:
        """Convert and check one chunk (samples must follow the previous chunk's)."""
        n = raw.theta_in.size
        if raw.theta_out.size != n or (raw.time is not None and raw.time.size != n) \
                or (raw.torque is not None and raw.torque.size != n):
            msg = f'{self.origin}: channels of different lengths near {self.locate(raw.first)}'
            raise DataImportError(msg)
        self._finite('in', raw.first, raw.theta_in)
        self._finite('out', raw.first, raw.theta_out)
        if raw.torque is not None:
            self._finite('torque', raw.first, raw.torque)
        if raw.time is not None:
            t = np.asarray(raw.time, dtype=np.float64)
            self._finite('time', raw.first, t)
            prev = t[0] if self.t_last is None else self.t_last
            d = np.diff(t, prepend=prev)
            if self.t_last is None:
                d[0] = 1.0
            bad = np.flatnonzero(d <= 0)
            if bad.size:
                k = int(bad[0])
                before = t[k - 1] if k else self.t_last
                self.fail('time', raw.first + k,
                          f'time not increasing ({t[k]!r} after {before!r})')
            if self.t0 is None:
                self.t0 = float(t[0])
            self.t_last = float(t[-1])
            assert self.time_scale_s is not None
            t_s = (t - self.t0) * self.time_scale_s
        else:
            assert self.rate_hz is not None
            t_s = np.arange(raw.first, raw.first + n, dtype=np.float64) / self.rate_hz
        th_in = np.asarray(raw.theta_in, dtype=np.float64) * self.k_in
        th_out = np.asarray(raw.theta_out, dtype=np.float64) * self.k_out
        if self.unwrap:
            th_in = self.unwrap_in(th_in)
            th_out = self.unwrap_out(th_out)
        torque = (np.zeros(0) if raw.torque is None
                  else np.asarray(raw.torque, dtype=np.float64) * self.torque_scale_nm)
        self.samples += n
        return SiChunk(t_s=t_s, theta_in_rad=th_in, theta_out_rad=th_out, torque_out_nm=torque)
