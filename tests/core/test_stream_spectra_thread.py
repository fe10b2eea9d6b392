"""analyze_blocks(spectra_thread=True): the window spectra on a second thread change nothing.

The reference is the same call with the spectra computed in line (spectra_thread=False),
itself checked block by block in test_stream_batch.py. Compared: every window (stats,
seqs, close reason) with its whole spectrum bit for bit, the gaps, the counters (including
``spectrum_failures``) and the order in which ``on_window`` sees the windows. Then what the
thread must not do: run more than SPECTRA_AHEAD windows ahead, outlive an error of the
blocks' source, or run at all under RV_TE_READ_AHEAD=0 in ``analyze_bag``.
"""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rv_te_bench.core import offline, stream
from rv_te_bench.core.offline import SPECTRA_AHEAD, analyze_blocks
from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData, TeAnalysisConfig
from tests.core.test_stream_batch import (
    FS_HZ,
    ORDERS,
    RATIO,
    _group,
    _stream,
    draw_faulty_stream,
)


def _full_key(w: stream.WindowResult) -> tuple:
    """Everything of a window, the spectrum's arrays as bytes (bit-for-bit comparison)."""
    spec = w.spectrum
    spec_key = None if spec is None else (
        spec.revolutions, spec.samples_per_rev, spec.phi0_rad, spec.output_hz, spec.crank_hz,
        spec.mean_rad, spec.amplitude_rad.tobytes(), spec.bins.tobytes(),
        tuple((ln.label, ln.amplitude_rad, ln.phase_rad) for ln in spec.lines))
    return (w.index, w.start_stamp_s, w.end_stamp_s, w.complete, w.stats, w.first_seq,
            w.last_seq, w.close_reason, spec_key)


def _both(items: list, config: TeAnalysisConfig) -> tuple[tuple, tuple]:
    """(in line, on a thread): the thread of the analysis's own and a shared executor's
    (analyze_bag's helper, which reads the bag too) must give the same."""
    results = []
    with ThreadPoolExecutor(max_workers=1) as helper:
        for threaded in (False, True, helper):
            seen: list[stream.WindowResult] = []
            res = analyze_blocks(items, config, on_window=seen.append, spectra_thread=threaded)
            results.append(([_full_key(w) for w in seen], res.gaps, res.counters,
                            res.cumulative))
    assert results[2] == results[1]
    return results[0], results[1]


@settings(max_examples=40, deadline=None)
@given(data=st.data(), direction=st.sampled_from([1.0, -1.0]),
       max_window_samples=st.sampled_from([2_000_000, 1500]))
def test_spectra_thread_gives_the_same_analysis(data: st.DataObject, direction: float,
                                                max_window_samples: int) -> None:
    sizes, faults, cuts = draw_faulty_stream(data)
    config = TeAnalysisConfig(orders=ORDERS, max_window_samples=max_window_samples)
    inline, threaded = _both(_group(_stream(sizes, faults, direction), faults, cuts), config)
    assert threaded == inline


def test_spectra_thread_with_many_windows_and_kept_windows() -> None:
    """40 whole-revolution windows (the spare arrays cycle many times), kept in the result."""
    blocks = _stream([500] * 200, ['ok'] * 200, 1.0)
    config = TeAnalysisConfig(orders=ORDERS)
    items = [EncoderBatch.from_blocks(blocks[k:k + 7]) for k in range(0, 200, 7)]
    inline = analyze_blocks(items, config)
    threaded = analyze_blocks(items, config, spectra_thread=True)
    assert len(inline.windows) >= 40
    assert sum(w.spectrum is not None for w in inline.windows) >= 40
    assert [_full_key(w) for w in threaded.windows] == [_full_key(w) for w in inline.windows]
    assert threaded.counters == inline.counters


def test_a_failed_spectrum_is_counted_as_in_line() -> None:
    """A window that goes back a little (not a gap) completes, but has no spectrum."""
    n = 6000
    t = np.arange(n) / FS_HZ
    theta_in = 2 * math.pi * 2.0 * RATIO * t
    theta_in[1500:1510] = theta_in[1500] - 1e-3 * np.arange(10)     # a short reversal
    theta_out = theta_in / RATIO + 1e-4 * np.cos(25 * theta_in / RATIO)
    blocks = [EncoderBlockData(seq=k, stamp_s=float(t[a]), sample_rate_hz=FS_HZ,
                               time_offset_s=t[a:a + 500] - t[a],
                               theta_in_rad=theta_in[a:a + 500],
                               theta_out_rad=theta_out[a:a + 500])
              for k, a in enumerate(range(0, n, 500))]
    config = TeAnalysisConfig(orders=ORDERS)
    inline, threaded = _both([EncoderBatch.from_blocks(blocks)], config)
    assert threaded == inline
    assert inline[2]['spectrum_failures'] == 1
    assert inline[2]['complete_windows'] >= 2


def _with_a_slow_thread(monkeypatch: pytest.MonkeyPatch,
                        n_blocks: int) -> tuple[list[int], list[str]]:
    """Spectra take 30 ms on the spectra thread (none on the caller's). Per window handed
    on: how many windows had been closed beyond it then; and where each spectrum ran."""
    real = stream.order_spectrum
    closed: list[int] = []
    where: list[str] = []
    real_submit = offline._SpectraThread._submit

    def slow_on_the_thread(*args: object, **kwargs: object) -> object:
        name = threading.current_thread().name
        where.append('thread' if name.startswith('te-spectra') else 'caller')
        if where[-1] == 'thread':
            time.sleep(0.03)
        return real(*args, **kwargs)

    def counting_submit(self: offline._SpectraThread, index: int, buf: object) -> None:
        closed.append(index)
        real_submit(self, index, buf)
        # a job handed to the thread has started before the caller goes on (else, on a
        # loaded machine, the caller may take it back: test_a_job_the_helper_has_not_...)
        job = self._jobs[index]
        while job is self._on_thread and not (job.running() or job.done()):
            time.sleep(0.0005)

    monkeypatch.setattr(stream, 'order_spectrum', slow_on_the_thread)
    monkeypatch.setattr(offline._SpectraThread, '_submit', counting_submit)
    blocks = _stream([250] * n_blocks, ['ok'] * n_blocks, 1.0)   # a window per 4 blocks
    ahead: list[int] = []
    analyze_blocks(blocks, TeAnalysisConfig(orders=ORDERS),
                   on_window=lambda w: ahead.append(len(closed) - (w.index + 1)),
                   spectra_thread=True)
    return ahead, where


def test_windows_wait_at_most_spectra_ahead_behind_the_thread(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The caller goes on (computing spectra itself) while the thread is busy, but hands
    the windows on in order and waits once SPECTRA_AHEAD are queued behind the thread's."""
    ahead, where = _with_a_slow_thread(monkeypatch, 100)
    assert len(ahead) >= 20
    assert max(ahead) <= SPECTRA_AHEAD
    assert max(ahead) >= 2   # windows did queue behind the thread (the bound is exercised)
    # both shared the spectra, one per complete window
    assert where.count('thread') >= 2 and where.count('caller') >= 2
    assert len(where) == len(ahead) - 1   # the last, partial window has none


def test_an_error_of_the_source_stops_the_spectra_thread() -> None:
    blocks = _stream([500] * 20, ['ok'] * 20, 1.0)

    def source() -> object:
        yield from blocks
        msg = 'the bag went away'
        raise OSError(msg)

    with pytest.raises(OSError, match='went away'):
        analyze_blocks(source(), TeAnalysisConfig(orders=ORDERS), spectra_thread=True)
    assert not [t for t in threading.enumerate() if t.name.startswith('te-spectra')]


def test_an_error_of_the_source_leaves_a_shared_executor_running_and_idle(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """With the caller's executor, an error of the source cancels this analysis's queued
    spectra and waits for the running one; the executor itself is left running."""
    blocks = _stream([250] * 60, ['ok'] * 60, 1.0)   # a window per 4 blocks
    real = stream.order_spectrum
    ran: list[str] = []

    def slow(*args: object, **kwargs: object) -> object:
        ran.append(threading.current_thread().name)
        if ran[-1].startswith('shared'):
            time.sleep(0.02)
        return real(*args, **kwargs)

    monkeypatch.setattr(stream, 'order_spectrum', slow)

    def source() -> object:
        yield from blocks
        msg = 'the bag went away'
        raise OSError(msg)

    with ThreadPoolExecutor(max_workers=1, thread_name_prefix='shared') as helper:
        blocker = helper.submit(time.sleep, 0.3)   # the reader's job, ahead in the queue
        with pytest.raises(OSError, match='went away'):
            analyze_blocks(source(), TeAnalysisConfig(orders=ORDERS), spectra_thread=helper)
        at_return = len(ran)
        assert helper.submit(lambda: 42).result() == 42
        assert len(ran) == at_return      # no spectrum of the ended analysis ran later
        assert blocker.done()
    assert 'MainThread' in ran            # the caller computed spectra while it was busy


@pytest.mark.parametrize(('env', 'cores', 'big', 'spectra', 'reads'), [
    (None, {0, 1}, True, 'te-helper', 'te-helper'),
    (None, {0, 1}, False, 'MainThread', 'MainThread'),     # too small for the helper
    ('0', {0, 1}, True, 'MainThread', 'MainThread'),
    (None, {1}, True, 'MainThread', 'MainThread'),
    ('1', {0, 1}, False, 'te-helper', 'te-helper'),        # forced on, whatever the size
    ('1', {1}, True, 'MainThread', 'MainThread')])
def test_analyze_bag_helper_thread_follows_the_read_ahead_switch(
        tmp_path: object, monkeypatch: pytest.MonkeyPatch, env: str | None, cores: set[int],
        big: bool, spectra: str, reads: str) -> None:
    """analyze_bag reads ahead and computes spectra on one helper thread, shared (no third
    thread on two cores), when the bag is big enough for it to pay (HELPER_MIN_BAG_BYTES;
    here the limit is set just below or above the test bag's size) and the machine has
    room for it (planted here), unless
    RV_TE_READ_AHEAD=0 (a fleet worker per core: nothing off the main thread) or the
    process may run on one core only (taskset, a cpuset, a cgroup quota): then all on the
    main thread, the reader's read-ahead too (issue 41; it ran on a thread of the reader's
    own before). RV_TE_READ_AHEAD=1 forces the helper on small bags too (two cores)."""
    from rv_te_bench.io import _mcap_scan
    from rv_te_bench.io._helper import HelperThread
    from rv_te_bench.io.bag_reader import READ_AHEAD_ENV
    from rv_te_bench.report.analysis import analyze_bag
    from tests.io.test_helper_thread import _IDLE_CORE, plant_machine
    from tests.unit_bags import write_unit_bag

    if env is None:
        monkeypatch.delenv(READ_AHEAD_ENV, raising=False)
    else:
        monkeypatch.setenv(READ_AHEAD_ENV, env)
    monkeypatch.setattr('os.sched_getaffinity', lambda _pid: cores)
    monkeypatch.setattr('rv_te_bench.io._cores.allowed_cores', lambda: float(len(cores)))
    spectra_on: set[str] = set()
    reads_on: set[str] = set()

    def spy(real: object, names: set[str]) -> object:
        def call(*args: object, **kwargs: object) -> object:
            names.add(threading.current_thread().name.split('_')[0])
            return real(*args, **kwargs)
        return call

    monkeypatch.setattr(stream, 'order_spectrum', spy(stream.order_spectrum, spectra_on))
    monkeypatch.setattr(_mcap_scan, '_chunk_records', spy(_mcap_scan._chunk_records, reads_on))
    monkeypatch.setattr(_mcap_scan, 'PREFETCH_CHUNKS', 1)   # the small bag: read on the thread
    # what is handed to a pool (which thread then runs it is timing: the caller takes back
    # a job the helper has not started, see test_a_job_the_thread_has_not_started_...)
    submitted: set[tuple[str, str]] = set()
    real_submit = HelperThread.submit

    def submit(pool: HelperThread, fn: object, /, *args: object, **kwargs: object):
        name = getattr(fn, '__name__', '')
        submitted.add(('te-helper', 'read' if name == 'call' and args
                       and isinstance(args[0], memoryview) else name))
        return real_submit(pool, fn, *args, **kwargs)
    monkeypatch.setattr(HelperThread, 'submit', submit)
    # unset switch: the machine decides whether the helper starts; here it has room at the
    # first job handed over (the decision itself: tests/io/test_helper_thread.py)
    plant_machine(monkeypatch, _IDLE_CORE)
    monkeypatch.setattr('rv_te_bench.io._cores.DECIDE_AFTER_S', 0.0)
    # 4 output revolutions of an independently generated unit (2 kHz, 1 crank-order line)
    rate = 2000.0
    t = np.arange(int(4 * 15.8 * rate)) / rate
    theta_in = 2 * math.pi * (300 / 60) * t
    theta_out = theta_in / 79.0 + 1e-4 * np.cos(25 * theta_in / 79.0)
    bag = write_unit_bag(tmp_path / 'bag', theta_in, theta_out, rate_hz=rate, block=1000)
    size = sum(f.stat().st_size for f in bag.glob('*.mcap'))   # the storage files
    monkeypatch.setattr('rv_te_bench.io._cores.HELPER_MIN_BAG_BYTES',
                        size if big else size + 1)
    result = analyze_bag(bag, with_advice=False)
    assert result.spectrum is not None
    if spectra == 'te-helper':
        # chunks and the first spectrum go to the one helper; the caller computes a
        # spectrum while it is busy and takes back what it has not started
        assert submitted == {('te-helper', 'read'), ('te-helper', 'window_spectrum')}
        assert spectra_on and spectra_on <= {'te-helper', 'MainThread'}
        assert reads_on and reads_on <= {'te-helper', 'MainThread'}   # no reader's thread
    else:
        assert submitted == set()         # no pool at all
        assert spectra_on == {spectra}
        assert reads_on == {reads}        # no read-ahead thread of the reader's own either
    assert not [t.name for t in threading.enumerate() if t.name.startswith('te-helper')]


def test_a_job_the_helper_has_not_started_is_done_by_the_caller(tmp_path: object) -> None:
    """A helper that gets no core (a loaded machine; here a job that blocks it) costs the
    analysis nothing but its hand-overs: the caller takes back each chunk and spectrum the
    helper has not started and does it itself (the same call, the same values) instead of
    waiting (issue 41: the helper path must never be slower than one thread). Fails on
    code that waits: the analysis would end only after the gate opens."""
    from rv_te_bench.io.bag_reader import read_encoder_batches
    from tests.unit_bags import write_unit_bag

    rate = 2000.0
    t = np.arange(int(4 * 15.8 * rate)) / rate
    theta_in = 2 * math.pi * (300 / 60) * t
    theta_out = theta_in / 79.0 + 1e-4 * np.cos(25 * theta_in / 79.0)
    bag = write_unit_bag(tmp_path / 'bag', theta_in, theta_out, rate_hz=rate, block=500)
    config = TeAnalysisConfig(orders=ORDERS)
    inline = analyze_blocks(read_encoder_batches(bag, read_ahead=False), config)
    assert sum(w.spectrum is not None for w in inline.windows) >= 3

    gate = threading.Event()
    opened = threading.Timer(20.0, gate.set)     # (code that waits ends after 20 s)
    helper = ThreadPoolExecutor(max_workers=1, thread_name_prefix='te-helper')
    helper.submit(gate.wait)
    opened.start()
    try:
        taken = analyze_blocks(read_encoder_batches(bag, executor=helper, read_ahead=True),
                               config, spectra_thread=helper)
        ended_before_the_gate = not gate.is_set()
    finally:
        gate.set()
        opened.cancel()
        helper.shutdown(wait=True)
    assert ended_before_the_gate
    assert [_full_key(w) for w in taken.windows] == [_full_key(w) for w in inline.windows]
    assert taken.counters == inline.counters
    assert taken.cumulative == inline.cumulative


def test_jobs_an_executor_declines_are_done_by_the_caller(tmp_path: object) -> None:
    """An executor that hands every job back cancelled (the analysis's helper once it has
    decided against starting, issue 41): each spectrum is computed by the caller, none is
    lost, and a window's arrays are not reused for the next window before its spectrum is
    computed. Fails on the code before, which took a cancelled job's arrays for free:
    windows came out with a wrong spectrum or none."""
    from concurrent.futures import Executor, Future

    from rv_te_bench.io.bag_reader import read_encoder_batches
    from tests.unit_bags import write_unit_bag

    class Declining(Executor):
        def submit(self, fn, /, *args, **kwargs):   # type: ignore[no-untyped-def]
            job: Future[object] = Future()
            job.cancel()
            return job

    rate = 2000.0
    t = np.arange(int(5 * 15.8 * rate)) / rate
    theta_in = 2 * math.pi * (300 / 60) * t
    theta_out = theta_in / 79.0 + 1e-4 * np.cos(25 * theta_in / 79.0)
    bag = write_unit_bag(tmp_path / 'bag', theta_in, theta_out, rate_hz=rate, block=500)
    config = TeAnalysisConfig(orders=ORDERS)
    inline = analyze_blocks(read_encoder_batches(bag, read_ahead=False), config)
    assert sum(w.spectrum is not None for w in inline.windows) >= 4
    declined = analyze_blocks(read_encoder_batches(bag, executor=Declining(), read_ahead=True),
                              config, spectra_thread=Declining())
    assert [_full_key(w) for w in declined.windows] == [_full_key(w) for w in inline.windows]
    assert declined.counters == inline.counters
