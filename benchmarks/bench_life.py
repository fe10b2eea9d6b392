"""A life-test-length session: record HOURS at 10 kHz (simulated, fast mode), then analyse it.

Issue 41, target 5. One command, every length a parameter:

    .venv/bin/python benchmarks/bench_life.py [--hours 10] [--short-minutes 10]
        [--rate-hz 10000] [--block-size 1000] [--speed-factor 30] [--repeats 3]
        [--long-repeats N] [--stage all|record|analyze] [--dir DIR] [--keep]

Steps, each in fresh processes as a user runs them:

1. ``rv-te launch --default --nodes bench,recorder`` with the bench in fast mode for 2 s
   (the command's fixed cost), ``--short-minutes`` (the reference bag) and ``--hours`` (the
   life-test bag); the recorder's peak resident memory is its VmHWM and its CPU time
   utime+stime, read from /proc every 0.5 s while it runs (the last reading before it exits).
   Blocks on disk are compared with the blocks the bench published. Before 642c45d
   ``--speed-factor 0`` (as fast as the bench can) outran the recorder on a loaded 2-core
   machine (5714 of 6000 blocks reached the 10-minute bag at 96x real time); a fast bench
   now waits for its recorder (rv_te_bench/nodes/backpressure.py).
2. ``rv-te analyze BAG --json --no-advice --report DIR`` on the three bags, ``--repeats``
   rounds interleaved (the long bag in ``--long-repeats`` middle rounds): wall time, CPU
   time (user+sys) and peak RSS (``ru_maxrss``) from ``wait4``; linearity =
   (long - fixed) / (hours * 60 / short minutes * (short - fixed)), in CPU time (what a
   machine whose load changes over the hour does not distort) and in wall time, and the
   same without taking the fixed cost off.
3. The long bag's report is kept in ``DIR/report_long``: te.png is drawn from the min/max
   envelope of every sample (rv_te_bench/core/envelope.py), windows.png has one point per
   window.

``--stage record`` records into ``--dir`` and keeps the bags (record.json); ``--stage
analyze`` analyses them there later (e.g. after the analysis code changed). With ``--stage
all`` the bags are deleted at the end unless ``--keep``; otherwise delete ``DIR/rec_*``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RV_TE = [sys.executable, '-m', 'rv_te_bench.cli.main']


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env.setdefault('ROS_DOMAIN_ID', str(100 + os.getpid() % 100))
    return env


def _descendants(pid: int) -> list[int]:
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            kids = Path(f'/proc/{p}/task/{p}/children').read_text().split()
        except OSError:
            continue
        out += [int(k) for k in kids]
        todo += [int(k) for k in kids]
    return out


_TICK_S = 1.0 / os.sysconf('SC_CLK_TCK')
#: node name -> the module its process runs (``python -m rv_te_bench.nodes._entry MODULE``)
_NODE_MODULES = {'recorder': 'rv_te_bench.nodes.recorder', 'bench': 'rv_te_bench.nodes.bench_node'}


def _node_usage(pid: int) -> tuple[str, float, float] | None:
    """(node name, VmHWM [MB], user+sys CPU [s]) of a node process of the launch; else None."""
    try:
        args = Path(f'/proc/{pid}/cmdline').read_bytes().split(b'\0')
        status = Path(f'/proc/{pid}/status').read_text()
        stat = Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return None
    words = [a.decode(errors='replace') for a in args]
    name = next((n for n, m in _NODE_MODULES.items() if m in words), None)
    hwm = [ln for ln in status.splitlines() if ln.startswith('VmHWM:')]
    if name is None or not hwm:
        return None
    fields = stat[stat.rindex(')') + 2:].split()   # after the command name in parentheses
    cpu_s = (int(fields[11]) + int(fields[12])) * _TICK_S   # utime, stime
    return name, int(hwm[0].split()[1]) / 1024.0, cpu_s


def record(out_dir: Path, seconds: float, args: argparse.Namespace) -> dict:
    """One fast-mode session recorded by the packaged launch; the recorder's peak RSS."""
    cmd = [*RV_TE, 'launch', '--default', '--nodes', 'bench,recorder',
           '--param', f'bench.sample_rate_hz={args.rate_hz}',
           '--param', f'bench.block_size={args.block_size}',
           '--param', 'bench.duration_output_revs=0.0',
           '--param', f'bench.duration_s={seconds}',
           '--param', f'bench.speed_factor={args.speed_factor}',
           '--param', f'recorder.output_dir={out_dir}']
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=_env(), cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    peaks: dict[str, float] = {}
    cpu: dict[str, float] = {}
    stop = threading.Event()

    def poll() -> None:
        while not stop.is_set():
            for pid in _descendants(proc.pid):
                got = _node_usage(pid)
                if got is not None:
                    peaks[got[0]] = max(peaks.get(got[0], 0.0), got[1])
                    cpu[got[0]] = max(cpu.get(got[0], 0.0), got[2])
            stop.wait(0.5)

    th = threading.Thread(target=poll, daemon=True)
    th.start()
    log = proc.communicate()[0]
    stop.set()
    th.join()
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        msg = f'launch exited {proc.returncode}: {log[-2000:]}'
        raise RuntimeError(msg)
    (bag,) = [p for p in out_dir.iterdir() if p.is_dir()]
    return {'bag': str(bag), 'wall_s': wall, 'peaks_mb': peaks, 'cpu_s': cpu,
            'log': [ln for ln in log.splitlines() if 'complete' in ln or 'closed' in ln]}


def analyze(bag: Path, report: Path) -> tuple[float, float, float, dict]:
    """``rv-te analyze`` in a fresh process: wall [s], user+sys CPU [s], peak RSS [MB], JSON."""
    if report.exists():
        shutil.rmtree(report)
    cmd = [*RV_TE, 'analyze', str(bag), '--json', '--no-advice', '--no-db', '--quiet',
           '--report', str(report)]
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(cmd, env=_env(), cwd=ROOT, stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        out.seek(0)
        err.seek(0)
        text, problem = out.read(), err.read().decode(errors='replace')
    if status != 0:
        msg = f'analyze exited with status {status}: {problem[-2000:]}'
        raise RuntimeError(msg)
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0, json.loads(text)


def _median(values: list[float]) -> float:
    import statistics
    return float(statistics.median(values))


def _record_stage(work: Path, args: argparse.Namespace) -> dict:
    """Record the three bags (fixed-cost, short, long); their figures, also in record.json."""
    rows: dict = {}
    for name, seconds in (('fixed', 2.0), ('short', args.short_minutes * 60.0),
                          ('long', args.hours * 3600)):
        shutil.rmtree(work / f'rec_{name}', ignore_errors=True)
        t_start = time.strftime('%H:%M:%S')
        rec = record(work / f'rec_{name}', seconds, args)
        size_gb = sum(f.stat().st_size for f in Path(rec['bag']).iterdir()) / 1e9
        print(f'{name}: recorded {seconds:g} s from {t_start} in {rec["wall_s"]:.0f} s, '
              f'{size_gb:.2f} GB, peak RSS {rec["peaks_mb"]} MB, CPU {rec["cpu_s"]} s, '
              f'load {os.getloadavg()[0]:.1f}; {rec["log"]}', file=sys.stderr, flush=True)
        rows[name] = {'rec': rec, 'seconds': seconds, 'size_gb': size_gb}
        (work / 'record.json').write_text(json.dumps(rows, indent=1))
    return rows


def _analyze_stage(work: Path, rows: dict, args: argparse.Namespace) -> None:
    """Analyse the bags interleaved (the long one in the middle rounds); print the table."""
    load0 = os.getloadavg()
    first = max(0, (args.repeats - args.long_repeats) // 2)
    long_rounds = range(first, first + args.long_repeats)
    for r in rows.values():
        r.update(walls=[], cpus=[], rss=[])
    for k in range(args.repeats):
        for name in ('fixed', 'short', 'long'):
            if name == 'long' and k not in long_rounds:
                continue
            wall, cpu, rss, doc = analyze(Path(rows[name]['rec']['bag']),
                                          work / f'report_{name}')
            rows[name]['walls'].append(wall)
            rows[name]['cpus'].append(cpu)
            rows[name]['rss'].append(rss)
            rows[name]['doc'] = doc
            print(f'{name}: analysed in {wall:.1f} s wall, {cpu:.1f} s CPU, peak RSS '
                  f'{rss:.0f} MB, load {os.getloadavg()[0]:.1f} '
                  f'({time.strftime("%H:%M:%S")})', file=sys.stderr, flush=True)
    load1 = os.getloadavg()
    factor = args.hours * 60.0 / args.short_minutes
    print(f'\nload average {load0[0]:.1f} at the start of the analyses, {load1[0]:.1f} at '
          f'the end; {os.cpu_count()} CPUs; date {time.strftime("%Y-%m-%d %H:%M")}\n')
    print('| bag | simulated | recorded in | blocks on disk | size | recorder peak RSS / CPU '
          '| analyse wall / CPU (median) | analyse peak RSS | windows |')
    print('|---|---|---|---|---|---|---|---|---|')
    for name, r in rows.items():
        doc = r['doc']['bags'][0]
        c = doc['counters']
        rec = r['rec']
        print(f'| {name} | {r["seconds"]:g} s | {rec["wall_s"]:.0f} s | {c["blocks"]} '
              f'(gaps {c["gaps"]}) | {r["size_gb"]:.2f} GB | '
              f'{rec["peaks_mb"].get("recorder", float("nan")):.0f} MB / '
              f'{rec["cpu_s"].get("recorder", float("nan")):.0f} s | '
              f'{_median(r["walls"]):.1f} s / {_median(r["cpus"]):.1f} s '
              f'(n={len(r["walls"])}) | {max(r["rss"]):.0f} MB | {c["complete_windows"]} |')
    for what, key in (('CPU (user+sys)', 'cpus'), ('wall', 'walls')):
        fixed, short, long_ = (_median(rows[n][key]) for n in ('fixed', 'short', 'long'))
        print(f'\nlinearity, {what}: (long - fixed) / ({factor:g} x (short - fixed)) = '
              f'{(long_ - fixed) / (factor * (short - fixed)):.3f}, fixed cost {fixed:.1f} s '
              f'(the command on a 2-second bag); without taking it off: '
              f'{long_ / (factor * short):.3f}')
    print(f'report of the long bag: {work / "report_long"}')
    (work / 'analyze.json').write_text(json.dumps(
        {n: {k: r[k] for k in ('walls', 'cpus', 'rss')} for n, r in rows.items()}, indent=1))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--hours', type=float, default=10.0)
    ap.add_argument('--short-minutes', type=float, default=10.0)
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--block-size', type=int, default=1000)
    ap.add_argument('--speed-factor', type=float, default=30.0,
                    help='bench fast-mode factor (0: as fast as possible, which outruns the '
                         'recorder on a loaded 2-core machine)')
    ap.add_argument('--repeats', type=int, default=3,
                    help='analyses of the 2-second and the short bag (interleaved)')
    ap.add_argument('--long-repeats', type=int, default=None,
                    help='analyses of the long bag, in the middle rounds (default: --repeats)')
    ap.add_argument('--stage', choices=('all', 'record', 'analyze'), default='all',
                    help='record: record the bags into --dir and keep them; analyze: analyse '
                         'the bags recorded there (record.json); all: both, then delete')
    ap.add_argument('--dir', type=Path, default=None)
    ap.add_argument('--keep', action='store_true', help='keep the bags and reports')
    args = ap.parse_args(argv)
    args.long_repeats = min(args.repeats, args.long_repeats or args.repeats)
    if args.stage != 'all' and args.dir is None:
        print('ERROR: --stage record/analyze needs --dir', file=sys.stderr)
        return 1
    work = args.dir or Path(tempfile.mkdtemp(prefix='rv-te-life-'))
    work.mkdir(parents=True, exist_ok=True)
    print(f'load average {os.getloadavg()[0]:.1f} at the start; '
          f'{time.strftime("%Y-%m-%d %H:%M:%S")}', file=sys.stderr, flush=True)
    if args.stage == 'analyze':
        rows = json.loads((work / 'record.json').read_text())
        _analyze_stage(work, rows, args)
        return 0
    free_gb = shutil.disk_usage(work).free / 1e9
    need_gb = args.hours * 3600 * args.rate_hz * 14.5 / 1e9 * 1.1
    if free_gb < need_gb + 5:
        print(f'ERROR: {free_gb:.0f} GB free in {work}, the bag needs ~{need_gb:.0f} GB',
              file=sys.stderr)
        return 1
    try:
        rows = _record_stage(work, args)
        if args.stage == 'all':
            _analyze_stage(work, rows, args)
    finally:
        if args.stage == 'all' and not args.keep:
            for name in ('fixed', 'short', 'long'):
                shutil.rmtree(work / f'rec_{name}', ignore_errors=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
