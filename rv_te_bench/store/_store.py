"""The results store: open (and migrate), write a record, query, series for SPC.

SQLAlchemy 2.0 does the database access (one ORM for SQLite and PostgreSQL, parameters
bound, no SQL strings in the code) and Alembic the schema migrations (the store is
upgraded to the newest schema when opened; a store newer than the software is refused).
SQLite is the default: a file next to the bags, no server; PostgreSQL is given by URL.

Every write is one transaction: a process killed mid-write leaves either the old record or
the new one, never a record without its metrics.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy import Column, MetaData, String, Table, create_engine, event, inspect, select
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, IntegrityError, SQLAlchemyError
from sqlalchemy.orm import Session, selectinload

from rv_te_bench.errors import StoreError
from rv_te_bench.store._schema import LineRow, MetricRow, ResultRow

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

    from sqlalchemy import Select
    from sqlalchemy.engine import Engine
    from sqlalchemy.engine.interfaces import DBAPIConnection
    from sqlalchemy.pool import ConnectionPoolEntry

    from rv_te_bench.store.records import UnitRecord

__all__ = ['DEFAULT_DB_NAME', 'ResultFilter', 'ResultStore', 'Series', 'StoredResult',
           'open_store']

#: File name of the embedded (SQLite) store next to the bags.
DEFAULT_DB_NAME = 'rv-te-results.sqlite'
_MIGRATIONS = Path(__file__).resolve().parent / 'migrations'
#: The newest schema revision in migrations/versions (a test checks it is alembic's head,
#: so a new migration must move it): a store at it is opened without alembic.
SCHEMA_HEAD = '0002'
_VERSION_TABLE = Table('alembic_version', MetaData(), Column('version_num', String(32)))


@dataclass(frozen=True)
class ResultFilter:
    """Which records a query returns (None: no condition)."""

    serial: str | None = None
    since: datetime | None = None
    until: datetime | None = None
    verdict: str | None = None
    preset: str | None = None
    status: str | None = None
    lot: str | None = None
    test: str | None = None

    def __post_init__(self) -> None:
        for name in ('since', 'until'):
            v = getattr(self, name)
            if v is not None and v.tzinfo is None:
                msg = f'{name} must be timezone-aware, got {v.isoformat()}'
                raise StoreError(msg)


@dataclass(frozen=True)
class StoredResult:
    """A record as read back (SI values; metrics keyed by (name, direction))."""

    id: int
    test: str
    plan: str
    serial: str | None
    lot: str | None
    operator: str | None
    bench_id: str | None
    preset: str | None
    reducer_type: str | None
    tested_at: datetime
    analysed_at: datetime
    status: str
    failure: str | None
    verdict: str
    command: str
    software_version: str
    bag_path: str
    bag_sha256: str
    metrics: dict[tuple[str, str], float]
    limits: dict[tuple[str, str], tuple[float | None, float | None, str | None]]
    lines: dict[str, tuple[float, float | None]]
    advice: dict[str, Any] | None


@dataclass(frozen=True)
class Series:
    """One metric across units in test order (for control charts)."""

    metric: str
    direction: str
    values: list[float]
    serials: list[str | None]
    lots: list[str | None]
    tested_at: list[datetime]
    result_ids: list[int]


def _redact(url: str) -> str:
    try:
        return make_url(url).render_as_string(hide_password=True)
    except ArgumentError:
        return url[:200]


def _normalise_url(db: str | os.PathLike[str]) -> str:
    text = os.fspath(db)
    if '://' not in text:
        path = Path(text).expanduser()
        if not path.parent.is_dir():
            msg = f'results store {path}: folder {path.parent} does not exist'
            raise StoreError(msg)
        return f'sqlite:///{path.resolve()}'
    for prefix in ('postgresql://', 'postgres://'):
        if text.startswith(prefix):  # psycopg 3 is the driver we install
            return 'postgresql+psycopg://' + text[len(prefix):]
    return text


def _sqlite_pragmas(dbapi_conn: DBAPIConnection, _record: ConnectionPoolEntry) -> None:
    cur = dbapi_conn.cursor()
    cur.execute('PRAGMA foreign_keys=ON')
    cur.execute('PRAGMA journal_mode=WAL')
    cur.execute('PRAGMA synchronous=NORMAL')
    cur.close()


def _at_head(engine: Engine) -> bool:
    """True when the store's alembic_version is SCHEMA_HEAD (read without alembic)."""
    with engine.connect() as conn:
        if not inspect(conn).has_table(_VERSION_TABLE.name):
            return False
        return conn.execute(select(_VERSION_TABLE.c.version_num)).scalars().all() == [SCHEMA_HEAD]


def _migrate(engine: Engine, shown: str) -> None:
    if _at_head(engine):
        return   # the usual case, without alembic's import and script parsing (~0.15 s)
    from alembic import command
    from alembic.config import Config
    from alembic.runtime.migration import MigrationContext
    from alembic.script import ScriptDirectory
    cfg = Config()
    cfg.set_main_option('script_location', os.fspath(_MIGRATIONS))
    head = ScriptDirectory.from_config(cfg).get_current_head()
    with engine.begin() as conn:
        current = MigrationContext.configure(conn).get_current_revision()
        if current == head:
            return
        known = {s.revision for s in ScriptDirectory.from_config(cfg).walk_revisions()}
        if current is not None and current not in known:
            msg = (f'results store {shown} has schema revision {current!r}, newer than this '
                   f'rv-te knows (head {head!r}): upgrade rv-te-bench')
            raise StoreError(msg)
        cfg.attributes['connection'] = conn
        command.upgrade(cfg, 'head')


def open_store(db: str | os.PathLike[str]) -> ResultStore:
    """Open (creating or upgrading) the results store at a path (SQLite) or URL.

    Raises:
        StoreError: The database cannot be reached or its schema is newer than ours.
    """
    url = _normalise_url(db)
    shown = url[len('sqlite:///'):] if url.startswith('sqlite:///') else _redact(url)
    try:
        if url.startswith('sqlite'):
            engine = create_engine(url, connect_args={'timeout': 30.0})
            event.listen(engine, 'connect', _sqlite_pragmas)
        else:
            engine = create_engine(url, pool_pre_ping=True)
        _migrate(engine, shown)
    except ModuleNotFoundError as exc:
        msg = (f'results store {shown} needs the Python module {exc.name!r}'
               + (": pip install 'rv-te-bench[postgres]'" if 'psycopg' in str(exc.name) else ''))
        raise StoreError(msg) from None
    except (SQLAlchemyError, ArgumentError) as exc:
        detail = str(getattr(exc, 'orig', None) or exc).strip().splitlines()[0][:300]
        msg = f'cannot open results store {shown}: {detail}'
        raise StoreError(msg) from None
    return ResultStore(engine, shown)


def _row_values(rec: UnitRecord, now: datetime) -> dict[str, Any]:
    return {
        'record_key': rec.key, 'test': rec.test, 'plan': rec.plan, 'serial': rec.serial,
        'lot': rec.lot, 'operator': rec.operator, 'bench_id': rec.bench_id,
        'preset': rec.preset, 'reducer_type': rec.reducer_type, 'tested_at': rec.tested_at,
        'analysed_at': now, 'status': rec.status, 'failure': rec.failure,
        'verdict': rec.verdict, 'command': rec.command,
        'software_version': rec.software_version, 'bag_path': rec.bag_path,
        'bag_sha256': rec.bag_sha256, 'bag_size_bytes': rec.bag_size_bytes,
        'bag_mtime_ns': rec.bag_mtime_ns, 'advice': rec.advice, 'details': rec.details,
    }


def _opt(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


class ResultStore:
    """Records of units and tests in a SQLite file or a PostgreSQL database."""

    def __init__(self, engine: Engine, shown: str) -> None:
        self._engine = engine
        self.url = shown

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Release the connections."""
        self._engine.dispose()

    # ------------------------------------------------------------------ writing

    def upsert(self, record: UnitRecord) -> int:
        """Write a record in one transaction; the same key updates it. Returns its id."""
        for attempt in range(2):
            try:
                return self._upsert_once(record)
            except IntegrityError:
                if attempt:   # a concurrent writer inserted the same key: update it now
                    raise
            except SQLAlchemyError as exc:
                detail = str(getattr(exc, 'orig', None) or exc).strip().splitlines()[0][:300]
                msg = f'cannot write to results store {self.url}: {detail}'
                raise StoreError(msg) from None
        raise AssertionError  # pragma: no cover

    def _upsert_once(self, record: UnitRecord) -> int:
        now = datetime.now(tz=UTC)
        values = _row_values(record, now)
        with Session(self._engine) as s, s.begin():
            row = s.scalars(select(ResultRow).where(ResultRow.record_key == record.key)
                            .with_for_update()).one_or_none()
            if row is None:
                row = ResultRow(**values)
                s.add(row)
            else:
                for k, v in values.items():
                    setattr(row, k, v)
                row.metrics.clear()
                row.lines.clear()
                s.flush()     # the old children go before the new ones (unique keys)
            row.metrics.extend(
                MetricRow(name=m.name, direction=m.direction, value=float(m.value),
                          limit_low=_opt(m.limit_low), limit_high=_opt(m.limit_high),
                          verdict=m.verdict) for m in record.metrics)
            row.lines.extend(
                LineRow(label=ln.label, output_order=_opt(ln.output_order),
                        crank_order=_opt(ln.crank_order), frequency_hz=_opt(ln.frequency_hz),
                        amplitude_rad=float(ln.amplitude_rad), phase_rad=_opt(ln.phase_rad))
                for ln in record.lines)
            s.flush()
            return row.id

    # ------------------------------------------------------------------ reading

    def known_bags(self, *, test: str = 'te-analysis', plan: str = '',
                   ) -> dict[str, tuple[int | None, int | None, str, str]]:
        """bag_path -> (size, mtime_ns, status, bag sha256) of the records of ``test``/``plan``."""
        with Session(self._engine) as s:
            rows = s.execute(select(ResultRow.bag_path, ResultRow.bag_size_bytes,
                                    ResultRow.bag_mtime_ns, ResultRow.status,
                                    ResultRow.bag_sha256)
                             .where(ResultRow.test == test, ResultRow.plan == plan)).all()
        return {r[0]: (r[1], r[2], r[3], r[4]) for r in rows}

    def _where(self, stmt: Select[tuple[ResultRow]], f: ResultFilter) -> Select[tuple[ResultRow]]:
        conds = []
        for col, v in ((ResultRow.serial, f.serial), (ResultRow.verdict, f.verdict),
                       (ResultRow.preset, f.preset), (ResultRow.status, f.status),
                       (ResultRow.lot, f.lot), (ResultRow.test, f.test)):
            if v is not None:
                conds.append(col == v)
        if f.since is not None:
            conds.append(ResultRow.tested_at >= f.since)
        if f.until is not None:
            conds.append(ResultRow.tested_at < f.until)
        return stmt.where(*conds) if conds else stmt

    def query(self, flt: ResultFilter | None = None) -> list[StoredResult]:
        """Records matching ``flt``, in test order (tested_at, then id)."""
        flt = flt or ResultFilter()
        stmt = self._where(select(ResultRow), flt).options(
            selectinload(ResultRow.metrics), selectinload(ResultRow.lines)).order_by(
            ResultRow.tested_at, ResultRow.id)
        try:
            with Session(self._engine) as s:
                return [_stored(r) for r in s.scalars(stmt)]
        except SQLAlchemyError as exc:
            detail = str(getattr(exc, 'orig', None) or exc).strip().splitlines()[0][:300]
            msg = f'cannot read results store {self.url}: {detail}'
            raise StoreError(msg) from None

    def series(self, metric: str, *, direction: str = 'all',
               flt: ResultFilter | None = None) -> Series:
        """One metric across units in test order; ``line:LABEL`` for a line amplitude.

        Records without the metric (failed analyses, tests that did not measure it) are
        left out.
        """
        rows = self.query(flt)
        vals, serials, lots, when, ids = [], [], [], [], []
        for r in rows:
            if metric.startswith('line:'):
                hit = r.lines.get(metric[5:])
                v = None if hit is None else hit[0]
            else:
                v = r.metrics.get((metric, direction))
            if v is None:
                continue
            vals.append(v)
            serials.append(r.serial)
            lots.append(r.lot)
            when.append(r.tested_at)
            ids.append(r.id)
        return Series(metric, direction, vals, serials, lots, when, ids)

    def metric_names(self) -> list[tuple[str, str]]:
        """The (name, direction) pairs present in the store, sorted."""
        with Session(self._engine) as s:
            rows = s.execute(select(MetricRow.name, MetricRow.direction).distinct()).all()
        return sorted((r[0], r[1]) for r in rows)

    def line_labels(self) -> list[str]:
        """The spectral line labels present in the store, sorted."""
        with Session(self._engine) as s:
            return sorted(s.scalars(select(LineRow.label).distinct()))


def _stored(r: ResultRow) -> StoredResult:
    return StoredResult(
        id=r.id, test=r.test, plan=r.plan, serial=r.serial, lot=r.lot, operator=r.operator,
        bench_id=r.bench_id, preset=r.preset, reducer_type=r.reducer_type,
        tested_at=r.tested_at, analysed_at=r.analysed_at, status=r.status,
        failure=r.failure, verdict=r.verdict, command=r.command,
        software_version=r.software_version, bag_path=r.bag_path, bag_sha256=r.bag_sha256,
        metrics={(m.name, m.direction): m.value for m in r.metrics},
        limits={(m.name, m.direction): (m.limit_low, m.limit_high, m.verdict)
                for m in r.metrics},
        lines={ln.label: (ln.amplitude_rad, ln.phase_rad) for ln in r.lines},
        advice=r.advice)


def upsert_all(store: ResultStore, records: Iterable[UnitRecord]) -> list[int]:
    """Write several records, each in its own transaction (ids in order)."""
    return [store.upsert(r) for r in records]


def default_db_for(bags: Sequence[Path]) -> Path:
    """The embedded store next to the bags: their common parent folder."""
    parents = [os.fspath(Path(b).resolve().parent) for b in bags]
    return Path(os.path.commonpath(parents)) / DEFAULT_DB_NAME
