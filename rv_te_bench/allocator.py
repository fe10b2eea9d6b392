"""Process-wide allocator settings for the batch command ``rv-te analyze``.

The offline analysis allocates and frees arrays of one analysis window (~1.3 MB per
output revolution at 10 kHz) dozens of times per window. glibc's malloc serves blocks of
that size with fresh ``mmap`` s (above its mmap threshold, which it raises only
dynamically) and hands freed heap tops back to the kernel, so every window pays for
thousands of page faults; on virtual machines a page fault costs microseconds, and
``benchmarks/bench_analyze.py`` measured a quarter to a third of the analysis time going
there. Keeping such blocks on the heap and the freed memory in the process (until it
exits) removes that cost; the price is that the process's resident size stays at its high
water mark, which is harmless for a command that runs once and exits.

Only the command-line entry points call :func:`tune_for_batch_work`; the library and the
long-running nodes leave the allocator alone. It does nothing where ``mallopt`` is not
available (musl, macOS, Windows).
"""

from __future__ import annotations

import ctypes
import sys

__all__ = ['tune_for_batch_work']

# glibc <malloc.h>
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
#: Blocks below this come from the heap (32 MiB is glibc's largest allowed value on 64-bit).
MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024
#: Freed memory at the top of the heap is given back to the kernel only beyond this.
TRIM_THRESHOLD_BYTES = 512 * 1024 * 1024

_done: bool | None = None


def tune_for_batch_work() -> bool:
    """Set glibc's mmap and trim thresholds for this process (once).

    Returns:
        True when the settings are in effect (glibc), False where they do not apply.
    """
    global _done  # noqa: PLW0603 - a process-wide setting is made once
    if _done is not None:
        return _done
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
