"""CSV measurement files, read in blocks of rows with ``pyarrow.csv`` (memory stays flat).

Layout: one header line naming the columns (``--no-header``: none, columns by 0-based index),
then one sample per line; the delimiter (``,`` ``;`` tab, or blanks) is sniffed from the
first line unless given; lines starting with ``#`` are comments. A column's unit may be in
its name (``theta_in_deg``, ``theta_in [deg]``, ``in (arcsec)``, ``t_ms``, ``time [min]``);
an option overrides it. An empty cell (how pandas writes NaN) is a missing value: the row is
a drop-out, as a ``nan`` cell is. A time column in nanoseconds is read as 64-bit integers
(epoch nanoseconds keep every digit). A decimal-comma export (``1,5;2,25``, as European
locales write) is read with ``decimal=','``; without it, such a cell is refused with that
hint.

Each block of whole lines (bytes, cut at a line break) is parsed by Arrow's multithreaded
CSV parser and converted to numpy column by column (no Python loop over rows). A block Arrow
cannot read as the columns say falls back to ``numpy.loadtxt`` on the same lines, which
reads what Arrow has no option for and names the first bad cell: comment lines (``#``),
columns separated by runs of blanks, a bad or missing cell (the error path). Without
pyarrow every block takes the numpy path (about 4x slower).
"""

from __future__ import annotations

import io
import re
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import DataImportError
from rv_te_bench.io.importers._common import (
    RawChunk,
    head_roles,
    loss_roles,
    stack_heads,
    stack_loss,
    time_unit,
)

if TYPE_CHECKING:
    from collections.abc import Iterator

    from rv_te_bench.io.importers._common import ImportOptions

__all__ = ['CsvReader']

_UNIT_IN_NAME = re.compile(r'(?:[\[(]\s*([^\])]+?)\s*[\])]\s*$)|(?:_(rad|deg|arcmin|arcsec|counts|'
                           r'rev|s|ms|us|ns)$)')
_TIME_UNIT_IN_NAME = re.compile(r'(?:[\[(]\s*([^\])]+?)\s*[\])]\s*$)|(?:_(s|sec|ms|us|ns|min|h)$)')
_MAX_HEADER = 1 << 20
_BOM = b'\xef\xbb\xbf'
_NL = b'\n'
#: Longest line read [characters] (a DAQ row of a few dozen numbers is ~1 kB).
MAX_LINE_CHARS = 1 << 20
_MAX_BLOCK_CHARS = 64 << 20
_DECIMAL_COMMA = re.compile(r'^[+-]?\d*,\d+(?:[eE][+-]?\d+)?$')
_EMPTY_CELL = {',': re.compile(r'(?<=,)(?=,|\r?$)|^(?=,)', re.MULTILINE),
               ';': re.compile(r'(?<=;)(?=;|\r?$)|^(?=;)', re.MULTILINE),
               '\t': re.compile(r'(?<=\t)(?=\t|\r?$)|^(?=\t)', re.MULTILINE)}


def _unit_from_name(name: str, role: str = 'in') -> str | None:
    m = (_TIME_UNIT_IN_NAME if role == 'time' else _UNIT_IN_NAME).search(name.strip())
    if not m:
        return None
    return m.group(1) or m.group(2)


class CsvReader:
    """A CSV file opened for import (see the module docstring).

    Args:
        path: The file.
        options: Column names / indices, delimiter, chunk size.
        header: The first line names the columns.

    Raises:
        DataImportError: Unreadable or empty file, no data rows, a column not in the header.
    """

    has_time: bool
    declared_rate_hz: float | None = None
    start_ns: int | None = None

    def __init__(self, path: Path, options: ImportOptions, *, header: bool = True) -> None:
        self.path = Path(path)
        self.origin = str(path)
        self.options = options
        try:
            self._file = self.path.open('rb')
            if self._file.read(3) != _BOM:
                self._file.seek(0)
            start = self._file.tell()
            first = self._file.readline(_MAX_HEADER).decode()
            self._line = 1
            while first.startswith('#'):
                start = self._file.tell()
                first = self._file.readline(_MAX_HEADER).decode()
                self._line += 1
        except (OSError, UnicodeDecodeError) as exc:
            msg = f'{path}: cannot read ({getattr(exc, "strerror", None) or exc})'
            raise DataImportError(msg) from None
        if not first.strip():
            msg = f'{path}: the file is empty (no header line and no data)'
            raise DataImportError(msg)
        self.delimiter = options.delimiter or self._sniff(
            first, (';', '\t') if options.decimal == ',' else (',', ';', '\t'))
        self._comma = options.decimal == ','
        cells = [c.strip().strip('"').strip() for c in
                 (first.split(self.delimiter) if self.delimiter else first.split())]
        self.columns = cells if header else [str(j) for j in range(len(cells))]
        self._n_columns = len(cells)
        if not header:           # the first line is data: read it again with the rest
            self._file.seek(start)
        self.data_line = self._line + 1 if header else self._line   # line of sample 0
        self._line_shifts: list[tuple[int, int]] = []   # (first sample, lines skipped)
        self._line_chars = max(16, 2 * len(first))   # block size estimate per row
        roles = {'in': options.theta_in, 'out': options.theta_out, 'torque': options.torque,
                 'time': options.time, **head_roles(options), **loss_roles(options)}
        if roles['in'] is None or roles['out'] is None:
            msg = (f'{path}: name the angle columns with --theta-in and --theta-out '
                   f'(columns: {", ".join(self.columns[:20])})')
            raise DataImportError(msg)
        self.index = {role: self._column(spec) for role, spec in roles.items() if spec is not None}
        self.labels = {role: self.columns[j] for role, j in self.index.items()}
        self.declared_units = {role: _unit_from_name(self.columns[j], role)
                               for role, j in self.index.items()}
        self.has_time = 'time' in self.index
        self.time_unit: str | None = None     # from the name or --time-unit (write_bag)
        self._roles = list(self.index)
        self._usecols = [self.index[r] for r in self._roles]
        # nanoseconds (epoch stamps need all 19 digits): the time column as int64
        unit = options.time_unit or time_unit(self.declared_units.get('time'))
        self._int_time = self.has_time and unit == 'ns'

    @staticmethod
    def _sniff(line: str, candidates: tuple[str, ...]) -> str | None:
        counts = {d: line.count(d) for d in candidates}
        best = max(counts, key=lambda d: counts[d])
        return best if counts[best] else None

    def _column(self, spec: str) -> int:
        if spec in self.columns:
            return self.columns.index(spec)
        if spec.isdigit() and int(spec) < len(self.columns):
            return int(spec)
        shown = ', '.join(repr(c) for c in self.columns[:20])
        more = f' and {len(self.columns) - 20} more' if len(self.columns) > 20 else ''
        msg = f'{self.origin}: column {spec!r} not found (columns: {shown}{more})'
        raise DataImportError(msg)

    def locate(self, index: int) -> str:
        """Sample index -> ``'line N'`` (1-based line of the file)."""
        shift = sum(k for start, k in self._line_shifts if start <= index)
        return f'line {self.data_line + index + shift}'

    def chunks(self) -> Iterator[RawChunk]:
        """Yield the rows about ``options.chunk_samples`` at a time.

        The file is read in blocks of characters, never a line at a time: memory stays
        bounded by the block however long a line is, and a line longer than
        :data:`MAX_LINE_CHARS` is refused (no DAQ row is; a file without line breaks is not
        a CSV export).

        Raises:
            DataImportError: No data rows; a non-numeric or missing cell (line and column);
                a line over the limit.
        """
        first = 0
        rest = b''
        block = min(_MAX_BLOCK_CHARS, max(1 << 16, self.options.chunk_samples
                                          * self._line_chars))
        while True:
            # the last block's unfinished line, then the file's next bytes, in one buffer
            # that the parser reads in place (no copies of the block)
            buf = bytearray(len(rest) + block)
            buf[:len(rest)] = rest
            try:
                got = self._file.readinto(memoryview(buf)[len(rest):])
            except OSError as exc:
                msg = f'{self.origin}: cannot read near {self.locate(first)} ({exc})'
                raise DataImportError(msg) from None
            total = len(rest) + got
            if got:
                cut = buf.rfind(_NL, 0, total) + 1
                rest = bytes(buf[cut:total])
                if len(rest) > MAX_LINE_CHARS:
                    msg = (f'{self.origin}: {self.locate(first + buf.count(_NL, 0, cut))} is '
                           f'longer than {MAX_LINE_CHARS} characters: not a row of a DAQ '
                           'export (no line break)')
                    raise DataImportError(msg)
                if not cut:
                    continue
            elif not total:
                break
            else:
                cut, rest = total, b''
            data = memoryview(buf)[:cut]
            n_lines = (int(np.count_nonzero(np.frombuffer(data, np.uint8) == _NL[0]))
                       + (0 if buf[cut - 1] == _NL[0] else 1))
            cols = self._parse(data, n_lines, first, comments=buf.find(b'#', 0, cut) >= 0)
            n = cols['in'].size
            if n:
                yield RawChunk(first=first, time=cols.get('time'), theta_in=cols['in'],
                               theta_out=cols['out'], torque=cols.get('torque'),
                               out_heads=stack_heads(cols, self.options),
                               loss=stack_loss(cols, self.options))
                first += n
        if first == 0:
            msg = f'{self.origin}: no data rows after the header'
            raise DataImportError(msg)

    def _parse(self, data: memoryview, n_lines: int, first: int, *, comments: bool
               ) -> dict[str, np.ndarray]:
        """The block's columns by role (time as int64 for nanoseconds when it parses);
        ``comments``: the block holds a ``#`` (numpy's path reads comment lines)."""
        cols = self._load_arrow(data, comments=comments)
        if cols is None:
            try:
                text = str(data, 'utf-8')
            except UnicodeDecodeError as exc:
                msg = f'{self.origin}: cannot read near {self.locate(first)} ({exc})'
                raise DataImportError(msg) from None
            cols = self._load_numpy(text, first)
        n = cols['in'].size
        if n != n_lines and n:
            # blank or comment lines inside the block shift the line numbers from this
            # block on: only counted per block (rare in DAQ exports); kept by sample index,
            # as the import may read a block ahead of the one whose line it names
            self._line_shifts.append((first, n_lines - n))
        return cols

    @cached_property
    def _arrow(self) -> tuple[Any, Any, Any, list[str]] | None:
        """pyarrow's CSV module, its read and parse options and the column names to convert
        (None: every block takes the numpy path: no pyarrow, or columns split by blanks)."""
        if self.delimiter is None:
            return None      # runs of blanks: pyarrow splits on one character only
        try:
            import pyarrow.csv as pacsv
        except ImportError:
            return None
        names = [f'c{j}' for j in range(self._n_columns)]
        read = pacsv.ReadOptions(column_names=names, block_size=1 << 20)
        parse = pacsv.ParseOptions(delimiter=self.delimiter, quote_char='"')
        return pacsv, read, parse, sorted({names[j] for j in self._usecols})

    def _load_arrow(self, data: memoryview, *, comments: bool
                    ) -> dict[str, np.ndarray] | None:
        """The block parsed by pyarrow, or None when it cannot be (comment lines, a bad or
        missing cell, ...: the numpy path then reads it or names the cell)."""
        if self._arrow is None or comments:
            return None
        import pyarrow as pa

        pacsv, read, parse, names = self._arrow
        decimal = ',' if self._comma else '.'
        for int_time in ((True, False) if self._int_time else (False,)):
            types = {n: pa.float64() for n in names}
            if int_time:
                types[f'c{self.index["time"]}'] = pa.int64()
            conv = pacsv.ConvertOptions(column_types=types, include_columns=names,
                                        null_values=[''], decimal_point=decimal)
            try:
                table = pacsv.read_csv(pa.py_buffer(data), read_options=read,
                                       parse_options=parse, convert_options=conv)
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
                continue
            return {r: np.ascontiguousarray(table.column(f'c{j}').to_numpy())
                    for r, j in zip(self._roles, self._usecols, strict=True)}
        return None

    def _load_numpy(self, text: str, first: int) -> dict[str, np.ndarray]:
        """The block parsed by ``numpy.loadtxt``; a bad cell named (line, column)."""
        try:
            return self._load(text)
        except ValueError:
            # empty cells (pandas' NaN) are missing values; anything else is named
            pattern = _EMPTY_CELL.get(self.delimiter or '')
            try:
                if pattern is None:
                    raise ValueError
                return self._load(pattern.sub('nan', text))
            except ValueError:
                self._explain(text.splitlines(keepends=True), first)
                raise   # _explain always raises; kept for the type checker

    def _load(self, text: str) -> dict[str, np.ndarray]:
        if self._comma:
            text = text.replace(',', '.')
        if self._int_time:
            fields = [(r, np.int64 if r == 'time' else np.float64) for r in self._roles]
            try:
                rec = np.loadtxt(io.StringIO(text), delimiter=self.delimiter,
                                 usecols=self._usecols, comments='#', quotechar='"', ndmin=1,
                                 dtype=fields)
                return {r: np.ascontiguousarray(rec[r]) for r in self._roles}
            except ValueError:
                pass   # not integers (1.7e18, 12.5, nan): read as float64 below
        data = np.loadtxt(io.StringIO(text), delimiter=self.delimiter, usecols=self._usecols,
                          comments='#', quotechar='"', ndmin=2, dtype=np.float64)
        return {r: np.ascontiguousarray(data[:, k]) for k, r in enumerate(self._roles)}

    def _explain(self, lines: list[str], first: int) -> None:
        """Find the first bad cell of a chunk that numpy refused (error path only)."""
        for k, line in enumerate(lines):
            body = line.split('#', 1)[0].strip()
            if not body:
                continue
            cells = body.split(self.delimiter) if self.delimiter else body.split()
            for role, j in zip(self._roles, self._usecols, strict=True):
                if j >= len(cells):
                    msg = (f'{self.origin}: column {self.labels[role]!r}, '
                           f'{self.locate(first + k)}: missing (the line has {len(cells)} '
                           f'cells)')
                    raise DataImportError(msg)
                cell = cells[j].strip().strip('"')
                if not cell:
                    continue   # an empty cell is a missing value
                try:
                    float(cell.replace(',', '.') if self._comma else cell)
                except ValueError:
                    hint = ("; a decimal comma? read it with --decimal , (columns then by ';' "
                            'or tab)') if not self._comma and _DECIMAL_COMMA.match(cell) else ''
                    msg = (f'{self.origin}: column {self.labels[role]!r}, '
                           f'{self.locate(first + k)}: {cell!r} is not a number{hint}')
                    raise DataImportError(msg) from None
        msg = f'{self.origin}: unreadable rows near {self.locate(first)}'
        raise DataImportError(msg)

    def close(self) -> None:
        """Close the file."""
        self._file.close()
