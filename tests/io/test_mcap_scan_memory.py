"""The bag reader's resident memory does not grow with the bag (issue 41 s.5).

The record walk maps the MCAP file; a mapped page, once read, counts in the process's
resident memory (RssFile) until it is unmapped, so a 10-hour bag (5 GB) read to its end
showed as 5 GB resident. The walk now hands back the pages behind it every
``RELEASE_STEP_BYTES``. Measured here on a 48 MB file written by ``mcap`` (uncompressed
chunks: the messages are views of the map itself, the worst case), with the step lowered to
4 MB: the resident file pages stay within a few steps, and every message still reads back
as written. The same walk with the release off (the old code) holds the whole file.
"""

from __future__ import annotations

import hashlib
import sys
from typing import TYPE_CHECKING

import numpy as np
import pytest
from mcap.writer import CompressionType, Writer

from rv_te_bench.io import _mcap_scan

if TYPE_CHECKING:
    from pathlib import Path

pytestmark = pytest.mark.skipif(not sys.platform.startswith('linux'),
                                reason='RssFile from /proc/self/status (Linux)')

_MSG_BYTES = 64 << 10
_N_MSGS = 768    # 48 MB


def _rss_file_mb() -> float:
    with open('/proc/self/status', encoding='ascii') as fh:
        for line in fh:
            if line.startswith('RssFile:'):
                return int(line.split()[1]) / 1024.0
    raise AssertionError('no RssFile in /proc/self/status')


def _write(path: Path) -> list[str]:
    rng = np.random.default_rng(41)
    digests = []
    with path.open('wb') as fh:
        w = Writer(fh, compression=CompressionType.NONE, chunk_size=1 << 20)
        w.start()
        sid = w.register_schema(name='raw', encoding='', data=b'')
        cid = w.register_channel(topic='/raw', message_encoding='cdr', schema_id=sid)
        for k in range(_N_MSGS):
            data = rng.bytes(_MSG_BYTES)
            digests.append(hashlib.sha1(data).hexdigest())
            w.add_message(channel_id=cid, log_time=k, data=data, publish_time=k)
        w.finish()
    return digests


def _walk(path: Path) -> tuple[float, list[str]]:
    """Walk the file once; (largest RssFile growth [MB], digest of every message)."""
    problems: list[str] = []
    base = _rss_file_mb()
    grow = 0.0
    seen = []
    for inner, found in _mcap_scan._scan_units(path, _mcap_scan._ScanState(), problems.append,
                                                prefetch=False):
        for _cid, _t, start, end in found.rows():
            seen.append(hashlib.sha1(inner[start:end]).hexdigest())
        grow = max(grow, _rss_file_mb() - base)
    assert problems == []
    return grow, seen


def test_resident_file_pages_stay_flat(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       ) -> None:
    path = tmp_path / 'big.mcap'
    written = _write(path)
    size_mb = path.stat().st_size / 2**20
    assert size_mb > 47

    monkeypatch.setattr(_mcap_scan, 'RELEASE_STEP_BYTES', 4 << 20)
    grow, seen = _walk(path)
    assert seen == written
    assert grow < 16.0, f'{grow:.1f} MB of a {size_mb:.0f} MB file resident'

    # the old walk (nothing released): the whole file becomes resident
    monkeypatch.setattr(_mcap_scan, 'RELEASE_STEP_BYTES', 1 << 62)
    grow_old, seen_old = _walk(path)
    assert seen_old == written
    assert grow_old > 0.8 * size_mb, grow_old
