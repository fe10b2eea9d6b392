"""The opener: a bag's layout read once, and the storage (MCAP or sqlite3) chosen for it.

As rosbags' ``rosbag2.Reader`` picks ``storage_mcap`` or ``storage_sqlite3`` from
metadata.yaml's ``storage_identifier``, :func:`open_bag` validates the layout and every
other function here asks the storage the bag was opened with:

* :func:`open_bag`: a bag folder (metadata.yaml + files) or a lone ``.mcap`` file ->
  :class:`~._bag_types.Bag`;
* :func:`units` / :func:`messages`: the wanted messages, by storage unit or one by one;
  :func:`unit_columns`: by storage unit as arrays (the offline reader's path);
* :func:`scan_topics` / :func:`topic_types`: the topics as the files hold them (a lone
  file, or metadata.yaml that lists none);
* :func:`find_messages`: a few messages of some topics, through an MCAP file's chunk
  index where it has one (BenchInfo), by a scan where not.

The readers on top (:mod:`.bag_reader`, :mod:`.bench_record`) use only these.
"""

from __future__ import annotations

import copy
import functools
import stat
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import BagError, YamlInputError
from rv_te_bench.io import _storage_mcap, _storage_sqlite3
from rv_te_bench.io._bag_folder import entry_problem, layout_notes, listed_files
from rv_te_bench.io._bag_types import Bag, UnitColumns
from rv_te_bench.safe_yaml import BAG_METADATA_LIMITS, decode_text, load_yaml, read_yaml_file

if TYPE_CHECKING:
    from collections.abc import Collection, Iterator
    from concurrent.futures import Executor

    from rv_te_bench.io._bag_types import MessageStream, Unit

__all__ = ['find_messages', 'messages', 'open_bag', 'scan_topics', 'topic_types',
           'unit_columns', 'units']


def open_bag(path: str | Path) -> Bag:
    """Validate a bag's layout and read its metadata.yaml.

    Args:
        path: A rosbag2 bag folder (metadata.yaml + .mcap or .db3 files) or a single
            ``.mcap`` file.

    Returns:
        The bag's layout.

    Raises:
        BagError: Missing path or metadata, unreadable YAML, storage other than MCAP or
            sqlite3, files missing, or a file that is not of its storage.
    """
    path = Path(path)
    if path.is_file():
        _storage_mcap.check_magic(path)
        return Bag(path=path, files=(path,), info={}, topic_types={})
    if not path.is_dir():
        what = entry_problem(path)
        msg = (f'Bag {path} does not exist.' if what == 'missing' else
               f'Bag {path} is not a bag folder or .mcap file: {what}.')
        raise BagError(msg)
    meta_path = path / 'metadata.yaml'
    if not meta_path.is_file():
        msg = f'Bag {path} has no metadata.yaml: not a rosbag2 bag folder.'
        raise BagError(msg)
    try:
        doc = _metadata_doc(meta_path)   # bounded (issue #16), parsed once per content
        info = doc['rosbag2_bagfile_information']
        storage = info['storage_identifier']
        listed = listed_files(path, info['relative_file_paths'], where=meta_path)
        topics = {
            str(t['topic_metadata']['name']): str(t['topic_metadata']['type'])
            for t in info.get('topics_with_message_count') or []
        }
    except YamlInputError as exc:
        msg = f'Cannot read {exc}.'
        raise BagError(msg) from None
    except (KeyError, TypeError, AttributeError) as exc:
        msg = f'{meta_path} is not rosbag2 metadata (missing or bad key {exc}).'
        raise BagError(msg) from None
    if storage == _storage_sqlite3.STORAGE:   # read through rosbags (issue #19 s.4)
        return _storage_sqlite3.sqlite_bag(path, info, topics, listed)
    if storage != _storage_mcap.STORAGE:
        msg = f'Bag {path} uses storage {storage!r}; only mcap and sqlite3 are supported.'
        raise BagError(msg)
    problems = {p: entry_problem(p) for p in listed}
    if missing := [str(p) for p, what in problems.items() if what == 'missing']:
        # bounded: a 4 MiB metadata.yaml can list ~100,000 files (a 10 MB one-line error)
        shown = ', '.join(Path(m).name for m in missing[:3])
        more = f' and {len(missing) - 3} more' if len(missing) > 3 else ''
        msg = (f'Bag {path}: {len(missing)} file(s) listed in metadata.yaml are missing: '
               f'{shown}{more}.')
        raise BagError(msg)
    if odd := [f'{p.name} is {what}' for p, what in problems.items() if what]:
        msg = f'Bag {path}: listed in metadata.yaml but {"; ".join(odd)}.'
        raise BagError(msg)
    if not listed:
        msg = f'Bag {path} has no .mcap files.'
        raise BagError(msg)
    for file in listed:
        _storage_mcap.check_magic(file)
    # unlisted .mcap files (another session's, or a split a killed recorder had not listed
    # yet, which holds no message: BagWriter lists a file before writing messages to it)
    # are ignored, as rosbags ignores them, with a note
    notes = tuple(layout_notes(path, listed, info))
    return Bag(path=path, files=tuple(listed), info=info, topic_types=topics, notes=notes)


@functools.lru_cache(maxsize=4)
def _parsed_metadata(origin: str, data: bytes) -> Any:
    # bounded: a ~1 KB alias bomb once expanded to gigabytes here (issue #16)
    return load_yaml(decode_text(data, origin), origin=origin, limits=BAG_METADATA_LIMITS)


def _metadata_doc(meta_path: Path) -> Any:
    """A bag's metadata.yaml parsed, once per content (an analysis opens its bag five
    times: 0.7 ms each, issue 41): a private copy of the document parsed from the same
    bytes before, else parsed now; a file that is not a regular one of at most the limit's
    size goes to :func:`~rv_te_bench.safe_yaml.read_yaml_file`, which says what is wrong.

    Raises:
        YamlInputError: As :func:`rv_te_bench.safe_yaml.read_yaml_file`.
    """
    try:
        st = meta_path.stat()
        if stat.S_ISREG(st.st_mode) and st.st_size <= BAG_METADATA_LIMITS.max_bytes:
            data = meta_path.read_bytes()
            if len(data) <= BAG_METADATA_LIMITS.max_bytes:
                return copy.deepcopy(_parsed_metadata(f'bag metadata {meta_path}', data))
    except OSError:
        pass
    return read_yaml_file(meta_path, what='bag metadata', limits=BAG_METADATA_LIMITS)


def units(bag: Bag, stream: MessageStream[Any], topics: Collection[str] | None,
          executor: Executor | None = None, *, read_ahead: bool = True) -> Iterator[Unit]:
    """Per storage unit: the buffer and its wanted messages (problems go to ``stream``).

    ``executor``: the thread that reads MCAP chunks ahead (None: one of the scan's own);
    ``read_ahead`` False: none read ahead, no thread.
    """
    if bag.storage == _storage_sqlite3.STORAGE:   # issue #19 s.4
        return _storage_sqlite3.sqlite_units(bag, stream.report_problem,
                                             None if topics is None else set(topics))
    return _storage_mcap.mcap_units(bag, stream.report_problem, topics, executor,
                                   read_ahead=read_ahead)


def unit_columns(bag: Bag, stream: MessageStream[Any], topics: Collection[str] | None,
                 executor: Executor | None = None, *, read_ahead: bool = True,
                 ) -> Iterator[UnitColumns]:
    """:func:`units` with each unit's messages as arrays (:class:`._bag_types.UnitColumns`)."""
    if bag.storage == _storage_sqlite3.STORAGE:
        return (UnitColumns.from_rows(buf, rows) for buf, rows in _storage_sqlite3.sqlite_units(
            bag, stream.report_problem, None if topics is None else set(topics)))
    return _storage_mcap.mcap_unit_columns(bag, stream.report_problem, topics, executor,
                                          read_ahead=read_ahead)


def messages(bag: Bag, stream: MessageStream[Any], topics: Collection[str] | None,
             ) -> Iterator[tuple[str, str, int, memoryview]]:
    """The wanted messages one by one: ``(topic, msgtype, log_time_ns, cdr)``."""
    for inner, found in units(bag, stream, topics):
        for topic, msgtype, log_time, start, end in found:
            yield topic, msgtype, log_time, inner[start:end]


def scan_topics(bag: Bag) -> dict[str, dict[str, Any]]:
    """Topic -> {'type', 'offered_qos_profiles'} as the storage holds them.

    MCAP: from the channels of every file (their summaries where sound); sqlite3: the
    topics its metadata.yaml lists (the database is read through rosbags from it).
    """
    if bag.storage == _storage_sqlite3.STORAGE:
        return {str(t['topic_metadata']['name']): {
            'type': str(t['topic_metadata']['type']),
            'offered_qos_profiles': t['topic_metadata'].get('offered_qos_profiles')}
            for t in bag.info.get('topics_with_message_count') or []}
    return _storage_mcap.mcap_topics(bag)


def topic_types(bag: Bag) -> dict[str, str]:
    """Topic -> type: metadata.yaml's, else (a lone file, or none listed) the files'."""
    return bag.topic_types or {topic: t['type'] for topic, t in scan_topics(bag).items()}


def find_messages(bag: Bag, stream: MessageStream[Any], topics: Collection[str],
                  ) -> Iterator[tuple[str, bytes]]:
    """``(msgtype, cdr)`` of the messages of a few ``topics``, file by file.

    An MCAP file's summary chunk index finds the few chunks that hold the topics; without
    a sound summary (killed recorder) or in sqlite3 storage, the file is scanned (its
    problems go to ``stream``).
    """
    if bag.storage == _storage_sqlite3.STORAGE:   # one database read, no index
        for _, msgtype, _, data in messages(bag, stream, topics):
            yield msgtype, bytes(data)
        return
    for file in bag.files:
        indexed = _storage_mcap.indexed_messages(file, topics)
        if indexed is None:
            one = Bag(path=bag.path, files=(file,), info=bag.info, topic_types=bag.topic_types)
            indexed = [(msgtype, bytes(data)) for _, msgtype, _, data
                       in messages(one, stream, topics)]
        yield from indexed
