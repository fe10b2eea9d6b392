"""Imported once where fleet workers come from, so that no bag pays for the imports.

A local cluster's workers are forked from a fork server that has imported this module
(``multiprocessing`` ``forkserver`` with this module preloaded, :func:`._run._local_config`):
every worker starts with the analysis, the report's JSON, the store and Dask's worker
already imported, and the first bag of each worker costs what the others cost. Workers of
an existing cluster (``--scheduler``) import it with their first task instead.

It is also each local worker's Dask preload: :func:`dask_setup` keeps the worker's own
shutdown off the command's stderr (see :class:`QuietHeartbeatAtClose`).
"""

from __future__ import annotations

import logging
import os
import weakref
from typing import Any

import distributed.nanny  # noqa: F401 - what a worker process runs, imported once too

import rv_te_bench.report.analysis
import rv_te_bench.report.html
import rv_te_bench.store  # noqa: F401
import sim.errors  # noqa: F401
from rv_te_bench.allocator import tune_for_batch_work

#: The process that imported this module: in a local cluster's worker, its fork server.
IMPORTED_IN_PID = os.getpid()

tune_for_batch_work()

#: Dask's words when a worker's heartbeat to the scheduler fails (distributed.worker).
HEARTBEAT_FAILED = 'Failed to communicate with scheduler during heartbeat'


class QuietHeartbeatAtClose(logging.Filter):
    """Drops Dask's heartbeat ERROR (and its traceback) once the worker is closing.

    A worker that closes closes its connections, among them the one of a heartbeat still
    waiting for the scheduler's reply; Dask then logs "Failed to communicate with scheduler
    during heartbeat" at ERROR with a traceback (dask/distributed#7192). The order of the
    shutdown does not prevent it: the local cluster already retires and stops the workers
    before the scheduler; it is the worker's own close that cuts its heartbeat off, so the
    busier the scheduler (slower replies, e.g. at load 13) the likelier. That is no error of
    the run, but it broke ``rv-te fleet analyze``'s one clear line on stderr. A heartbeat that
    fails while the worker runs is still logged.
    """

    def __init__(self, worker: Any) -> None:
        super().__init__()
        self._worker = weakref.ref(worker)

    def filter(self, record: logging.LogRecord) -> bool:
        if not str(record.msg).startswith(HEARTBEAT_FAILED):
            return True
        from distributed.core import Status

        worker = self._worker()
        return worker is not None and worker.status not in (
            Status.closing, Status.closed, Status.closing_gracefully, Status.failed)


def dask_setup(worker: Any) -> None:
    """Dask's preload hook, run in each local worker as it starts."""
    logging.getLogger('distributed.worker').addFilter(QuietHeartbeatAtClose(worker))
