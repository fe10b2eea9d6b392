"""The allocator setting of ``rv-te analyze``: in effect on glibc, once, and harmless."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='glibc mallopt')
def test_tuning_keeps_window_sized_blocks_off_fresh_pages() -> None:
    """Allocating and freeing 1.3 MB arrays (one window at 10 kHz) faults fresh pages each
    time with glibc's defaults and almost never once tuned (counted in a child process)."""
    code = textwrap.dedent('''
        import resource, sys
        import numpy as np
        from rv_te_bench.allocator import tune_for_batch_work
        if sys.argv[1] == 'tuned':
            assert tune_for_batch_work() is True
            assert tune_for_batch_work() is True   # once; the second call changes nothing
        def faults():
            return resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        for _ in range(5):   # warm up: the heap grows once
            a = np.ones(160_000); b = a * 2.0; c = b + a; del a, b, c
        f0 = faults()
        for _ in range(50):
            a = np.ones(160_000); b = a * 2.0; c = b + a; del a, b, c
        print(faults() - f0)
    ''')
    counts = {}
    for mode in ('default', 'tuned'):
        out = subprocess.run([sys.executable, '-c', code, mode], capture_output=True,
                             text=True, check=True, timeout=60)
        counts[mode] = int(out.stdout.strip())
    # 50 x 3 arrays x ~300 pages each with the defaults (~45,000); a few once tuned
    assert counts['tuned'] < 1000, counts
    assert counts['default'] > 10_000, counts
