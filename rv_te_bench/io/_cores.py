"""Whether the offline analysis should use its helper thread: two cores, a bag worth it,
and a machine with room for a second thread.

The analysis has two paths (``report/analysis.py``): all on the caller's thread, or with
one helper thread that decompresses chunks ahead and computes window spectra. The helper
needs a second core: on one core it only adds hand-overs (and before issue 41 the reader
still started a read-ahead thread of its own there). What the process may use is its
affinity mask (``taskset``, a cpuset) capped by its cgroup's CPU quota (``cpu.max``: a
container's ``--cpus``, where the mask still shows every core of the host).

Where two cores are allowed, the bag's size decides first (:func:`analysis_uses_helper`):
the helper overlaps the decompression of later chunks and the spectra of closed windows
with the rest of the analysis, a gain that grows with the bag, while starting it and
handing each chunk and window over costs about the same for any bag; below
:data:`HELPER_MIN_BAG_BYTES` the one-thread path was as fast or faster, on two free cores
and beside a CPU-bound process alike (``benchmarks/bench_paths.py``, issue 41).

Then the machine decides (:func:`helper_has_room`, used by
:class:`rv_te_bench.io._helper.HelperThread`). The analysis starts on one thread (jobs for
the helper wait, and the caller takes back each one it reaches first, so nothing waits for
the decision); once :data:`DECIDE_AFTER_S` have passed it compares two readings of the
machine (:func:`sample_machine`, ~0.04 ms each) and starts the helper or does without it:

* **the other core was idle** (at least :data:`FREE_CORE_MIN` of a core idle over the
  interval, ``/proc/stat`` idle + iowait of the CPUs this process may use): helper;
* **the machine is overloaded** (this thread waited for a CPU at least
  :data:`OVERLOADED_WAIT_MIN` of the interval: ``run_delay`` of
  ``/proc/thread-self/schedstat``, in ns; without it, on average at least two runnable
  tasks besides this one, ``procs_running`` of ``/proc/stat``): helper. Two runnable
  threads get the analysis a larger share of cores shared by many tasks;
* **otherwise** (the other core busy, this thread not kept waiting: one CPU-bound process
  beside it): one thread. The helper's thread then only competes with this one.

Measured basis (2026-11-28 03:25-03:28 UTC, AMD EPYC 2-core VM, otherwise quiet, load
0.4 -> 5.3 with the planted processes; both paths forced, interleaved, median of 9;
10 kHz sessions of 60 s / 120 s / 600 s at blocks of 1000 and 600 s at blocks of 100),
helper wall / one-thread wall:

* both cores free: 0.75 / 1.03 / 0.78 / 0.91 (one thread left 0.9-1.0 cores idle);
* one CPU-bound process pinned to the other core: 1.05 / 1.07 / 0.98 / 1.14 (no idle
  tick over the analysis; unpinned: 1.08 / 0.98 / 0.99 / 1.13);
* two CPU-bound processes (with the analysis, three runnable on two cores): 0.87 / 0.77
  / 0.85 / 0.84; three: 0.88 / 0.78 / 0.70 / 0.80; five: 0.82 / 0.71 / 0.66 / 0.72.

The wait threshold lies between those cases: one thread beside k CPU-bound processes on
two cores waits (k - 1) / (k + 1) of the time under a fair scheduler: 0 for k = 1 (helper
0.98-1.14x one thread above), 1/3 for k = 2 (0.77-0.87x). With the rule in place
(``benchmarks/README.md``, "Which path"): beside one busy core one thread 9 of 9 times at
every size, 0.96-1.03x the forced one-thread path; both cores free the helper from 60 s,
0.66x one thread at 600 s; two or four CPU-bound processes the helper in most repeats,
0.72-0.93x one thread at 600 s.

The interval is short enough that a 60-s session (~60 ms on a free machine, ~40 of them
reading) can still gain from the helper, long enough that ``/proc/stat``'s 10-ms ticks
tell an idle core (3 ticks in 30 ms; a tickless kernel keeps idle time in us and shows it
truncated, so the difference of two readings is off by less than one tick) from a busy
one (0). The wait is counted in ns. A cgroup quota is not looked at here (a container
capped at two CPUs whose mask shows more: the idle of the host's CPUs counts).

``RV_TE_READ_AHEAD=0`` turns the helper off; ``1`` uses it from the start whenever two
cores are allowed (whatever the bag's size and the machine); unset: the rules above. Where
``/proc/stat`` cannot be read the helper starts at once (the size rule alone, as before).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ['DECIDE_AFTER_S', 'FREE_CORE_MIN', 'HELPER_MIN_BAG_BYTES', 'OVERLOADED_WAIT_MIN',
           'READ_AHEAD_ENV', 'MachineSample', 'allowed_cores', 'analysis_uses_helper',
           'helper_forced', 'helper_has_room', 'helper_threads_allowed', 'read_ahead_setting',
           'sample_machine']

READ_AHEAD_ENV = 'RV_TE_READ_AHEAD'
_CPU_MAX = Path('/sys/fs/cgroup/cpu.max')
_PROC = Path('/proc')
_now = time.monotonic   # (tests plant a clock here)
#: Bags (their storage files) smaller than this are analysed on one thread even where two
#: cores are allowed: measured, the helper thread did not pay below it (issue 41).
HELPER_MIN_BAG_BYTES = 8 * 2**20


def read_ahead_setting() -> str:
    """``'0'`` (off) or ``'1'`` (on where two cores are allowed; also when unset)."""
    return '0' if os.environ.get(READ_AHEAD_ENV, '1').strip() == '0' else '1'


def allowed_cores() -> float:
    """Cores this process may run on: its affinity mask, capped by its cgroup's quota."""
    cores = float(len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity')
                  else (os.cpu_count() or 1))
    try:
        quota, period = _CPU_MAX.read_text().split()[:2]
        if quota != 'max' and float(period) > 0:
            cores = min(cores, float(quota) / float(period))
    except (OSError, ValueError):
        pass
    return cores


def helper_threads_allowed() -> bool:
    """True when the helper thread may have a core of its own (see the module docstring)."""
    return read_ahead_setting() != '0' and allowed_cores() >= 2.0


def helper_forced() -> bool:
    """``RV_TE_READ_AHEAD=1``: the helper from the start wherever two cores are allowed."""
    return os.environ.get(READ_AHEAD_ENV, '').strip() == '1'


def analysis_uses_helper(bag_bytes: int) -> bool:
    """True when the analysis of a bag of ``bag_bytes`` (its storage files) may run its
    helper thread: two cores allowed, and the bag at least :data:`HELPER_MIN_BAG_BYTES`
    (or ``RV_TE_READ_AHEAD=1``, which forces it on wherever two cores are allowed). Unless
    forced, the machine then decides whether it starts (:func:`helper_has_room`)."""
    if not helper_threads_allowed():
        return False
    return helper_forced() or bag_bytes >= HELPER_MIN_BAG_BYTES


#: Wall time the analysis runs on one thread before it looks at the machine.
DECIDE_AFTER_S = 0.030
#: Idle cores (averaged over the interval) from which the other core counts as free.
FREE_CORE_MIN = 0.5
#: Share of the interval this thread waited for a CPU from which the machine counts as
#: overloaded (one thread beside one CPU-bound process waits ~0; three runnable CPU-bound
#: threads on two cores wait ~1/3 each).
OVERLOADED_WAIT_MIN = 0.2


def _clock_ticks() -> int:
    try:
        return int(os.sysconf('SC_CLK_TCK')) or 100
    except (AttributeError, ValueError, OSError):
        return 100


#: ``/proc/stat``'s time unit (USER_HZ, 100 on Linux).
CLOCK_TICKS_HZ = _clock_ticks()


@dataclass(frozen=True)
class MachineSample:
    """One reading of the machine, for :func:`helper_has_room`."""

    t_s: float                   # time.monotonic() of the reading [s]
    idle_ticks: int              # idle + iowait of the CPUs this process may use (USER_HZ)
    run_delay_ns: int | None     # this thread's time waiting on a run queue (schedstat)
    procs_running: int | None    # runnable tasks on the machine now (/proc/stat)


def sample_machine(proc: Path | None = None) -> MachineSample | None:
    """Read ``/proc/stat`` and this thread's ``schedstat`` (``proc``: another /proc, for
    tests). None when ``/proc/stat`` cannot be read or parsed; never raises."""
    proc = _PROC if proc is None else proc
    try:
        text = (proc / 'stat').read_bytes()
        cpus = os.sched_getaffinity(0) if hasattr(os, 'sched_getaffinity') else None
        idle, seen, running = 0, 0, None
        for line in text.splitlines():
            if line.startswith(b'cpu') and line[3:4].isdigit():
                fields = line.split()
                if cpus is None or int(fields[0][3:]) in cpus:
                    idle += int(fields[4]) + int(fields[5])
                    seen += 1
            elif line.startswith(b'procs_running '):
                running = int(line.split()[1])
        if not seen:
            return None
    except (OSError, ValueError, IndexError):
        return None
    try:
        delay: int | None = int((proc / 'thread-self' / 'schedstat').read_bytes().split()[1])
    except (OSError, ValueError, IndexError):
        delay = None
    # (the time after the wait read: the waits of two readings are that far apart)
    return MachineSample(t_s=_now(), idle_ticks=idle, run_delay_ns=delay,
                         procs_running=running)


def helper_has_room(before: MachineSample, after: MachineSample) -> tuple[bool, str]:
    """Whether to start the helper thread, from two readings of the analysis's thread's
    machine (the rule and its measured basis: the module docstring), and why."""
    dt = after.t_s - before.t_s
    if dt <= 0.0:
        return False, 'no interval between the readings'
    idle_cores = (after.idle_ticks - before.idle_ticks) / (CLOCK_TICKS_HZ * dt)
    if idle_cores >= FREE_CORE_MIN:
        return True, f'{idle_cores:.2f} cores idle'
    if before.run_delay_ns is not None and after.run_delay_ns is not None:
        waited = (after.run_delay_ns - before.run_delay_ns) * 1e-9 / dt
        why = f'{idle_cores:.2f} cores idle, waited {waited:.0%} of the time for a CPU'
        return waited >= OVERLOADED_WAIT_MIN, why
    if before.procs_running is not None and after.procs_running is not None:
        others = (before.procs_running + after.procs_running) / 2.0 - 1.0
        why = f'{idle_cores:.2f} cores idle, {others:g} other runnable tasks'
        return others >= 2.0, why
    return False, f'{idle_cores:.2f} cores idle'
