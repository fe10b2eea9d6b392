"""Tick-by-tick trace of a bench node process (issue 41 item 4; benchmarks only).

Put this folder first on ``PYTHONPATH`` and set ``RV_TE_TRACE_BENCH`` to a folder: every
process that then imports :mod:`rv_te_bench.nodes.bench_node` records, for each tick of
its block timer, when the timer was due, when its Python callback began (the executor thread
holds the interpreter lock then), when each block's simulation and publish returned, the
thread's page faults and context switches across the tick, and the collector's passes; at
exit it writes ``bench-<namespace>-<pid>.npz`` there, with every thread's scheduling.
Used by ``trace_multibench.py``; nothing else imports it.
"""

from __future__ import annotations

import atexit
import gc
import importlib.abc
import importlib.machinery
import os
import resource
import sys
import threading
import time
from pathlib import Path

_DIR = os.environ.get('RV_TE_TRACE_BENCH')


def _patch(mod):
    import numpy as np

    cls = mod.BenchNode
    ticks: list[tuple] = []      # one row per tick that published
    blocks: list[tuple] = []     # one row per block: tick index, t sim start, sim done, pub done
    gcs: list[tuple] = []        # (start/stop, generation, t, thread id)
    state = {'node': None, 'tids': {}}
    gc_t = {}

    def on_gc(phase, info):
        now = time.monotonic()
        if phase == 'start':
            gc_t['t'] = now
        else:
            gcs.append((info.get('generation', -1), gc_t.get('t', now), now,
                        threading.get_native_id()))
    gc.callbacks.append(on_gc)

    tick = cls._on_tick

    def on_tick(self):
        t_in = time.monotonic()
        r0 = resource.getrusage(resource.RUSAGE_THREAD)
        n0 = self.blocks_published
        due_s = self.mono_start + self.sim_time_s + self.block_period_s   # first block's end
        if state['node'] is None:
            state['node'] = self
            state['ns'] = self.get_namespace().strip('/') or 'root'
            state['mono_start'] = self.mono_start
            Path(_DIR, f"pid-{state['ns']}").write_text(f'{os.getpid()}\n')   # (perf -p)
        state['tick'] = len(ticks)
        if len(ticks) == 1000 and 'threads' not in state:   # (10 s in: every thread there)
            state['threads'] = snapshot()
        tick(self)
        if self.started and self.blocks_published > n0 and not self.fast:
            r1 = resource.getrusage(resource.RUSAGE_THREAD)
            ticks.append((due_s, t_in, time.monotonic(), self.blocks_published - n0,
                          r1.ru_minflt - r0.ru_minflt, r1.ru_majflt - r0.ru_majflt,
                          r1.ru_nivcsw - r0.ru_nivcsw, r1.ru_nvcsw - r0.ru_nvcsw,
                          (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)))

    def traced_publish_one(self):
        t0 = time.monotonic()
        b = self.sim.next_block()
        t1 = time.monotonic()
        self._publish_block(b)
        blocks.append((state.get('tick', -1), t0, t1, time.monotonic()))

    cls._on_tick = on_tick
    cls._publish_one = traced_publish_one

    def snapshot():
        threads = []
        for tid in sorted(int(t) for t in os.listdir('/proc/self/task')):
            try:
                comm = Path(f'/proc/self/task/{tid}/comm').read_text().strip()
                pol = os.sched_getscheduler(tid)
                prio = os.sched_getparam(tid).sched_priority
                nice = os.getpriority(os.PRIO_PROCESS, tid)
                st = Path(f'/proc/self/task/{tid}/stat').read_text().rsplit(')', 1)[1].split()
                cpu = (int(st[11]) + int(st[12])) / os.sysconf('SC_CLK_TCK')
            except OSError:
                continue
            threads.append(f'{tid} {comm} policy={pol} prio={prio} nice={nice} cpu_s={cpu:.2f}')
        return threads

    def dump():
        node = state['node']
        if node is None:   # (a process that imported the module but ran no bench)
            return
        ns = state['ns']
        threads = state.get('threads') or snapshot()
        np.savez(os.path.join(_DIR, f'bench-{ns}-{os.getpid()}.npz'),
                 ticks=np.asarray(ticks, dtype=float).reshape(-1, 9),
                 blocks=np.asarray(blocks, dtype=float).reshape(-1, 4),
                 gcs=np.asarray(gcs, dtype=float).reshape(-1, 4),
                 threads=np.asarray(threads),
                 main_tid=threading.get_native_id(), pid=os.getpid(),
                 mono_start=node.mono_start, period_s=node.block_period_s)
    atexit.register(dump)


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name != 'rv_te_bench.nodes.bench_node':
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        run = loader.exec_module

        def exec_module(module):
            run(module)
            _patch(module)
        loader.exec_module = exec_module
        return spec


if _DIR:
    sys.meta_path.insert(0, _Finder())
