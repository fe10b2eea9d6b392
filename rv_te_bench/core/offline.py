"""The offline TE analysis: a recording through the streaming analyzer, spectra on a helper.

:func:`analyze_blocks` runs the blocks (or batches) of a whole recording through one
:class:`~rv_te_bench.core.stream.StreamingTeAnalyzer`, with the same windows, gaps and
counters as a live TE node, can hand each window to a callback instead of keeping them all
(memory bounded by one window however long the recording), and can compute the window
spectra on a second thread while it reads on (``spectra_thread``: the same results; one
more window's arrays are then held besides the open one). That thread may be one the
caller shares with other work, e.g. the bag reader's read-ahead (``analyze_bag`` does).
"""

from __future__ import annotations

import contextlib
from collections import deque
from concurrent.futures import Executor, Future
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.head_combine import WindowBreak
from rv_te_bench.core.spectrum import OrderSpectrum, SpectrumWorkspace
from rv_te_bench.core.stream import StreamingTeAnalyzer
from rv_te_bench.core.stream_records import (
    EncoderBatch,
    EncoderBlockData,
    GapEvent,
    OfflineResult,
    TeAnalysisConfig,
    WindowResult,
)
from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable

    from rv_te_bench.core.envelope import MinMaxEnvelope
    from rv_te_bench.core.stream import WindowBuffer

__all__ = ['SPECTRA_AHEAD', 'analyze_blocks']


def analyze_blocks(blocks: Iterable[EncoderBlockData | EncoderBatch | WindowBreak],
                   config: TeAnalysisConfig,
                   *, on_window: Callable[[WindowResult], None] | None = None,
                   spectra_thread: bool | Executor = False,
                   envelope: MinMaxEnvelope | None = None) -> OfflineResult:
    """Run a whole recording through a :class:`StreamingTeAnalyzer` (offline analysis).

    Args:
        blocks: The blocks (or batches of consecutive blocks) in recording order, and
            :class:`~rv_te_bench.core.head_combine.WindowBreak` markers where the open window
            closes (other read heads form the angle from there).
        config: Analysis settings.
        on_window: Called with each window as it closes; the windows are then not kept
            (memory stays bounded by one window however long the recording).
        spectra_thread: Compute the window spectra on a second thread while the next
            blocks are analysed (the resampler and the FFT run without the GIL), and here
            while that thread is busy. The windows, their order, the spectra and the
            counters are the same as without; the thread holds one window's phi and TE
            arrays besides the open window's, and at most :data:`SPECTRA_AHEAD` closed
            windows wait behind it. An executor instead of True: its (one) worker thread
            is that thread, shared with the caller's other jobs (such as reading the bag
            ahead); it is not shut down here. Two cores run the caller and one helper
            thread without preempting either (a third runnable thread costs the caller
            CPU time: issue 23, 6-14 % less wall time with one shared helper).
        envelope: Filled with the min/max envelope of every clean sample's TE
            (:meth:`StreamingTeAnalyzer.set_envelope`), for plots of long records.

    Returns:
        All windows (the last, partial one from the final flush; none with ``on_window``),
        cumulative statistics, counters and gap events.
    """
    analyzer = StreamingTeAnalyzer(config)
    analyzer.set_envelope(envelope)
    windows: list[WindowResult] = []
    gaps: list[GapEvent] = []
    keep = windows.extend if on_window is None else (lambda ws: [on_window(w) for w in ws])
    threaded = spectra_thread is not False and config.compute_spectrum
    shared = spectra_thread if isinstance(spectra_thread, Executor) else None
    with _SpectraThread(analyzer, keep, shared) if threaded \
            else contextlib.nullcontext() as spectra:
        closed = keep if spectra is None else spectra.closed
        for item in blocks:
            if isinstance(item, WindowBreak):   # other read heads form the angle from here
                analyzer.split_window()
                continue
            update = analyzer.push_batch(item) if isinstance(item, EncoderBatch) \
                else analyzer.push(item)
            closed(update.windows)
            gaps.extend(update.gaps)
        closed(analyzer.flush())
        if spectra is not None:
            spectra.drain()
    return OfflineResult(windows=tuple(windows), cumulative=analyzer.cumulative,
                         counters=analyzer.counters, gaps=tuple(gaps))


#: Closed windows of an offline analysis that may wait (in order) behind the one whose
#: spectrum is on the spectra thread.
SPECTRA_AHEAD = 4


class _SpectraThread:
    """The window spectra of :func:`analyze_blocks`, shared by a worker thread and the caller.

    A complete window's spectrum goes to the worker thread when the thread is free, with
    the window's phi and TE arrays (the window buffer gets the arrays of the thread's
    previous window, which is done: nothing is copied); while the thread is busy, the
    calling thread computes the spectrum itself (the same call, the same values), so the
    cores share the spectra as they are free (3-4 % less wall time than every spectrum on
    the thread, measured side by side). :meth:`closed` hands the windows on in closing
    order; at most SPECTRA_AHEAD wait behind the one on the thread. A spectrum that fails
    counts in ``spectrum_failures`` and leaves the window without one, as the analyzer
    does itself. The worker is a thread of its own, or the one of an executor the caller
    shares (left running on exit: only this analysis's pending spectra are cancelled, and
    the one running is waited for).
    """

    def __init__(self, analyzer: StreamingTeAnalyzer,
                 keep: Callable[[list[WindowResult]], object],
                 shared: Executor | None = None) -> None:
        from concurrent.futures import ThreadPoolExecutor

        self._analyzer = analyzer
        self._keep = keep
        self._own = shared is None
        self._pool: Executor = shared if shared is not None else ThreadPoolExecutor(
            max_workers=1, thread_name_prefix='te-spectra')
        self._work = SpectrumWorkspace()            # used by the worker thread only
        self._jobs: dict[int, Future[OrderSpectrum]] = {}   # window index -> its spectrum
        self._on_thread: Future[OrderSpectrum] | None = None   # the thread's latest job
        self._on_thread_index = -1                              # ... its window
        self._thread_arrays: tuple[np.ndarray, np.ndarray] | None = None   # ... its arrays
        # the thread's jobs' arguments (phi, te, duration), to compute one here instead
        self._args: dict[int, tuple[np.ndarray, np.ndarray, float]] = {}
        self._queue: deque[WindowResult] = deque()
        analyzer.set_spectrum_hook(self._submit)

    def __enter__(self) -> _SpectraThread:
        return self

    def __exit__(self, *exc: object) -> None:
        self._analyzer.set_spectrum_hook(None)
        if self._own:
            self._pool.shutdown(wait=True, cancel_futures=True)
            return
        from concurrent.futures import wait

        wait([job for job in self._jobs.values() if not job.cancel()])

    def _submit(self, index: int, buf: WindowBuffer) -> None:
        """The window's spectrum: to the thread if it is free, else computed here."""
        ana = self._analyzer
        n = buf.n
        duration_s = buf.t_last - buf.t_first
        if self._thread_busy():
            job: Future[OrderSpectrum] = Future()
            try:   # with the caller's own workspace
                job.set_result(ana.window_spectrum(
                    buf.phi[:n], buf.te[:n], duration_s, ana.spectrum_workspace))
            except TeInputError as exc:
                job.set_exception(exc)
            self._jobs[index] = job
            return
        # the thread is free: its previous window's arrays are free too
        phi, te = buf.phi, buf.te
        spare = self._thread_arrays
        buf.phi, buf.te = (spare if spare is not None and spare[0].size == phi.size
                           else (np.empty_like(phi), np.empty_like(te)))
        self._thread_arrays = (phi, te)
        self._args[index] = (phi[:n], te[:n], duration_s)
        self._on_thread = self._jobs[index] = self._pool.submit(
            ana.window_spectrum, phi[:n], te[:n], duration_s, self._work)
        self._on_thread_index = index

    def _thread_busy(self) -> bool:
        """Whether the thread's latest job still needs its arrays: not done, or cancelled
        (an executor that declines a job, or one taken back) and not yet computed here."""
        job = self._on_thread
        return job is not None and (not job.done() or (
            job.cancelled() and self._on_thread_index in self._args))

    def closed(self, windows: Iterable[WindowResult]) -> None:
        """Queue closed windows; hand on those at the head whose spectrum is done."""
        self._queue.extend(windows)
        ready = []
        while self._queue:
            job = self._jobs.get(self._queue[0].index)
            if job is not None and not job.done() and len(self._queue) <= SPECTRA_AHEAD:
                break
            ready.append(self._finish(self._queue.popleft()))
        if ready:
            self._keep(ready)

    def drain(self) -> None:
        """Wait for every pending spectrum and hand on the rest of the windows."""
        if self._queue:
            self._keep([self._finish(w) for w in self._queue])
            self._queue.clear()

    def _steal(self, index: int) -> OrderSpectrum:
        """The spectrum of a job taken back from the thread, computed here."""
        phi, te, duration_s = self._args[index]
        ana = self._analyzer
        return ana.window_spectrum(phi, te, duration_s, ana.spectrum_workspace)

    def _finish(self, window: WindowResult) -> WindowResult:
        job = self._jobs.pop(window.index, None)
        if job is None:
            return window
        try:
            # one the thread has not started (busy reading ahead, or not given a core by a
            # loaded machine) is computed here rather than waited for: the same call
            spectrum = self._steal(window.index) if job.cancel() else job.result()
        except TeInputError:
            self._analyzer.count_spectrum_failure()
            return window
        finally:
            self._args.pop(window.index, None)
        return replace(window, spectrum=spectrum)
