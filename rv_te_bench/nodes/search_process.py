"""Where the compensation node's searches run: a worker process of its own, or a thread.

A search (the Wang 2020 Eq. 21 phase grid, the identification after each window) is 0.4-1
CPU s of Python and numpy. On a thread of the node's process it holds the interpreter lock
the node's other threads need; in a one-process session (``rv-te launch --single-process``)
one of them is the bench's pacing thread, and its blocks then left 52-83 ms late with the
session alone on the machine (issue 41 item 4, ``benchmarks/trace_one_process.py``: 11 of
its 12 worst ticks fell inside a search). :class:`SearchRunner` runs each search in a
worker process (default; started with the node, ``spawn``: nothing of the node's threads
or middleware is copied), fed the job's inputs by pickling and handing back the advice: the
node's process is left the lock. ``in_process=True`` runs them on one thread instead, as
before (the same functions, the same advice).

The worker process:

* runs one search at a time (in submission order), at the niceness of the thread that
  started it + ``nice``, on the normal policy even when started from a SCHED_FIFO thread;
* reports progress per kind through shared memory, and stops a search at its next progress
  report once :meth:`SearchRunner.shutdown` is called (``Cancelled``);
* ignores SIGINT and SIGTERM (a Ctrl-C in the terminal or the launcher's stop reaches the
  node, which ends the worker in its own order), and exits when its parent process is gone
  (a SIGKILLed node leaves no worker behind);
* is started again for the next search when it died (the search it ran fails with
  ``BrokenProcessPool``, logged by the node).

An error inside a search comes back as raised (its type and message), or, when it does not
survive pickling, as :class:`SearchError` with the original's message and type name.
No rclpy here.
"""

from __future__ import annotations

import contextlib
import importlib
import itertools
import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, BinaryIO

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping, Sequence

__all__ = ['Cancelled', 'SearchError', 'SearchJob', 'SearchRunner', 'current_nice',
           'lower_priority']

#: Shortest interval between two progress reports of the worker process [s].
PROGRESS_PERIOD_S = 0.05


class Cancelled(Exception):  # noqa: N818 - a control-flow signal, not an error
    """Raised inside a search's progress report when the runner shuts down."""


class SearchError(Exception):
    """A search in the worker process failed; ``str()`` is the original error's message,
    ``error_type`` its class name."""

    def __init__(self, message: str, error_type: str = '') -> None:
        """Keep the message and the original's type name (both pickled)."""
        super().__init__(message, error_type)
        self.message = message
        self.error_type = error_type

    def __str__(self) -> str:
        """The original error's message."""
        return self.message


@dataclass(frozen=True)
class SearchJob:
    """One search: ``fn(*args, **kwargs)`` (with ``progress=`` when ``progress``).

    For a worker process ``fn`` must be a module-level function and the arguments
    picklable (a preset, numpy arrays, numbers)."""

    kind: str
    fn: Callable[..., Any]
    args: tuple[Any, ...] = ()
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    progress: bool = True


def current_nice() -> int:
    """The niceness of the calling thread (Linux: per thread; else the process's)."""
    who = threading.get_native_id() if sys.platform.startswith('linux') else 0
    return os.getpriority(os.PRIO_PROCESS, who)


def lower_priority(nice: int) -> int | None:
    """Put the calling thread on the normal policy (a thread or process started from a
    SCHED_FIFO thread inherits it: in a one-process session the bench's pacing thread is
    one, and a search of 0.4-0.8 s then ran on SCHED_FIFO 50 where no niceness applies),
    then raise its niceness by ``nice``; return the niceness it has then (None: not set,
    ``nice`` 0 or not Linux)."""
    if not sys.platform.startswith('linux'):
        return None
    if os.sched_getscheduler(0) != os.SCHED_OTHER:
        with contextlib.suppress(OSError):   # (lowering needs no permission)
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    if nice <= 0:
        return None
    tid = threading.get_native_id()
    try:
        os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid)
                                                 + nice))
        return os.getpriority(os.PRIO_PROCESS, tid)
    except OSError:
        return None


def _report(progress: Any, index: int, cancel: Any) -> Callable[[float], None]:
    def report(fraction: float) -> None:
        if cancel.is_set():
            raise Cancelled
        progress[index] = float(fraction)
    return report


def _call(job: SearchJob, report: Callable[[float], None] | None) -> Any:
    if report is None:
        return job.fn(*job.args, **job.kwargs)
    return job.fn(*job.args, **job.kwargs, progress=report)


# -- the wire between the node and its worker: length-prefixed pickles ---------------------
_HEADER = struct.Struct('<Q')


def _send(stream: BinaryIO, item: Any) -> None:
    data = pickle.dumps(item, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)))
    stream.write(data)
    stream.flush()


def _receive(stream: BinaryIO) -> Any:
    """The next item (EOFError: the other end closed)."""
    head = stream.read(_HEADER.size)
    if len(head) < _HEADER.size:
        raise EOFError
    size = _HEADER.unpack(head)[0]
    data = stream.read(size)
    if len(data) < size:
        raise EOFError
    return pickle.loads(data)   # (our own worker's pipe, not outside input)


# -- in the worker process ----------------------------------------------------------------
def worker_main() -> int:
    """The worker process (``python -m rv_te_bench.nodes._search_worker NICE``): jobs in on
    stdin, progress and results out on what was stdout (stdout itself then goes to stderr:
    a stray print cannot break the wire); ends at EOF on stdin (its node closed it, or is
    gone)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    nice = lower_priority(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
    out = os.fdopen(os.dup(1), 'wb')
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    inp = sys.stdin.buffer
    lock = threading.Lock()
    cancel = threading.Event()
    jobs: queue.Queue[tuple[int, int, bytes] | None] = queue.Queue()

    def send(item: Any) -> None:
        with lock, contextlib.suppress(OSError, ValueError):   # (the node is gone)
            _send(out, item)

    def answer(job_id: int, kind: str, payload: Any) -> None:
        # the payload pickled on its own: one that cannot be read fails its job only
        try:
            data = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # noqa: BLE001 - said to the node, by message
            kind, data = 'error', pickle.dumps(SearchError(
                f'the result cannot be handed back: {exc}', type(exc).__name__))
        send((kind, job_id, data))

    def read() -> None:
        try:
            while True:
                item = _receive(inp)
                if item[0] == 'cancel':
                    cancel.set()
                    continue
                # unpickled by the main thread: unpickling may import (numpy for arrays),
                # and an import here beside the main thread's ('cannot import name ... from
                # partially initialized module numpy') failed a job
                jobs.put(item[1:])
        except Exception:  # noqa: BLE001, S110 - EOF (the node closed the pipe or is gone)
            pass
        finally:
            cancel.set()   # stop the search under way, and end
            jobs.put(None)

    send(('nice', nice))
    threading.Thread(target=read, name='search-input', daemon=True).start()
    sent = [0.0]

    def progress(index: int) -> Callable[[float], None]:
        def report(fraction: float) -> None:
            if cancel.is_set():
                raise Cancelled
            now = time.monotonic()
            if now - sent[0] >= PROGRESS_PERIOD_S:
                sent[0] = now
                send(('progress', index, float(fraction)))
        return report

    while (item := jobs.get()) is not None:
        job_id, index, data = item
        try:
            job = pickle.loads(data)
        except Exception as exc:  # noqa: BLE001 - that job fails, not the worker
            answer(job_id, 'error', SearchError(f'the job cannot be read: {exc}',
                                                type(exc).__name__))
            continue
        try:
            result = _call(job, progress(index) if job.progress else None)
        except Cancelled:
            answer(job_id, 'cancelled', None)
        except Exception as exc:  # noqa: BLE001 - handed back by message (pickling)
            answer(job_id, 'error', _portable(exc))
        else:
            answer(job_id, 'done', result)
    return 0


def _portable(exc: Exception) -> Exception:
    """``exc`` itself when it survives pickling, else a :class:`SearchError` with its
    message."""
    try:
        back = pickle.loads(pickle.dumps(exc, protocol=pickle.HIGHEST_PROTOCOL))
    except Exception:  # noqa: BLE001 - any failure: the message is what is left
        return SearchError(str(exc), type(exc).__name__)
    if type(back) is not type(exc) or str(back) != str(exc):
        return SearchError(str(exc), type(exc).__name__)
    return exc


#: The modules of the searches' results and errors (imported by the node's process before
#: the first result comes).
_RESULT_MODULES = ('numpy', 'rv_te_bench.core.advice', 'rv_te_bench.core.identification',
                   'rv_te_bench.errors', 'sim.errors')


def _warm() -> None:
    """Import what the searches use (at start, not at the first window)."""
    for name in ('rv_te_bench.core.compensation_search', 'rv_te_bench.core.identify',
                 'rv_te_bench.core.phases', 'rv_te_bench.core.tooth_compensation',
                 'sim.wang2020', 'scipy.optimize'):
        importlib.import_module(name)


# -- in the node's process ----------------------------------------------------------------
class _Worker:
    """The node's end of one worker process: sends jobs, takes progress and results."""

    def __init__(self, nice: int, progress: list[float]) -> None:
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
        self.proc = subprocess.Popen(
            [sys.executable, '-m', 'rv_te_bench.nodes._search_worker', str(int(nice))],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env, close_fds=True)
        self._progress = progress
        self._futures: dict[int, Future[Any]] = {}
        self._lock = threading.Lock()
        self._ids = itertools.count()
        self.nice: int | None = None
        self.ended = False
        self._reader = threading.Thread(target=self._read, name='search-results', daemon=True)
        self._reader.start()

    def submit(self, index: int, job: SearchJob) -> Future[Any]:
        data = pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL)   # (unpicklable: raises)
        fut: Future[Any] = Future()
        fut.set_running_or_notify_cancel()
        with self._lock:
            if self.ended:
                msg = 'the search process has ended'
                raise BrokenPipeError(msg)
            job_id = next(self._ids)
            self._futures[job_id] = fut
        assert self.proc.stdin is not None
        try:
            _send(self.proc.stdin, ('job', job_id, index, data))
        except (OSError, ValueError) as exc:
            with self._lock:
                self._futures.pop(job_id, None)
            raise BrokenPipeError(str(exc)) from None
        return fut

    def _read(self) -> None:
        assert self.proc.stdout is not None
        while True:
            try:
                item = _receive(self.proc.stdout)
            except Exception:  # noqa: BLE001 - EOF, or a broken wire: the worker is done
                break
            kind = item[0]
            if kind == 'progress':
                self._progress[item[1]] = item[2]
                continue
            if kind == 'nice':
                self.nice = item[1]
                continue
            with self._lock:
                fut = self._futures.pop(item[1], None)
            if fut is None:
                continue
            try:
                payload = pickle.loads(item[2])
            except Exception as exc:  # noqa: BLE001 - the job fails, the reader goes on
                fut.set_exception(SearchError(f'the result cannot be read: {exc}',
                                              type(exc).__name__))
                continue
            if kind == 'done':
                fut.set_result(payload)
            else:
                fut.set_exception(Cancelled() if kind == 'cancelled' else payload)
        code = self.proc.wait()
        with self._lock:
            self.ended = True
            left, self._futures = self._futures, {}
        for fut in left.values():
            fut.set_exception(SearchError(
                f'the search process ended (exit code {code}) before the search did',
                'SearchProcessEnded'))

    def cancel(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            assert self.proc.stdin is not None
            _send(self.proc.stdin, ('cancel',))

    def close(self, *, wait: bool, timeout_s: float = 2.0) -> None:
        """Close its input (it stops the search under way at its next progress report and
        ends); ``wait``: wait for that (killed after ``timeout_s``: a node that stops must
        not wait long for a search it no longer wants), else kill it now."""
        with contextlib.suppress(OSError, ValueError):
            assert self.proc.stdin is not None
            self.proc.stdin.close()
        if wait:
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        else:
            self.proc.kill()
        self._reader.join(timeout_s)


class SearchRunner:
    """Runs :class:`SearchJob` s one at a time, in a worker process or on a thread.

    Args:
        kinds: The job kinds (progress is kept per kind).
        in_process: Run on a thread of this process instead of a worker process.
        nice: Niceness added to the worker's (0: as the starting thread).
    """

    def __init__(self, kinds: Sequence[str], *, in_process: bool = False,
                 nice: int = 0) -> None:
        """Start the worker (a process: started now, and warmed with the searches'
        imports)."""
        self.kinds = tuple(kinds)
        self.in_process = in_process
        self._want_nice = int(nice)
        self._closed = False
        self._progress: list[float] = [0.0] * len(self.kinds)
        self._cancel = threading.Event()
        self._thread_nice: int | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._worker: _Worker | None = None
        if in_process:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix='compensation',
                                            initializer=self._thread_init)
        else:
            # what the results and errors unpickle into, imported here and now: not by the
            # reader thread beside the node's (two threads importing numpy's modules at
            # once can fail, seen in the worker)
            for name in _RESULT_MODULES:
                importlib.import_module(name)
            self._worker = _Worker(self._want_nice, self._progress)
            self._worker.submit(0, SearchJob(self.kinds[0], _warm, progress=False))

    def _thread_init(self) -> None:
        self._thread_nice = lower_priority(self._want_nice)

    @property
    def search_nice(self) -> int | None:
        """The niceness the searches run at (None: not set, or the worker not ready)."""
        if self._worker is not None:
            return self._worker.nice
        return self._thread_nice

    @property
    def worker_pid(self) -> int | None:
        """The worker process's pid (None: searches on a thread)."""
        return None if self._worker is None else self._worker.proc.pid

    def progress(self, kind: str) -> float:
        """Fraction done of the latest search of ``kind`` (0..1)."""
        return float(self._progress[self.kinds.index(kind)])

    def set_progress(self, kind: str, fraction: float) -> None:
        """Set the progress of ``kind`` (0 when a search is submitted, 1 when taken)."""
        self._progress[self.kinds.index(kind)] = float(fraction)

    def submit(self, job: SearchJob) -> Future[Any]:
        """Queue ``job``; its progress starts at 0.

        Raises:
            RuntimeError: After :meth:`shutdown`.
        """
        if self._closed:
            msg = 'the search runner is shut down'
            raise RuntimeError(msg)
        index = self.kinds.index(job.kind)
        self._progress[index] = 0.0
        if self._pool is not None:
            report = _report(self._progress, index, self._cancel) if job.progress else None
            return self._pool.submit(_call, job, report)
        assert self._worker is not None
        try:
            return self._worker.submit(index, job)
        except BrokenPipeError:   # the worker died (its search failed saying so): anew
            self._worker.close(wait=False)
            self._worker = _Worker(self._want_nice, self._progress)
            return self._worker.submit(index, job)

    def shutdown(self, *, wait: bool = True) -> None:
        """Stop the search under way at its next progress report, drop queued ones, end
        the worker; ``wait=False`` kills a worker process instead of waiting for it."""
        if self._closed:
            return
        self._closed = True
        self._cancel.set()
        if self._pool is not None:
            self._pool.shutdown(wait=wait, cancel_futures=True)
            return
        assert self._worker is not None
        self._worker.cancel()
        self._worker.close(wait=wait)

