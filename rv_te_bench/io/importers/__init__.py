"""Measurement files -> rosbag2/MCAP bags of the suite's messages (``rv-te import``), no rclpy.

One module per format: :mod:`.csv_file` (pyarrow; numpy as the fallback), :mod:`.tdms_file`
(NI TDMS, ``nptdms``), :mod:`.mdf_file` (ASAM MDF4, ``asammdf``; these two are the optional
extra ``daq``), and
:mod:`.jointstate_bag` (rosbag2 bags of ``sensor_msgs/JointState``, MCAP or sqlite3, rosbags).
Every reader streams (``chunk_samples`` at a time), :mod:`._common` converts to SI, unwraps
and checks, :mod:`._to_bag` writes the bag whole or not at all.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from rv_te_bench.errors import DataImportError
from rv_te_bench.io.importers._common import ANGLE_UNITS, TIME_UNITS, ImportOptions
from rv_te_bench.io.importers._to_bag import ENCODER_TOPIC, INFO_TOPIC, ImportSummary, write_bag

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.io.bench_description import BenchDescription
    from rv_te_bench.io.importers._common import ImportReader

__all__ = [
    'ANGLE_UNITS',
    'ENCODER_TOPIC',
    'FORMATS',
    'INFO_TOPIC',
    'TIME_UNITS',
    'ImportOptions',
    'ImportSummary',
    'detect_format',
    'import_file',
    'open_reader',
]

#: Format name -> file suffixes that select it.
FORMATS = {'csv': ('.csv', '.txt', '.tsv'), 'tdms': ('.tdms',), 'mdf': ('.mf4', '.mdf', '.dat'),
           'bag': ('.mcap', '.db3')}


def detect_format(path: Path) -> str:
    """The format of ``path`` from its suffix.

    Raises:
        DataImportError: Unknown suffix (the known ones listed).
    """
    if Path(path).is_dir():
        return 'bag'
    suffix = Path(path).suffix.lower()
    for name, suffixes in FORMATS.items():
        if suffix in suffixes:
            return name
    known = ', '.join(s for v in FORMATS.values() for s in v)
    msg = f'{path}: unknown file type {suffix or "(no suffix)"!r} (known: {known}); give --format'
    raise DataImportError(msg)


def open_reader(path: Path, fmt: str, options: ImportOptions, *, header: bool = True,
                joints: tuple[str | None, str | None] = (None, None),
                head_joints: tuple[str, ...] = ()) -> ImportReader:
    """Open ``path`` with the reader of ``fmt`` (checks the columns / channels).

    Raises:
        DataImportError: Missing file, unknown format, missing library, bad layout.
    """
    path = Path(path)
    if fmt == 'bag':
        from rv_te_bench.io.importers.jointstate_bag import JointStateBagReader

        if not path.exists():
            msg = f'{path} does not exist'
            raise DataImportError(msg)
        return JointStateBagReader(path, options, joints, head_joints)
    if not path.is_file():
        what = 'does not exist' if not path.exists() else 'is not a regular file'
        msg = f'{path} {what}'
        raise DataImportError(msg)
    if fmt == 'csv':
        from rv_te_bench.io.importers.csv_file import CsvReader

        return CsvReader(path, options, header=header)
    if fmt == 'tdms':
        from rv_te_bench.io.importers.tdms_file import TdmsReader

        return TdmsReader(path, options)
    if fmt == 'mdf':
        from rv_te_bench.io.importers.mdf_file import MdfReader

        return MdfReader(path, options)
    msg = f'unknown format {fmt!r} (known: {", ".join(FORMATS)})'
    raise DataImportError(msg)


def import_file(path: str | Path, desc: BenchDescription, out: str | Path, *,
                options: ImportOptions, fmt: str | None = None, header: bool = True,
                on_note: Callable[[str], None] | None = None) -> ImportSummary:
    """Import one measurement file into the bag ``out`` (whole or nothing).

    Raises:
        DataImportError: A bad file (one line naming file, column/channel, row/sample).
        BagExistsError: ``out`` exists already.
    """
    path = Path(path)
    fmt = fmt or detect_format(path)
    reader = open_reader(path, fmt, options, header=header,
                         joints=(desc.joint_in_name, desc.joint_out_name),
                         head_joints=desc.encoder_out.head_joints)
    try:
        return write_bag(reader, desc, options, Path(out), fmt=fmt, on_note=on_note)
    finally:
        reader.close()
