"""Imported once where fleet workers come from, so that no bag pays for the imports.

A local cluster's workers are forked from a fork server that has imported this module
(``multiprocessing`` ``forkserver`` with this module preloaded, :func:`._run._local_config`):
every worker starts with the analysis, the report's JSON, the store and Dask's worker
already imported, and the first bag of each worker costs what the others cost. Workers of
an existing cluster (``--scheduler``) import it with their first task instead.
"""

from __future__ import annotations

import os

import distributed.nanny  # noqa: F401 - what a worker process runs, imported once too

import rv_te_bench.report.analysis
import rv_te_bench.report.html
import rv_te_bench.store  # noqa: F401
import sim.errors  # noqa: F401
from rv_te_bench.allocator import tune_for_batch_work

#: The process that imported this module: in a local cluster's worker, its fork server.
IMPORTED_IN_PID = os.getpid()

tune_for_batch_work()
