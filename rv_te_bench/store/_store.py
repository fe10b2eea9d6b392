"""The results store: open (and migrate), write a record, query, series for SPC.

SQLAlchemy 2.0 does the database access (one ORM for SQLite and PostgreSQL, parameters
bound, no SQL strings in the code) and Alembic the schema migrations (the store is
upgraded to the newest schema when opened; a store newer than the software is refused).
SQLite is the default: a file next to the bags, no server; PostgreSQL is given by URL.

Every write is one transaction: a process killed mid-write leaves either the old record or
the new one, never a record without its metrics. Creating or upgrading the schema is one
transaction too, under the database's own lock (SQLite ``BEGIN IMMEDIATE``, a PostgreSQL
advisory lock): concurrent first writers wait for each other instead of failing.

Reading commands open a store with ``create=False``: a database that is not a store is
refused untouched (no tables made, not switched to WAL), and a SQLite store is opened
read-only (also in a folder that cannot be written).

Passwords never leave this module: :func:`redact_url` hides them in every URL shown, also
in a malformed one, and error messages are scrubbed of them.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy import (
    Column,
    MetaData,
    String,
    Table,
    create_engine,
    event,
    func,
    inspect,
    select,
    text,
)
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, IntegrityError, SQLAlchemyError
from sqlalchemy.orm import Session, selectinload

from rv_te_bench.errors import StoreError
from rv_te_bench.store._schema import LineRow, MetricRow, ResultRow

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence
    from types import ModuleType

    from alembic.config import Config
    from alembic.runtime.migration import MigrationContext
    from alembic.script import ScriptDirectory
    from sqlalchemy import Select
    from sqlalchemy.engine import Connection, Engine
    from sqlalchemy.engine.interfaces import DBAPIConnection
    from sqlalchemy.pool import ConnectionPoolEntry

    from rv_te_bench.store.records import UnitRecord

__all__ = ['DEFAULT_DB_NAME', 'DEFAULT_STORE_NAME', 'ResultFilter', 'ResultStore', 'Series',
           'StoredResult', 'default_store_path', 'open_store', 'redact_url']

#: File name of an embedded (SQLite) store kept next to bags (``default_db_for``).
DEFAULT_DB_NAME = 'rv-te-results.sqlite'
#: File name of the user's default store (:func:`default_store_path`).
DEFAULT_STORE_NAME = 'results.sqlite'
_MIGRATIONS = Path(__file__).resolve().parent / 'migrations'
#: The newest schema revision in migrations/versions (a test checks it is alembic's head,
#: so a new migration must move it): a store at it is opened without alembic.
SCHEMA_HEAD = '0003'
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
    u95: dict[tuple[str, str], float] = field(default_factory=dict)
    uc: dict[tuple[str, str], float] = field(default_factory=dict)
    line_u95: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    line_uc: dict[str, float] = field(default_factory=dict)


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
    u95: list[float | None] = field(default_factory=list)
    uc: list[float | None] = field(default_factory=list)


#: scheme://user:PASSWORD@host... (the password runs to the last '@', as SQLAlchemy reads it)
_USERINFO = re.compile(r'^(?P<head>[A-Za-z][A-Za-z0-9+.\-]*://[^:/@?#]*):(?P<pw>.*)@(?P<tail>[^@]*)$',
                       re.DOTALL)
_QUERY_PW = re.compile(r'(?i)(password=)[^&]*')
#: the advisory lock key of schema changes on PostgreSQL (any constant shared by all rv-te)
_PG_LOCK_KEY = 0x72762D7465   # 'rv-te'


def _password(url: str) -> str | None:
    """The password in ``url`` (None without one), read the way SQLAlchemy reads it."""
    m = _USERINFO.match(url)
    if m and m.group('pw'):
        return m.group('pw')
    try:
        return make_url(url).password
    except (ArgumentError, ValueError):
        return None


def redact_url(url: str) -> str:
    """``url`` with its password (userinfo or ``password=`` query) shown as ``***``; a path
    or a URL without one unchanged; a malformed URL never shows it either."""
    m = _USERINFO.match(url)
    out = f'{m.group("head")}:***@{m.group("tail")}' if m and m.group('pw') else url
    return _QUERY_PW.sub(r'\1***', out)[:300]


def _scrub(message: str, url: str) -> str:
    """An error message with the URL's password (if the driver echoed it) replaced."""
    pw = _password(url)
    if pw:
        message = message.replace(pw, '***')
    return _QUERY_PW.sub(r'\1***', message)


def _normalise_url(db: str | os.PathLike[str], *, create: bool) -> str:
    text = os.fspath(db)
    if '://' not in text:
        path = Path(text).expanduser()
        if not path.parent.is_dir():
            msg = f'results store {path}: folder {path.parent} does not exist'
            raise StoreError(msg)
        if not create and not path.is_file():
            msg = f'no results store at {path}'
            raise StoreError(msg)
        return f'sqlite:///{path.resolve()}'
    try:
        url = make_url(text)
    except (ArgumentError, ValueError):
        msg = f'results store URL {redact_url(text)!r} is not a database URL'
        raise StoreError(msg) from None
    if url.get_backend_name() == 'sqlite':
        name = url.database or ''
        if name in ('', ':memory:') or 'memory' in str(url.query.get('mode', '')):
            msg = (f'results store {redact_url(text)}: an in-memory SQLite database keeps '
                   'nothing; give a file (--db results.sqlite)')
            raise StoreError(msg)
        return text
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


def _sqlite_readonly(dbapi_conn: DBAPIConnection, _record: ConnectionPoolEntry) -> None:
    cur = dbapi_conn.cursor()
    cur.execute('PRAGMA query_only=ON')
    cur.close()


def _revision(conn: Connection) -> list[str] | None:
    """The store's alembic_version rows, None when the table is missing."""
    if not inspect(conn).has_table(_VERSION_TABLE.name):
        return None
    return list(conn.execute(select(_VERSION_TABLE.c.version_num)).scalars().all())


def _at_head(engine: Engine) -> bool:
    """True when the store's alembic_version is SCHEMA_HEAD (read without alembic)."""
    with engine.connect() as conn:
        return _revision(conn) == [SCHEMA_HEAD]


def _lock_schema(conn: Connection) -> None:
    """Take the database's lock for a schema change (held to the end of the transaction)."""
    if conn.dialect.name == 'sqlite':
        # pysqlite would begin lazily (and run DDL outside a transaction): begin ourselves
        conn.exec_driver_sql('BEGIN IMMEDIATE')
    elif conn.dialect.name == 'postgresql':
        conn.execute(text('SELECT pg_advisory_xact_lock(:k)'), {'k': _PG_LOCK_KEY})


def _migrate(engine: Engine, shown: str) -> None:
    """Bring the store to the newest schema: one transaction under the schema lock, so that
    concurrent first writers wait and then find it done."""
    if _at_head(engine):
        return   # the usual case, without alembic's import and script parsing (~0.15 s)
    from alembic import command
    from alembic.config import Config
    from alembic.runtime.migration import MigrationContext
    from alembic.script import ScriptDirectory
    cfg = Config()
    cfg.set_main_option('script_location', os.fspath(_MIGRATIONS))
    script = ScriptDirectory.from_config(cfg)
    head = script.get_current_head()
    with engine.connect() as conn:
        if conn.dialect.name == 'sqlite':
            conn = conn.execution_options(isolation_level='AUTOCOMMIT')   # BEGIN is ours
            _lock_schema(conn)
            raw = conn.connection.dbapi_connection
            try:
                _upgrade(conn, cfg, script, head, shown, MigrationContext, command)
            except BaseException:
                if getattr(raw, 'in_transaction', True):
                    conn.exec_driver_sql('ROLLBACK')
                raise
            if getattr(raw, 'in_transaction', True):   # (alembic may have committed it)
                conn.exec_driver_sql('COMMIT')
        else:
            with conn.begin():
                _lock_schema(conn)
                _upgrade(conn, cfg, script, head, shown, MigrationContext, command)


def _upgrade(conn: Connection, cfg: Config, script: ScriptDirectory, head: str | None,
             shown: str, migration_context: type[MigrationContext], command: ModuleType,
             ) -> None:
    current = migration_context.configure(conn).get_current_revision()
    if current == head:
        return   # another process did it while we waited for the lock
    known = {s.revision for s in script.walk_revisions()}
    if current is not None and current not in known:
        msg = (f'results store {shown} has schema revision {current!r}, newer than this '
               f'rv-te knows (head {head!r}): upgrade rv-te-bench')
        raise StoreError(msg)
    cfg.attributes['connection'] = conn
    command.upgrade(cfg, 'head')


def _readonly_engine(url: str) -> Engine:
    """A read-only engine on a SQLite store (never created, never switched to WAL); in a
    folder this process cannot write, SQLite's ``immutable`` mode (no lock files)."""
    path = url[len('sqlite:///'):]
    folder = os.path.dirname(path) or '.'
    flags = 'mode=ro' if os.access(folder, os.W_OK) else 'mode=ro&immutable=1'
    engine = create_engine(f'sqlite:///file:{path}?{flags}&uri=true',
                           connect_args={'timeout': 30.0})
    event.listen(engine, 'connect', _sqlite_readonly)
    return engine


def open_store(db: str | os.PathLike[str], *, create: bool = True) -> ResultStore:
    """Open the results store at a path (SQLite) or URL.

    Args:
        db: A SQLite file or a database URL.
        create: Create the store or upgrade its schema as needed (the writing commands).
            False (``results``, ``spc``): the database must already be a store; it is not
            changed, and a SQLite store is opened read-only.

    Raises:
        StoreError: The database cannot be reached, is not a store (``create=False``), is
            an in-memory SQLite database, or its schema is newer than ours. The message
            never shows a password.
    """
    url = _normalise_url(db, create=create)
    shown = url[len('sqlite:///'):] if url.startswith('sqlite:///') else redact_url(url)
    try:
        if url.startswith('sqlite') and not create:
            engine = _readonly_engine(url)
            with engine.connect() as conn:
                rev = _revision(conn)
            if rev is None:
                engine.dispose()
                msg = (f'{shown} is not a results store (it has no alembic_version table); '
                       'nothing was changed')
                raise StoreError(msg)
            if rev != [SCHEMA_HEAD]:
                engine.dispose()   # an older store: upgraded by opening it to write
                return open_store(db, create=True)
            return ResultStore(engine, shown)
        if url.startswith('sqlite'):
            engine = create_engine(url, connect_args={'timeout': 30.0})
            event.listen(engine, 'connect', _sqlite_pragmas)
        else:
            engine = create_engine(url, pool_pre_ping=True)
        if not create:
            with engine.connect() as conn:
                if _revision(conn) is None:
                    engine.dispose()
                    msg = (f'{shown} is not a results store (it has no alembic_version '
                           'table); nothing was changed')
                    raise StoreError(msg)
        _migrate(engine, shown)
    except ModuleNotFoundError as exc:
        msg = (f'results store {shown} needs the Python module {exc.name!r}'
               + (": pip install 'rv-te-bench[postgres]'" if 'psycopg' in str(exc.name) else ''))
        raise StoreError(msg) from None
    except (SQLAlchemyError, ArgumentError, ValueError) as exc:
        detail = str(getattr(exc, 'orig', None) or exc).strip().splitlines()[0][:300]
        msg = f'cannot open results store {shown}: {_scrub(detail, url)}'
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


#: Identity a record keeps when a rewrite of it does not say (None): a bag analysed again
#: without --serial keeps the serial an earlier --serial gave it.
_KEPT_WHEN_MISSING = frozenset({'serial', 'lot', 'operator'})


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
        return self.upsert_many([record])[0]

    def upsert_many(self, records: Sequence[UnitRecord]) -> list[int]:
        """Write records in one transaction (all of them or none), each as :meth:`upsert`
        writes it (the same key updates it; a later record of the same key updates the
        earlier one). Returns their ids in order."""
        if not records:
            return []
        for attempt in range(2):
            try:
                return self._upsert_once(records)
            except IntegrityError as exc:
                if attempt:   # a concurrent writer inserted the same key: update it now
                    detail = str(getattr(exc, 'orig', None) or exc).strip().splitlines()[0]
                    msg = f'cannot write to results store {self.url}: {detail[:300]}'
                    raise StoreError(msg) from None
            except SQLAlchemyError as exc:
                detail = str(getattr(exc, 'orig', None) or exc).strip().splitlines()[0][:300]
                msg = f'cannot write to results store {self.url}: {detail}'
                raise StoreError(msg) from None
        raise AssertionError  # pragma: no cover

    def _upsert_once(self, records: Sequence[UnitRecord]) -> list[int]:
        now = datetime.now(tz=UTC)
        with Session(self._engine) as s, s.begin():
            keys = list(dict.fromkeys(r.key for r in records))
            found = {row.record_key: row for row in s.scalars(
                select(ResultRow).where(ResultRow.record_key.in_(keys)).with_for_update())}
            out = []
            for record in records:
                values = _row_values(record, now)
                row = found.get(record.key)
                if row is None:
                    row = found[record.key] = ResultRow(**values)
                    s.add(row)
                else:
                    for k, v in values.items():
                        if v is None and k in _KEPT_WHEN_MISSING:
                            continue   # a re-analysis without --serial keeps the serial given
                        setattr(row, k, v)
                    row.metrics.clear()
                    row.lines.clear()
                    s.flush()     # the old children go before the new ones (unique keys)
                row.metrics.extend(
                    MetricRow(name=m.name, direction=m.direction, value=float(m.value),
                              limit_low=_opt(m.limit_low), limit_high=_opt(m.limit_high),
                              verdict=m.verdict, u95=_opt(m.u95), uc=_opt(m.uc))
                    for m in record.metrics)
                row.lines.extend(
                    LineRow(label=ln.label, output_order=_opt(ln.output_order),
                            crank_order=_opt(ln.crank_order),
                            frequency_hz=_opt(ln.frequency_hz),
                            amplitude_rad=float(ln.amplitude_rad), phase_rad=_opt(ln.phase_rad),
                            amplitude_u95_rad=_opt(ln.amplitude_u95_rad),
                            amplitude_uc_rad=_opt(ln.amplitude_uc_rad),
                            phase_u95_rad=_opt(ln.phase_u95_rad))
                    for ln in record.lines)
                out.append(row)
            s.flush()
            return [row.id for row in out]

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

    def _where(self, stmt: Select[ResultRow], f: ResultFilter) -> Select[ResultRow]:
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
        us: list[float | None] = []
        ucs: list[float | None] = []
        for r in rows:
            if metric.startswith('line:'):
                hit = r.lines.get(metric[5:])
                v = None if hit is None else hit[0]
                u = (r.line_u95.get(metric[5:]) or (None, None))[0]
                uc = r.line_uc.get(metric[5:])
            else:
                v = r.metrics.get((metric, direction))
                u = r.u95.get((metric, direction))
                uc = r.uc.get((metric, direction))
            if v is None:
                continue
            vals.append(v)
            us.append(u)
            ucs.append(uc)
            serials.append(r.serial)
            lots.append(r.lot)
            when.append(r.tested_at)
            ids.append(r.id)
        return Series(metric, direction, vals, serials, lots, when, ids, us, ucs)

    def count(self) -> int:
        """How many records the store holds."""
        try:
            with Session(self._engine) as s:
                return int(s.scalar(select(func.count()).select_from(ResultRow)) or 0)
        except SQLAlchemyError as exc:
            detail = str(getattr(exc, 'orig', None) or exc).strip().splitlines()[0][:300]
            msg = f'cannot read results store {self.url}: {detail}'
            raise StoreError(msg) from None

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
        advice=r.advice,
        u95={(m.name, m.direction): m.u95 for m in r.metrics if m.u95 is not None},
        uc={(m.name, m.direction): m.uc for m in r.metrics if m.uc is not None},
        line_u95={ln.label: (ln.amplitude_u95_rad, ln.phase_u95_rad) for ln in r.lines
                  if ln.amplitude_u95_rad is not None or ln.phase_u95_rad is not None},
        line_uc={ln.label: ln.amplitude_uc_rad for ln in r.lines
                 if ln.amplitude_uc_rad is not None})


def upsert_all(store: ResultStore, records: Iterable[UnitRecord]) -> list[int]:
    """Write several records, each in its own transaction (ids in order)."""
    return [store.upsert(r) for r in records]


def default_db_for(bags: Sequence[Path]) -> Path:
    """An embedded store next to the bags: their common parent folder (not the default:
    :func:`default_store_path` is; kept for callers that want one store per folder)."""
    parents = [os.fspath(Path(b).resolve().parent) for b in bags]
    return Path(os.path.commonpath(parents)) / DEFAULT_DB_NAME


def default_store_path() -> Path:
    """The user's one results store: ``$XDG_DATA_HOME/rv-te/results.sqlite``, by default
    ``~/.local/share/rv-te/results.sqlite`` (the XD Base Directory place for a user's data,
    as platformdirs' ``user_data_path`` gives on Linux). ``$RV_TE_DB`` or ``--db`` choose
    another (the commands' ``rv_te_bench.cli._db``)."""
    xdg = os.environ.get('XDG_DATA_HOME', '')
    base = Path(xdg) if xdg and Path(xdg).is_absolute() else Path.home() / '.local' / 'share'
    return base / 'rv-te' / DEFAULT_STORE_NAME
