"""What delays a bench's blocks in a one-process session (issue 41 item 4): a tick-by-tick trace.

Runs one session (bench, TE node, compensation node, recorder) in this process, as
``rv-te launch --single-process`` does (:func:`rv_te_bench.launch.session.run_single_process`),
real time at 10 kHz in blocks of 100, and records

* for every bench tick that published: when, how late its first block left after the end of
  its samples (the bench's own lag measure), how many blocks it caught up, how long it took;
* every callback of the other nodes that took more than 5 ms, and every compensation search
  (wall and CPU time, and the scheduling policy of the thread it ran on).

It prints the lag distribution after the warm-up, the worst ticks, and the lag inside and
outside the searches (while a search runs it holds the interpreter lock the bench needs).
``--switch-interval-s`` sets Python's switch interval the session runs with (the launcher
uses :data:`rv_te_bench.launch.pacing.PACED_SWITCH_INTERVAL_S`), so the lock's share can be
measured side by side.

    ROS_DOMAIN_ID=45 .venv/bin/python benchmarks/trace_one_process.py --duration-s 40
    ROS_DOMAIN_ID=45 .venv/bin/python benchmarks/trace_one_process.py --switch-interval-s 0.005
    ROS_DOMAIN_ID=45 .venv/bin/python benchmarks/trace_one_process.py --search-thread

Since issue 41 s.4 the searches run in a worker process of the compensation node (its
``search_process`` parameter); ``--search-thread`` runs them on a thread as before.
"""

from __future__ import annotations

import argparse
import functools
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

WARMUP_S = 2.0


def trace(duration_s: float, priority: int, switch_s: float | None,
          search_process: bool = True) -> dict[str, Any]:
    """Run the session with the trace hooks; return ticks, slow callbacks and searches."""
    from rv_te_bench.launch import pacing
    from rv_te_bench.launch.session import build_session, run_single_process
    from rv_te_bench.nodes import bench_node, compensation_node, recorder, te_node

    if switch_s is not None:
        pacing.PACED_SWITCH_INTERVAL_S = switch_s
    t0 = time.monotonic()
    ticks: list[tuple[float, float, int, float]] = []
    slow: list[tuple[str, float, float]] = []
    searches: list[tuple[str, float, float, float, int]] = []

    tick = bench_node.BenchNode._on_tick

    def on_tick(self: Any) -> None:
        t, n0 = time.monotonic(), self.blocks_published
        first_end_s = self.sim_time_s + self.block_period_s
        tick(self)
        if self.started and self.blocks_published > n0:
            ticks.append((t - t0, t - self.mono_start - first_end_s,
                          self.blocks_published - n0, time.monotonic() - t))

    bench_node.BenchNode._on_tick = on_tick   # type: ignore[method-assign]

    def timed(label: str, f: Any) -> Any:
        @functools.wraps(f)
        def w(*a: Any, **k: Any) -> Any:
            t = time.monotonic()
            try:
                return f(*a, **k)
            finally:
                if (d := time.monotonic() - t) > 0.005:
                    slow.append((label, t - t0, d))
        return w

    for cls, names in ((te_node.TeNode, ('_on_block', '_publish_diagnostics')),
                       (compensation_node.CompensationNode,
                        ('_on_samples', '_on_window', '_on_spectrum', '_collect',
                         '_publish_diagnostics')),
                       (recorder.RecorderNode, ('_on_flush_timer', '_publish_diagnostics',
                                                '_discover'))):
        for n in names:
            setattr(cls, n, timed(f'{cls.__name__}.{n}', getattr(cls, n)))
    for n in ('_make_callback', '_make_encoder_callback'):
        make = getattr(recorder.RecorderNode, n)
        setattr(recorder.RecorderNode, n, lambda self, state, m=make, n=n: timed(
            f'RecorderNode.{n}()', m(self, state)))
    submit = compensation_node.CompensationNode._submit

    def worker_cpu_s(pid: int | None) -> float:
        if pid is None:   # (searches on a thread: not separable from the process's CPU)
            return float('nan')
        try:
            f = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
            return (int(f[11]) + int(f[12])) / os.sysconf('SC_CLK_TCK')
        except (OSError, IndexError, ValueError):
            return float('nan')

    def traced_submit(self: Any, name: str, job: Any) -> None:
        # from submission to result: a search queued behind another counts its wait too
        pid = self.searches.worker_pid
        t, c = time.monotonic(), worker_cpu_s(pid)
        submit(self, name, job)
        policy = os.sched_getscheduler(pid) if pid else -1

        def done(_: Any) -> None:
            searches.append((name, t - t0, time.monotonic() - t, worker_cpu_s(pid) - c,
                             policy))
        self.jobs[-1][1].add_done_callback(done)

    compensation_node.CompensationNode._submit = traced_submit  # type: ignore[method-assign]
    out = tempfile.mkdtemp(prefix='rv-te-trace-')
    spec = build_session([], namespace=f'trace{os.getpid()}', single_process=True, overrides=[
        'bench.te_mode=nlte', 'bench.sample_rate_hz=10000', 'bench.block_size=100',
        f'bench.duration_s={duration_s}', 'bench.time_mode=realtime',
        f'bench.realtime_priority={priority}', f'recorder.output_dir={out}',
        'recorder.bag_name=bag', f'compensation.search_process={str(search_process).lower()}'])
    code = run_single_process(spec)
    return {'code': code, 'ticks': ticks, 'slow': slow, 'searches': searches}


def report(res: dict[str, Any], args: argparse.Namespace) -> None:
    """The lag after the warm-up, the worst ticks, the lag in and out of the searches."""
    t = np.asarray(res['ticks'])
    start = t[0, 0] + WARMUP_S
    steady = t[t[:, 0] > start]
    lag_ms = steady[:, 1] * 1e3
    in_search = np.zeros(len(steady), dtype=bool)
    for _, at, wall, _, _ in res['searches']:
        in_search |= (steady[:, 0] >= at) & (steady[:, 0] <= at + wall + 0.05)
    print(f"\none process, 10 kHz, blocks of 100, {args.duration_s:g} s, realtime_priority "
          f"{args.priority}, switch interval {args.switch_interval_s or 'launcher default'} "
          f"s; exit code {res['code']}; {time.strftime('%Y-%m-%d %H:%M')}, load "
          f"{os.getloadavg()[0]:.1f}, {platform.node()}\n")
    print('| ticks after the warm-up | lag max / p99.9 / p99 / median | ticks > 1 ms late | '
          'during searches: ticks, lag max | outside: ticks, lag max |')
    print('|---|---|---|---|---|')
    out = lag_ms[~in_search]
    print(f'| {len(lag_ms)} | {lag_ms.max():.2f} / {np.percentile(lag_ms, 99.9):.2f} / '
          f'{np.percentile(lag_ms, 99):.2f} / {np.median(lag_ms):.2f} ms | '
          f'{int(np.count_nonzero(lag_ms > 1.0))} | {int(in_search.sum())}, '
          f'{lag_ms[in_search].max() if in_search.any() else float("nan"):.2f} ms | '
          f'{len(out)}, {out.max() if len(out) else float("nan"):.2f} ms |')
    print('\nworst ticks (s from start: lag, blocks caught up, tick time):')
    for i in np.argsort(-lag_ms)[:8]:
        print(f'  {steady[i, 0]:.3f} s: {lag_ms[i]:.2f} ms, {int(steady[i, 2])} blocks, '
              f'{steady[i, 3] * 1e3:.2f} ms' + (' (search running)' if in_search[i] else ''))
    where = 'a thread of the session' if args.search_thread else 'the worker process'
    print(f'\ncompensation searches, on {where} (s from start: wall from submission, CPU '
          'of the worker process, its policy):')
    for name, at, wall, cpu, pol in res['searches']:
        print(f"  {at:.2f} s {name}: {wall:.3f} s wall, {cpu:.3f} s CPU, "
              f"{'-' if pol < 0 else 'SCHED_FIFO' if pol == os.SCHED_FIFO else 'SCHED_OTHER'}")
    print('\nother nodes\' callbacks > 5 ms (in the other nodes\' thread), by kind: n, max:')
    kinds: dict[str, list[float]] = {}
    for label, _, d in res['slow']:
        kinds.setdefault(label, []).append(d * 1e3)
    for label, v in sorted(kinds.items()):
        print(f'  {label}: {len(v)}, {max(v):.1f} ms')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--duration-s', type=float, default=40.0)
    ap.add_argument('--priority', type=int, default=50,
                    help="the bench's realtime_priority (0: normal scheduling)")
    ap.add_argument('--switch-interval-s', type=float, default=None,
                    help="Python's switch interval while the session runs (default: the "
                         "launcher's, PACED_SWITCH_INTERVAL_S)")
    ap.add_argument('--search-thread', action='store_true',
                    help='the compensation searches on a thread of the session '
                         '(compensation.search_process false: as before issue 41 s.4)')
    args = ap.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    report(trace(args.duration_s, args.priority, args.switch_interval_s,
                 not args.search_thread), args)
    return 0


if __name__ == '__main__':
    sys.exit(main())
