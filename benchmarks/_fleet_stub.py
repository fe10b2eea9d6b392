"""The stub analysis of ``bench_fleet.py``'s engine-alone runs.

A module of its own so that Dask sends ``stub_batch`` to the workers by reference, as it
sends ``rv_te_bench.fleet._run.analyse_batch`` (a function of the benchmark's ``__main__``
would be pickled by value with everything it uses, per task: a cost the real engine does
not have). The ready record it copies is read once per worker from the pickle named by
``$RV_TE_BENCH_FLEET_TEMPLATE`` (the workers inherit the environment).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pickle
from functools import cache
from typing import Any

TEMPLATE_ENV = 'RV_TE_BENCH_FLEET_TEMPLATE'


@cache
def _template() -> Any:
    with open(os.environ[TEMPLATE_ENV], 'rb') as f:
        return pickle.load(f)   # the benchmark's own file


def stub_batch(paths: list[str], options: object) -> list[Any]:
    """Records of ``paths`` without analysing them: copies of the template, each with its
    path and a hash of its path (distinct keys)."""
    t = _template()
    return [dataclasses.replace(t, bag_path=p,
                                bag_sha256=hashlib.sha256(p.encode()).hexdigest())
            for p in paths]
