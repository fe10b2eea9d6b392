"""The results store: one record per unit and test, across units and over time.

``open_store(path_or_url)`` opens (and migrates) a SQLite file or a PostgreSQL database;
``ResultStore.upsert(UnitRecord)`` writes one record in one transaction (the same bag and
test again updates it); ``query``/``series`` read them back for ``rv-te results`` and
``rv-te spc``. No rclpy here.

The records (``records``) are imported with the package; the database side (``_store``:
SQLAlchemy, ~0.3 CPU s to import) and the export only when one of their names is first
used: a fleet worker makes records and never opens the store (issue 41: its fork server
imports what the workers need, once per run).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from rv_te_bench.store.records import (
    LineValue,
    MetricValue,
    UnitRecord,
    bag_fingerprint,
    bag_probe,
    bag_stat,
    failed_record,
    records_from_analysis_json,
)

if TYPE_CHECKING:
    from rv_te_bench.store._export import export_records, records_table
    from rv_te_bench.store._store import (
        DEFAULT_DB_NAME,
        DEFAULT_STORE_NAME,
        ResultFilter,
        ResultStore,
        Series,
        StoredResult,
        default_db_for,
        default_store_path,
        open_store,
        redact_url,
        upsert_all,
    )

__all__ = ['DEFAULT_DB_NAME', 'DEFAULT_STORE_NAME', 'LineValue', 'MetricValue', 'ResultFilter',
           'ResultStore', 'Series', 'StoredResult', 'UnitRecord', 'bag_fingerprint', 'bag_probe',
           'bag_stat', 'default_db_for', 'default_store_path', 'export_records',
           'failed_record', 'open_store', 'records_from_analysis_json', 'records_table',
           'redact_url', 'upsert_all']

_LAZY = dict.fromkeys(('export_records', 'records_table'), '_export') | dict.fromkeys(
    ('DEFAULT_DB_NAME', 'DEFAULT_STORE_NAME', 'ResultFilter', 'ResultStore', 'Series',
     'StoredResult', 'default_db_for', 'default_store_path', 'open_store', 'redact_url',
     'upsert_all'), '_store')


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        msg = f'module {__name__!r} has no attribute {name!r}'
        raise AttributeError(msg)
    value = getattr(importlib.import_module(f'{__name__}.{module}'), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
