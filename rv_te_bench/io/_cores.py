"""Whether the offline analysis should use its helper thread: two cores, and a bag worth it.

The analysis has two paths (``report/analysis.py``): all on the caller's thread, or with
one helper thread that decompresses chunks ahead and computes window spectra. The helper
needs a second core: on one core it only adds hand-overs (and before issue 41 the reader
still started a read-ahead thread of its own there). What the process may use is its
affinity mask (``taskset``, a cpuset) capped by its cgroup's CPU quota (``cpu.max``: a
container's ``--cpus``, where the mask still shows every core of the host).

The load of the machine is not looked at: beside a CPU-bound process on the other core,
and on a machine with many runnable tasks, the helper path is still the faster one (the
scheduler shares the cores among runnable threads, so a second thread gets the analysis a
larger share; issue 41, ``benchmarks/README.md``: 0.83x vs 1.37x the rosbags read at
blocks of 10000 with the other core busy). A fleet worker per core is told to do without
(``RV_TE_READ_AHEAD=0``): there the other cores run other analyses.

Where two cores are allowed, the bag's size decides (:func:`analysis_uses_helper`): the
helper overlaps the decompression of later chunks and the spectra of closed windows with
the rest of the analysis, a gain that grows with the bag, while starting it and handing
each chunk and window over costs about the same for any bag; below
:data:`HELPER_MIN_BAG_BYTES` the one-thread path was as fast or faster, on two free cores
and beside a CPU-bound process alike (``benchmarks/bench_paths.py``, issue 41).

``RV_TE_READ_AHEAD=0`` turns the helper off; ``1`` uses it whenever two cores are allowed
(whatever the bag's size); unset: the rule above.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ['HELPER_MIN_BAG_BYTES', 'READ_AHEAD_ENV', 'allowed_cores', 'analysis_uses_helper',
           'helper_threads_allowed', 'read_ahead_setting']

READ_AHEAD_ENV = 'RV_TE_READ_AHEAD'
_CPU_MAX = Path('/sys/fs/cgroup/cpu.max')
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


def analysis_uses_helper(bag_bytes: int) -> bool:
    """True when the analysis of a bag of ``bag_bytes`` (its storage files) should run its
    helper thread: two cores allowed, and the bag at least :data:`HELPER_MIN_BAG_BYTES`
    (or ``RV_TE_READ_AHEAD=1``, which forces it on wherever two cores are allowed)."""
    if not helper_threads_allowed():
        return False
    return (os.environ.get(READ_AHEAD_ENV, '').strip() == '1'
            or bag_bytes >= HELPER_MIN_BAG_BYTES)
