"""ASAM MDF (MDF4, also MDF3) measurement files through ``asammdf`` (optional extra ``daq``).

Channels are read a data fragment of about ``chunk_samples`` records at a time
(``read_fragment_size``; each fragment read once for all the channels), so memory stays
flat. The angle (and torque)
channels must be in one channel group (one DAQ clock); time is that group's master channel [s]
unless ``--time`` names another channel of the group; the absolute start is the file header's
start time.
Units: each channel's unit unless an option gives one.
"""

from __future__ import annotations

import builtins
import gc
import sys
import warnings
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

    from rv_te_bench.io.importers._common import ImportOptions

__all__ = ['MdfReader']


def _quiet_loader() -> None:
    """Keep asammdf's data loader off stdout: asammdf 8.x prints a throughput line
    (``'12.1 MB/s cc=30 vv=10.1'``) on stdout every 10 s a fragment iterator runs, so a
    long import broke ``rv-te import --json`` (stdout one JSON document). Only that line
    is dropped (a ``print`` in the module's namespace); anything else it prints passes."""
    mod = sys.modules.get('asammdf.blocks.mdf_v4')
    if mod is None or getattr(mod, '_rv_te_quiet', False):
        return

    def quiet(*args: Any, **kwargs: Any) -> None:
        if not kwargs and len(args) == 1 and isinstance(args[0], str) \
                and ' MB/s cc=' in args[0]:
            return
        builtins.print(*args, **kwargs)

    mod.print = quiet  # type: ignore[attr-defined]
    mod._rv_te_quiet = True  # type: ignore[attr-defined]


def _short(exc: BaseException) -> str:
    return ' '.join(str(exc).split())[:200] or type(exc).__name__


class MdfReader:
    """An MDF file opened for import (see the module docstring).

    Raises:
        DataImportError: ``asammdf`` missing, not an MDF file or truncated, a channel not in
            the file, channels in different groups, no samples.
    """

    def __init__(self, path: Path, options: ImportOptions) -> None:
        asammdf = require_reader('asammdf', 'MDF')
        _quiet_loader()
        self.path = Path(path)
        self.origin = str(path)
        self.options = options
        refuse_empty(self.path)
        problem = None
        hook = sys.unraisablehook
        sys.unraisablehook = lambda _u: None    # a half-built MDF4 complains in __del__
        opened = False
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                self._mdf = asammdf.MDF(self.path)  # type: ignore[attr-defined]
            opened = True
        except Exception as exc:  # noqa: BLE001 - asammdf raises many types on bad files
            problem = _short(exc)
        finally:
            if not opened:   # the half-built MDF's __del__ runs now, silenced (a whole one
                gc.collect()  # leaves none: the collection cost 20-50 ms per import)
            sys.unraisablehook = hook
        if problem is not None:
            msg = f'{path}: not a readable MDF file, truncated or damaged ({problem})'
            raise DataImportError(msg)
        roles = channel_roles(path, options, self._names)
        self.where = {r: self._find(spec) for r, spec in roles.items()}
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
        # from the channel blocks: MDF.get(record_count=1) would load the whole group first
        self.declared_units = {}
        for role, (gp, idx) in self.where.items():
            ch = self._mdf.groups[gp].channels[idx]
            unit = getattr(ch, 'unit', '') or ''
            conv = getattr(ch, 'conversion', None)
            conv_unit = getattr(conv, 'unit', '') if conv is not None else ''
            if conv_unit:
                unit = conv_unit
            self.declared_units[role] = str(unit) or None
        self.has_time = True     # the master channel, or --time
        # a time master channel is in seconds (ASAM MDF4: sync type time); a --time channel
        # in the unit it states (or --time-unit)
        self.time_unit: str | None = None if 'time' in self.where else 's'
        self.declared_rate_hz: float | None = None
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
        return tuple(places[0])

    def locate(self, index: int) -> str:
        """Sample index -> ``'sample N'`` (0-based record of the channel group)."""
        return f'sample {index}'

    def chunks(self) -> Iterator[RawChunk]:
        """Yield the channel group's data fragments (about ``chunk_samples`` records each);
        time = the master channel [s] (or ``--time``).

        One fragment at a time (``read_fragment_size``), each read once for all the
        channels of the group (:meth:`_fragments`). (``MDF.get`` with ``record_offset``
        re-reads the group from its start: 58 s for 10 M records.)
        asammdf maps the file into memory: the resident size grows by the pages read (file
        pages the kernel can drop); the heap stays flat.

        Raises:
            DataImportError: A channel cannot be read or ends early (truncated file).
        """
        grp = self._mdf.groups[self.group]
        record = int(getattr(grp.channel_group, 'samples_byte_nr', 0) or 8) + int(
            getattr(grp.channel_group, 'invalidation_bytes_nr', 0) or 0)
        self._mdf.configure(read_fragment_size=max(record * self.options.chunk_samples, 1 << 16))
        roles = list(self.where)
        first = 0
        for master, samples in self._fragments(roles):
            cols: dict[str, np.ndarray] = {}
            for role, got in zip(roles, samples, strict=True):
                data = None if got is None else self._numbers(role, got)
                if data is None or (cols and data.size != cols[roles[0]].size):
                    at = first + (0 if data is None else data.size)
                    msg = (f'{self.origin}: channel {self.labels[role]!r}, sample {at}: the '
                           f'data ends early (truncated or damaged file: {self.n} records '
                           'announced)')
                    raise DataImportError(msg)
                cols[role] = data
            n = cols['in'].size
            time = cols.get('time')
            if time is None:
                assert master is not None   # a missing first channel raised above
                time = np.asarray(master, dtype=np.float64)
            yield RawChunk(first=first, time=time, theta_in=cols['in'],
                           theta_out=cols['out'], torque=cols.get('torque'),
                           out_heads=stack_heads(cols, self.options),
                           loss=stack_loss(cols, self.options))
            first += n
        if first != self.n:
            msg = (f'{self.origin}: channel {self.labels["in"]!r}, sample {first}: the data '
                   f'ends early (truncated or damaged file: {self.n} records announced)')
            raise DataImportError(msg)

    def _numbers(self, role: str, samples: Any) -> np.ndarray:
        """A channel's samples as float64; text (a value-to-text conversion) or a structure
        (composed channel) refused in one line."""
        a = np.asarray(samples)
        if a.dtype.names:
            msg = (f'{self.origin}: channel {self.labels[role]!r} is a structure (fields '
                   f'{", ".join(a.dtype.names[:8])}), not numbers: name one of its numeric '
                   'members')
            raise DataImportError(msg)
        if a.dtype.kind not in 'biuf':
            what = 'text (a value-to-text conversion)' if a.dtype.kind in 'SUO' \
                else f'values of type {a.dtype}'
            msg = f'{self.origin}: channel {self.labels[role]!r} holds {what}, not numbers'
            raise DataImportError(msg)
        return a.astype(np.float64, copy=False)

    def _fragments(self, roles: list[str]) -> Iterator[tuple[Any, list[Any]]]:
        """(master times or None, each role's samples or None) per data fragment of the group.

        The group's data is read once per fragment and each channel taken from it
        (``MDF.get(data=fragment)``, as ``MDF.iter_get`` does per channel): ``iter_get``
        would read every fragment once per channel and decode the master channel with
        each (4 channels: 3 reads and 8 decodes per fragment, issue 41). The fragments come
        from asammdf's own ``_load_data`` (what ``iter_get`` iterates); an asammdf without
        it is read by ``iter_get`` as before.
        """
        load = getattr(getattr(self._mdf, '_mdf', None), '_load_data', None)
        if load is None:
            yield from self._zipped(roles)
            return
        where = [self.where[r] for r in roles]
        need_master = 'time' not in self.where
        role, done = roles[0], 0
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                for fragment in load(self._mdf.groups[self.group]):
                    samples = []
                    for role, (gp, idx) in zip(roles, where, strict=True):  # noqa: B007
                        samples.append(self._mdf.get(
                            group=gp, index=idx, data=fragment, samples_only=True,
                            ignore_invalidation_bits=True)[0])
                    role = roles[0]
                    master = self._mdf.get_master(self.group, data=fragment) \
                        if need_master else None
                    done += len(samples[0])
                    yield master, samples
        except Exception as exc:  # noqa: BLE001 - truncated files raise many types
            msg = (f'{self.origin}: channel {self.labels[role]!r}, sample {done}: cannot be '
                   f'read, the file is truncated or damaged ({_short(exc)})')
            raise DataImportError(msg) from None

    def _zipped(self, roles: list[str]) -> Iterator[tuple[Any, list[Any]]]:
        """:meth:`_fragments` by ``MDF.iter_get``, one iterator per channel, zipped."""
        iters = [self._iter(role) for role in roles]
        while True:
            sigs = [next(it, None) for it in iters]
            if all(sig is None for sig in sigs):
                return
            yield (None if sigs[0] is None else sigs[0].timestamps,
                   [None if sig is None else sig.samples for sig in sigs])

    def _iter(self, role: str) -> Iterator[Any]:
        gp, idx = self.where[role]
        done = 0
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                for sig in self._mdf.iter_get(group=gp, index=idx):
                    done += len(sig.samples)
                    yield sig
        except Exception as exc:  # noqa: BLE001 - truncated files raise many types
            msg = (f'{self.origin}: channel {self.labels[role]!r}, sample {done}: cannot be '
                   f'read, the file is truncated or damaged ({_short(exc)})')
            raise DataImportError(msg) from None

    def close(self) -> None:
        """Close the file."""
        self._mdf.close()
