"""Imported once where fleet workers come from, so that no bag pays for the imports.

A local cluster's workers are forked from a fork server that has imported this module
(``multiprocessing`` ``forkserver`` with this module preloaded): every worker starts with
the analysis, the report's JSON and the store already imported, and the first bag of each
worker costs what the others cost. Workers of an existing cluster (``--scheduler``) import
it with their first task instead.
"""

from __future__ import annotations

import distributed.nanny  # noqa: F401 - what a worker process runs, imported once too

import rv_te_bench.report.analysis
import rv_te_bench.report.html
import rv_te_bench.store  # noqa: F401
import sim.errors  # noqa: F401
from rv_te_bench.allocator import tune_for_batch_work

tune_for_batch_work()
