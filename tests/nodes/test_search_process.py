"""Issue 41 item 4: the compensation node's searches in a worker process of its own.

A search on a thread of the node's process held the interpreter lock the bench's pacing
thread needs in a one-process session. The worker process must give the advice the same
search gives in the caller's process, bit for bit (the inputs and the advice cross by
pickling); errors come back with their messages; a search stops on shutdown; no worker
outlives its node (killed or not); a worker that dies fails its search, and the next one
runs in a new worker. The last test runs two real compensation nodes over the middleware,
one searching in a process and one on a thread, on the same published TE: the same advice.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.core import compensation_search as cs
from rv_te_bench.nodes.search_process import (
    Cancelled,
    SearchError,
    SearchJob,
    SearchRunner,
)
from sim.presets import load_preset

ROOT = Path(__file__).resolve().parents[2]
KINDS = ('assembly-phases', 'identified-assembly-phases', 'tooth-profile')


def canonical(advice: object) -> str:
    """The whole advice as text (NaN compares equal to NaN here, unlike ==)."""
    return json.dumps(dataclasses.asdict(advice), default=repr, sort_keys=True)


def gone(pid: int, within_s: float) -> bool:
    end = time.monotonic() + within_s
    while time.monotonic() < end:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        try:   # (a zombie waits for its parent's wait)
            if Path(f'/proc/{pid}/stat').read_text().split(')')[-1].split()[0] == 'Z':
                return True
        except OSError:
            return True
        time.sleep(0.05)
    return False


def measured_te(n: int = 20_000, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """One output revolution of the Table 2 unit's NLTE with 0.3" of white noise."""
    from sim.wang2020 import Wang2kvParams, nlte_rad

    params = Wang2kvParams.from_preset(load_preset('wang2020-2kv'))
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    noise = np.random.default_rng(seed).normal(0.0, math.radians(0.3 / 3600), n)
    return phi, nlte_rad(phi, params) + noise


@pytest.fixture(scope='module')
def worker():
    runner = SearchRunner(KINDS)
    yield runner
    runner.shutdown()


@pytest.mark.timeout(180)
def test_worker_process_gives_the_advice_of_the_same_search_in_the_caller(worker) -> None:
    kv, rv = load_preset('wang2020-2kv'), load_preset('hu2020-rv')
    phi, te = measured_te()
    jobs = [SearchJob('assembly-phases', cs.preset_phases_advice, (kv,),
                      {'step_deg': 10.0, 'refine': True}),
            SearchJob('identified-assembly-phases', cs.identified_phases_advice,
                      (kv, phi, te), {'step_deg': 10.0, 'refine': True}),
            SearchJob('tooth-profile', cs.tooth_advice, (rv, math.radians(1.2 / 60)),
                      {'te_metric': 'pp'}, progress=False)]
    assert worker.submit(SearchJob('tooth-profile', os.getpid, progress=False)).result(60) \
        not in (os.getpid(), None)
    for job in jobs:
        here = job.fn(*job.args, **job.kwargs)
        there = worker.submit(job).result(120)
        assert canonical(there) == canonical(here), job.kind
        assert there.method == job.kind
    # (the identification found the Table 2 unit: the comparison is of a real result)
    ident = worker.submit(jobs[1]).result(120)
    current = np.rad2deg([m.current_value for m in ident.modifications])
    np.testing.assert_allclose(np.mod(current - [90, 180, -135, 90] + 180, 360) - 180, 0,
                               atol=1.0)
    assert worker.progress('assembly-phases') > 0.0   # reported from the worker


@pytest.mark.timeout(120)
def test_an_error_in_the_worker_comes_back_as_raised(worker) -> None:
    from rv_te_bench.core.identification import CompensationError, PoorFitError

    kv = load_preset('wang2020-2kv')
    phi = np.linspace(0.0, 2 * np.pi, 20_000, endpoint=False)
    noise = np.random.default_rng(1).normal(0.0, 1e-4, phi.size)   # no eccentricity in it
    for args, error in (((kv, phi[:10], noise[:10]), CompensationError),
                        ((kv, phi, noise), PoorFitError)):
        job = SearchJob('identified-assembly-phases', cs.identified_phases_advice, args,
                        {'step_deg': 10.0, 'refine': False})
        with pytest.raises(error) as here:
            job.fn(*job.args, **job.kwargs)
        with pytest.raises(error) as there:
            worker.submit(job).result(120)
        assert str(there.value) == str(here.value)
        assert type(there.value) is type(here.value)
    assert there.value.identification.fit == here.value.identification.fit   # (PoorFit)
    # the worker goes on after its errors
    assert worker.submit(SearchJob('tooth-profile', int, ('7',), progress=False)).result(60) == 7


@pytest.mark.timeout(120)
@pytest.mark.parametrize('in_process', [False, True], ids=['process', 'thread'])
def test_shutdown_stops_a_running_search(in_process: bool) -> None:
    runner = SearchRunner(KINDS, in_process=in_process)
    fut = runner.submit(SearchJob('assembly-phases', cs.preset_phases_advice,
                                  (load_preset('wang2020-2kv'),),
                                  {'step_deg': 2.0, 'refine': True}))   # minutes of grid
    end = time.monotonic() + 60.0
    while runner.progress('assembly-phases') <= 0.0 and time.monotonic() < end:
        time.sleep(0.05)
    assert runner.progress('assembly-phases') > 0.0
    pid = runner.worker_pid
    t0 = time.monotonic()
    runner.shutdown(wait=True)
    assert time.monotonic() - t0 < 10.0
    assert isinstance(fut.exception(10), Cancelled)
    if pid is not None:
        assert gone(pid, 5.0)
    with pytest.raises(RuntimeError, match='shut down'):
        runner.submit(SearchJob('tooth-profile', int, progress=False))


CHILD = r'''
import sys, time
from rv_te_bench.core import compensation_search as cs
from rv_te_bench.nodes.search_process import SearchJob, SearchRunner
from sim.presets import load_preset
r = SearchRunner(['assembly-phases'])
r.submit(SearchJob('assembly-phases', cs.preset_phases_advice,
                   (load_preset('wang2020-2kv'),), {'step_deg': 2.0, 'refine': True}))
while r.progress('assembly-phases') <= 0.0:
    time.sleep(0.05)
print(r.worker_pid, flush=True)
time.sleep(600)
'''


@pytest.mark.timeout(120)
@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='/proc')
def test_the_worker_ends_when_its_node_is_killed() -> None:
    """A node SIGKILLed mid-search (nothing of it runs to stop the worker) leaves no worker
    process behind: the worker sees its input closed."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    child = subprocess.Popen([sys.executable, '-c', CHILD], cwd=ROOT, env=env,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None
        pid = int(child.stdout.readline())
        assert not gone(pid, 0.3)            # searching
        child.send_signal(signal.SIGKILL)
        child.wait(10)
        assert gone(pid, 5.0), f'worker {pid} outlived its node'
    finally:
        child.kill()
        child.wait(10)


@pytest.mark.timeout(120)
def test_a_worker_that_dies_fails_its_search_and_the_next_runs_in_a_new_one() -> None:
    runner = SearchRunner(KINDS)
    try:
        fut = runner.submit(SearchJob('assembly-phases', cs.preset_phases_advice,
                                      (load_preset('wang2020-2kv'),),
                                      {'step_deg': 2.0, 'refine': True}))
        end = time.monotonic() + 60.0
        while runner.progress('assembly-phases') <= 0.0 and time.monotonic() < end:
            time.sleep(0.05)
        first = runner.worker_pid
        assert first is not None
        os.kill(first, signal.SIGKILL)
        with pytest.raises(SearchError, match='search process ended'):
            fut.result(30)
        assert runner.submit(SearchJob('tooth-profile', int, ('5',),
                                       progress=False)).result(60) == 5
        assert runner.worker_pid not in (first, None)
    finally:
        runner.shutdown()


@pytest.mark.ros
@pytest.mark.timeout(240)
def test_nodes_give_the_same_advice_with_the_search_in_a_process_and_on_a_thread(
        graph) -> None:
    """Two compensation nodes (2K-V preset; in /proc_ns the searches in a worker process,
    in /thread_ns on a thread, as before issue 41) are sent the same TE over the
    middleware: the phase optimum and the identified re-assembly phases they publish are
    the same, field by field."""
    rclpy = pytest.importorskip('rclpy')
    from rclpy.parameter import Parameter
    from rv_te_msgs.msg import CompensationAdvice, TransmissionError

    from rv_te_bench.nodes import qos
    from rv_te_bench.nodes.compensation_node import CompensationNode
    from tests.nodes.rosutil import spin_until

    ctx, ex, add = graph
    phi, te = measured_te()
    src = add(rclpy.create_node('te_source', context=ctx))
    got: dict[str, list[CompensationAdvice]] = {}
    nodes = {}
    pubs = {}
    for ns, in_worker in (('proc_ns', True), ('thread_ns', False)):
        nodes[ns] = add(CompensationNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter('preset', value='wang2020-2kv'),
            Parameter('search_process', value=in_worker)]))
        got[ns] = []
        src.create_subscription(CompensationAdvice, f'/{ns}/compensation/advice',
                                got[ns].append, qos.LATCHED_QOS)
        pubs[ns] = (src.create_publisher(TransmissionError, f'/{ns}/te/samples',
                                         qos.TE_SAMPLES_QOS),
                    src.create_publisher(TransmissionError, f'/{ns}/te/statistics',
                                         qos.LATCHED_QOS))
    assert (nodes['proc_ns'].searches.worker_pid is not None
            and nodes['thread_ns'].searches.worker_pid is None)
    assert spin_until(ex, lambda: all(s.get_subscription_count() >= 1 and
                                      w.get_subscription_count() >= 1
                                      for s, w in pubs.values()), 20.0)
    for ns, (pub_samples, pub_stats) in pubs.items():
        for k, (p, t) in enumerate(zip(np.array_split(phi, 40), np.array_split(te, 40),
                                       strict=True)):
            pub_samples.publish(TransmissionError(seq=k, te_rad=t.tolist(),
                                                  theta_out_rad=p.tolist()))
        node = nodes[ns]
        assert spin_until(ex, lambda node=node: node._n_buffered == phi.size, 30.0)
        stats = TransmissionError(window_index=0, window_complete=True)
        stats.window.pp_rad = float(np.ptp(te))
        pub_stats.publish(stats)

    def both() -> bool:
        return all({a.method for a in v} >= {'assembly-phases', 'identified-assembly-phases'}
                   for v in got.values())

    assert spin_until(ex, both, 180.0), {k: n.errors for k, n in nodes.items()}

    def fields(a: CompensationAdvice) -> str:   # (as text: NaN == NaN)
        return repr((a.method, a.preset, a.summary, a.te_metric, a.te_before_rad, a.te_after_rad,
                [(m.factor, m.symbol, m.unit, m.current_value, m.recommended_value,
                  m.sensitivity_index) for m in a.modifications]))

    for method in ('assembly-phases', 'identified-assembly-phases'):
        a, b = ([fields(x) for x in got[ns] if x.method == method]
                for ns in ('proc_ns', 'thread_ns'))
        assert a == b, method
    assert all(len(x.modifications) == 4 for x in got['proc_ns'])   # four phases each


class _Unreadable:
    """Pickles, but cannot be unpickled (unpickling calls int('x'))."""

    def __reduce__(self) -> tuple:
        return (int, ('x',))


@pytest.mark.timeout(60)
def test_a_job_the_worker_cannot_read_fails_and_the_worker_goes_on(worker) -> None:
    with pytest.raises(SearchError, match='the job cannot be read'):
        worker.submit(SearchJob('tooth-profile', int, (_Unreadable(),),
                                progress=False)).result(30)
    with pytest.raises(Exception, match=r'pickle|lambda'):   # refused before it is sent
        worker.submit(SearchJob('tooth-profile', lambda: 1, progress=False))
    assert worker.submit(SearchJob('tooth-profile', int, ('3',), progress=False)).result(30) == 3
