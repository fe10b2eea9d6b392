"""The results store: one record per unit and test, across units and over time.

``open_store(path_or_url)`` opens (and migrates) a SQLite file or a PostgreSQL database;
``ResultStore.upsert(UnitRecord)`` writes one record in one transaction (the same bag and
test again updates it); ``query``/``series`` read them back for ``rv-te results`` and
``rv-te spc``. No rclpy here.
"""

from __future__ import annotations

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

__all__ = ['DEFAULT_DB_NAME', 'DEFAULT_STORE_NAME', 'LineValue', 'MetricValue', 'ResultFilter',
           'ResultStore', 'Series', 'StoredResult', 'UnitRecord', 'bag_fingerprint', 'bag_probe',
           'bag_stat', 'default_db_for', 'default_store_path', 'export_records',
           'failed_record', 'open_store', 'records_from_analysis_json', 'records_table',
           'redact_url', 'upsert_all']
