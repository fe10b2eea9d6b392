"""Whether the offline analysis should use its helper thread: may it run on two cores?

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

``RV_TE_READ_AHEAD=0`` turns the helper off; ``1`` (or unset) uses it when two cores are
allowed.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ['READ_AHEAD_ENV', 'allowed_cores', 'helper_threads_allowed', 'read_ahead_setting']

READ_AHEAD_ENV = 'RV_TE_READ_AHEAD'
_CPU_MAX = Path('/sys/fs/cgroup/cpu.max')


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
