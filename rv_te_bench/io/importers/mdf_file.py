"""ASAM MDF (MDF4, also MDF3) measurement files through ``asammdf`` (optional extra ``daq``).

Channels are read ``chunk_samples`` records at a time (``MDF.get(..., record_offset,
record_count)``), so memory stays flat. The angle (and torque) channels must be in one
channel group (one DAQ clock); time is that group's master channel [s] unless ``--time``
names another channel of the group; the absolute start is the file header's start time.
Units: each channel's unit unless an option gives one.
"""

from __future__ import annotations

import gc
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import DataImportError
from rv_te_bench.io.importers._common import RawChunk

if TYPE_CHECKING:
    from collections.abc import Iterator

    from rv_te_bench.io.importers._common import ImportOptions

__all__ = ['MdfReader']


def _short(exc: BaseException) -> str:
    return ' '.join(str(exc).split())[:200] or type(exc).__name__


class MdfReader:
    """An MDF file opened for import (see the module docstring).

    Raises:
        DataImportError: ``asammdf`` missing, not an MDF file or truncated, a channel not in
            the file, channels in different groups, no samples.
    """

    def __init__(self, path: Path, options: ImportOptions) -> None:
        try:
            from asammdf import MDF  # noqa: PLC0415
        except ImportError:
            msg = ('reading MDF needs the asammdf library: pip install "rv-te-bench[daq]" '
                   '(or pip install asammdf)')
            raise DataImportError(msg) from None
        self.path = Path(path)
        self.origin = str(path)
        self.options = options
        if self.path.is_file() and self.path.stat().st_size == 0:
            msg = f'{path}: the file is empty'
            raise DataImportError(msg)
        problem = None
        hook = sys.unraisablehook
        sys.unraisablehook = lambda _u: None    # a half-built MDF4 complains in __del__
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                self._mdf = MDF(self.path)
        except Exception as exc:  # noqa: BLE001 - asammdf raises many types on bad files
            problem = _short(exc)
        finally:
            gc.collect()
            sys.unraisablehook = hook
        if problem is not None:
            msg = f'{path}: not a readable MDF file, truncated or damaged ({problem})'
            raise DataImportError(msg)
        if options.theta_in is None or options.theta_out is None:
            msg = (f'{path}: name the angle channels with --theta-in and --theta-out '
                   f'(channels: {", ".join(self._names()[:20])})')
            raise DataImportError(msg)
        roles = {'in': options.theta_in, 'out': options.theta_out, 'torque': options.torque,
                 'time': options.time}
        self.where = {r: self._find(spec) for r, spec in roles.items() if spec is not None}
        self.labels = {r: str(roles[r]) for r in self.where}
        groups = {gp for gp, _ in self.where.values()}
        if len(groups) > 1:
            shown = ', '.join(f'{self.labels[r]}: group {gp}' for r, (gp, _) in self.where.items())
            msg = (f'{path}: the channels are in different channel groups ({shown}); they '
                   'must share one DAQ clock (group)')
            raise DataImportError(msg)
        self.group = groups.pop()
        self.n = int(self._mdf.groups[self.group].channel_group.cycles_nr)
        if self.n == 0:
            msg = f'{path}: channel {self.labels["in"]!r} has no samples'
            raise DataImportError(msg)
        self.declared_units = {}
        for role, spec in roles.items():
            if spec is None:
                continue
            sig = self._get(role, 0, 1)
            self.declared_units[role] = str(getattr(sig, 'unit', '') or '') or None
        self.has_time = True     # the master channel, or --time
        self.time_unit = options.time_unit if 'time' in self.where else 's'
        self.declared_rate_hz = None
        start = getattr(self._mdf.header, 'start_time', None)
        try:
            self.start_ns = int(start.timestamp() * 1e9) if start is not None else None
        except (AttributeError, ValueError, OverflowError, OSError):
            self.start_ns = None

    def _names(self) -> list[str]:
        return sorted(self._mdf.channels_db)

    def _find(self, spec: str) -> tuple[int, int]:
        places = self._mdf.channels_db.get(spec)
        if not places:
            msg = (f'{self.origin}: channel {spec!r} not found (channels: '
                   f'{", ".join(self._names()[:20])})')
            raise DataImportError(msg)
        return tuple(places[0])  # type: ignore[return-value]

    def _get(self, role: str, first: int, count: int) -> Any:  # noqa: ANN401 - Signal
        gp, idx = self.where[role]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                return self._mdf.get(group=gp, index=idx, record_offset=first,
                                     record_count=count)
        except Exception as exc:  # noqa: BLE001 - truncated files raise many types
            msg = (f'{self.origin}: channel {self.labels[role]!r}, samples {first}..'
                   f'{first + count - 1}: cannot be read, the file is truncated or damaged '
                   f'({_short(exc)})')
            raise DataImportError(msg) from None

    def locate(self, index: int) -> str:
        """Sample index -> ``'sample N'`` (0-based record of the channel group)."""
        return f'sample {index}'

    def chunks(self) -> Iterator[RawChunk]:
        """Yield ``chunk_samples`` records at a time; time = master channel [s].

        Raises:
            DataImportError: A channel cannot be read or ends early (truncated file).
        """
        size = self.options.chunk_samples
        for first in range(0, self.n, size):
            count = min(size, self.n - first)
            cols: dict[str, np.ndarray] = {}
            master = None
            for role in self.where:
                sig = self._get(role, first, count)
                data = np.asarray(sig.samples, dtype=np.float64)
                if data.size != count:
                    msg = (f'{self.origin}: channel {self.labels[role]!r}, sample '
                           f'{first + data.size}: the data ends early (truncated file: '
                           f'{self.n} records announced)')
                    raise DataImportError(msg)
                cols[role] = data
                if master is None:
                    master = np.asarray(sig.timestamps, dtype=np.float64)
            time = cols.get('time', master)
            yield RawChunk(first=first, time=time, theta_in=cols['in'], theta_out=cols['out'],
                           torque=cols.get('torque'))

    def close(self) -> None:
        """Close the file."""
        self._mdf.close()
