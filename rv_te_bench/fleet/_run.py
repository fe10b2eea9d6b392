"""Analyse many bags with Dask distributed and write each result to the store.

The client (this process) is the only writer of the store: workers analyse a bag and hand
back its :class:`~rv_te_bench.store.UnitRecord` (the same record ``rv-te analyze`` writes,
~10 kB, no arrays), the client writes a task's records the moment they arrive, in one
transaction. A worker that dies mid-task loses nothing: the
scheduler runs its task again on another worker (up to Dask's ``allowed-failures``, then
the bag is recorded as failed with that reason); results already handed back are already
in the store. A bag that cannot be analysed is recorded as failed with its one-line reason.

Hand-over costs are kept off the bags (issue 41): bags go to the workers in batches (several
per task while many remain, one per task at the end so that the workers finish together),
a batch whose worker died is split into single bags (only a bag that kills its worker every
time is recorded failed), a local cluster's workers are forked warm from a fork server
that imported the analysis once (:mod:`._warm`, :func:`_local_config`), and bags of one
size are told apart by their ends before any is hashed whole (:func:`_todo`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from rv_te_bench import __version__
from rv_te_bench.errors import RvTeError, StoreError
from rv_te_bench.io.bag_reader import READ_AHEAD_ENV
from rv_te_bench.store import (
    bag_fingerprint,
    bag_probe,
    bag_stat,
    failed_record,
    records_from_analysis_json,
)

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from rv_te_bench.store import ResultStore, UnitRecord

__all__ = ['FleetOptions', 'FleetSummary', 'analyse_batch', 'analyse_one', 'batches',
           'run_fleet']

@dataclass(frozen=True)
class FleetOptions:
    """The analysis options of every bag (as ``rv-te analyze`` takes them)."""

    topic: str | None = None
    gear_ratio: float | None = None
    crank_per_output: float | None = None
    n_crank_harmonics: int = 10
    window_revolutions: int = 1
    with_advice: bool = True
    serial: str | None = None
    lot: str | None = None
    operator: str | None = None


@dataclass
class FleetSummary:
    """What a fleet run did (counts of bags)."""

    total: int = 0
    ok: int = 0
    partial: int = 0
    failed: int = 0
    skipped: int = 0
    elapsed_s: float = 0.0
    workers: int = 0
    failures: list[tuple[str, str]] = field(default_factory=list)
    #: Paths holding the same bag (same content hash): one record, analysed once.
    duplicates: list[list[str]] = field(default_factory=list)

    @property
    def duplicate_paths(self) -> int:
        """Paths not analysed because another path of the run holds the same bag."""
        return sum(len(g) - 1 for g in self.duplicates)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {'total': self.total, 'ok': self.ok, 'partial': self.partial,
                'failed': self.failed, 'skipped': self.skipped, 'elapsed_s': self.elapsed_s,
                'workers': self.workers, 'duplicate_paths': self.duplicate_paths,
                'duplicates': self.duplicates,
                'failures': [{'bag': b, 'reason': r} for b, r in self.failures]}


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0] if text else type(exc).__name__)[:500]


def analyse_one(path: str, options: FleetOptions) -> UnitRecord:
    """Analyse one bag into its record (run on a worker; never raises for a bad bag)."""
    from rv_te_bench.allocator import tune_for_batch_work
    from rv_te_bench.report.analysis import analyze_bag
    from rv_te_bench.report.html import report_json
    from sim.errors import SimError

    tune_for_batch_work()
    bag = Path(path)
    try:
        res = analyze_bag(bag, topic=options.topic, gear_ratio=options.gear_ratio,
                          crank_per_output=options.crank_per_output,
                          n_crank_harmonics=options.n_crank_harmonics,
                          window_revolutions=options.window_revolutions,
                          with_advice=options.with_advice)
        (rec,) = records_from_analysis_json(
            report_json([res]), bag_paths=[bag], command='fleet',
            software_version=__version__, serial=options.serial, lot=options.lot,
            operator=options.operator)
    except (RvTeError, SimError, OSError, ValueError) as exc:
        return failed_record(bag, _one_line(exc), command='fleet', software_version=__version__)
    return rec


def analyse_batch(paths: Sequence[str], options: FleetOptions) -> list[UnitRecord]:
    """Analyse several bags in one task (run on a worker; never raises for a bad bag)."""
    return [analyse_one(p, options) for p in paths]


_P = TypeVar('_P')

#: Most bags in one task: ~2-3 s of work at 2 output revolutions and 10 kHz.
MAX_BATCH = 8


def batches(paths: Sequence[_P], workers: int) -> list[list[_P]]:
    """Cut ``paths`` into tasks: about a third of each worker's share of what is left per
    task (at most MAX_BATCH), shrinking to single bags at the end (guided scheduling)."""
    out: list[list[_P]] = []
    k = 0
    while k < len(paths):
        size = max(1, min(MAX_BATCH, (len(paths) - k) // (3 * max(1, workers))))
        out.append(list(paths[k:k + size]))
        k += size
    return out


def _todo(bags: Sequence[Path], store: ResultStore, force: bool,
          ) -> tuple[list[Path], int, list[list[str]]]:
    """Bags to analyse, how many are skipped, and the groups of paths holding the same bag.

    A record is keyed by the bag's content hash, so a bag copied to two places is one test
    of one unit: one record, analysed once (the first path in order), the other paths
    reported as duplicates. A bag is skipped when its content already has a good record:
    known by its path with the recorded size and mtime (no reading), else by its hash. The
    hash is computed only where it can matter: for a bag whose total size equals a good
    record's (a copy of the same bag has the same size), and for bags of this run that
    share their size and their probe (:func:`bag_probe`: the files' first and last 64 kB,
    which tell two recordings of the same length apart without reading them whole).
    """
    known = store.known_bags()
    good = {k[3] for k in known.values() if k[2] != 'failed'}
    good_sizes = {k[0] for k in known.values() if k[2] != 'failed'}
    stats: dict[Path, tuple[int, int] | None] = {}
    for b in bags:
        try:
            stats[b] = bag_stat(b)
        except (OSError, StoreError):
            stats[b] = None
    sizes = Counter(st[0] for st in stats.values() if st is not None)
    sha_of: dict[Path, str] = {}
    to_hash: list[Path] = []
    probed: dict[tuple[int, str], list[Path]] = {}
    for b in bags:
        st, k = stats[b], known.get(str(b))
        if st is None:
            continue
        if k is not None and k[2] != 'failed' and (k[0], k[1]) == st:
            sha_of[b] = k[3]                       # unchanged since its record: no reading
        elif st[0] in good_sizes:
            to_hash.append(b)                      # may be a recorded bag at another path
        elif sizes[st[0]] > 1:
            try:
                probed.setdefault((st[0], bag_probe(b)), []).append(b)
            except (OSError, StoreError):
                pass
    to_hash += [b for same in probed.values() if len(same) > 1 for b in same]
    for b in to_hash:
        try:
            sha_of[b] = bag_fingerprint(b)[0]
        except (OSError, StoreError):
            pass
    groups: dict[str, list[Path]] = {}
    for b in bags:
        if b in sha_of:
            groups.setdefault(sha_of[b], []).append(b)
    duplicates = [[str(p) for p in g] for g in groups.values() if len(g) > 1]
    todo, skipped = [], 0
    for b in bags:
        sha = sha_of.get(b)
        if sha is not None and groups[sha][0] != b:
            continue                               # another path holds the same bag
        if not force and sha is not None and sha in good:
            skipped += 1
            continue
        todo.append(b)
    return todo, skipped, duplicates


_WARM = 'rv_te_bench.fleet._warm'

#: How long the scheduler has to accept a connection and answer its handshake [s].
SCHEDULER_TIMEOUT_S = 20.0


def _probe_scheduler(address: str) -> None:
    """Refuse a malformed address, and one whose endpoint does not answer Dask's handshake
    within SCHEDULER_TIMEOUT_S (an endpoint that accepts and never answers would keep
    ``Client`` waiting for ever), in one line each.

    Raises:
        RvTeError: Malformed, unreachable or silent.
    """
    import asyncio

    from distributed.comm import connect
    from distributed.comm.addressing import parse_address

    shown = address[:200]
    try:
        scheme, loc = parse_address(address, strict=True)
        if scheme not in ('tcp', 'tls', 'ws', 'wss', 'ucx'):
            msg = f'protocol {scheme!r}: use tcp://, tls://, ws://, wss:// or ucx://'
            raise ValueError(msg)
        host, sep, port = loc.rpartition(':')
        if scheme in ('tcp', 'tls', 'ws', 'wss') and not (sep and host and port.isdigit()
                                                          and 0 < int(port) < 65536):
            msg = f'expected {scheme}://HOST:PORT'
            raise ValueError(msg)
    except ValueError as exc:
        msg = (f'--scheduler {shown!r} is not a Dask scheduler address '
               f'(tcp://host:8786): {_one_line(exc)}')
        raise RvTeError(msg) from None

    async def handshake() -> None:
        comm = await connect(address, timeout=SCHEDULER_TIMEOUT_S)
        await comm.close()

    try:
        asyncio.run(asyncio.wait_for(handshake(), SCHEDULER_TIMEOUT_S))
    except TimeoutError:
        msg = (f'the Dask scheduler at {shown} did not answer within '
               f'{SCHEDULER_TIMEOUT_S:g} s')
        raise RvTeError(msg) from None
    except (OSError, ValueError) as exc:
        msg = f'cannot reach the Dask scheduler at {shown}: {_one_line(exc)}'
        raise RvTeError(msg) from None


#: How often a local cluster's event loops check their own health (Dask's default: 20 ms).
TICK_INTERVAL = '1s'


def _local_config() -> Any:
    """Dask's settings for a local cluster whose workers are forked warm (a context manager).

    The workers are forked from a fork server that imported :mod:`._warm` (the analysis,
    the report's JSON, the store, Dask's worker) once, instead of each spawned cold and
    importing it all. Dask sets the fork server's preload itself the first time it starts
    a worker (its own list: distributed, numpy, pandas, ..., each imported in this process
    too), replacing ours, unless it has done so already: marked done, ours stays. The
    setting also covers a worker the nanny starts again after it died.

    The workers' statistical profiler is off: it samples the task's stack every 10 ms on
    the worker's event loop, for a dashboard nobody sees here (a worker's event loop used
    0.73-1.34 CPU s during a 10 s task with it, 0.66 s without it).

    Every event loop (the scheduler's and the nannies' here, each worker's) checks its own
    health once a second instead of every 20 ms: the check only warns of a loop blocked for
    more than 3 s (``distributed.admin.tick.limit``), at WARNING, which the command does not
    show. A 2-worker cluster doing nothing used 3.2-3.5 CPU s in 20 s with the 20 ms
    check, 2.3-2.5 s with 1 s (mostly Python's and Dask's start-up; AMD EPYC, load 9-14).
    """
    import multiprocessing

    import dask
    import distributed.utils

    multiprocessing.get_context('forkserver').set_forkserver_preload([_WARM])
    distributed.utils._forkserver_preload_set = True   # see above
    return dask.config.set({'distributed.worker.multiprocessing-method': 'forkserver',
                            'distributed.worker.profile.enabled': False,
                            'distributed.admin.tick.interval': TICK_INTERVAL})


def _client(workers: int, scheduler: str | None) -> tuple[Any, Any]:
    try:
        from distributed import Client, LocalCluster
    except ModuleNotFoundError:
        msg = "rv-te fleet needs Dask distributed: pip install 'rv-te-bench[fleet]'"
        raise RvTeError(msg) from None
    if scheduler:
        _probe_scheduler(scheduler)
        try:
            return Client(scheduler, timeout=f'{SCHEDULER_TIMEOUT_S:g}s'), None
        except (OSError, TimeoutError, ValueError) as exc:
            msg = f'cannot reach the Dask scheduler at {scheduler[:200]}: {_one_line(exc)}'
            raise RvTeError(msg) from None
    # the scheduler's HTTP server on a free port: with None it still tries 8787 and warns
    # on stderr when another cluster holds it (one clear line is all the command prints)
    # with a worker per core, bags in parallel use the cores better than each analysis's
    # helper threads (read-ahead and window spectra: one analysis takes ~1.6 cores): off in
    # the workers
    env = {READ_AHEAD_ENV: '0'} if workers >= (os.cpu_count() or 1) else {}
    with _local_config():
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=':0', silence_logs=logging.ERROR, env=env,
                               preload=[_WARM])
    return Client(cluster), cluster


def run_fleet(bags: Sequence[Path], store: ResultStore, *, options: FleetOptions,
              workers: int = 2, scheduler: str | None = None, force: bool = False,
              progress: Callable[[int, int, int], None] | None = None,
              on_client: Callable[[Any], None] | None = None) -> FleetSummary:
    """Analyse ``bags`` in parallel, one record per bag written to ``store`` as it arrives.

    Args:
        bags: Bag folders / .mcap files (absolute paths; the workers must see them).
        store: Where the records go (written by this process only).
        options: Analysis options of every bag.
        workers: Worker processes of the local cluster (ignored with ``scheduler``).
        scheduler: Address of an existing Dask scheduler (``tcp://host:8786``).
        force: Analyse bags again that already have a good record of the same content
            (paths holding the same bag are still analysed once).
        progress: Called as ``progress(done, total, failed)`` after each bag.
        on_client: Called with the Dask client once it is up (tests, diagnostics).
    """
    t0 = time.monotonic()
    summary = FleetSummary()
    todo, summary.skipped, summary.duplicates = _todo(bags, store, force)
    summary.total = len(bags)
    if not todo:
        summary.elapsed_s = time.monotonic() - t0
        return summary
    with contextlib.ExitStack() as stack:
        if scheduler is None:
            stack.enter_context(_local_config())   # also for a worker started again
        client, cluster = _client(workers, scheduler)
        stack.callback(_close, client, cluster)
        _hand_out(client, todo, summary, scheduler=scheduler, workers=workers,
                  options=options, store=store, progress=progress, on_client=on_client)
    summary.elapsed_s = time.monotonic() - t0
    return summary


def _close(client: Any, cluster: Any) -> None:
    client.close()
    if cluster is not None:
        cluster.close()


def _hand_out(client: Any, todo: list[Path], summary: FleetSummary, *, scheduler: str | None,
              workers: int, options: FleetOptions, store: ResultStore,
              progress: Callable[[int, int, int], None] | None,
              on_client: Callable[[Any], None] | None) -> None:
    """Send the bags in batches; write each batch's records as it comes back (one
    transaction per batch: a batch's records are in the store together or not at all)."""
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    if on_client is not None:
        on_client(client)
    summary.workers = len(client.scheduler_info().get('workers', {}))
    n_workers = max(1, summary.workers if scheduler else workers)
    ac = as_completed()
    batch_of: dict[str, list[Path]] = {}

    def submit(group: list[Path]) -> None:
        fut = client.submit(analyse_batch, [str(b) for b in group], options, pure=False)
        batch_of[fut.key] = group
        ac.add(fut)

    for group in batches(todo, n_workers):
        submit(group)
    done = 0
    for fut in ac:
        group = batch_of.pop(fut.key)
        try:
            recs = fut.result()
        except KilledWorker:
            if len(group) > 1:     # one of them may kill its worker: each on its own
                for b in group:
                    submit([b])
                continue
            recs = [failed_record(group[0], 'the worker analysing this bag died every '
                                  'time it was tried (Dask allowed-failures)',
                                  command='fleet', software_version=__version__)]
        except Exception as exc:  # noqa: BLE001 - recorded with its reason, not lost
            recs = [failed_record(b, f'{type(exc).__name__}: {_one_line(exc)}',
                                  command='fleet', software_version=__version__)
                    for b in group]
        fut.release()
        store.upsert_many(recs)
        for bag, rec in zip(group, recs, strict=True):
            done += 1
            if rec.status == 'failed':
                summary.failed += 1
                summary.failures.append((str(bag), rec.failure or ''))
            elif rec.status == 'partial':
                summary.partial += 1
            else:
                summary.ok += 1
            if progress is not None:
                progress(done, len(todo), summary.failed)
