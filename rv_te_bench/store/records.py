"""What the results store keeps: one record per unit and test, with metrics and lines.

A record is written by ``rv-te analyze``, ``rv-te fleet analyze`` and ``rv-te test``. Its
key is (test, plan, bag content hash): the same bag analysed again updates its record
instead of adding one. Values are SI (radians, N m, N m/rad), names carry the unit suffix;
arcmin appears only where results are shown.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

from rv_te_bench.errors import StoreError

__all__ = ['DIRECTIONS', 'FIELD_MAX_CHARS', 'LineValue', 'MetricValue', 'UnitRecord',
           'bag_fingerprint', 'bag_probe',
           'bag_stat', 'failed_record', 'records_from_analysis_json']

Direction = Literal['all', 'cw', 'ccw']
Verdict = Literal['pass', 'fail', 'indeterminate', 'not-measured', 'not-judged']
Status = Literal['ok', 'partial', 'failed']
DIRECTIONS: tuple[str, ...] = ('all', 'cw', 'ccw')
_VERDICTS = ('pass', 'fail', 'indeterminate', 'not-measured', 'not-judged')
_STATUSES = ('ok', 'partial', 'failed')
_HASH_CHUNK = 1 << 20
#: Bytes read from each end of each file by :func:`bag_probe`.
PROBE_BYTES = 1 << 16
# The store's column widths (rv_te_bench/store/_schema.py): SQLite ignores them, PostgreSQL
# refuses a longer value ('value too long'); a record is checked here so that both stores
# take exactly the same records (issue #21).
FIELD_MAX_CHARS: dict[str, int] = {
    'test': 32, 'plan': 128, 'serial': 128, 'lot': 128, 'operator': 128, 'bench_id': 128,
    'preset': 128, 'reducer_type': 16, 'command': 32, 'software_version': 64,
}


@dataclass(frozen=True, slots=True)
class MetricValue:
    """One measured quantity of a unit (SI value; the name carries the unit suffix)."""

    name: str
    value: float
    direction: Direction = 'all'
    limit_low: float | None = None
    limit_high: float | None = None
    verdict: Verdict | None = None
    u95: float | None = None
    uc: float | None = None

    def __post_init__(self) -> None:
        if not self.name or len(self.name) > 64:
            msg = f'metric name must be 1-64 characters, got {self.name[:80]!r}'
            raise StoreError(msg)
        if self.direction not in DIRECTIONS:
            msg = (f'metric {self.name}: direction must be one of {DIRECTIONS}, '
                   f'got {self.direction!r}')
            raise StoreError(msg)
        if not math.isfinite(self.value):
            msg = f'metric {self.name}: value must be finite, got {self.value!r}'
            raise StoreError(msg)
        for what in ('u95', 'uc'):
            u = getattr(self, what)
            if u is not None and not (math.isfinite(u) and u >= 0):
                msg = f'metric {self.name}: {what} must be finite and >= 0, got {u!r}'
                raise StoreError(msg)
        if self.verdict is not None and self.verdict not in _VERDICTS:
            msg = f'metric {self.name}: verdict must be one of {_VERDICTS}, got {self.verdict!r}'
            raise StoreError(msg)


@dataclass(frozen=True, slots=True)
class LineValue:
    """One labelled spectral line (amplitude [rad] of TE, phase [rad])."""

    label: str
    amplitude_rad: float
    output_order: float | None = None
    crank_order: float | None = None
    frequency_hz: float | None = None
    phase_rad: float | None = None
    amplitude_u95_rad: float | None = None
    amplitude_uc_rad: float | None = None
    phase_u95_rad: float | None = None

    def __post_init__(self) -> None:
        if not self.label or len(self.label) > 64:
            msg = (f'line label must be 1-64 characters, got {len(self.label)}: '
                   f'{self.label[:40]!r}')
            raise StoreError(msg)


def _storable(text: str) -> str:
    """``text`` with surrogates (bytes of a non-UTF-8 path) as ``\\xNN``: a database takes
    UTF-8 only, and the escape keeps two such paths apart (issue #16)."""
    return text.encode('utf-8', 'surrogateescape').decode('utf-8', 'backslashreplace')


@dataclass(frozen=True)
class UnitRecord:
    """One unit tested once (one bag, one test).

    Attributes:
        test: What was run: 'te-analysis' (rv-te analyze / fleet) or 'test-plan' (rv-te test).
        plan: The test plan's name ('' for an analysis).
        bag_path: Where the bag was when it was analysed.
        bag_sha256: Content hash of the bag (the record's identity with test and plan).
        serial: Unit serial number (None when the bag does not say).
        tested_at: When the unit was measured (the bag's start), timezone-aware.
        status: 'ok', 'partial' (a damaged bag analysed in part) or 'failed'.
        failure: The one-line reason of a failed analysis.
        verdict: 'pass' / 'fail' against a tolerance profile, or 'not-judged'.
        advice: The recommendation (JSON-able dict) or None.
        details: Test conditions and anything else worth keeping (JSON-able).
    """

    test: str
    bag_path: str
    bag_sha256: str
    tested_at: datetime
    plan: str = ''
    serial: str | None = None
    lot: str | None = None
    bench_id: str | None = None
    preset: str | None = None
    reducer_type: str | None = None
    operator: str | None = None
    status: Status = 'ok'
    failure: str | None = None
    verdict: Verdict = 'not-judged'
    command: str = 'analyze'
    software_version: str = ''
    bag_size_bytes: int | None = None
    bag_mtime_ns: int | None = None
    metrics: tuple[MetricValue, ...] = ()
    lines: tuple[LineValue, ...] = ()
    advice: dict[str, Any] | None = None
    details: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ('bag_path', 'plan', 'serial', 'lot', 'bench_id', 'preset', 'reducer_type',
                     'operator', 'failure', 'command', 'software_version'):
            value = getattr(self, name)
            if isinstance(value, str):   # undecodable bytes of a path or argument: \xNN
                object.__setattr__(self, name, _storable(value))
        for name, limit in FIELD_MAX_CHARS.items():
            value = getattr(self, name)
            if isinstance(value, str) and len(value) > limit:
                shown = value[:40] + '...' if len(value) > 40 else value
                msg = (f'{name} is {len(value)} characters, the results store keeps at most '
                       f'{limit}: {shown!r}')
                raise StoreError(msg)
        if self.test not in ('te-analysis', 'test-plan'):
            msg = f"test must be 'te-analysis' or 'test-plan', got {self.test!r}"
            raise StoreError(msg)
        if len(self.bag_sha256) != 64 or any(c not in '0123456789abcdef' for c in self.bag_sha256):
            msg = f'bag_sha256 must be 64 lower-case hex digits, got {self.bag_sha256[:80]!r}'
            raise StoreError(msg)
        if self.tested_at.tzinfo is None:
            msg = 'tested_at must be timezone-aware (UTC)'
            raise StoreError(msg)
        if self.status not in _STATUSES:
            msg = f'status must be one of {_STATUSES}, got {self.status!r}'
            raise StoreError(msg)
        if self.verdict not in _VERDICTS:
            msg = f'verdict must be one of {_VERDICTS}, got {self.verdict!r}'
            raise StoreError(msg)
        keys = [(m.name, m.direction) for m in self.metrics]
        if len(set(keys)) != len(keys):
            msg = f'metrics repeat a (name, direction): {sorted(keys)}'
            raise StoreError(msg)
        labels = [ln.label for ln in self.lines]
        if len(set(labels)) != len(labels):
            msg = f'lines repeat a label: {labels}'
            raise StoreError(msg)

    @property
    def key(self) -> str:
        """The record's identity: same test, plan and bag content -> same record."""
        return f'{self.test}|{self.plan}|{self.bag_sha256}'


def _bag_files(bag: Path) -> list[Path]:
    if bag.is_file():
        return [bag]
    if not bag.is_dir():
        msg = f'{bag}: no such bag folder or file'
        raise StoreError(msg)
    return sorted(p for p in bag.iterdir()
                  if p.is_file() and (p.suffix in ('.mcap', '.db3') or p.name == 'metadata.yaml'))


def bag_fingerprint(bag: Path) -> tuple[str, int, int]:
    """(sha256 of the bag's files, total size [bytes], newest mtime [ns]).

    The hash covers every .mcap/.db3 file and metadata.yaml, each preceded by its name,
    so a renamed folder keeps its identity and a changed file does not.
    """
    h = hashlib.sha256()
    size = 0
    mtime = 0
    for f in _bag_files(bag):
        st = f.stat()
        size += st.st_size
        mtime = max(mtime, st.st_mtime_ns)
        h.update(f.name.encode('utf-8', 'surrogateescape') + b'\0')
        with f.open('rb') as fh:
            while chunk := fh.read(_HASH_CHUNK):
                h.update(chunk)
    return h.hexdigest(), size, mtime


def bag_probe(bag: Path) -> str:
    """sha256 of each file's name, size, first and last PROBE_BYTES: equal for two copies of
    a bag, different for two recordings of the same size (their first and last messages
    differ), read in a few hundred kB where :func:`bag_fingerprint` reads everything.

    Only ever used to tell bags apart: bags with equal probes are compared by
    :func:`bag_fingerprint`.
    """
    h = hashlib.sha256()
    for f in _bag_files(bag):
        with f.open('rb') as fh:
            size = os.fstat(fh.fileno()).st_size
            h.update(f.name.encode('utf-8', 'surrogateescape') + b'\0'
                     + size.to_bytes(8, 'little'))
            h.update(fh.read(PROBE_BYTES))
            if size > PROBE_BYTES:
                fh.seek(max(PROBE_BYTES, size - PROBE_BYTES))
                h.update(fh.read(PROBE_BYTES))
    return h.hexdigest()


def bag_stat(bag: Path) -> tuple[int, int]:
    """(total size [bytes], newest mtime [ns]) of the bag's files, without reading them."""
    files = _bag_files(bag)
    stats = [f.stat() for f in files]
    return sum(s.st_size for s in stats), max((s.st_mtime_ns for s in stats), default=0)


def _f(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _uc(bag: dict[str, Any], budget: str) -> float | None:
    """u_c of a budget of the analysis JSON (``uncertainty.budgets.<name>.u_c``)."""
    b = ((bag.get('uncertainty') or {}).get('budgets') or {}).get(budget) or {}
    return _f(b.get('u_c')) if isinstance(b, dict) else None


def _metrics_of(bag: dict[str, Any]) -> list[MetricValue]:
    out: list[MetricValue] = []
    cum = bag.get('cumulative') or {}
    for name in ('te_pp_rad', 'te_amplitude_rad', 'te_mean_rad', 'te_std_rad'):
        v = _f(cum.get(name))
        if v is not None:
            out.append(MetricValue(name, v, u95=_f(cum.get(f'{name}_u95')),
                                   uc=_uc(bag, name)))
    complete = [w for w in bag.get('windows') or [] if w.get('complete')]
    pps = [v for v in (_f(w.get('te_pp_rad')) for w in complete) if v is not None]
    if pps:
        # the catalogue's TE: p-p over one whole output revolution; the worst and the mean
        unc = bag.get('uncertainty') or {}
        out.append(MetricValue('te_pp_revolution_max_rad', max(pps),
                               u95=_f(unc.get('te_pp_revolution_max_rad_u95')),
                               uc=_uc(bag, 'te_pp_revolution_max_rad')))
        out.append(MetricValue('te_pp_revolution_mean_rad', sum(pps) / len(pps)))
    for key, name in (('revolutions', 'revolutions'), ('n_samples', 'samples_count')):
        v = _f(cum.get(key))
        if v is not None:
            out.append(MetricValue(name, v))
    counters = bag.get('counters') or {}
    v = _f(counters.get('gaps'))
    if v is not None:
        out.append(MetricValue('gaps_count', v))
    hyst = bag.get('hysteresis') or {}         # a hysteresis record: lost motion, ...
    for name, value in (hyst.get('metrics') or {}).items():
        v = _f(value)
        if v is not None and isinstance(name, str):
            out.append(MetricValue(name, v))
    for d in bag.get('directions') or []:      # per-direction statistics when present
        direction = d.get('direction')
        if direction in ('cw', 'ccw'):
            for name in ('te_pp_rad', 'te_amplitude_rad', 'te_mean_rad', 'te_std_rad'):
                v = _f(d.get(name))
                if v is not None:
                    out.append(MetricValue(name, v, direction=direction))
    return out


def _lines_of(bag: dict[str, Any]) -> list[LineValue]:
    lines = []
    seen: set[str] = set()
    for ln in (bag.get('spectrum') or {}).get('lines') or []:
        amp = _f(ln.get('amplitude_rad'))
        label = str(ln.get('label', ''))
        if amp is None or not label or label in seen:
            continue
        seen.add(label)
        lines.append(LineValue(label=label, amplitude_rad=amp,
                               output_order=_f(ln.get('output_order')),
                               crank_order=_f(ln.get('crank_order')),
                               frequency_hz=_f(ln.get('frequency_hz')),
                               phase_rad=_f(ln.get('phase_rad')),
                               amplitude_u95_rad=_f(ln.get('amplitude_rad_u95')),
                               amplitude_uc_rad=_uc(bag, f'line {label} amplitude'),
                               phase_u95_rad=_f(ln.get('phase_rad_u95'))))
    return lines


def _tested_at(bag: dict[str, Any], fallback: datetime) -> datetime:
    for w in bag.get('windows') or []:
        t = _f(w.get('start_stamp_s'))
        if t is not None and t > 0:
            return datetime.fromtimestamp(t, tz=UTC)
    return fallback


def records_from_analysis_json(doc: dict[str, Any], *, bag_paths: list[Path],
                               command: str, software_version: str,
                               serial: str | None = None, lot: str | None = None,
                               operator: str | None = None) -> list[UnitRecord]:
    """One record per analysed bag of an ``rv-te analyze --json`` document.

    Args:
        doc: The analysis JSON (``AnalysisResult`` documents under ``bags``).
        bag_paths: The bag of each entry, in order (hashed here).
        command: Which command wrote it ('analyze', 'fleet').
        software_version: The suite's version.
        serial, lot, operator: Override what the bag says (its session metadata:
            ``unit_serial``, ``operator`` of a bench description or a recorder).
    """
    bags = doc.get('bags') or []
    if len(bags) != len(bag_paths):
        msg = f'{len(bags)} analysed bags for {len(bag_paths)} paths'
        raise StoreError(msg)
    out = []
    for entry, path in zip(bags, bag_paths, strict=True):
        sha, size, mtime = bag_fingerprint(path)
        bench = entry.get('bench') or {}
        unit = bench.get('unit') or {}
        session = entry.get('session') or {}   # the bag's metadata: imported and recorded
        rec = entry.get('recommendation') or {}
        advice = rec.get('advice') if rec.get('available') else None
        fallback = datetime.fromtimestamp(mtime / 1e9, tz=UTC)
        out.append(UnitRecord(
            test='te-analysis', bag_path=os.fspath(path.resolve()), bag_sha256=sha,
            tested_at=_tested_at(entry, fallback),
            serial=(serial or session.get('unit_serial') or unit.get('serial')
                    or bench.get('unit_serial') or None),
            lot=lot or session.get('lot') or unit.get('lot') or None,
            operator=operator or session.get('operator') or unit.get('operator') or None,
            bench_id=bench.get('bench_id') or None, preset=bench.get('preset') or None,
            reducer_type=bench.get('reducer_type') or None,
            status='partial' if entry.get('partial') else 'ok',
            command=command, software_version=software_version,
            bag_size_bytes=size, bag_mtime_ns=mtime,
            metrics=tuple(_metrics_of(entry)), lines=tuple(_lines_of(entry)),
            advice=advice,
            details={'bench': bench, 'problems': (entry.get('problems') or [])[:20],
                     'recommendation_reason': rec.get('reason')}))
    return out


def failed_record(path: Path, reason: str, *, command: str, software_version: str,
                  test: str = 'te-analysis') -> UnitRecord:
    """The record of a bag that could not be analysed (its one-line reason kept)."""
    try:
        sha, size, mtime = bag_fingerprint(path)
    except (OSError, StoreError):
        # unreadable: identify it by its path so that a rerun updates the same record
        sha = hashlib.sha256(os.fsencode(path.resolve())).hexdigest()
        size, mtime = None, None
    when = datetime.fromtimestamp(mtime / 1e9, tz=UTC) if mtime else datetime.now(tz=UTC)
    return UnitRecord(test=test, bag_path=os.fspath(path.resolve()), bag_sha256=sha,
                      tested_at=when, status='failed', failure=reason[:2000],
                      command=command, software_version=software_version,
                      bag_size_bytes=size, bag_mtime_ns=mtime)
