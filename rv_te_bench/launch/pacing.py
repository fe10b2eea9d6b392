"""The bench of a one-process session on a thread of its own (issue 41 item 4).

In a session whose nodes share one process (``rv-te launch --single-process``) a real-time
bench used to run on the one executor thread with the TE node, the compensation node and
the recorder. Its block timer then waited behind whatever callback ran (a recorder's graph
discovery took 20-475 ms, a TE window 5-24 ms, the compensation node's result 28-54 ms),
and the SCHED_FIFO its ``realtime_priority`` asks for went to that thread, so every node's
work, and the compensation search thread it started, ran real-time (a search of 0.4-0.8 CPU
s on SCHED_FIFO 50). Measured: blocks up to 91-101 ms late with one session alone.

:class:`PacedNode` builds the bench on a thread of its own, which spins an executor of its
own: the SCHED_FIFO goes to that thread (and to its executor's timer thread, started
after), and a block tick waits for no other node's callback. The thread that runs the
other nodes gets what the middleware's threads get (nice -10, normal policy:
:func:`rv_te_bench.nodes.scheduling.realtime_scheduling`): the TE node and the recorder
are the data path, and in one process they share one thread's share of the CPU (left at
nice 0 beside other work, load 24-32, eight sessions lost 14-46 % of their blocks where
the per-node layout's 24 reader processes kept up). What the bench still shares is the
interpreter lock; Python hands it to a waiting thread only after the switch interval (5 ms
by default, and again at each release a tick makes, e.g. in publish), so while the bench
runs the interval is :data:`PACED_SWITCH_INTERVAL_S`.
"""

from __future__ import annotations

import sys
import threading
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Callable

    from rclpy.context import Context

#: Python's thread switch interval while a paced bench shares its process with other nodes
#: [s]: the longest a tick waits for the interpreter lock held by another node's Python code.
PACED_SWITCH_INTERVAL_S = 0.0005


class PacedNode:
    """A node built and spun on a thread of its own (the bench of a one-process session).

    Args:
        build: Builds the node (on the new thread).
        context: The session's rclpy context.
    """

    def __init__(self, build: Callable[[], Any], context: Context) -> None:
        """Prepare; nothing runs until :meth:`start`."""
        self._build = build
        self._ctx = context
        self._ready = threading.Event()
        self._stop = threading.Event()
        self._switch_s = sys.getswitchinterval()
        self.node: Any = None
        #: What ended the thread with an error (raised again by :meth:`check`).
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name='bench-pacing', daemon=True)

    def start(self) -> Any:
        """Build the node on its thread and start spinning it; return the node.

        Raises:
            Exception: Whatever building the node raised (bad parameters), as it was.
        """
        sys.setswitchinterval(PACED_SWITCH_INTERVAL_S)
        self._thread.start()
        self._ready.wait()
        if self.error is not None:
            sys.setswitchinterval(self._switch_s)
            raise self.error
        return self.node

    def _run(self) -> None:
        from rclpy.executors import ExternalShutdownException
        from rclpy.task import Future

        from rv_te_bench.nodes.common import make_executor

        try:
            self.node = self._build()
            executor = make_executor('events', context=self._ctx)
            executor.add_node(self.node)
        except BaseException as exc:  # noqa: BLE001 - handed to the starting thread
            self.error = exc
            self._ready.set()
            return
        self._ready.set()
        try:
            while self._ctx.ok() and not self._stop.is_set():
                # up to 0.1 s of events per Python pass (as rv_te_bench.nodes.common.run_node)
                executor.spin_until_future_complete(Future(), timeout_sec=0.1)
        except ExternalShutdownException:
            pass
        except Exception as exc:  # noqa: BLE001 - a callback's error: the session ends
            self.error = exc
        finally:
            executor.remove_node(self.node)
            executor.shutdown()

    def check(self) -> None:
        """Raise, in the calling thread, the error that ended the node's thread (if any).

        Raises:
            Exception: A callback's error, as a node's own process would have raised it.
        """
        if self.error is not None:
            raise self.error

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop spinning (the node is left to destroy) and restore the switch interval."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)
        sys.setswitchinterval(self._switch_s)
