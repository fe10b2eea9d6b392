"""Real-time scheduling of the bench's pacing thread (issue #23 item 1).

What took effect is read back from ``/proc/<pid>/task/<tid>/stat`` (the kernel's view, not
the function's own report): field 19 nice, 40 rt_priority, 41 policy (1 = SCHED_FIFO).
Everything that changes a thread's scheduling runs in a child process, so the test runner's
own threads stay as they were.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rv_te_bench.nodes.scheduling import realtime_scheduling
from tests.procs import stat_fields

ROOT = Path(__file__).resolve().parents[2]
linux = pytest.mark.skipif(not sys.platform.startswith('linux'), reason='Linux scheduling')

SCHED_OTHER, SCHED_FIFO = 0, 1


def task_sched(pid: int) -> dict[int, tuple[int, int, int]]:
    """{tid: (policy, rt_priority, nice)} of every thread of ``pid``, from /proc."""
    out = {}
    for tid in os.listdir(f'/proc/{pid}/task'):
        try:
            fields = stat_fields(f'/proc/{pid}/task/{tid}/stat')   # fields 3.. (index 0)
        except OSError:   # the thread ended meanwhile
            continue
        out[int(tid)] = (int(fields[41 - 3]), int(fields[40 - 3]), int(fields[19 - 3]))
    return out


def may_set_fifo(priority: int) -> bool:
    """Whether this user may set SCHED_FIFO ``priority``: CAP_SYS_NICE in the effective set
    (bit 23 of CapEff) or an RLIMIT_RTPRIO at least that high."""
    import resource

    caps = next(int(line.split()[1], 16) for line in
                Path('/proc/self/status').read_text().splitlines()
                if line.startswith('CapEff:'))
    return bool(caps >> 23 & 1) or resource.getrlimit(resource.RLIMIT_RTPRIO)[0] >= priority


CHILD = r'''
import ctypes, json, os, sys, threading
from rv_te_bench.nodes.scheduling import realtime_scheduling
go, named = threading.Event(), threading.Event()

def as_fast_dds():   # a thread named as Fast DDS names its own (prctl PR_SET_NAME)
    ctypes.CDLL(None).prctl(15, b'dds.ev.0', 0, 0, 0)
    named.set()
    go.wait()

before = [threading.Thread(target=go.wait) for _ in range(2)]
for t in before:
    t.start()
dds = threading.Thread(target=as_fast_dds)
dds.start()
named.wait()
line = realtime_scheduling(int(sys.argv[1]), middleware_priority=int(sys.argv[2]))
after = threading.Thread(target=go.wait)
after.start()
print(json.dumps({'line': line, 'main': threading.get_native_id(),
                  'before': [t.native_id for t in before], 'after': after.native_id,
                  'dds': dds.native_id}),
      flush=True)
sys.stdin.readline()        # the test reads /proc meanwhile
go.set()
'''


def run_child(priority: int, prefix: tuple[str, ...] = (),
              middleware_priority: int = 0) -> tuple[dict, dict]:
    """CHILD in a process (optionally under ``prefix``, e.g. setpriv): its report and the
    scheduling of its threads from /proc."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([*prefix, sys.executable, '-c', CHILD, str(priority),
                          str(middleware_priority)], cwd=ROOT,
                         env=env, text=True, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    try:
        first = p.stdout.readline()
        assert first, p.stderr.read()
        report = json.loads(first)
        seen = task_sched(p.pid)
        p.stdin.write('\n')
        p.stdin.flush()
        assert p.wait(timeout=20) == 0, p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    return report, seen


def test_priority_zero_changes_nothing() -> None:
    before = (os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0))
    assert realtime_scheduling(0) == 'normal'
    assert (os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0)) == before


@pytest.mark.parametrize(('priority', 'nice', 'message'), [
    (-1, -10, 'priority must be an integer 0..99, got -1'),
    (100, -10, 'priority must be an integer 0..99, got 100'),
    (True, -10, 'priority must be an integer 0..99, got True'),
    (1.5, -10, 'priority must be an integer 0..99, got 1.5'),
    (10, -21, 'nice must be an integer -20..19, got -21'),
    (10, 20, 'nice must be an integer -20..19, got 20')])
def test_out_of_range_values_are_named(priority: object, nice: int, message: str) -> None:
    with pytest.raises(ValueError) as err:
        realtime_scheduling(priority, nice)  # type: ignore[arg-type]
    assert message in str(err.value)


@linux
def test_pacing_thread_fifo_middleware_threads_niced() -> None:
    """The calling thread gets SCHED_FIFO at the priority, the threads that existed before
    nice -10 (normal policy), a thread it starts afterwards inherits SCHED_FIFO; when the
    user may not (no CAP_SYS_NICE, rtprio limit 0), nothing changes and the line says so."""
    report, seen = run_child(7)
    main, before, after = report['main'], report['before'], report['after']
    if may_set_fifo(7):
        assert report['line'] == 'SCHED_FIFO 7, middleware threads nice -10'
        assert seen[main][:2] == (SCHED_FIFO, 7)
        assert [seen[t] for t in (*before, report['dds'])] == [(SCHED_OTHER, 0, -10)] * 3
        assert seen[after][:2] == (SCHED_FIFO, 7)
    else:
        assert report['line'].startswith('normal (SCHED_FIFO 7 not permitted')
        assert {seen[t][:2] for t in (main, *before, after)} == {(SCHED_OTHER, 0)}


@linux
def test_middleware_threads_on_fifo_below_the_pacing_thread() -> None:
    """With a middleware priority Fast DDS's threads (named dds.*) that existed before get
    SCHED_FIFO at it (below the pacing thread, not niced); other threads that existed (in
    one process: the thread of the other nodes) nice -10 as without it; a thread started
    afterwards inherits the pacing thread's."""
    report, seen = run_child(7, middleware_priority=3)
    main, before, after = report['main'], report['before'], report['after']
    if may_set_fifo(7):
        assert report['line'] == ('SCHED_FIFO 7, middleware threads SCHED_FIFO 3 (the others '
                                  'nice -10)')
        assert seen[main][:2] == (SCHED_FIFO, 7)
        assert seen[report['dds']] == (SCHED_FIFO, 3, 0)
        assert [seen[t] for t in before] == [(SCHED_OTHER, 0, -10)] * 2
        assert seen[after][:2] == (SCHED_FIFO, 7)
    else:
        assert report['line'].startswith('normal (SCHED_FIFO 7 not permitted')


@pytest.mark.parametrize(('priority', 'middleware', 'message'), [
    (7, 7, 'below the pacing thread'), (7, 9, 'got 9'), (0, 3, 'got 3'), (7, -1, 'got -1'),
    (7, True, 'got True')])
def test_a_middleware_priority_not_below_the_pacing_thread_is_named(
        priority: int, middleware: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        realtime_scheduling(priority, middleware_priority=middleware)  # type: ignore[arg-type]


@linux
@pytest.mark.skipif(os.geteuid() != 0 or shutil.which('setpriv') is None,
                    reason='needs root to start a child as an unprivileged user')
def test_without_permission_nothing_changes_and_the_line_says_why() -> None:
    """As user nobody (no capabilities, RLIMIT_RTPRIO 0): no error, normal scheduling,
    a line that names the priority and what would permit it."""
    nobody = ('setpriv', '--reuid=65534', '--regid=65534', '--clear-groups',
              '--inh-caps=-all')
    probe = subprocess.run([*nobody, sys.executable, '-c', 'import rv_te_bench'], cwd=ROOT,
                           env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                           check=False)
    if probe.returncode != 0:   # e.g. the checkout lives under a 0700 home directory
        pytest.skip('user nobody cannot run this checkout\'s interpreter: '
                    + probe.stderr.decode(errors='replace').strip()[-200:])
    report, seen = run_child(7, nobody)
    assert report['line'] == ('normal (SCHED_FIFO 7 not permitted: needs CAP_SYS_NICE or an '
                              'rtprio limit >= 7, e.g. in /etc/security/limits.conf)')
    threads = (report['main'], *report['before'], report['after'])
    assert {seen[t] for t in threads} == {(SCHED_OTHER, 0, 0)}


@linux
@pytest.mark.skipif(not may_set_fifo(20), reason='SCHED_FIFO not permitted for this user')
def test_bench_node_process_runs_its_pacing_thread_on_fifo(ros_domain_id: int) -> None:
    """A bench node with realtime_priority 20 in realtime mode: its main thread (which
    spins the executor) is SCHED_FIFO 20 and its other threads run at nice <= -10 or
    inherited SCHED_FIFO, as the kernel reports it, while it publishes."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), ROS_DOMAIN_ID=str(ros_domain_id))
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    p = subprocess.Popen(
        [sys.executable, '-m', 'rv_te_bench.nodes._entry', 'rv_te_bench.nodes.bench_node',
         '--ros-args', '-p', 'realtime_priority:=20', '-p', 'time_mode:=realtime',
         '-p', 'duration_s:=60.0', '-p', 'encoder_in:=ideal', '-p', 'encoder_out:=ideal'],
        cwd=ROOT, env=env, text=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        lines = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            line = p.stdout.readline()
            lines.append(line)
            if 'scheduling:' in line or not line:
                break
        assert any('scheduling: SCHED_FIFO 20, middleware threads SCHED_FIFO 19 (the others '
                   'nice -10)' in x for x in lines), ''.join(lines)
        time.sleep(1.0)   # the executor and its timer thread are up
        seen = task_sched(p.pid)
        names = {int(t): Path(f'/proc/{p.pid}/task/{t}/comm').read_text().strip()
                 for t in os.listdir(f'/proc/{p.pid}/task')}
        assert seen[p.pid][:2] == (SCHED_FIFO, 20)
        fast_dds = [v for t, v in seen.items() if names.get(t, '').startswith('dds.')]
        assert fast_dds, names   # (middleware_priority -1: one below the pacing thread)
        assert all(v[:2] == (SCHED_FIFO, 19) for v in fast_dds), (seen, names)
        others = [v for t, v in seen.items()
                  if t != p.pid and not names.get(t, '').startswith('dds.')]
        assert all(v[:2] == (SCHED_FIFO, 20) or (v[0] == SCHED_OTHER and v[2] <= -10)
                   for v in others), seen
    finally:
        p.terminate()
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def test_fast_mode_bench_keeps_normal_scheduling(graph) -> None:
    """In fast time mode the bench computes as fast as it can: realtime_priority is ignored
    (with a warning), and the thread that built the node stays as it was."""
    from rclpy.parameter import Parameter

    from rv_te_bench.nodes.bench_node import BenchNode

    ctx, _ex, add = graph
    before = (os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0))
    bench = add(BenchNode(context=ctx, parameter_overrides=[
        Parameter('time_mode', value='fast'), Parameter('realtime_priority', value=20),
        Parameter('duration_s', value=1.0)]))
    assert bench.scheduling == 'normal (fast time mode)'
    assert (os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0)) == before


@pytest.mark.ros
@pytest.mark.parametrize('middleware', [20, 25])
def test_a_middleware_priority_not_below_the_benches_is_refused(graph, middleware: int) -> None:
    """A middleware priority at or above the pacing thread's would let a busy middleware
    thread hold the pacing thread off the core: the bench refuses to start, naming both
    (before anything's scheduling changed)."""
    from rclpy.parameter import Parameter

    from rv_te_bench.errors import ParameterFileError
    from rv_te_bench.nodes.bench_node import BenchNode

    ctx, _ex, _add = graph
    before = (os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0))
    with pytest.raises(ParameterFileError, match=f'middleware_priority {middleware} must be '
                       'below realtime_priority 20'):
        BenchNode(context=ctx, parameter_overrides=[
            Parameter('time_mode', value='realtime'), Parameter('realtime_priority', value=20),
            Parameter('middleware_priority', value=middleware),
            Parameter('duration_s', value=1.0)])
    assert (os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0)) == before
    # refused before it made its writers: none is left behind in this process (a later
    # session in it saw such a bench/encoders writer as a foreign publisher)
    from rclpy.node import Node

    probe = _add(Node('probe', context=ctx))
    assert probe.count_publishers('/bench/encoders') == 0
    assert probe.count_publishers('/bench/info') == 0


@linux
def test_fifo_permitted_but_nice_not_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    """An rtprio limit without a nice limit (limits.conf with rtprio only): the pacing
    thread gets SCHED_FIFO, the middleware threads keep nice 0, and the line says how many
    were refused. (The kernel calls and the thread list are replaced here: the test
    runner's own threads are not to be changed.)"""
    import threading

    from rv_te_bench.nodes import scheduling

    fifo: list[tuple[int, int, int]] = []
    tried: list[int] = []

    def refuse(_which: int, tid: int, _nice: int) -> None:
        tried.append(tid)
        raise PermissionError(13, 'Permission denied')

    monkeypatch.setattr(os, 'sched_setscheduler',
                        lambda pid, policy, param: fifo.append((pid, policy,
                                                                param.sched_priority)))
    monkeypatch.setattr(os, 'setpriority', refuse)
    own = threading.get_native_id()
    monkeypatch.setattr(scheduling, '_thread_ids', lambda: [own, 101, 102, 103])
    line = realtime_scheduling(7)
    assert fifo == [(0, os.SCHED_FIFO, 7)]
    assert tried == [101, 102, 103]          # every thread but the caller's
    assert line == ('SCHED_FIFO 7, middleware threads nice 0 (nice -10 not permitted for '
                    '3 of 3)')


WORKER_CHILD = r'''
import json, os, threading
from rv_te_bench.nodes.search_process import SearchJob, SearchRunner, current_nice
out = {}
def pacing():   # a SCHED_FIFO thread that starts the searches (a one-process session)
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(20))
    for mode, in_process in (('thread', True), ('process', False)):
        runner = SearchRunner(['k'], in_process=in_process, nice=5)
        out[mode] = [runner.submit(SearchJob('k', f, a, progress=False)).result(60)
                     for f, a in ((os.sched_getscheduler, (0,)), (current_nice, ()))]
        out[mode + '_pid'] = runner.submit(SearchJob('k', os.getpid, progress=False)).result(60)
        out[mode + '_nice'] = runner.search_nice
        runner.shutdown()
    out['pacing'] = os.sched_getscheduler(0)
t = threading.Thread(target=pacing)
t.start()
t.join()
out['pid'] = os.getpid()
print(json.dumps(out))
'''


@linux
@pytest.mark.skipif(not may_set_fifo(20), reason='SCHED_FIFO not permitted for this user')
def test_search_worker_started_from_a_fifo_thread_runs_normal_and_niced() -> None:
    """The compensation node's searches, started from a SCHED_FIFO thread (a thread or a
    process started from it inherits the policy), go back to SCHED_OTHER before they raise
    their niceness (issue 41 item 4: a 0.4-0.8 s search ran on SCHED_FIFO 50 in a
    one-process session): on a thread and in the worker process (another pid)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    done = subprocess.run([sys.executable, '-c', WORKER_CHILD], cwd=ROOT, env=env, text=True,
                          capture_output=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out['pacing'] == SCHED_FIFO
    want = os.getpriority(os.PRIO_PROCESS, 0) + 5
    assert out['thread'] == [SCHED_OTHER, want] and out['thread_nice'] == want
    assert out['process'] == [SCHED_OTHER, want] and out['process_nice'] == want
    assert out['thread_pid'] == out['pid'] != out['process_pid']


SESSION_CHILD = r'''
import sys
from rv_te_bench.launch.session import build_session, run_single_process
sys.exit(run_single_process(build_session(
    [], nodes=['bench', 'te_node', 'compensation', 'recorder'], overrides=sys.argv[1:],
    single_process=True)))
'''


@linux
@pytest.mark.ros
@pytest.mark.skipif(not may_set_fifo(20), reason='SCHED_FIFO not permitted for this user')
def test_one_process_session_paces_the_bench_on_its_own_fifo_thread(
        tmp_path: Path, ros_domain_id: int) -> None:
    """A real-time session in one process (as ``rv-te launch --single-process``: bench, TE
    node, compensation, recorder; realtime_priority 20; 3 s at 10 kHz in blocks of 100):
    the bench's pacing thread is SCHED_FIFO 20, the process's main thread, which runs the
    other nodes, is on the normal policy at the middleware's nice -10 (it ran every node's
    callbacks on SCHED_FIFO, and the bench's blocks waited behind them; issue 41 item 4);
    and nothing is lost: the
    bag (rosbags) holds blocks 0..299 and the TE node's samples of each block."""
    from rosbags.highlevel import AnyReader

    from rv_te_bench.io.msgdefs import rv_te_typestore

    env = dict(os.environ, PYTHONPATH=str(ROOT), ROS_DOMAIN_ID=str(ros_domain_id),
               RV_TE_DB=str(tmp_path / 'results.sqlite'))
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    params = ['bench.realtime_priority=20', 'bench.time_mode=realtime', 'bench.duration_s=3.0',
              'bench.sample_rate_hz=10000.0', 'bench.block_size=100',
              f'recorder.output_dir={tmp_path}', 'recorder.bag_name=bag']
    p = subprocess.Popen(
        [sys.executable, '-c', SESSION_CHILD, *params],
        cwd=ROOT, env=env, text=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    lines: list[str] = []
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            line = p.stdout.readline()
            lines.append(line)
            if 'scheduling:' in line or not line:
                break
        assert any('scheduling: SCHED_FIFO 20, middleware threads SCHED_FIFO 19 (the others '
                   'nice -10)' in x for x in lines), ''.join(lines)
        time.sleep(0.5)   # the bench's executor and its timer thread are up
        seen = task_sched(p.pid)
        assert seen[p.pid] == (SCHED_OTHER, 0, -10), seen         # the other nodes' thread
        assert (SCHED_FIFO, 20) in {v[:2] for v in seen.values()}, seen   # the pacing one
        lines += p.stdout.readlines()
        assert p.wait(timeout=60) == 0, ''.join(lines)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    with AnyReader([tmp_path / 'bag'], default_typestore=rv_te_typestore()) as reader:
        seqs: dict[str, list[int]] = {}
        te_status: list[dict[str, str]] = []
        for conn, _t, raw in reader.messages(connections=[
                c for c in reader.connections
                if c.topic in {'/bench/encoders', '/te/samples', '/diagnostics'}]):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == '/diagnostics':
                te_status += [{kv.key: kv.value for kv in st.values} for st in msg.status
                              if st.name == '/te_node: te analysis']
            else:
                seqs.setdefault(conn.topic, []).append(int(msg.seq))
    assert seqs['/bench/encoders'] == list(range(300))
    assert seqs['/te/samples'] == list(range(len(seqs['/te/samples'])))
    # the TE node analysed every block before the session ended
    assert (te_status[-1]['blocks'], te_status[-1]['gaps_reported']) == ('300', '0')
