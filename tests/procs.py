"""Processes as Linux shows them in /proc: the helpers of the tests that kill, interrupt or
reschedule real processes (shared, so that no test file imports another)."""

from __future__ import annotations

from pathlib import Path


def stat_fields(stat_file: str | Path) -> list[str]:
    """Fields 3.. of a ``/proc/.../stat`` file (after the command name, which may hold
    spaces and parentheses): index 0 is field 3 (state), index 1 field 4 (ppid), ...

    Raises:
        OSError: The process (or thread) is gone.
    """
    return Path(stat_file).read_text().rsplit(')', 1)[1].split()


def children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid``."""
    out = []
    for d in Path('/proc').iterdir():
        if d.name.isdigit():
            try:
                fields = stat_fields(d / 'stat')
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(d.name))
    return out


def alive(pid: int) -> bool:
    """Running (a zombie waiting for its new parent to reap it counts as gone)."""
    try:
        state = stat_fields(f'/proc/{pid}/stat')[0]
    except OSError:
        return False
    return state != 'Z'


def runqueue_wait_s(pid: int) -> float:
    """Longest time any thread of ``pid`` has waited on a run queue, runnable but given no
    CPU (``/proc/PID/task/TID/schedstat``, field 2) [s]; 0.0 once the process is gone."""
    longest = 0
    try:
        tasks = list(Path(f'/proc/{pid}/task').iterdir())
    except OSError:
        return 0.0
    for task in tasks:
        try:
            longest = max(longest, int((task / 'schedstat').read_text().split()[1]))
        except (OSError, IndexError, ValueError):
            continue
    return longest * 1e-9


def wait_gone(pids: list[int], budget_s: float, cap_s: float = 30.0) -> float:
    """Wait until every process of ``pids`` is gone, allowing ``budget_s`` of the time they
    could run: the time the kernel kept a process runnable but off every CPU (a busy
    machine) does not count against it, up to ``cap_s`` of wall time. Returns the wall time
    waited [s]."""
    import time

    t0 = time.monotonic()
    start = {p: runqueue_wait_s(p) for p in pids}
    starved = dict.fromkeys(pids, 0.0)
    while True:
        now = time.monotonic()
        running = [p for p in pids if alive(p)]
        for p in running:
            starved[p] = max(starved[p], runqueue_wait_s(p) - start[p])
        if not running:
            return now - t0
        if now - t0 - max(starved[p] for p in running) > budget_s or now - t0 > cap_s:
            return now - t0
        time.sleep(0.05)
