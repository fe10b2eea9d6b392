"""The allocator setting of ``rv-te analyze``: in effect on glibc, once, and harmless."""

from __future__ import annotations

import os
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


_BLAS_CHILD = textwrap.dedent('''
    import json, sys
    import numpy as np
    from threadpoolctl import threadpool_info, threadpool_limits
    from rv_te_bench.allocator import tune_for_batch_work
    threadpool_limits(limits=2, user_api='blas')   # a 2-core machine's pool, on any machine
    before = {i['filepath']: i['num_threads'] for i in threadpool_info()
              if i['user_api'] == 'blas'}
    tune_for_batch_work()
    import scipy.linalg   # scipy's own OpenBLAS, loaded after the setting
    scipy.linalg.svd(np.ones((300, 300)))
    after = {i['filepath']: i['num_threads'] for i in threadpool_info()
             if i['user_api'] == 'blas'}
    print(json.dumps({'before': before, 'after': after}))
''')


def _blas_threads(env_value: str | None) -> dict[str, dict[str, int]]:
    import json
    env = {k: v for k, v in os.environ.items()
           if k not in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')}
    if env_value is not None:
        env['OPENBLAS_NUM_THREADS'] = env_value
    out = subprocess.run([sys.executable, '-c', _BLAS_CHILD], capture_output=True, text=True,
                         check=True, timeout=60, env=env)
    return json.loads(out.stdout)


_TWO_CORES = pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2,
                                reason='OpenBLAS keeps one thread per allowed core at most')


@_TWO_CORES
def test_batch_work_uses_one_blas_thread() -> None:
    """numpy's and scipy's OpenBLAS pools (issue 41: they spin between the advice's small
    calls, +40-60 % CPU for nothing): one thread each after the batch setting, both the
    library loaded before it and the one loaded after."""
    got = _blas_threads(None)
    assert got['before'] and all(n == 2 for n in got['before'].values()), got
    assert len(got['after']) > len(got['before']), got   # scipy's loaded after the setting
    assert all(n == 1 for n in got['after'].values()), got


@_TWO_CORES
def test_user_blas_threads_kept() -> None:
    """A user's own OPENBLAS_NUM_THREADS is theirs: the batch setting leaves the pools be."""
    got = _blas_threads('2')
    assert len(got['after']) > len(got['before']), got   # scipy's loaded after the setting
    assert all(n == 2 for n in got['after'].values()), got
