"""The results store's tables (SQLAlchemy 2.0 declarative ORM).

``results``: one row per unit and test (unique ``record_key`` = test | plan | bag sha256);
``metrics``: its measured quantities (name with unit suffix, direction, SI value, limits,
verdict); ``lines``: its labelled spectral lines. Children are deleted with their result.
The schema is created and upgraded by the Alembic migrations in ``migrations/``; keep the
two in step (a test compares them).
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from sqlalchemy import (
    JSON,
    BigInteger,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship
from sqlalchemy.types import TypeDecorator

if TYPE_CHECKING:
    from sqlalchemy.engine import Dialect

__all__ = ['Base', 'LineRow', 'MetricRow', 'ResultRow', 'UtcDateTime']


class UtcDateTime(TypeDecorator[datetime]):
    """A UTC instant stored as a naive UTC timestamp (SQLite keeps no zone; PostgreSQL
    ``timestamp without time zone``), handed back timezone-aware (UTC)."""

    impl = DateTime
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            msg = f'naive datetime {value.isoformat()} given to the results store: use UTC'
            raise ValueError(msg)
        return value.astimezone(UTC).replace(tzinfo=None)

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        return None if value is None else value.replace(tzinfo=UTC)


class Base(DeclarativeBase):
    """Declarative base of the store's tables."""


class ResultRow(Base):
    """One unit tested once."""

    __tablename__ = 'results'

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    # test (32) | plan (128) | sha256 (64) = up to 226 characters (issue #21; 0002 widened it)
    record_key: Mapped[str] = mapped_column(String(256), unique=True, nullable=False)
    test: Mapped[str] = mapped_column(String(32), nullable=False)
    plan: Mapped[str] = mapped_column(String(128), nullable=False, default='')
    serial: Mapped[str | None] = mapped_column(String(128))
    lot: Mapped[str | None] = mapped_column(String(128))
    operator: Mapped[str | None] = mapped_column(String(128))
    bench_id: Mapped[str | None] = mapped_column(String(128))
    preset: Mapped[str | None] = mapped_column(String(128))
    reducer_type: Mapped[str | None] = mapped_column(String(16))
    tested_at: Mapped[datetime] = mapped_column(UtcDateTime(), nullable=False)
    analysed_at: Mapped[datetime] = mapped_column(UtcDateTime(), nullable=False)
    status: Mapped[str] = mapped_column(String(16), nullable=False)
    failure: Mapped[str | None] = mapped_column(Text)
    verdict: Mapped[str] = mapped_column(String(16), nullable=False)
    command: Mapped[str] = mapped_column(String(32), nullable=False)
    software_version: Mapped[str] = mapped_column(String(64), nullable=False)
    bag_path: Mapped[str] = mapped_column(Text, nullable=False)
    bag_sha256: Mapped[str] = mapped_column(String(64), nullable=False)
    bag_size_bytes: Mapped[int | None] = mapped_column(BigInteger)
    bag_mtime_ns: Mapped[int | None] = mapped_column(BigInteger)
    advice: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    details: Mapped[dict[str, Any] | None] = mapped_column(JSON)

    metrics: Mapped[list[MetricRow]] = relationship(
        back_populates='result', cascade='all, delete-orphan', passive_deletes=True,
        order_by='MetricRow.id')
    lines: Mapped[list[LineRow]] = relationship(
        back_populates='result', cascade='all, delete-orphan', passive_deletes=True,
        order_by='LineRow.id')

    __table_args__ = (
        Index('ix_results_serial', 'serial'),
        Index('ix_results_tested_at', 'tested_at'),
        Index('ix_results_preset', 'preset'),
        Index('ix_results_verdict', 'verdict'),
        Index('ix_results_bag_path', 'bag_path'),
    )


class MetricRow(Base):
    """One measured quantity of a result."""

    __tablename__ = 'metrics'

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    result_id: Mapped[int] = mapped_column(
        ForeignKey('results.id', ondelete='CASCADE'), nullable=False)
    name: Mapped[str] = mapped_column(String(64), nullable=False)
    direction: Mapped[str] = mapped_column(String(8), nullable=False)
    value: Mapped[float] = mapped_column(Float, nullable=False)
    limit_low: Mapped[float | None] = mapped_column(Float)
    limit_high: Mapped[float | None] = mapped_column(Float)
    verdict: Mapped[str | None] = mapped_column(String(16))
    u95: Mapped[float | None] = mapped_column(Float)
    uc: Mapped[float | None] = mapped_column(Float)

    result: Mapped[ResultRow] = relationship(back_populates='metrics')

    __table_args__ = (
        UniqueConstraint('result_id', 'name', 'direction', name='uq_metrics_result_name'),
        Index('ix_metrics_name', 'name', 'direction'),
    )


class LineRow(Base):
    """One labelled spectral line of a result."""

    __tablename__ = 'lines'

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    result_id: Mapped[int] = mapped_column(
        ForeignKey('results.id', ondelete='CASCADE'), nullable=False)
    label: Mapped[str] = mapped_column(String(64), nullable=False)
    output_order: Mapped[float | None] = mapped_column(Float)
    crank_order: Mapped[float | None] = mapped_column(Float)
    frequency_hz: Mapped[float | None] = mapped_column(Float)
    amplitude_rad: Mapped[float] = mapped_column(Float, nullable=False)
    phase_rad: Mapped[float | None] = mapped_column(Float)
    amplitude_u95_rad: Mapped[float | None] = mapped_column(Float)
    amplitude_uc_rad: Mapped[float | None] = mapped_column(Float)
    phase_u95_rad: Mapped[float | None] = mapped_column(Float)

    result: Mapped[ResultRow] = relationship(back_populates='lines')

    __table_args__ = (
        UniqueConstraint('result_id', 'label', name='uq_lines_result_label'),
        Index('ix_lines_label', 'label'),
    )
