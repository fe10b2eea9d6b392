"""The MCAP storage of rosbag2: a bag's ``.mcap`` files as units of messages, and their topics.

The storage the suite writes and reads itself. The record walk (records, chunks, summary,
read-ahead, chunk CRC) is :mod:`._mcap_scan`; here it is turned into what the opener
(:mod:`._bag_open`) asks of any storage, in the shapes :mod:`._storage_sqlite3` gives too:

* :func:`check_magic`: a file is MCAP (its first 8 bytes);
* :func:`mcap_units`: the wanted messages of each chunk as offsets into its buffer
  (:data:`._bag_types.Unit`), file by file, in recording order; :func:`mcap_unit_columns`
  the same as arrays (:class:`._bag_types.UnitColumns`);
* :func:`mcap_topics`: topic -> type and offered QoS from the channels of every file;
* :func:`indexed_messages`: the few messages of some topics found through a file's
  summary (its chunk index), None without a sound summary;
* :func:`mcap_counts`: every record walked, messages counted per topic (``rv-te bag``'s
  summary).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import BagError
from rv_te_bench.io._bag_types import UnitColumns
from rv_te_bench.io._mcap_file import MAGIC
from rv_te_bench.io._mcap_scan import (
    _file_channels,
    _indexed_messages,
    _scan_file,
    _scan_units,
    _ScanState,
)

if TYPE_CHECKING:
    from collections.abc import Callable, Collection, Iterator
    from concurrent.futures import Executor
    from pathlib import Path

    from rv_te_bench.io._bag_types import Bag, Unit

__all__ = ['STORAGE', 'check_magic', 'indexed_messages', 'mcap_counts', 'mcap_topics',
           'mcap_unit_columns', 'mcap_units']

STORAGE = 'mcap'


def check_magic(file: Path) -> None:
    """Raise unless ``file`` starts with the MCAP magic.

    Raises:
        BagError: The file cannot be opened, is empty or is not MCAP.
    """
    try:
        with file.open('rb') as fh:
            head = fh.read(8)
    except OSError as exc:
        msg = f'Cannot open {file}: {exc}.'
        raise BagError(msg) from None
    if not head:
        msg = f'{file} is empty (0 bytes).'
        raise BagError(msg)
    if head != MAGIC:
        msg = f'{file} is not an MCAP file (bad magic {head[:8]!r}).'
        raise BagError(msg)


def mcap_units(bag: Bag, report: Callable[[str], None], topics: Collection[str] | None,
               executor: Executor | None = None, *, read_ahead: bool = True,
               ) -> Iterator[Unit]:
    """Per chunk: the buffer and its wanted messages (topic, msgtype, log_time, start, end).

    Args:
        bag: The bag (its ``.mcap`` files).
        report: Called with one line per problem (the read goes on where it can).
        topics: Topic names to keep; None keeps all.
        executor: The thread that reads MCAP chunks ahead (None: one of the scan's own).
        read_ahead: False: no chunk is read ahead (no thread at all; the one-core path).
    """
    for unit in mcap_unit_columns(bag, report, topics, executor, read_ahead=read_ahead):
        yield unit.buf, unit.rows()


def mcap_unit_columns(bag: Bag, report: Callable[[str], None], topics: Collection[str] | None,
                      executor: Executor | None = None, *, read_ahead: bool = True,
                      ) -> Iterator[UnitColumns]:
    """:func:`mcap_units` by columns: per chunk, its wanted messages as arrays (a chunk's
    few channels are resolved once, its messages selected with one mask)."""
    wanted = None if topics is None else set(topics)
    for file in bag.files:
        state = _ScanState()
        resolved: dict[int, tuple[str, str] | None] = {}
        for inner, cols in _scan_units(file, state, report, executor=executor,
                                        prefetch=read_ahead):
            cid = cols.cid
            lo, hi = int(cid.min()), int(cid.max())
            ids = [lo] if lo == hi else np.unique(cid).tolist()
            keep: list[int] = []
            targets: list[tuple[str, str]] = []
            for c in ids:
                if c not in resolved:
                    chan = state.channels.get(c)
                    if chan is None:
                        for _ in range(int(np.count_nonzero(cid == c))):
                            report(f'{file}: message on unknown channel {c}; skipped')
                        continue
                    topic, sid = chan
                    msgtype = state.schemas.get(sid, ('', ''))[0] or bag.topic_types.get(topic, '')
                    resolved[c] = (topic, msgtype) if wanted is None or topic in wanted else None
                target = resolved[c]
                if target is not None:
                    keep.append(c)
                    targets.append(target)
            if not keep:
                continue
            if len(keep) == len(ids) == 1:   # the usual chunk: one channel, every message
                yield UnitColumns(inner, (targets[0],), np.zeros(cid.size, np.intp),
                                  cols.log_time, cols.start, cols.end)
                continue
            ids_kept = np.array(keep, np.int64)   # sorted (np.unique)
            mask = np.isin(cid, ids_kept)
            yield UnitColumns(inner, tuple(targets), np.searchsorted(ids_kept, cid[mask]),
                              cols.log_time[mask], cols.start[mask], cols.end[mask])


def mcap_topics(bag: Bag) -> dict[str, dict[str, Any]]:
    """Topic -> {'type', 'offered_qos_profiles'} from the MCAP channels of every file."""
    out: dict[str, dict[str, Any]] = {}
    for file in bag.files:
        state = _file_channels(file)
        for cid, (topic, sid) in state.channels.items():
            meta = state.channel_meta.get(cid, {})
            out.setdefault(topic, {'type': state.schemas.get(sid, ('', ''))[0],
                                   'offered_qos_profiles': meta.get('offered_qos_profiles')})
    return out


def indexed_messages(file: Path, topics: Collection[str]) -> list[tuple[str, bytes]] | None:
    """``(msgtype, cdr)`` of every message of ``topics`` in ``file``, found through its
    summary's chunk index; None when the file has no sound summary (then scan it)."""
    return _indexed_messages(file, topics)


def mcap_counts(bag: Bag, report: Callable[[str], None], types: dict[str, str],
                ) -> tuple[dict[str, int], int | None, int | None, dict[str, dict[str, str]]]:
    """Walk every record of every file: messages per topic, first and last log time.

    Args:
        bag: The bag.
        report: Called with one line per problem (the walk goes on where it can).
        types: Topic -> type, completed in place with the channels' schema names.

    Returns:
        ``(counts per topic, start_ns, end_ns, metadata records by name)``; the times are
        None when no message was read.
    """
    counts: dict[str, int] = {}
    meta: dict[str, dict[str, str]] = {}
    start, stop = None, None
    for file in bag.files:
        state = _ScanState()
        per_cid: dict[int, int] = {}
        times: list[int] = []
        for cid, log_time, _ in _scan_file(file, state, report):
            per_cid[cid] = per_cid.get(cid, 0) + 1
            times.append(log_time)
        for cid, n in per_cid.items():
            topic, _sid = state.channels.get(cid, (f'<unknown channel {cid}>', 0))
            counts[topic] = counts.get(topic, 0) + n
        for topic, sid in state.channels.values():
            types.setdefault(topic, state.schemas.get(sid, ('', ''))[0])
        meta.update(state.metadata)
        if times:
            lo, hi = min(times), max(times)
            start = lo if start is None else min(start, lo)
            stop = hi if stop is None else max(stop, hi)
    return counts, start, stop, meta
