"""Helpers for node tests: spin until a condition, collect messages."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Callable


def spin_until(executor: Any, cond: Callable[[], bool], timeout_s: float) -> bool:
    """Spin ``executor`` until ``cond()`` is true or the timeout passes; return cond()."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        executor.spin_once(timeout_sec=0.05)
    return cond()


def spin_while_progress(executor: Any, cond: Callable[[], bool], progress: Callable[[], Any],
                        idle_s: float, limit_s: float = 300.0) -> bool:
    """Spin until ``cond()``, for as long as ``progress()`` keeps changing: gives up after
    ``idle_s`` without a change (or ``limit_s`` in all). On a busy machine the work takes
    longer but still moves; a lost message stops it for good."""
    end = time.monotonic() + limit_s
    last, since = progress(), time.monotonic()
    while time.monotonic() < end and time.monotonic() - since < idle_s:
        if cond():
            return True
        executor.spin_once(timeout_sec=0.05)
        if (now := progress()) != last:
            last, since = now, time.monotonic()
    return cond()


def spin_for(executor: Any, seconds: float) -> None:
    """Spin ``executor`` for a fixed time."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.02)
