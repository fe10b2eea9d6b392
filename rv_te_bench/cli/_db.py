"""The ``--db`` option shared by the commands that read or write the results store.

Where results go: ``--db PATH_OR_URL`` if given, else ``$RV_TE_DB``, else the embedded
SQLite file ``rv-te-results.sqlite`` next to the bags (their common parent folder); the
commands that only read (``results``, ``spc``) look in ``./bags/`` when no bag is named.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from rv_te_bench.errors import StoreError

if TYPE_CHECKING:
    import argparse
    from collections.abc import Sequence

__all__ = ['DB_ENV', 'add_db_argument', 'check_record_text', 'db_for_bags', 'db_to_read']

DB_ENV = 'RV_TE_DB'
_NAME = 'rv-te-results.sqlite'


def add_db_argument(p: argparse.ArgumentParser, *, mode: str) -> None:
    """Add ``--db``: ``mode`` 'read' (results, spc), 'write' (fleet) or 'also' (analyze,
    which records as a side effect and so also gets ``--no-db``)."""
    where = ('default: $RV_TE_DB, else ./bags/rv-te-results.sqlite' if mode == 'read'
             else 'default: $RV_TE_DB, else rv-te-results.sqlite next to the bags')
    p.add_argument('--db', metavar='PATH|URL', default=None,
                   help=f'results store: a SQLite file or postgresql://user@host/db ({where})')
    if mode == 'also':
        p.add_argument('--no-db', action='store_true',
                       help='do not record the results in the results store')


def db_for_bags(args: argparse.Namespace, bags: Sequence[Path]) -> str | None:
    """Where the records of ``bags`` go (None with --no-db)."""
    if getattr(args, 'no_db', False):
        return None
    if args.db:
        return str(args.db)
    if os.environ.get(DB_ENV):
        return os.environ[DB_ENV]
    parents = [os.fspath(Path(b).resolve().parent) for b in bags]
    return os.fspath(Path(os.path.commonpath(parents)) / _NAME)


def db_to_read(args: argparse.Namespace) -> str:
    """The store a reading command opens; it must exist when it is a file."""
    db = args.db or os.environ.get(DB_ENV) or os.fspath(Path('bags') / _NAME)
    if '://' not in db and not Path(db).is_file():
        msg = f'no results store at {db}: give --db PATH|URL (or set {DB_ENV})'
        raise StoreError(msg)
    return db   # (open it with create=False: a database that is not a store is not changed)


def check_record_text(args: argparse.Namespace, names: Sequence[str] = ('serial', 'lot',
                                                                     'operator')) -> None:
    """Refuse, before any work, a --serial / --lot / --operator longer than the results
    store keeps (PostgreSQL would refuse the record at the end; issue #21).

    Raises:
        StoreError: One line naming the flag, its length and the limit.
    """
    from rv_te_bench.store.records import FIELD_MAX_CHARS
    for name in names:
        value = getattr(args, name, None)
        limit = FIELD_MAX_CHARS[name]
        if isinstance(value, str) and len(value) > limit:
            shown = value[:40] + '...' if len(value) > 40 else value
            msg = (f'--{name} is {len(value)} characters, the results store keeps at most '
                   f'{limit}: {shown!r}')
            raise StoreError(msg)
