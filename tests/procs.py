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
