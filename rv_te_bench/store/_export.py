"""Export records as a table: one row per record, one column per metric (CSV, Parquet).

Columns: the record's identity and conditions, then ``<metric>`` for the whole record and
``<metric>_cw`` / ``<metric>_ccw`` per direction (SI, the name carries the unit), then
``line_<label>_amplitude_rad`` per spectral line (labels made column-safe); beside each
value that has one, its expanded uncertainty U in ``<column>_u95``. Empty cells where a
record has no such value.

CSV is opened by spreadsheets, which run a cell starting with ``=``, ``+``, ``-``, ``@`` (or
a tab / carriage return) as a formula: such text cells (a serial, an operator, a failure
reason, a path) are written with a leading ``'`` (OWASP's CSV-injection rule); numbers are
written as numbers.
"""

from __future__ import annotations

import csv
import os
import re
from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import StoreError

if TYPE_CHECKING:
    from pathlib import Path

    from rv_te_bench.store._store import StoredResult

__all__ = ['export_records', 'records_table']

_BASE = ('id', 'serial', 'lot', 'operator', 'bench_id', 'preset', 'reducer_type', 'test',
         'plan', 'tested_at', 'analysed_at', 'status', 'verdict', 'failure', 'command',
         'software_version', 'bag_path', 'bag_sha256')


_FORMULA_START = ('=', '+', '-', '@', '\t', '\r')


def _csv_safe(v: object) -> object:
    """A text cell that a spreadsheet would run as a formula, quoted with a leading '."""
    if isinstance(v, str) and v.startswith(_FORMULA_START):
        return "'" + v
    return v


def _line_column(label: str) -> str:
    safe = re.sub(r'[^0-9A-Za-z]+', '_', label).strip('_').lower()
    return f'line_{safe}_amplitude_rad'


def _metric_column(name: str, direction: str) -> str:
    return name if direction == 'all' else f'{name}_{direction}'


def records_table(rows: list[StoredResult]) -> tuple[list[str], list[dict[str, Any]]]:
    """(columns, one dict per record) of the wide table."""
    metric_cols = sorted({_metric_column(n, d) for r in rows for (n, d) in r.metrics}
                         | {f'{_metric_column(n, d)}_u95' for r in rows for (n, d) in r.u95})
    line_cols = sorted({_line_column(lab) for r in rows for lab in r.lines}
                       | {f'{_line_column(lab)}_u95' for r in rows for lab, (u, _) in
                          r.line_u95.items() if u is not None})
    cols = list(_BASE) + metric_cols + line_cols
    table = []
    for r in rows:
        d: dict[str, Any] = {c: getattr(r, c) for c in _BASE}
        d['tested_at'] = r.tested_at.isoformat()
        d['analysed_at'] = r.analysed_at.isoformat()
        for (n, dirn), v in r.metrics.items():
            d[_metric_column(n, dirn)] = v
        for (n, dirn), u95 in r.u95.items():
            d[f'{_metric_column(n, dirn)}_u95'] = u95
        for lab, (amp, _phase) in r.lines.items():
            d[_line_column(lab)] = amp
        for lab, (u, _pu) in r.line_u95.items():
            if u is not None:
                d[f'{_line_column(lab)}_u95'] = u
        table.append(d)
    return cols, table


def export_records(rows: list[StoredResult], path: Path) -> int:
    """Write ``rows`` to ``path`` (.csv or .parquet, atomically). Returns the row count.

    Raises:
        StoreError: Unknown extension, or pyarrow missing for Parquet.
    """
    cols, table = records_table(rows)
    suffix = path.suffix.lower()
    tmp = path.with_name(f'.{path.name}.tmp-{os.getpid()}')
    try:
        if suffix == '.csv':
            with tmp.open('w', newline='', encoding='utf-8') as fh:
                w = csv.DictWriter(fh, fieldnames=cols, extrasaction='raise')
                w.writerow({c: _csv_safe(c) for c in cols})   # column names too
                w.writerows({k: _csv_safe(v) for k, v in row.items()} for row in table)
        elif suffix == '.parquet':
            try:
                import pyarrow as pa
                import pyarrow.parquet as pq
            except ModuleNotFoundError:
                msg = "Parquet export needs pyarrow: pip install 'rv-te-bench[parquet]'"
                raise StoreError(msg) from None
            arrays = {c: [row.get(c) for row in table] for c in cols}
            pq.write_table(pa.table(arrays), tmp)
        else:
            msg = f'export file {path.name!r}: use a .csv or .parquet name'
            raise StoreError(msg)
        os.replace(tmp, path)
    except OSError as exc:
        msg = f'cannot write {path}: {exc.strerror or exc}'
        raise StoreError(msg) from None
    finally:
        tmp.unlink(missing_ok=True)
    return len(table)
