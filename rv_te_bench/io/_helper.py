"""The offline analysis's helper thread, started once the machine is seen to have room.

:class:`HelperThread` is the one-thread executor the bag reader (chunks decompressed
ahead) and the spectra (:func:`rv_te_bench.core.offline.analyze_blocks`) share. Started at
once (``RV_TE_READ_AHEAD=1``, or no ``/proc`` to look at) it is a plain single worker.
Otherwise it holds the jobs handed to it, and the caller takes back each job it reaches
before the helper has started it (as it does from a busy helper), so the analysis runs on
one thread meanwhile, and at the first job handed over or batch read (:meth:`watch`) once
:data:`~rv_te_bench.io._cores.DECIDE_AFTER_S` have passed it reads the machine again and
starts its thread on the jobs still waiting, or does without it (each further job comes
back cancelled: the caller does it). Which thread does a job never changes its result.
The rule: :mod:`rv_te_bench.io._cores`.
"""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import Executor, Future
from queue import Empty, SimpleQueue
from typing import TYPE_CHECKING, Any, TypeVar

from rv_te_bench.io import _cores

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Iterator

__all__ = ['HelperThread']

_log = logging.getLogger(__name__)
T = TypeVar('T')
_now = time.monotonic   # (tests plant a clock here)

_Job = tuple['Future[Any]', 'Callable[..., Any]', tuple[Any, ...], dict[str, Any]]


class HelperThread(Executor):
    """One worker thread (named ``te-helper``), started now or when the machine has room.

    Args:
        decide: False: start the thread now. True: hold the jobs, and decide after
            :data:`~rv_te_bench.io._cores.DECIDE_AFTER_S` from two readings of the machine
            (:func:`~rv_te_bench.io._cores.helper_has_room`); where ``/proc`` cannot be
            read, start now.

    ``decision`` says what was decided and why (also logged at DEBUG).
    """

    def __init__(self, *, decide: bool) -> None:
        self._jobs: SimpleQueue[_Job | None] = SimpleQueue()
        self._thread: threading.Thread | None = None
        self._declined = False
        self._closed = False
        self._t0 = _now()
        self._first = _cores.sample_machine() if decide else None
        self.decision = 'deciding'
        if self._first is None:
            self._start('helper from the start' if not decide
                        else 'helper from the start (the machine cannot be read)')

    @property
    def started(self) -> bool:
        """True once the worker thread runs."""
        return self._thread is not None

    def poll(self) -> None:
        """Decide now if it is time to (cheap otherwise: call it often)."""
        if self._thread is None and not self._declined and not self._closed \
                and _now() - self._t0 >= _cores.DECIDE_AFTER_S:
            self._decide()

    def watch(self, items: Iterable[T]) -> Iterator[T]:
        """``items`` as they come, polling for the decision after each (the caller's loop:
        jobs alone are not handed over often enough, all of a small bag's at the start)."""
        for item in items:
            yield item
            self.poll()

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        """Hand a job to the helper: run by its thread, or (not started, declined) left for
        the caller to take back with ``cancel()``; after a decline it comes cancelled."""
        self.poll()
        job: Future[Any] = Future()
        if self._declined or self._closed:
            job.cancel()
            return job
        self._jobs.put((job, fn, args, kwargs))
        return job

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Stop the thread after its current job; jobs it has not started are cancelled
        where it never started or ``cancel_futures``, else run first."""
        if self._closed:
            return
        self._closed = True
        if self._thread is None or cancel_futures:
            self._cancel_waiting()
        if self._thread is not None:
            self._jobs.put(None)
            if wait:
                self._thread.join()

    def _decide(self) -> None:
        after = _cores.sample_machine()
        elapsed_ms = (_now() - self._t0) * 1e3
        if self._first is None or after is None:
            room, why = True, 'the machine cannot be read'
        else:
            room, why = _cores.helper_has_room(self._first, after)
        if room:
            self._start(f'helper after {elapsed_ms:.0f} ms ({why})')
        else:
            self._declined = True
            self._cancel_waiting()
            self.decision = f'one thread after {elapsed_ms:.0f} ms ({why})'
            _log.debug('analysis: %s', self.decision)

    def _start(self, decision: str) -> None:
        self.decision = decision
        _log.debug('analysis: %s', decision)
        self._thread = threading.Thread(target=self._work, name='te-helper', daemon=True)
        self._thread.start()

    def _cancel_waiting(self) -> None:
        while True:
            try:
                item = self._jobs.get_nowait()
            except Empty:
                return
            if item is None:        # (the stop for a running thread: put back)
                self._jobs.put(None)
                return
            item[0].cancel()

    def _work(self) -> None:
        while (item := self._jobs.get()) is not None:
            _run(item)
            del item   # (no window's arrays held while idle)


def _run(item: _Job) -> None:
    job, fn, args, kwargs = item
    if job.set_running_or_notify_cancel():
        try:
            result = fn(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001 (handed to the caller, as an executor does)
            job.set_exception(exc)
        else:
            job.set_result(result)
