"""The MDF reader takes every channel from one read of each data fragment (issue 41).

``MdfReader.chunks`` reads the channel group's data fragment by fragment once and takes the
channels from it (``MDF.get(data=fragment)``), where ``MDF.iter_get`` per channel read each
fragment once per channel and decoded the master channel with each. These tests check it
gives what ``iter_get`` gives, chunk for chunk, on files written by asammdf the ways a DAQ
writes them (float64; integer counts with a linear conversion; MDF 3; a time channel that is
not the master; several fragments), and the values written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

asammdf = pytest.importorskip('asammdf')

from rv_te_bench.errors import DataImportError  # noqa: E402
from rv_te_bench.io.importers._common import ImportOptions  # noqa: E402
from rv_te_bench.io.importers.mdf_file import MdfReader  # noqa: E402

N = 25_000
RATE_HZ = 10_000.0


def _columns() -> dict[str, np.ndarray]:
    t = np.arange(N) / RATE_HZ
    th_in = 2 * np.pi * 5.0 * t
    return {'t': t, 'in': th_in, 'out': th_in / 79.0 + 3e-4 * np.cos(25 * th_in / 79.0),
            'torque': 30.0 + 0.1 * np.sin(th_in / 79.0)}


def _write(path: Path, version: str = '4.10', *, counts: bool = False,
           time_channel: bool = False) -> dict[str, np.ndarray]:
    """An MDF file of the session; returns the values a reader must give (SI floats)."""
    from asammdf import MDF, Signal

    c = _columns()
    want = dict(c)
    if counts:   # a DAQ's integer counts, the file's linear conversion to radians
        k = 2 * np.pi / 2**20
        raw_in = np.round(np.mod(c['in'], 2 * np.pi) / k).astype(np.int32)
        raw_out = np.round(c['out'] / k).astype(np.int32)
        sigs = [Signal(raw_in, c['t'], name='theta_in', unit='rad',
                       conversion={'a': k, 'b': 0.0}),
                Signal(raw_out, c['t'], name='theta_out', unit='rad',
                       conversion={'a': k, 'b': 0.0})]
        want['in'], want['out'] = raw_in * k, raw_out * k
    else:
        sigs = [Signal(c['in'], c['t'], name='theta_in', unit='rad'),
                Signal(c['out'], c['t'], name='theta_out', unit='rad')]
    sigs.append(Signal(c['torque'], c['t'], name='torque', unit='Nm'))
    if time_channel:   # the DAQ's own clock [ms], beside the master
        sigs.append(Signal(c['t'] * 1e3 + 5.0, c['t'], name='daq_ms', unit='ms'))
        want['time'] = c['t'] * 1e3 + 5.0
    mdf = MDF(version=version)
    mdf.append(sigs)
    mdf.save(str(path), overwrite=True)
    mdf.close()
    return want


def _chunks(path: Path, *, one_read: bool, **extra: Any) -> list[Any]:
    opts = ImportOptions(theta_in='theta_in', theta_out='theta_out', torque='torque',
                         chunk_samples=4_000, **extra)
    reader = MdfReader(path, opts)
    if not one_read:   # the iter_get path (an asammdf without _load_data)
        reader._fragments = reader._zipped   # type: ignore[method-assign]
    try:
        return list(reader.chunks())
    finally:
        reader.close()


@pytest.mark.parametrize(('version', 'counts', 'time_channel'), [
    ('4.10', False, False), ('4.10', True, False), ('3.30', False, False),
    ('4.10', False, True)])
def test_one_read_per_fragment_equals_iter_get(tmp_path: Path, version: str, counts: bool,
                                               time_channel: bool) -> None:
    path = tmp_path / ('run.mf4' if version.startswith('4') else 'run.mdf')
    want = _write(path, version, counts=counts, time_channel=time_channel)
    extra = {'time': 'daq_ms'} if time_channel else {}
    fast = _chunks(path, one_read=True, **extra)
    ref = _chunks(path, one_read=False, **extra)
    assert len(fast) == len(ref) >= 3          # several fragments
    for a, b in zip(fast, ref, strict=True):
        assert a.first == b.first
        for name in ('time', 'theta_in', 'theta_out', 'torque'):
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype == np.float64
            np.testing.assert_array_equal(x, y, err_msg=name)
    got = {k: np.concatenate([getattr(ch, f) for ch in fast]) for k, f in (
        ('in', 'theta_in'), ('out', 'theta_out'), ('torque', 'torque'))}
    got['time'] = np.concatenate([ch.time for ch in fast])
    for k in ('in', 'out', 'torque'):
        np.testing.assert_allclose(got[k], want[k], rtol=0, atol=1e-12 * max(
            1.0, float(np.abs(want[k]).max())), err_msg=k)
    np.testing.assert_allclose(got['time'], want['time'] if time_channel else want['t'],
                               rtol=0, atol=1e-9)


def test_truncated_file_is_named(tmp_path: Path) -> None:
    """A file cut short (a DAQ PC that lost power): one line naming the file, not a crash
    and not a silent short import."""
    path = tmp_path / 'run.mf4'
    _write(path)
    data = path.read_bytes()
    path.write_bytes(data[:len(data) * 2 // 3])
    with pytest.raises(DataImportError, match=r'run\.mf4') as info:
        _chunks(path, one_read=True)
    assert 'truncated' in str(info.value) or 'damaged' in str(info.value)


def test_loader_prints_nothing_on_stdout(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                         capfd: pytest.CaptureFixture[str]) -> None:
    """asammdf 8.x prints a throughput line on stdout every 10 s its data loader runs (a
    1 GB file on a busy PC): ``rv-te import --json``'s stdout would not be one JSON
    document. A clock that moves 11 s per reading makes the loader print at once."""
    import time

    path = tmp_path / 'run.mf4'
    _write(path)
    clock = iter(range(0, 10**6, 11))
    # the loader imports perf_counter from time when it starts
    monkeypatch.setattr(time, 'perf_counter', lambda: float(next(clock)))
    chunks = _chunks(path, one_read=True)
    assert sum(c.theta_in.size for c in chunks) == N
    out = capfd.readouterr().out
    assert out == '', f'asammdf wrote {out[:200]!r} on stdout'
