"""Checks of a bag folder's layout against its metadata.yaml (used by ``open_bag``).

* ``relative_file_paths`` must be a list of file names (a string would be read character by
  character);
* every listed entry must be a regular file: a FIFO, a directory or a device (a symlink to
  /dev/zero) is named as what it is and never opened (a FIFO blocks, /dev/zero never ends);
* a ``.mcap`` the metadata does not list is ignored with a note, as rosbags ignores it (it
  may belong to another session); an empty one (a recorder killed between creating a split
  and listing it) is ignored silently;
* the write gaps a recorder stated (a full disk, ``rv_te_bench.write_gaps``) become notes.
"""

from __future__ import annotations

import datetime as dt
import os
import stat
from pathlib import Path
from typing import Any

from rv_te_bench.errors import BagError, YamlInputError
from rv_te_bench.safe_yaml import YamlLimits, load_yaml

__all__ = ['entry_problem', 'layout_notes', 'listed_files']

_SHOWN = 60          # characters of a bad value shown in a message
_GAPS_SHOWN = 5
_GAPS_LIMITS = YamlLimits(max_bytes=64 << 10, max_depth=16, max_aliases=100,
                          max_nodes=10_000)
_KINDS = ((stat.S_ISFIFO, 'a FIFO'), (stat.S_ISDIR, 'a directory'),
          (stat.S_ISCHR, 'a character device'), (stat.S_ISBLK, 'a block device'),
          (stat.S_ISSOCK, 'a socket'))


def _show(value: object) -> str:
    text = repr(value)
    return text if len(text) <= _SHOWN else f'{text[:_SHOWN - 10]}... ({len(text)} characters)'


def listed_files(folder: Path, value: object, *, where: Path) -> list[Path]:
    """The files ``relative_file_paths`` lists, inside ``folder``.

    Raises:
        BagError: ``value`` is not a list of file names (names what it is instead).
    """
    if isinstance(value, list) and all(isinstance(p, str) and p for p in value):
        return [folder / Path(p).name for p in value]
    got = (f'a string: {_show(value)}' if isinstance(value, str)
           else f'{type(value).__name__} {_show(value)}')
    msg = f'{where}: relative_file_paths must be a list of file names, got {got}.'
    raise BagError(msg)


def entry_problem(path: Path) -> str | None:
    """None for a regular file (or a symlink to one), else what it is; nothing is opened."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return 'missing'
    except OSError as exc:
        return f'not readable ({exc.strerror})'
    if stat.S_ISREG(mode):
        return None
    kind = next((name for test, name in _KINDS if test(mode)), 'not a file')
    if path.is_symlink():
        kind += f' (a symlink to {os.readlink(path)})'
    return f'not a regular file: {kind}'


def layout_notes(folder: Path, listed: list[Path], info: dict[str, Any]) -> list[str]:
    """Notes on a bag folder that does not stop reading it: unlisted files, write gaps."""
    notes = []
    for p in sorted(folder.glob('*.mcap')):
        if p in listed:
            continue
        try:
            empty = p.stat().st_size == 0 and stat.S_ISREG(p.stat().st_mode)
        except OSError:
            empty = False
        if not empty:
            notes.append(f'{p.name} is not listed in metadata.yaml: ignored')
    return notes + _write_gap_notes(info.get('custom_data'))


def _write_gap_notes(custom: object) -> list[str]:
    """What the recorder could not write (``rv_te_bench.write_gaps``), one line per gap."""
    if not isinstance(custom, dict) or 'rv_te_bench.lost_messages' not in custom:
        return []
    try:
        lost = int(str(custom['rv_te_bench.lost_messages'])[:20])
    except ValueError:
        return []
    gaps = custom.get('rv_te_bench.write_gaps')
    notes = [(f'the recorder could not write {lost} messages to this bag (disk full: '
              'rv_te_bench.write_gaps in metadata.yaml)')]
    try:   # a string the writer dumped; bounded (the suite's loader), only the first gaps
        parsed = load_yaml(gaps, origin='rv_te_bench.write_gaps',
                           limits=_GAPS_LIMITS) if isinstance(gaps, str) else None
    except YamlInputError:
        parsed = None
    for k, gap in enumerate((parsed if isinstance(parsed, list) else [])[:_GAPS_SHOWN], 1):
        if not isinstance(gap, dict):
            continue
        n, span = gap.get('lost_messages'), gap.get('lost_log_time_ns')
        if not (isinstance(n, int) and n > 0 and isinstance(span, list) and len(span) == 2
                and all(isinstance(t, int) for t in span)):
            continue
        t0, t1 = (dt.datetime.fromtimestamp(t * 1e-9, dt.UTC).isoformat(timespec='milliseconds')
                  for t in span)
        error = gap.get('error')
        notes.append(f'write gap {k}: {n} messages logged {t0} .. {t1} '
                     f'({(span[1] - span[0]) * 1e-9:.2f} s) are missing'
                     + (f' ({error[:_SHOWN]})' if isinstance(error, str) else ''))
    return notes
