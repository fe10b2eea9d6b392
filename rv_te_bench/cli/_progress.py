"""Progress of a long CLI computation on stderr: a redrawn bar on a terminal, lines in a log.

On a terminal the bar is redrawn in place (carriage return) when the shown percentage
changes. When the stream is not a terminal (a log file, a pipe, CI) carriage-return frames
would pile up as ~100 overwritten copies of the bar on one line, so one plain line is
written every :data:`LOG_STEP_PCT` percent instead.
"""

from __future__ import annotations

import sys
from typing import TextIO

__all__ = ['LOG_STEP_PCT', 'ProgressBar']

#: Percent between two progress lines when the stream is not a terminal.
LOG_STEP_PCT = 10


def _is_terminal(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):   # no isatty, or a closed stream
        return False


class ProgressBar:
    """A one-line text progress bar on a stream (stderr); call it with the fraction done.

    Args:
        label: What is being done, e.g. ``'grid search'``.
        stream: Where to write (default ``sys.stderr``).
        width: Characters of the bar.
        terminal: Draw the redrawn bar (True) or periodic lines (False); default: whether
            ``stream`` is a terminal.
    """

    def __init__(self, label: str, stream: TextIO | None = None, width: int = 30, *,
                 terminal: bool | None = None) -> None:
        """Remember where and how to draw (see class docstring)."""
        self._label = label
        self._stream = sys.stderr if stream is None else stream
        self._width = width
        self._terminal = _is_terminal(self._stream) if terminal is None else terminal
        self._last = -1

    def __call__(self, fraction: float) -> None:
        """Redraw when the shown percentage changes (a line per step in a log)."""
        pct = int(max(0.0, min(1.0, fraction)) * 100)
        if not self._terminal:
            step = pct - pct % LOG_STEP_PCT
            if step > self._last:
                self._last = step
                self._stream.write(f'{self._label}: {step}%\n')
                self._stream.flush()
            return
        if pct == self._last:
            return
        self._last = pct
        fill = pct * self._width // 100
        bar = '#' * fill + '.' * (self._width - fill)
        self._stream.write(f'\r{self._label} [{bar}] {pct:3d}%')
        self._stream.flush()

    def close(self) -> None:
        """End the bar's line if anything was drawn (the log lines are ended already)."""
        if self._terminal and self._last >= 0:
            self._stream.write('\n')
            self._stream.flush()
