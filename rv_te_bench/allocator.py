"""Process-wide allocator and BLAS settings for the batch commands (``rv-te analyze``).

The offline analysis allocates and frees arrays of one analysis window (~1.3 MB per
output revolution at 10 kHz) dozens of times per window. glibc's malloc serves blocks of
that size with fresh ``mmap`` s (above its mmap threshold, which it raises only
dynamically) and hands freed heap tops back to the kernel, so every window pays for
thousands of page faults; on virtual machines a page fault costs microseconds, and
``benchmarks/bench_analyze.py`` measured a quarter to a third of the analysis time going
there. Keeping such blocks on the heap and the freed memory in the process (until it
exits) removes that cost; the price is that the process's resident size stays at its high
water mark, which is harmless for a command that runs once and exits.

BLAS: numpy and scipy each bring an OpenBLAS, and each starts a pool of threads, one per
core, for calls above a small size. After a call those threads spin, waiting for the next
one, before they sleep; the analysis (the advice's fits: normal equations, SVDs, the phase
grid) makes thousands of small calls with Python work between them, so the pools spin
almost all the time. Issue 41 measured it: a loop of ``analyse_one`` over 2-revolution unit
bags on 2 cores spent 1.4-1.6x the CPU time with the pools as with one BLAS thread
(2.65-2.96 vs 1.85-1.87 CPU s for 8 bags, side by side) and was no faster in wall time;
Dask's workers run with one BLAS thread already (its ``pre-spawn-environ``), which is why
a fleet of workers spent less CPU on the same bags than the plain loop. So the batch
commands use one BLAS thread: :func:`one_blas_thread` limits the BLAS libraries loaded so
far (threadpoolctl) and sets ``OPENBLAS_NUM_THREADS=1`` for those loaded later. A user's
own ``OPENBLAS_NUM_THREADS`` is left as it is.

Only the command-line entry points (and the fleet's analysis) call
:func:`tune_for_batch_work`; the library and the long-running nodes leave the allocator and
BLAS alone. The allocator part does nothing where ``mallopt`` is not available (musl,
macOS, Windows).
"""

from __future__ import annotations

import ctypes
import os
import sys

__all__ = ['BLAS_THREADS_ENV', 'one_blas_thread', 'tune_for_batch_work']

#: The environment variable OpenBLAS reads when it is loaded; set by the user, it is kept.
BLAS_THREADS_ENV = 'OPENBLAS_NUM_THREADS'

# glibc <malloc.h>
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
#: Blocks below this come from the heap (32 MiB is glibc's largest allowed value on 64-bit).
MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024
#: Freed memory at the top of the heap is given back to the kernel only beyond this.
TRIM_THRESHOLD_BYTES = 512 * 1024 * 1024

_done: bool | None = None
_blas_done = False


def one_blas_thread() -> None:
    """One BLAS thread for this process (once), unless the user set ``OPENBLAS_NUM_THREADS``.

    The BLAS libraries already loaded are limited now; one loaded later (scipy's, on its
    first use) reads the environment variable set here.
    """
    global _blas_done  # noqa: PLW0603 - a process-wide setting is made once
    if _blas_done:
        return
    _blas_done = True
    if os.environ.get(BLAS_THREADS_ENV, '').strip():
        return
    os.environ[BLAS_THREADS_ENV] = '1'
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:   # an environment made before the dependency: later loads only
        return
    threadpool_limits(limits=1, user_api='blas')   # not as a context: it stays in effect


def tune_for_batch_work() -> bool:
    """Set glibc's mmap and trim thresholds for this process, and one BLAS thread (once).

    Returns:
        True when the allocator settings are in effect (glibc), False where they do not
        apply.
    """
    global _done  # noqa: PLW0603 - a process-wide setting is made once
    if _done is not None:
        return _done
    one_blas_thread()
    _done = False
    if not sys.platform.startswith('linux'):
        return False
    try:
        # the process's own symbols: glibc's malloc when it is the allocator in use (no
        # ctypes.util.find_library, which may start ldconfig or a compiler to look)
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    _done = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)) and \
        bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
    return _done
