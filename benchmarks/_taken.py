"""Which path ``analyze_bag`` took (benchmarks): its helper's decision as logged."""

from __future__ import annotations

import logging


class Taken(logging.Handler):
    """The path the analysis took: its helper's decision as logged (io/_helper.py), none
    logged: one thread (one core, or a bag under the size limit)."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.messages: list[str] = []
        log = logging.getLogger('rv_te_bench.io._helper')
        log.setLevel(logging.DEBUG)
        log.addHandler(self)
        log.propagate = False

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())

    def clear(self) -> None:
        self.messages.clear()

    def path(self) -> str:
        return 'helper' if any(m.startswith('analysis: helper') for m in self.messages) \
            else 'one thread'
