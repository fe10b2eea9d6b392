"""NI TDMS measurement files through ``nptdms`` (optional extra ``daq``), streamed.

The file is opened with ``TdmsFile.open`` (metadata only) and each channel is read
``chunk_samples`` at a time with ``TdmsChannel.read_data(offset, length)``, so memory stays
flat. Channels are named ``group/channel`` or ``channel`` (when one group has it). Time: a
time channel (``--time``: TDMS timestamps, read exactly to the nanosecond, or numbers in the
unit its ``unit_string`` states), else the waveform properties of the input channel
(``wf_increment`` [s], ``wf_start_time``), else a fixed rate. Units: the channel property
``unit_string`` unless an option gives one.
"""

from __future__ import annotations

import contextlib
import logging
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import DataImportError
from rv_te_bench.io.importers._common import (
    RawChunk,
    channel_roles,
    refuse_empty,
    require_reader,
    stack_heads,
    stack_loss,
)

if TYPE_CHECKING:
    from collections.abc import Iterator

    from nptdms import TdmsChannel

    from rv_te_bench.io.importers._common import ImportOptions

__all__ = ['TdmsReader']


def _short(exc: BaseException) -> str:
    return ' '.join(str(exc).split())[:200] or type(exc).__name__


#: Seconds from the TDMS epoch (1904-01-01 UTC) to the Unix epoch.
_TDMS_EPOCH_S = 2_082_844_800
_HALF = 1 << 31


def _timestamps_ns(seconds: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """TDMS timestamps (seconds since 1904, 2^-64 s fractions) -> int64 ns since 1970,
    rounded to the nearest ns in integer arithmetic (no float64 on the way)."""
    f = np.asarray(fractions, dtype=np.uint64)
    hi, lo = f >> np.uint64(32), f & np.uint64(0xFFFFFFFF)
    g = np.uint64(1_000_000_000)
    lo_ns = (lo * g + np.uint64(_HALF)) >> np.uint64(32)
    frac_ns = ((hi * g + lo_ns + np.uint64(_HALF)) >> np.uint64(32)).astype(np.int64)
    return (np.asarray(seconds, dtype=np.int64) - _TDMS_EPOCH_S) * 1_000_000_000 + frac_ns


def _datetime64_ns(value: Any) -> int | None:
    if hasattr(value, 'seconds') and hasattr(value, 'second_fractions'):   # TdmsTimestamp
        return (int(value.seconds) - _TDMS_EPOCH_S) * 1_000_000_000 \
            + ((int(value.second_fractions) * 1_000_000_000 + (1 << 63)) >> 64)
    try:
        return int(np.datetime64(value, 'ns').astype(np.int64))
    except (TypeError, ValueError, OverflowError):
        return None


@contextlib.contextmanager
def _nptdms_warnings() -> Iterator[list[str]]:
    """Collect what nptdms logs (it prints warnings to stderr itself) instead of printing."""
    from nptdms.log import log_manager

    seen: list[str] = []

    def keep(record: logging.LogRecord) -> bool:
        seen.append(record.getMessage())
        return False

    handler = log_manager.console_handler
    handler.addFilter(keep)
    try:
        yield seen
    finally:
        handler.removeFilter(keep)


class TdmsReader:
    """A TDMS file opened for import (see the module docstring).

    Raises:
        DataImportError: ``nptdms`` missing, not a TDMS file (or truncated in its metadata),
            a channel not in the file, channels of different lengths, an empty channel.
    """

    def __init__(self, path: Path, options: ImportOptions) -> None:
        nptdms = require_reader('nptdms', 'TDMS')
        self.path = Path(path)
        self.origin = str(path)
        self.options = options
        refuse_empty(self.path)
        with _nptdms_warnings() as warned:
            try:
                self._file = nptdms.TdmsFile.open(  # type: ignore[attr-defined]
                    self.path, raw_timestamps=True)
            except Exception as exc:  # noqa: BLE001 - nptdms raises many types on bad files
                msg = f'{path}: not a readable TDMS file, truncated or damaged ({_short(exc)})'
                raise DataImportError(msg) from None
        if any('less data than expected' in w or 'not a multiple' in w for w in warned):
            self._truncated()
        roles = channel_roles(path, options, self._names)
        self.channels = {r: self._channel(spec) for r, spec in roles.items()}
        self.labels = {r: f'{c.group_name}/{c.name}' for r, c in self.channels.items()}
        self.declared_units = {r: c.properties.get('unit_string') or None
                               for r, c in self.channels.items()}
        lengths = {r: len(c) for r, c in self.channels.items()}
        self.n = lengths['in']
        if any(v != self.n for v in lengths.values()):
            shown = ', '.join(f'{self.labels[r]}: {v}' for r, v in lengths.items())
            msg = f'{path}: channels of different lengths ({shown} samples)'
            raise DataImportError(msg)
        if self.n == 0:
            msg = f'{path}: channel {self.labels["in"]!r} has no samples'
            raise DataImportError(msg)
        props = self.channels['in'].properties
        self.has_time = 'time' in self.channels
        self._stamps = self.has_time and self._is_timestamp(self.channels['time'])
        self.time_unit: str | None = 'ns' if self._stamps else None   # else unit_string
        self.declared_rate_hz = self._rate(props.get('wf_increment'))
        self.start_ns = _datetime64_ns(props.get('wf_start_time')) \
            if props.get('wf_start_time') is not None and not self._stamps else None

    @staticmethod
    def _is_timestamp(ch: TdmsChannel) -> bool:
        return getattr(ch.data_type, '__name__', '') == 'TimeStamp'

    def _rate(self, inc: Any) -> float | None:
        """1 / wf_increment, or None without one; refused in one line when not a positive
        number of seconds."""
        if inc is None:
            return None
        try:
            value = float(inc)
        except (TypeError, ValueError):
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            msg = (f'{self.origin}: channel {self.labels["in"]!r}: property wf_increment '
                   f'{str(inc)[:40]!r} is not a positive number of seconds')
            raise DataImportError(msg)
        return 1.0 / value

    def _truncated(self) -> None:
        """Name the first channel whose data ends early (a truncated last segment)."""
        lengths = [(f'{g.name}/{c.name}', len(c)) for g in self._file.groups()
                   for c in g.channels()]
        longest = max((n for _, n in lengths), default=0)
        short = [(name, n) for name, n in lengths if n < longest]
        name, n = short[0] if short else (lengths[-1] if lengths else ('?', 0))
        self._file.close()
        msg = (f'{self.origin}: channel {name!r}, sample {n}: the data ends there, the file is '
               f'truncated (its last segment holds less data than announced; the longest '
               f'channel has {longest} samples)')
        raise DataImportError(msg)

    def _names(self) -> list[str]:
        return [f'{g.name}/{c.name}' for g in self._file.groups() for c in g.channels()]

    def _channel(self, spec: str) -> TdmsChannel:
        group, _, name = spec.rpartition('/')
        found = [c for g in self._file.groups() for c in g.channels()
                 if c.name == name and (not group or g.name == group)]
        if len(found) == 1:
            return found[0]
        names = self._names()
        what = 'not found' if not found else 'is in several groups; name it as group/channel'
        msg = f'{self.origin}: channel {spec!r} {what} (channels: {", ".join(names[:20])})'
        raise DataImportError(msg)

    def locate(self, index: int) -> str:
        """Sample index -> ``'sample N'`` (0-based)."""
        return f'sample {index}'

    def chunks(self) -> Iterator[RawChunk]:
        """Yield ``chunk_samples`` samples at a time.

        Raises:
            DataImportError: A channel cannot be read (truncated data), naming it and the
                sample range.
        """
        size = self.options.chunk_samples
        for first in range(0, self.n, size):
            count = min(size, self.n - first)
            cols = {}
            for role, ch in self.channels.items():
                try:
                    raw = ch.read_data(first, count)
                    data = (_timestamps_ns(raw['seconds'], raw['second_fractions'])
                            if role == 'time' and self._stamps
                            else np.asarray(raw, dtype=np.float64))
                except Exception as exc:  # noqa: BLE001 - truncated files raise many types
                    msg = (f'{self.origin}: channel {self.labels[role]!r}, samples {first}..'
                           f'{first + count - 1}: cannot be read, the file is truncated or '
                           f'damaged ({_short(exc)})')
                    raise DataImportError(msg) from None
                if data.size != count:
                    msg = (f'{self.origin}: channel {self.labels[role]!r}, sample '
                           f'{first + data.size}: the data ends early (truncated file: '
                           f'{self.n} samples announced)')
                    raise DataImportError(msg)
                cols[role] = data
            yield RawChunk(first=first, time=cols.get('time'), theta_in=cols['in'],
                           theta_out=cols['out'], torque=cols.get('torque'),
                           out_heads=stack_heads(cols, self.options),
                               loss=stack_loss(cols, self.options))

    def close(self) -> None:
        """Close the file."""
        self._file.close()
