"""cli._progress.ProgressBar: redrawn on a terminal, periodic lines in a log."""

from __future__ import annotations

import io

from rv_te_bench.cli._progress import ProgressBar


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_terminal_gets_one_redrawn_line() -> None:
    out = _Tty()
    bar = ProgressBar('grid', out, width=10)
    for k in range(0, 101, 5):
        bar(k / 100)
    bar(1.0)              # no change: no redraw
    bar.close()
    text = out.getvalue()
    assert text.count('\r') == 21
    assert text.endswith('\rgrid [##########] 100%\n')
    assert text.count('\n') == 1


def test_a_log_gets_a_line_every_ten_percent() -> None:
    out = io.StringIO()   # not a terminal
    bar = ProgressBar('grid', out)
    for k in range(1001):
        bar(k / 1000)
    bar.close()
    lines = out.getvalue().splitlines()
    assert lines == [f'grid: {p}%' for p in range(0, 101, 10)]
    assert '\r' not in out.getvalue()


def test_nothing_drawn_nothing_closed() -> None:
    for out in (io.StringIO(), _Tty()):
        ProgressBar('grid', out).close()
        assert out.getvalue() == ''
