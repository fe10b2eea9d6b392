"""The CSV reader's two parsers (pyarrow per block, numpy.loadtxt as the fallback) read the
same values, the line numbers stay right across both, and the read-ahead thread hands
errors over in order (issue 41: import at columnar speed).

Expected values are the numbers written into the files here (17 significant digits read back
exactly), not the reader's own output.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.errors import DataImportError
from rv_te_bench.io.importers import ImportOptions
from rv_te_bench.io.importers._ahead import read_ahead
from rv_te_bench.io.importers.csv_file import CsvReader

pytest.importorskip('pyarrow')

N = 2500
T = np.arange(N) / 1000.0
TH_IN = np.linspace(0.0, 50.0, N) + 1e-13
TH_OUT = TH_IN / 79.0 + 3e-4 * np.sin(TH_IN)


def _rows(delim: str = ',', decimal: str = '.') -> list[str]:
    out = []
    for a, b, c in zip(T, TH_IN, TH_OUT, strict=True):
        cells = [f'{a:.17g}', f'{b:.17g}', f'{c:.17g}']
        if decimal == ',':
            cells = [x.replace('.', ',') for x in cells]
        out.append(delim.join(cells))
    return out


def _read(path: Path, *, numpy_only: bool, header: bool = True, **opts: object
          ) -> tuple[dict[str, np.ndarray], CsvReader]:
    o = ImportOptions(theta_in=str(opts.pop('theta_in', 'theta_in_rad')),
                      theta_out=str(opts.pop('theta_out', 'theta_out_rad')),
                      chunk_samples=300, **opts)  # type: ignore[arg-type]
    r = CsvReader(path, o, header=header)
    if numpy_only:
        r.__dict__['_arrow'] = None      # the cached_property: every block via numpy
    chunks = list(r.chunks())
    r.close()
    cols = {k: np.concatenate([getattr(c, k) for c in chunks])
            for k in ('theta_in', 'theta_out')}
    if chunks[0].time is not None:
        cols['time'] = np.concatenate([c.time for c in chunks])  # type: ignore[misc]
    return cols, r


@pytest.mark.parametrize('layout', ['plain', 'crlf', 'bom', 'quoted', 'semicolon', 'tab',
                                    'blanks', 'comments', 'decimal_comma', 'no_header'])
@pytest.mark.parametrize('numpy_only', [False, True])
def test_both_parsers_read_the_written_values(tmp_path: Path, layout: str,
                                              numpy_only: bool) -> None:
    delim = {'semicolon': ';', 'tab': '\t', 'decimal_comma': ';', 'blanks': ' '}.get(layout, ',')
    rows = _rows(delim, ',' if layout == 'decimal_comma' else '.')
    if layout == 'quoted':
        rows = [','.join(f'"{c}"' for c in r.split(',')) for r in rows]
    if layout == 'comments':
        rows = ['# DAQ export v2', *rows[:1000], '# paused', '', *rows[1000:]]
    if layout == 'blanks':
        rows = ['  '.join(r.split(' ')) for r in rows]
    head = [] if layout == 'no_header' else [delim.join(['t_s', 'theta_in_rad', 'theta_out_rad'])]
    text = '\r\n'.join([*head, *rows]) + '\r\n' if layout == 'crlf' else \
        '\n'.join([*head, *rows]) + '\n'
    p = tmp_path / 'run.csv'
    p.write_bytes((b'\xef\xbb\xbf' if layout == 'bom' else b'') + text.encode())
    opts: dict[str, object] = {'time': 't_s'}
    if layout == 'decimal_comma':
        opts['decimal'] = ','
    if layout == 'no_header':
        opts = {'time': '0', 'theta_in': '1', 'theta_out': '2'}
    cols, _ = _read(p, numpy_only=numpy_only, header=layout != 'no_header', **opts)
    np.testing.assert_array_equal(cols['time'], T)
    np.testing.assert_array_equal(cols['theta_in'], TH_IN)
    np.testing.assert_array_equal(cols['theta_out'], TH_OUT)


@pytest.mark.parametrize('numpy_only', [False, True])
def test_empty_and_nan_cells_are_missing_values(tmp_path: Path, numpy_only: bool) -> None:
    rows = _rows()
    rows[700] = '0.7,,0.1'
    rows[1900] = '1.9,nan,0.1'
    p = tmp_path / 'run.csv'
    p.write_text('t_s,theta_in_rad,theta_out_rad\n' + '\n'.join(rows) + '\n')
    cols, _ = _read(p, numpy_only=numpy_only, time='t_s')
    assert np.flatnonzero(np.isnan(cols['theta_in'])).tolist() == [700, 1900]
    np.testing.assert_array_equal(np.delete(cols['theta_out'], [700, 1900]),
                                  np.delete(TH_OUT, [700, 1900]))


@pytest.mark.parametrize('numpy_only', [False, True])
def test_epoch_nanoseconds_keep_every_digit(tmp_path: Path, numpy_only: bool) -> None:
    t_ns = 1_764_000_000_123_456_789 + np.arange(N, dtype=np.int64) * 100_003
    p = tmp_path / 'run.csv'
    p.write_text('t_ns,theta_in_rad,theta_out_rad\n' + '\n'.join(
        f'{a},{r.split(",", 1)[1]}' for a, r in zip(t_ns, _rows(), strict=True)) + '\n')
    cols, _ = _read(p, numpy_only=numpy_only, time='t_ns')
    assert cols['time'].dtype == np.int64
    np.testing.assert_array_equal(cols['time'], t_ns)


@pytest.mark.parametrize('numpy_only', [False, True])
def test_bad_cell_named_by_its_line_after_comment_lines(tmp_path: Path,
                                                        numpy_only: bool) -> None:
    rows = _rows()
    rows[2000] = '2.0,abc,0.1'
    lines = ['t_s,theta_in_rad,theta_out_rad', *rows[:100], '# operator note', '',
             *rows[100:]]
    p = tmp_path / 'run.csv'
    p.write_text('\n'.join(lines) + '\n')
    bad_line = lines.index('2.0,abc,0.1') + 1
    with pytest.raises(DataImportError, match=rf"'theta_in_rad', line {bad_line}: 'abc' is not"):
        _read(p, numpy_only=numpy_only, time='t_s')


def test_line_of_a_sample_after_blank_lines(tmp_path: Path) -> None:
    """Lines of samples in blocks after a block with blank lines count them (the read-ahead
    parses later blocks first: the shift is kept by sample, not applied globally)."""
    rows = _rows()
    lines = ['t_s,theta_in_rad,theta_out_rad', *rows[:50], '', '', *rows[50:]]
    p = tmp_path / 'run.csv'
    p.write_text('\n'.join(lines) + '\n')
    _, r = _read(p, numpy_only=False, time='t_s')
    assert r.locate(2400) == f'line {lines.index(rows[2400]) + 1}'


def _gen(n: int, fail_at: int | None = None, seen: list[str] | None = None):  # type: ignore[no-untyped-def]
    try:
        for k in range(n):
            if k == fail_at:
                msg = f'bad cell in chunk {k}'
                raise DataImportError(msg)
            yield k
    finally:
        if seen is not None:
            seen.append(threading.current_thread().name)


@pytest.mark.parametrize('threads', [True, False])
def test_read_ahead_keeps_order_and_raises_in_place(threads: bool) -> None:
    assert list(read_ahead(_gen(50), threads=threads)) == list(range(50))
    got: list[int] = []
    with pytest.raises(DataImportError, match='chunk 7'):
        for k in read_ahead(_gen(50, fail_at=7), threads=threads):
            got.append(k)
    assert got == list(range(7))


def test_read_ahead_stops_its_thread_when_closed_early() -> None:
    seen: list[str] = []
    ahead = read_ahead(_gen(10_000, seen=seen), threads=True)
    assert next(ahead) == 0
    ahead.close()              # joins the helper: the reader's generator is closed too
    assert seen == ['import-read-ahead']
    assert not any(t.name == 'import-read-ahead' for t in threading.enumerate())
