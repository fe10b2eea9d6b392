"""Which unit a record is of: the serial from the command line, the bench description, or the
file name (issue 33 s.6), and where it came from.

A lab names its DAQ files after the unit (``SN-2026-0042_cw.csv``) more often than it edits
the bench description for each unit. When no ``--serial`` is given, the serial is the bench
description's ``unit_under_test.serial``, else the part of the file name the serial pattern
matches: :data:`DEFAULT_SERIAL_PATTERN` (``SN`` followed by letters, digits and dashes, with
at least one digit: ``SN-2026-0042``, ``SN0042``, ``SN_77A``), or the user's own
(``--serial-pattern REGEX``: the group named ``serial``, else the first group, else the whole
match). The source is stated with the serial (output, bag metadata ``unit_serial_source``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from rv_te_bench.errors import DataImportError

__all__ = ['DEFAULT_SERIAL_PATTERN', 'SerialChoice', 'choose_serial', 'serial_from_name']

#: ``SN`` (upper case), an optional ``-`` or ``_``, then letters, digits and dashes holding
#: at least one digit, not preceded by a letter or digit.
DEFAULT_SERIAL_PATTERN = (r'(?<![A-Za-z0-9])(?P<serial>SN[-_]?(?=[A-Za-z0-9-]*[0-9])'
                          r'[A-Za-z0-9]+(?:-[A-Za-z0-9]+)*)')


@dataclass(frozen=True)
class SerialChoice:
    """The unit's serial ('' when none is known) and where it came from, in words."""

    serial: str
    source: str

    def describe(self) -> str:
        """One line for people."""
        if not self.serial:
            return f'unit serial: not stated ({self.source})'
        return f'unit serial {self.serial} (from {self.source})'


def _compile(pattern: str) -> re.Pattern[str]:
    try:
        return re.compile(pattern)
    except re.error as exc:
        msg = f'--serial-pattern {pattern!r} is not a regular expression: {exc}'
        raise DataImportError(msg) from None


def serial_from_name(name: str, pattern: str | None = None) -> str:
    """The serial in a file name ('' when the pattern does not match).

    Examples:
        >>> serial_from_name('SN-2026-0042_cw.csv'), serial_from_name('run_SN0042.tdms')
        ('SN-2026-0042', 'SN0042')
        >>> serial_from_name('snapshot_1.csv'), serial_from_name('SNR_test.csv')
        ('', '')
        >>> serial_from_name('unit-RV80E-0042-cw.csv', r'unit-(.+)-c?c?w')
        'RV80E-0042'

    Raises:
        DataImportError: ``pattern`` is not a regular expression.
    """
    rx = _compile(pattern or DEFAULT_SERIAL_PATTERN)
    m = rx.search(Path(name).name)
    if m is None:
        return ''
    if 'serial' in rx.groupindex:
        return m.group('serial') or ''
    return (m.group(1) if rx.groups else m.group(0)) or ''


def choose_serial(given: str | None, *, bench_serial: str = '', bench_origin: str = '',
                  path: Path | str | None = None,
                  pattern: str | None = None) -> SerialChoice:
    """The serial: ``given`` (command line), the bench description's, else the file name's.

    Raises:
        DataImportError: ``pattern`` is not a regular expression.
    """
    if given:
        return SerialChoice(given, 'the command line (--serial)')
    if bench_serial:
        return SerialChoice(bench_serial,
                            f'bench description {bench_origin} (unit_under_test.serial)')
    shown = 'the default pattern SN...' if pattern is None else f'pattern {pattern!r}'
    if path is not None:
        name = Path(path).name
        found = serial_from_name(name, pattern)
        if found:
            return SerialChoice(found, f'the file name {name} ({shown})')
        return SerialChoice('', f'no --serial, none in the bench description, none in the '
                                f'file name {name} ({shown})')
    return SerialChoice('', 'no --serial and none in the bench description')
