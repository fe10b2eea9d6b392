"""``rv-te import`` throughput against the bare library read of the same file, and peak RSS.

For each format and size, one synthetic session file is written (a 2K-V at 300 rpm sampled
at 10 kHz: time, theta_in, theta_out, torque; CSV with 17 significant digits), then, side by
side in one run, each in a fresh Python process:

* **bare read**: the library alone reads the same columns of the same file in the same
  chunks and keeps nothing (CSV: ``numpy.loadtxt`` on chunks of lines; TDMS:
  ``TdmsFile.open`` + ``read_data``; MDF: ``MDF.iter_get`` of the three channels zipped);
* **import**: ``rv_te_bench.io.importers.import_file`` (read, convert, unwrap, check, CDR,
  zstd bag) to a bag on the same disk.

Printed: wall time of each, the ratio import / bare, samples per second, the peak RSS of
each process (``ru_maxrss``) and its peak heap (anonymous resident memory, sampled every
10 ms: asammdf maps the whole file, so the RSS of both MDF processes counts the file pages
read). Memory stays flat when the peak heap does not grow with the file size.

    .venv/bin/python benchmarks/bench_import.py --sizes-mb 10 100 1000 --formats csv
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RATE_HZ = 10_000.0
CSV_BYTES_PER_ROW = 74   # bytes per CSV row at %.17g (measured: 768 MB for 10.4 M rows)
CHUNK = 100_000

BARE = {
    'csv': """
import io, itertools, numpy as np
with open(PATH) as f:
    f.readline()
    while True:
        lines = list(itertools.islice(f, CHUNK))
        if not lines:
            break
        a = np.loadtxt(io.StringIO(''.join(lines)), delimiter=',', usecols=[0, 1, 2, 3],
                       ndmin=2)
""",
    'tdms': """
from nptdms import TdmsFile
with TdmsFile.open(PATH) as f:
    chans = [f['encoders'][c] for c in ('theta_in', 'theta_out', 'torque')]
    n = len(chans[0])
    for s in range(0, n, CHUNK):
        for c in chans:
            c.read_data(s, min(CHUNK, n - s))
""",
    'mdf': """
from asammdf import MDF
m = MDF(PATH)
m.configure(read_fragment_size=32 * CHUNK)
for sigs in zip(*(m.iter_get(n) for n in ('theta_in', 'theta_out', 'torque'))):
    pass
m.close()
""",
}

IMPORT = """
from pathlib import Path
from rv_te_bench.io.bench_description import parse_bench_description
from rv_te_bench.io.importers import ImportOptions, import_file
desc = parse_bench_description({'bench_id': 'b', 'preset': 'wang2020-2kv',
                                'sample_rate_hz': 10000.0, 'block_size': 1000})
cols = {'csv': dict(time='t_s', theta_in='theta_in_rad', theta_out='theta_out_rad',
                    torque='torque_nm'),
        'tdms': dict(theta_in='encoders/theta_in', theta_out='encoders/theta_out',
                     torque='encoders/torque'),
        'mdf': dict(theta_in='theta_in', theta_out='theta_out', torque='torque')}[FMT]
import_file(PATH, desc, OUT, options=ImportOptions(chunk_samples=CHUNK, start_ns=0, **cols))
"""

#: Imported before the clock starts (both sides): the libraries, not the interpreter start.
#: A thread samples the anonymous resident memory (RssAnon) every 10 ms: asammdf maps the
#: file, so ru_maxrss also counts file pages (the kernel can drop them), the heap does not.
PRE = """
import threading, time, numpy, nptdms, asammdf, rv_te_bench.io.importers
import rv_te_bench.io.bench_description, rv_te_bench.io.importers.csv_file
import rv_te_bench.io.importers.tdms_file, rv_te_bench.io.importers.mdf_file, sim.bench
_PEAK = [0]
def _anon():
    while True:
        with open('/proc/self/status') as f:
            for line in f:
                if line.startswith('RssAnon'):
                    _PEAK[0] = max(_PEAK[0], int(line.split()[1]))
        time.sleep(0.01)
threading.Thread(target=_anon, daemon=True).start()
_T0 = time.perf_counter()
"""
TAIL = """
import resource, sys
_T1 = time.perf_counter() - _T0
time.sleep(0.03)
print(_T1, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, _PEAK[0], file=sys.stderr)
"""


def columns(start: int, stop: int) -> dict[str, np.ndarray]:
    """Samples start..stop-1 of the session: time [s], angles [rad], torque [N m]."""
    t = np.arange(start, stop) / RATE_HZ
    th_in = 2 * np.pi * 5.0 * t                  # 300 rpm
    phi = th_in / 79.0
    return {'t_s': t, 'theta_in': th_in,
            'theta_out': phi + 3e-4 * np.cos(25 * phi) + 1e-4 * np.cos(phi),
            'torque': 30.0 + 0.1 * np.sin(phi)}


def _pieces(n: int, size: int = 1_000_000) -> list[tuple[int, int]]:
    return [(s, min(n, s + size)) for s in range(0, n, size)]


def write_csv(path: Path, n: int) -> None:
    with path.open('w') as f:
        f.write('t_s,theta_in_rad,theta_out_rad,torque_nm\n')
        for s, e in _pieces(n):
            c = columns(s, e)
            np.savetxt(f, np.c_[c['t_s'], c['theta_in'], c['theta_out'], c['torque']],
                       fmt='%.17g', delimiter=',')


def write_tdms(path: Path, n: int) -> None:
    from nptdms import ChannelObject, TdmsWriter

    props = {'wf_increment': 1.0 / RATE_HZ, 'unit_string': 'rad'}
    with TdmsWriter(str(path)) as w:
        for s, e in _pieces(n):
            c = columns(s, e)
            w.write_segment([ChannelObject('encoders', k, c[k], properties=props)
                             for k in ('theta_in', 'theta_out', 'torque')])


def write_mdf(path: Path, n: int) -> None:
    from asammdf import MDF, Signal

    c = columns(0, n)
    mdf = MDF(version='4.10')
    mdf.append([Signal(c['theta_in'], c['t_s'], name='theta_in', unit='rad'),
                Signal(c['theta_out'], c['t_s'], name='theta_out', unit='rad'),
                Signal(c['torque'], c['t_s'], name='torque', unit='Nm')])
    mdf.save(str(path), overwrite=True)
    mdf.close()


def run(code: str) -> tuple[float, int, int]:
    """Wall time [s] of ``code`` (libraries imported before the clock starts), the peak RSS
    and the peak anonymous RSS [kB] of its fresh Python process."""
    env = {k: v for k, v in os.environ.items() if k != '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}
    env['PYTHONPATH'] = str(ROOT)
    r = subprocess.run([sys.executable, '-c', PRE + code + TAIL], capture_output=True,
                       text=True, env=env, check=False)
    if r.returncode:
        raise RuntimeError(r.stderr[-2000:])
    wall, rss, anon = r.stderr.strip().splitlines()[-1].split()
    return float(wall), int(rss), int(anon)


def main() -> None:
    """Write the files, time bare reads and imports side by side, print a table."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--sizes-mb', type=float, nargs='+', default=[10.0, 100.0],
                    help='CSV sizes [MB]; TDMS/MDF hold the same number of samples')
    ap.add_argument('--formats', nargs='+', default=['csv', 'tdms', 'mdf'],
                    choices=['csv', 'tdms', 'mdf'])
    ap.add_argument('--dir', type=Path, default=None, help='work folder (default: a temp one)')
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(dir=args.dir, prefix='bench_import_'))
    print('| format | file size [MB] | samples | bare read [s] | import [s] | ratio | '
          'import [M samples/s] | peak RSS bare / import [MB] | peak heap (RssAnon) bare / '
          'import [MB] |')
    print('|---|---|---|---|---|---|---|---|---|')
    try:
        for mb in args.sizes_mb:
            n = int(mb * 1e6 / CSV_BYTES_PER_ROW)
            for fmt in args.formats:
                path = work / f'run_{mb:g}.{ {"csv": "csv", "tdms": "tdms", "mdf": "mf4"}[fmt] }'
                {'csv': write_csv, 'tdms': write_tdms, 'mdf': write_mdf}[fmt](path, n)
                head = f'PATH = {str(path)!r}\nCHUNK = {CHUNK}\nFMT = {fmt!r}\n'
                out = work / f'bag_{fmt}_{mb:g}'
                bare_s, bare_kb, bare_anon = run(head + BARE[fmt])
                imp_s, imp_kb, imp_anon = run(head + f'OUT = {str(out)!r}\n' + IMPORT)
                size = path.stat().st_size / 1e6
                print(f'| {fmt} | {size:.0f} | {n:,} | {bare_s:.2f} | {imp_s:.2f} | '
                      f'{imp_s / bare_s:.2f} | {n / imp_s / 1e6:.2f} | '
                      f'{bare_kb / 1024:.0f} / {imp_kb / 1024:.0f} | '
                      f'{bare_anon / 1024:.0f} / {imp_anon / 1024:.0f} |', flush=True)
                path.unlink()
                shutil.rmtree(out)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
