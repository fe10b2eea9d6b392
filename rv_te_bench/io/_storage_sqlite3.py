"""The sqlite3 storage of rosbag2 (``.db3``), read through ``rosbags`` (issue #19 s.4).

Many existing ROS 2 recordings use rosbag2's sqlite3 storage (the default before Iron).
The suite reads MCAP itself (:mod:`._storage_mcap`); for a sqlite3 bag the opener
(:mod:`._bag_open`) calls :func:`sqlite_bag` (the layout, from metadata.yaml) and
:func:`sqlite_units`, which hands the messages over in the shape the MCAP storage uses (a
buffer of several concatenated CDR messages and their offsets, :data:`._bag_types.Unit`),
so the vectorised EncoderBlock decoding, the analysis, identification and replay work
unchanged.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import BagError
from rv_te_bench.io._bag_types import Bag

if TYPE_CHECKING:
    from collections.abc import Callable, Collection, Iterator

    from rv_te_bench.io._bag_types import Unit

__all__ = ['STORAGE', 'UNIT_BYTES', 'sqlite_bag', 'sqlite_units']

#: Messages are handed over in buffers of about this many bytes (like an MCAP chunk).
UNIT_BYTES = 1 << 20
STORAGE = 'sqlite3'


def sqlite_bag(path: Path, info: dict[str, Any], topics: dict[str, str],
               listed: list[Path]) -> Bag:
    """The layout of a sqlite3 bag folder (its ``.db3`` files must exist and be sqlite3).

    Raises:
        BagError: No or missing files, or a file that is not an SQLite database.
    """
    if not listed:
        msg = f'Bag {path} has no .db3 files.'
        raise BagError(msg)
    for file in listed:
        if not file.is_file():
            msg = f'Bag {path}: {file.name} listed in metadata.yaml is missing.'
            raise BagError(msg)
        with file.open('rb') as f:
            head = f.read(16)
        if head != b'SQLite format 3\x00':
            msg = f'Bag {path}: {file.name} is not an SQLite database (sqlite3 storage).'
            raise BagError(msg)
    return Bag(path=path, files=tuple(listed), info=info, topic_types=topics)


def sqlite_units(bag: Bag, report: Callable[[str], None], topics: Collection[str] | None,
                 ) -> Iterator[Unit]:
    """Messages of ``topics`` in recording order, in buffers of ~``UNIT_BYTES``.

    Yields:
        ``(buffer, [(topic, msgtype, log_time_ns, start, end), ...])`` as the MCAP storage's
        :func:`~._storage_mcap.mcap_units` does.

    Unreadable parts are reported through ``report(line)`` (naming the bag) and end the
    read (the messages before were handed over).
    """
    from rosbags.rosbag2 import Reader

    try:
        reader = Reader(bag.path)
        reader.open()
    except Exception as exc:  # noqa: BLE001 - rosbags/sqlite3 raise several types
        report(f'{bag.path}: cannot open the sqlite3 bag: {" ".join(str(exc).split())}')
        return
    try:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        if not conns:
            return
        buf = bytearray()
        found: list[tuple[str, str, int, int, int]] = []
        try:
            for conn, log_time, data in reader.messages(connections=conns):
                start = len(buf)
                buf += data
                found.append((conn.topic, conn.msgtype, int(log_time), start, len(buf)))
                if len(buf) >= UNIT_BYTES:
                    yield memoryview(bytes(buf)), found
                    buf, found = bytearray(), []
        except Exception as exc:  # noqa: BLE001 - a damaged database
            if found:
                yield memoryview(bytes(buf)), found
            report(f'{bag.path}: sqlite3 storage unreadable after {len(found)} more '
                   f'messages: {" ".join(str(exc).split())}')
            return
        if found:
            yield memoryview(bytes(buf)), found
    finally:
        reader.close()
