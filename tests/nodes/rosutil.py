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


def spin_for(executor: Any, seconds: float) -> None:
    """Spin ``executor`` for a fixed time."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.02)
