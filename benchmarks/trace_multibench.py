"""What holds a bench of N per-node sessions (issue 41 item 4): tick by tick, with call stacks.

Runs ``bench_multibench.py`` (N sessions, one process per node, 10 kHz in blocks of 100)
with ``_bench_trace/sitecustomize.py`` loaded into every bench process (``PYTHONPATH``),
which records each tick of the bench's block timer: when it was due, when its Python
callback began, when each block's simulation and publish returned, the thread's page faults
and context switches, and the collector's passes. With ``--stacks-s`` it records, for that
long, every time the traced bench's threads leave their core, with the call stack (``perf
record -e sched:sched_switch --call-graph dwarf -p``; CLOCK_MONOTONIC, so the times line up
with the ticks), and says what the bench's thread slept on inside its slow publishes.

    ROS_DOMAIN_ID=63 flock /work/bench.lock .venv/bin/python benchmarks/trace_multibench.py \\
        --benches 8 --duration-s 90 --stacks-s 30
    .venv/bin/python benchmarks/trace_multibench.py --analyse /tmp/rv-te-trace-XXXX

``--stacks-s`` needs perf and root (or perf_event_paranoid <= 1).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
WARMUP_S = 5.0
LATE_MS = 5.0


def run(args: argparse.Namespace) -> Path:
    """Run the benches with the hook (and perf); return the folder with the traces."""
    out = Path(tempfile.mkdtemp(prefix='rv-te-trace-'))
    env = dict(os.environ, RV_TE_TRACE_BENCH=str(out),
               PYTHONPATH=os.pathsep.join(filter(None, [str(HERE / '_bench_trace'),
                                                        os.environ.get('PYTHONPATH')])))
    cmd = [sys.executable, str(HERE / 'bench_multibench.py'), '--benches', str(args.benches),
           '--duration-s', str(args.duration_s), *args.extra]
    with open(out / 'multibench.txt', 'w') as log, open(out / 'multibench.err', 'w') as err:
        proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=err)
        perf = None
        if args.stacks_s > 0:   # the benches' pacing threads' switches, with call stacks
            names = [f'bench{k + 1}' for k in range(args.benches)] if args.bench == 'all' \
                else [args.bench]
            while proc.poll() is None and not all((out / f'pid-{n}').exists() for n in names):
                time.sleep(0.5)
            time.sleep(args.perf_at_s)
            tids = ','.join((out / f'pid-{n}').read_text().strip() for n in names
                            if (out / f'pid-{n}').exists())
            perf = subprocess.Popen(
                ['perf', 'record', '-q', '-m', '1024', '-e', 'sched:sched_switch',
                 '--call-graph', f'dwarf,{4096 if args.bench == "all" else 16384}',
                 '-k', 'CLOCK_MONOTONIC', '-t', tids, '-o', str(out / 'stacks.data'), '--',
                 'sleep', str(args.stacks_s)], stdout=subprocess.DEVNULL, stderr=err)
            perf.wait()
        proc.wait()
    print((out / 'multibench.txt').read_text())
    return out


def read_stacks(path: Path, tid: int) -> list[tuple[float, str, list[str]]]:
    """(time, the switch line, call stack frames) of every time thread ``tid`` left its core."""
    text = subprocess.run(['perf', 'script', '-i', str(path), '--tid', str(tid), '-F',
                           'tid,time,trace,ip,sym,dso'], capture_output=True, text=True,
                          check=True).stdout
    recs: list[tuple[float, str, list[str]]] = []
    for line in text.splitlines():
        if re.match(r'^\s*\d+\s+\d+\.\d+: ', line):
            recs.append((float(line.split()[1].rstrip(':')), line.strip(), []))
        elif line.strip() and recs:
            recs[-1][2].append(line.strip().split(' ', 1)[-1])
    return recs


def what_it_waited_for(frames: list[str]) -> str:
    """The wait (lock, condition) and the middleware function it was called from."""
    wait = 'other'
    for keys in (('interprocess_mutex', 'interprocess_condition'), ('pthread_cond',),
                 ('pthread_mutex', 'lll_lock', 'clocklock'), ('sendto', 'sendmsg', 'poll')):
        hit = next((f.split(' (')[0] for f in frames if any(k in f for k in keys)), None)
        if hit:
            wait = hit
            break
    where = next((f.split(' (')[0] for f in frames if 'eprosima' in f), '-')
    return f'{wait} in {where}'


def analyse(folder: Path, bench: str | None) -> None:
    """Per bench: the ticks' lateness and where it went; with stacks: what publish waited for."""
    traces = sorted(folder.glob('bench-*.npz'))
    if not traces:
        print(f'no traces in {folder}')
        return
    print(f'{len(traces)} bench traces in {folder} (after the first {WARMUP_S:g} s)\n')
    print('| bench | ticks | callback began late: max / p99.9 / p99 ms | longest tick ms '
          '(simulation, publish: longest) | publishes > 5 ms | their thread slept '
          '(voluntary switches) | page faults (major) | collector passes, longest ms |')
    print('|---|---|---|---|---|---|---|---|')
    data = {}
    for f in traces:
        d = np.load(f)
        t, b, g = d['ticks'], d['blocks'], d['gcs']
        keep = t[:, 1] > t[0, 1] + WARMUP_S
        ts, lag = t[keep], (t[keep, 1] - t[keep, 0]) * 1e3
        bs = b[b[:, 1] > t[0, 1] + WARMUP_S]
        sim, pub = (bs[:, 2] - bs[:, 1]) * 1e3, (bs[:, 3] - bs[:, 2]) * 1e3
        gs = g[g[:, 1] > t[0, 1] + WARMUP_S] if len(g) else g
        gd = (gs[:, 2] - gs[:, 1]) * 1e3 if len(gs) else np.zeros(1)
        name = f.stem.split('-')[1]
        data[name] = d
        slow_ticks = set(bs[pub > LATE_MS, 0].astype(int))
        slept = int(sum(1 for i in np.nonzero(keep)[0] if i in slow_ticks and t[i, 7] > 0))
        print(f'| {name} | {len(ts)} | {lag.max():.1f} / {np.percentile(lag, 99.9):.1f} / '
              f'{np.percentile(lag, 99):.1f} | {((ts[:, 2] - ts[:, 1]) * 1e3).max():.1f} '
              f'({sim.max():.1f}, {pub.max():.1f}) | {int((pub > LATE_MS).sum())} | '
              f'{slept} of {len(slow_ticks)} ticks | {int(ts[:, 4].sum())} '
              f'({int(ts[:, 5].sum())}) | {len(gs)}, {gd.max():.1f} |')
    first = data.get(bench or '', next(iter(data.values())))
    print('\nthreads of the bench process (10 s in): tid, name, policy (1 = SCHED_FIFO), '
          'priority, nice, CPU s')
    for line in first['threads']:
        print('  ' + str(line))
    stacks = folder / 'stacks.data'
    if not stacks.exists():
        return
    for name in sorted(data) if bench == 'all' else [bench]:
        if name in data:
            explain_stacks(name, data[name], stacks)


def explain_stacks(name: str, d: Any, stacks: Path) -> None:
    """What the bench's pacing thread slept on inside its publishes > LATE_MS."""
    recs = read_stacks(stacks, int(d['main_tid']))
    if not recs:
        return
    b = d['blocks']
    pub = (b[:, 3] - b[:, 2]) * 1e3
    lo, hi = recs[0][0], recs[-1][0]
    slow = b[(pub > LATE_MS) & (b[:, 2] > lo) & (b[:, 3] < hi)]
    kinds: dict[str, list[float]] = defaultdict(list)
    for x in slow:
        waits = [r for r in recs if x[2] <= r[0] <= x[3]]
        for r in waits:
            kinds[what_it_waited_for(r[2])].append((x[3] - x[2]) * 1e3)
        if not waits:
            kinds['(no switch recorded)'].append((x[3] - x[2]) * 1e3)
    print(f'\n{name}: publishes > {LATE_MS:g} ms in the {hi - lo:.0f} s with stacks: '
          f'{len(slow)}; where its thread slept in them (sleeps, the publishes\' longest):')
    for k, v in sorted(kinds.items(), key=lambda kv: -len(kv[1])):
        print(f'  {len(v)} x {k} (up to {max(v):.1f} ms)')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--benches', type=int, default=8)
    ap.add_argument('--duration-s', type=float, default=90.0)
    ap.add_argument('--perf-at-s', type=float, default=20.0,
                    help="start perf this long after the traced bench's first tick")
    ap.add_argument('--stacks-s', type=float, default=0.0,
                    help="record the traced bench's context switches with call stacks "
                         '(perf --call-graph dwarf) for this long, --perf-at-s after its '
                         'first tick')
    ap.add_argument('--analyse', type=Path, help='analyse an earlier run\'s folder')
    ap.add_argument('--bench', default='bench1',
                    help="the bench whose pacing thread's stacks are recorded ('all': every "
                         "bench's, with 4 KiB of stack each)")
    ap.add_argument('extra', nargs='*', help='more arguments for bench_multibench.py')
    args = ap.parse_args()
    folder = args.analyse or run(args)
    analyse(folder, args.bench)
    print(f'\ntraces in {folder}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
