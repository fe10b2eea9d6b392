"""The ``--db`` option shared by the commands that read or write the results store.

One store per user (issue 33): ``--db PATH_OR_URL`` if given, else ``$RV_TE_DB``, else the
user's default store ``~/.local/share/rv-te/results.sqlite`` (``$XDG_DATA_HOME/rv-te/...``:
:func:`rv_te_bench.store.default_store_path`), whichever command wrote or reads it and
wherever its bags lie, so that ``rv-te results`` finds what ``rv-te analyze`` and ``rv-te
test`` recorded. Every command names the store it used.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from rv_te_bench.errors import StoreError

if TYPE_CHECKING:
    import argparse
    from collections.abc import Sequence

__all__ = ['DB_ENV', 'add_db_argument', 'check_record_text', 'db_for_bags', 'db_to_read',
           'default_db', 'store_summary']

DB_ENV = 'RV_TE_DB'
_WHERE = '$RV_TE_DB, else ~/.local/share/rv-te/results.sqlite'


def default_db() -> str:
    """``$RV_TE_DB``, else the user's default store."""
    from rv_te_bench.store import default_store_path

    if os.environ.get(DB_ENV):
        return os.environ[DB_ENV]
    return os.fspath(default_store_path())


def add_db_argument(p: argparse.ArgumentParser, *, mode: str) -> None:
    """Add ``--db``: ``mode`` 'read' (results, spc), 'write' (fleet) or 'also' (analyze,
    which records as a side effect and so also gets ``--no-db``)."""
    p.add_argument('--db', metavar='PATH|URL', default=None,
                   help='results store: a SQLite file or postgresql://user@host/db '
                        f'(default: {_WHERE}; $XDG_DATA_HOME moves the latter)')
    if mode == 'also':
        p.add_argument('--no-db', action='store_true',
                       help='do not record the results in the results store')


def db_for_bags(args: argparse.Namespace, bags: Sequence[Path]) -> str | None:
    """Where the records of ``bags`` go (None with --no-db): the one store of the user,
    whatever folder the bags are in."""
    del bags   # one store for every bag (issue 33): not next to them
    if getattr(args, 'no_db', False):
        return None
    db = str(args.db) if args.db else default_db()
    if '://' not in db:
        Path(db).expanduser().parent.mkdir(parents=True, exist_ok=True)
    return db


def db_to_read(args: argparse.Namespace) -> str:
    """The store a reading command opens; it must exist when it is a file."""
    db = str(args.db) if args.db else default_db()
    if '://' not in db and not Path(db).is_file():
        given = 'given with --db' if args.db else (
            f'from ${DB_ENV}' if os.environ.get(DB_ENV) else 'the default store')
        msg = (f'no results store at {db} ({given}): nothing has been recorded there yet '
               f'(rv-te analyze and rv-te test record into it); give --db PATH|URL (or set '
               f'{DB_ENV}) to read another')
        raise StoreError(msg)
    return db   # (open it with create=False: a database that is not a store is not changed)


def store_summary(url: str, total: int) -> str:
    """``results store URL (N records)``: how every command names the store it used."""
    return f'results store {url} ({total} record{"" if total == 1 else "s"})'


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
