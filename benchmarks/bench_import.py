"""``rv-te import`` throughput against the bare library read of the same file, and peak RSS.

For each format and size, one synthetic session file is written (a 2K-V at 300 rpm sampled
at 10 kHz: time, theta_in, theta_out, torque; CSV with 17 significant digits), then, side by
side in one run (``--repeats`` rounds, bare and import alternating), each in a fresh Python
process:

* **bare read**: the library alone reads the same columns of the same file in the same
  chunks and keeps nothing (CSV: ``pyarrow.csv.open_csv``, the streaming columnar reader,
  in blocks of the size the importer reads, the four columns as float64, each batch's
  columns to numpy; ``--csv-bare loadtxt``: ``numpy.loadtxt`` on chunks of lines, the
  reference before issue 41; TDMS: ``TdmsFile.open`` + ``read_data``; MDF:
  ``MDF.iter_get`` of the three channels zipped);
* **import**: ``rv_te_bench.io.importers.import_file`` (read, convert, unwrap, check, CDR,
  compressed bag) to a bag on the same disk, once per ``--compression`` choice (each
  side by side with its own bare reads; the bag's size is printed).

Printed: median wall time of each, the ratio import / bare, the ratio of their CPU times
(user + system of the process: the figure to trust on a loaded machine), samples per
second, the peak RSS of each process (``ru_maxrss``) and its peak heap (anonymous resident
memory, sampled every 10 ms: asammdf maps the whole file, so the RSS of both MDF processes
counts the file pages read). Memory stays flat when the peak heap does not grow with the
file size. ``--cpus 0`` runs both under ``taskset -c 0`` (one core: the importer then starts
no read-ahead thread). The header names the CPU and the load before and after.

    .venv/bin/python benchmarks/bench_import.py --sizes-mb 100 --repeats 5
    .venv/bin/python benchmarks/bench_import.py --sizes-mb 100 --repeats 5 --cpus 0
    .venv/bin/python benchmarks/bench_import.py --sizes-mb 100 --formats tdms \
        --compression zstd-fast zstd lz4 none
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RATE_HZ = 10_000.0
CSV_BYTES_PER_ROW = 74   # bytes per CSV row at %.17g (measured: 768 MB for 10.4 M rows)
CHUNK = 100_000

#: The importer's CSV block [bytes]: chunk_samples x 2 x the header line's length (csv_file).
CSV_BLOCK = 2 * CHUNK * len('t_s,theta_in_rad,theta_out_rad,torque_nm\n')

BARE = {
    'csv': """
import pyarrow as pa, pyarrow.csv as pacsv
r = pacsv.open_csv(PATH, read_options=pacsv.ReadOptions(block_size=CSV_BLOCK),
                   convert_options=pacsv.ConvertOptions(column_types={
                       c: pa.float64() for c in ('t_s', 'theta_in_rad', 'theta_out_rad',
                                                 'torque_nm')}))
for batch in r:
    cols = [c.to_numpy() for c in batch.columns]
""",
    'loadtxt': """
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
import_file(PATH, desc, OUT, options=ImportOptions(chunk_samples=CHUNK, start_ns=0,
                                                  compression=COMPRESSION, **cols))
"""

#: Imported before the clock starts (both sides): the libraries, not the interpreter start.
#: A thread samples the anonymous resident memory (RssAnon) every 10 ms: asammdf maps the
#: file, so ru_maxrss also counts file pages (the kernel can drop them), the heap does not.
PRE = """
import threading, time, numpy, nptdms, asammdf, pyarrow.csv, rv_te_bench.io.importers
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
import resource as _r
_RU0 = _r.getrusage(_r.RUSAGE_SELF)
_CPU0 = _RU0.ru_utime + _RU0.ru_stime
_T0 = time.perf_counter()
"""
TAIL = """
import resource, sys
_T1 = time.perf_counter() - _T0
time.sleep(0.03)
_RU = resource.getrusage(resource.RUSAGE_SELF)
print(_T1, _RU.ru_maxrss, _PEAK[0], _RU.ru_utime + _RU.ru_stime - _CPU0, file=sys.stderr)
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


def run(code: str, cpus: str | None) -> tuple[float, int, int, float]:
    """Wall time [s] of ``code`` (libraries imported before the clock starts), the peak RSS
    and the peak anonymous RSS [kB] of its fresh Python process, and its CPU time [s]."""
    env = {k: v for k, v in os.environ.items() if k != '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}
    env['PYTHONPATH'] = str(ROOT)
    cmd = [sys.executable, '-c', PRE + code + TAIL]
    if cpus is not None:
        cmd = ['taskset', '-c', cpus, *cmd]
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    if r.returncode:
        raise RuntimeError(r.stderr[-2000:])
    wall, rss, anon, cpu = r.stderr.strip().splitlines()[-1].split()
    return float(wall), int(rss), int(anon), float(cpu)


def machine() -> str:
    """The CPU model (``lscpu``), the cores this run may use and the load average."""
    model = platform.processor() or '?'
    try:
        out = subprocess.run(['lscpu'], capture_output=True, text=True, check=False).stdout
        model = next((ln.split(':', 1)[1].strip() for ln in out.splitlines()
                      if ln.startswith('Model name')), model)
    except OSError:
        pass
    load = ' '.join(Path('/proc/loadavg').read_text().split()[:3])
    return f'{model}, {os.cpu_count()} cores, load average {load}'


def main() -> None:
    """Write the files, time bare reads and imports side by side, print a table."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--sizes-mb', type=float, nargs='+', default=[10.0, 100.0],
                    help='CSV sizes [MB]; TDMS/MDF hold the same number of samples')
    ap.add_argument('--formats', nargs='+', default=['csv', 'tdms', 'mdf'],
                    choices=['csv', 'tdms', 'mdf'])
    ap.add_argument('--csv-bare', choices=['pyarrow', 'loadtxt'], default='pyarrow',
                    help='the bare CSV read: pyarrow.csv (default) or numpy.loadtxt')
    ap.add_argument('--compression', nargs='+', default=['zstd-fast'],
                    choices=['zstd-fast', 'zstd', 'lz4', 'none'],
                    help="the bag's chunk compression (rv-te import --compression); several: "
                         'one row each')
    ap.add_argument('--repeats', type=int, default=3, help='rounds (medians are printed)')
    ap.add_argument('--cpus', default=None, help="run both under taskset -c CPUS (e.g. '0')")
    ap.add_argument('--dir', type=Path, default=None, help='work folder (default: a temp one)')
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(dir=args.dir, prefix='bench_import_'))
    cores = f'taskset -c {args.cpus}' if args.cpus is not None else 'all cores'
    print(f'{machine()}; {cores}; {args.repeats} rounds', flush=True)
    print('| format | compression | file size [MB] | samples | bag [MB] | bare read [s] | '
          'import [s] | ratio | CPU bare / import [s] | CPU ratio | import [M samples/s] | '
          'peak RSS bare / import [MB] | peak heap (RssAnon) bare / import [MB] |')
    print('|---|---|---|---|---|---|---|---|---|---|---|---|---|')
    try:
        for mb in args.sizes_mb:
            n = int(mb * 1e6 / CSV_BYTES_PER_ROW)
            for fmt in args.formats:
                path = work / f'run_{mb:g}.{ {"csv": "csv", "tdms": "tdms", "mdf": "mf4"}[fmt] }'
                {'csv': write_csv, 'tdms': write_tdms, 'mdf': write_mdf}[fmt](path, n)
                for comp in args.compression:
                    head = (f'PATH = {str(path)!r}\nCHUNK = {CHUNK}\nFMT = {fmt!r}\n'
                            f'CSV_BLOCK = {CSV_BLOCK}\nCOMPRESSION = {comp!r}\n')
                    out = work / f'bag_{fmt}_{mb:g}'
                    bare_code = BARE['loadtxt' if fmt == 'csv' and args.csv_bare == 'loadtxt'
                                     else fmt]
                    bare, imp = [], []
                    bag_mb = 0.0
                    for _ in range(args.repeats):
                        bare.append(run(head + bare_code, args.cpus))
                        imp.append(run(head + f'OUT = {str(out)!r}\n' + IMPORT, args.cpus))
                        bag_mb = sum(f.stat().st_size for f in out.glob('*.mcap')) / 1e6
                        shutil.rmtree(out)
                    bare_s, imp_s = (statistics.median(r[0] for r in x) for x in (bare, imp))
                    bare_c, imp_c = (statistics.median(r[3] for r in x) for x in (bare, imp))
                    bare_kb, imp_kb = (max(r[1] for r in x) for x in (bare, imp))
                    bare_anon, imp_anon = (max(r[2] for r in x) for x in (bare, imp))
                    size = path.stat().st_size / 1e6
                    print(f'| {fmt} | {comp} | {size:.0f} | {n:,} | {bag_mb:.0f} | {bare_s:.2f} | '
                          f'{imp_s:.2f} | {imp_s / bare_s:.2f} | {bare_c:.2f} / {imp_c:.2f} | '
                          f'{imp_c / bare_c:.2f} | {n / imp_s / 1e6:.2f} | '
                          f'{bare_kb / 1024:.0f} / {imp_kb / 1024:.0f} | '
                          f'{bare_anon / 1024:.0f} / {imp_anon / 1024:.0f} |', flush=True)
                path.unlink()
        print(f'after: {machine()}')
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
