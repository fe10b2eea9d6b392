"""Real-time scheduling of a node's pacing thread (Linux), as ros2_control's ``thread_priority``.

A DAQ node that must hand over a block every 10 ms on a shared industrial PC cannot wait for
the time-sharing scheduler: with four benches on two cores, the blocks of a bench left up to
89 ms late when the four TE windows closed together (issue #23 item 1), although the bench
itself needs 7 % of a core. :func:`realtime_scheduling` gives

* the calling thread (the one that runs the executor: timers, publishing) ``SCHED_FIFO`` at
  ``priority``. Threads it starts afterwards inherit that (the executor's timer thread);
* the threads that exist already (the middleware's: Fast DDS receive, events, shared memory
  watchdog) nice ``middleware_nice``. They hold the writer's locks while they process
  acknowledgements; left at nice 0 they were preempted holding them, and a publish then
  waited 7-13 ms for them (priority inversion). ``SCHED_FIFO`` for them as well made it far
  worse (ticks up to 1.2 s late: real-time threads of equal priority do not share a core).

It needs ``CAP_SYS_NICE`` or an rtprio / nice limit (``/etc/security/limits.conf``:
``@realtime - rtprio 98`` and ``@realtime - nice -20``), as every real-time ROS 2 control loop.
Without it nothing changes and the returned line says so. Only a node that paces to the wall
clock should ask: a ``SCHED_FIFO`` thread that computes as fast as it can takes a core from
everything else.

What is left after it is the kernel's wake-up latency. On the 2-core VM of the benchmarks
(a ``PREEMPT_NONE`` kernel) a bare real-time thread that does nothing but wake every 10 ms
was up to 23 ms late beside the four benches, and the benches' worst lag matched it
(``benchmarks/README.md``, four benches, round 3).
"""

from __future__ import annotations

import os
import sys
import threading

#: The nice the existing (middleware) threads get with real-time scheduling.
MIDDLEWARE_NICE = -10


#: How Fast DDS names its threads (``dds.ev.0``, ``dds.udp.7400``, ``dds.asyn.0.0``...).
FAST_DDS_PREFIX = 'dds.'


def _thread_name(tid: int) -> str:
    try:
        with open(f'/proc/self/task/{tid}/comm', encoding='utf-8') as f:
            return f.read().strip()
    except OSError:
        return ''


def _thread_ids() -> list[int]:
    try:
        return sorted(int(t) for t in os.listdir('/proc/self/task'))
    except OSError:
        return []


def realtime_scheduling(priority: int, middleware_nice: int = MIDDLEWARE_NICE,
                        middleware_priority: int = 0) -> str:
    """Put the calling thread on ``SCHED_FIFO`` at ``priority``, the other threads at nice
    ``middleware_nice`` (or on ``SCHED_FIFO`` at ``middleware_priority``); return one line
    saying what took effect.

    A ``middleware_priority`` below ``priority`` keeps the pacing thread first while a
    middleware thread that holds a lock it needs (the writer's) runs before every
    time-shared thread: traced with eight per-node sessions (benchmarks/README.md), the
    bench's publishes waited up to 429 ms for the writer's mutexes held by its own
    middleware threads at nice -10.

    Args:
        priority: 1..99 (``sched_get_priority_max(SCHED_FIFO)``); 0 leaves everything alone.
        middleware_nice: -20..19 for the threads that exist already.
        middleware_priority: 0 (nice ``middleware_nice``) or 1..``priority`` - 1:
            ``SCHED_FIFO`` at that priority for the middleware's threads that exist already
            (Fast DDS names them ``dds.*``; any other thread, e.g. the thread that runs the
            other nodes of a one-process session, gets nice ``middleware_nice``).

    Returns:
        ``'SCHED_FIFO 50, middleware threads nice -10'``, ``'normal'`` (priority 0), or
        ``'normal (SCHED_FIFO 50 not permitted: ...)'``: never raises for a missing permission.

    Raises:
        ValueError: ``priority`` outside 0..99, ``middleware_nice`` outside -20..19 or
            ``middleware_priority`` not 0 or below ``priority`` (named).
    """
    if isinstance(priority, bool) or not isinstance(priority, int) or not 0 <= priority <= 99:
        msg = f'realtime priority must be an integer 0..99, got {priority!r}'
        raise ValueError(msg)
    if isinstance(middleware_nice, bool) or not isinstance(middleware_nice, int) \
            or not -20 <= middleware_nice <= 19:
        msg = f'middleware nice must be an integer -20..19, got {middleware_nice!r}'
        raise ValueError(msg)
    if isinstance(middleware_priority, bool) or not isinstance(middleware_priority, int) \
            or not (middleware_priority == 0 or 1 <= middleware_priority < priority):
        msg = (f'middleware priority must be 0 or an integer 1..{max(priority - 1, 1)} (below '
               f'the pacing thread\'s {priority}), got {middleware_priority!r}')
        raise ValueError(msg)
    if priority == 0:
        return 'normal'
    if not sys.platform.startswith('linux'):
        return f'normal (SCHED_FIFO {priority} is only set on Linux)'
    top = os.sched_get_priority_max(os.SCHED_FIFO)
    if priority > top:
        return f'normal (SCHED_FIFO {priority} is above this system\'s maximum {top})'
    try:   # first: without it nothing is changed (the middleware threads stay as they are)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError:
        return (f'normal (SCHED_FIFO {priority} not permitted: needs CAP_SYS_NICE or an '
                f'rtprio limit >= {priority}, e.g. in /etc/security/limits.conf)')
    own = threading.get_native_id()
    niced, refused = 0, 0
    for tid in _thread_ids():
        if tid == own:
            continue
        try:
            if middleware_priority and _thread_name(tid).startswith(FAST_DDS_PREFIX):
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(middleware_priority))
            else:
                os.setpriority(os.PRIO_PROCESS, tid, middleware_nice)
            niced += 1
        except PermissionError:
            refused += 1
        except ProcessLookupError:   # a thread that ended meanwhile
            continue
    want = (f'SCHED_FIFO {middleware_priority} (the others nice {middleware_nice})'
            if middleware_priority else f'nice {middleware_nice}')
    if refused:
        return (f'SCHED_FIFO {priority}, middleware threads nice 0 ({want} not permitted '
                f'for {refused} of {niced + refused})')
    return f'SCHED_FIFO {priority}, middleware threads {want}'
