"""A life-test-length session: record HOURS at 10 kHz (simulated, fast mode), then analyse it.

Issue 41, target 5. One command, every length a parameter:

    .venv/bin/python benchmarks/bench_life.py [--hours 10] [--short-minutes 10]
        [--rate-hz 10000] [--block-size 1000] [--speed-factor 0] [--dir DIR] [--keep]

Steps, each in fresh processes as a user runs them:

1. ``rv-te launch --default --nodes bench,recorder`` with the bench in fast mode for
   ``--short-minutes`` (the reference bag) and for ``--hours`` (the life-test bag); the
   recorder's peak resident memory is its VmHWM, read from /proc every 0.5 s while it runs
   (the last reading before it exits is its peak). Blocks on disk are counted against the
   blocks the bench published (the bag's own message count).
2. ``rv-te analyze BAG --json --no-advice --report DIR`` on both bags and on a 2-second bag
   recorded likewise (the command's fixed cost: interpreter start, imports, the report),
   ``--repeats`` times interleaved: wall time and peak RSS (``ru_maxrss`` from ``wait4``) of
   each; linearity = (long - fixed) / (hours * 60 / short minutes * (short - fixed)), and
   the same without taking the fixed cost off.
3. The report's TE plot of the long bag is kept with ``--keep``: it is drawn
   from the min/max envelope of every sample (rv_te_bench/core/envelope.py), not from every sample.

The long bag (~5.2 GB for 10 h at 10 kHz) is deleted at the end unless ``--keep``.
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


def _hwm_mb(pid: int) -> tuple[str, float] | None:
    try:
        cmd = Path(f'/proc/{pid}/cmdline').read_bytes().replace(b'\0', b' ').decode()
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmHWM:'):
                return cmd, int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


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
    stop = threading.Event()

    def poll() -> None:
        while not stop.is_set():
            for pid in _descendants(proc.pid):
                got = _hwm_mb(pid)
                if got is not None:
                    name = next((n for n in ('recorder', 'bench') if f' {n}' in got[0]
                                 or got[0].endswith(n)), None)
                    if name is not None:
                        peaks[name] = max(peaks.get(name, 0.0), got[1])
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
    return {'bag': bag, 'wall_s': wall, 'peaks_mb': peaks,
            'log': [ln for ln in log.splitlines() if 'complete' in ln or 'closed' in ln]}


def analyze(bag: Path, report: Path) -> tuple[float, float, dict]:
    """``rv-te analyze`` in a fresh process: wall [s], peak RSS [MB], its JSON."""
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
    return wall, usage.ru_maxrss / 1024.0, json.loads(text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--hours', type=float, default=10.0)
    ap.add_argument('--short-minutes', type=float, default=10.0)
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--block-size', type=int, default=1000)
    ap.add_argument('--speed-factor', type=float, default=0.0,
                    help='bench fast-mode factor (0: as fast as possible)')
    ap.add_argument('--repeats', type=int, default=3, help='analyses of each bag (interleaved)')
    ap.add_argument('--dir', type=Path, default=None)
    ap.add_argument('--keep', action='store_true', help='keep the bags and reports')
    args = ap.parse_args(argv)
    work = args.dir or Path(tempfile.mkdtemp(prefix='rv-te-life-'))
    work.mkdir(parents=True, exist_ok=True)
    load0 = os.getloadavg()
    free_gb = shutil.disk_usage(work).free / 1e9
    need_gb = args.hours * 3600 * args.rate_hz * 24.5 / 1e9 * 1.1
    if free_gb < need_gb + 5:
        print(f'ERROR: {free_gb:.0f} GB free in {work}, the bag needs ~{need_gb:.0f} GB',
              file=sys.stderr)
        return 1
    rows = {}
    try:
        for name, seconds in (('fixed', 2.0), ('short', args.short_minutes * 60.0),
                              ('long', args.hours * 3600)):
            rec = record(work / f'rec_{name}', seconds, args)
            size_gb = sum(f.stat().st_size for f in rec['bag'].iterdir()) / 1e9
            print(f'{name}: recorded {seconds:g} s in {rec["wall_s"]:.0f} s, {size_gb:.2f} GB, '
                  f'peak RSS {rec["peaks_mb"]}; {rec["log"]}', file=sys.stderr)
            rows[name] = {'rec': rec, 'size_gb': size_gb, 'walls': [], 'rss': []}
        for _ in range(args.repeats):
            for name in ('fixed', 'short', 'long'):
                wall, rss, doc = analyze(rows[name]['rec']['bag'], work / f'report_{name}')
                rows[name]['walls'].append(wall)
                rows[name]['rss'].append(rss)
                rows[name]['doc'] = doc
                print(f'{name}: analysed in {wall:.1f} s, peak RSS {rss:.0f} MB',
                      file=sys.stderr)
    finally:
        if not args.keep:
            for name in ('fixed', 'short', 'long'):
                shutil.rmtree(work / f'rec_{name}', ignore_errors=True)
    load1 = os.getloadavg()
    import statistics
    factor = args.hours * 60.0 / args.short_minutes
    med = {k: statistics.median(v['walls']) for k, v in rows.items()}
    print(f'\nload average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end; '
          f'{os.cpu_count()} CPUs; date {time.strftime("%Y-%m-%d %H:%M")}\n')
    print('| bag | recorded | blocks on disk | size | recorder peak RSS | analyse wall '
          f'(median of {args.repeats}) | analyse peak RSS | windows |')
    print('|---|---|---|---|---|---|---|---|')
    for name, r in rows.items():
        doc = r['doc']['bags'][0]
        c = doc['counters']
        print(f'| {name} | {r["rec"]["wall_s"]:.0f} s | {c["blocks"]} (gaps {c["gaps"]}) | '
              f'{r["size_gb"]:.2f} GB | {r["rec"]["peaks_mb"].get("recorder", float("nan")):.0f}'
              f' MB | {med[name]:.1f} s | {max(r["rss"]):.0f} MB | {c["complete_windows"]} |')
    per = [round(lo / (factor * s), 3)
           for lo, s in zip(rows['long']['walls'], rows['short']['walls'], strict=True)]
    fixed = med['fixed']
    print(f'\nlinearity: (long - fixed) / ({factor:g} x (short - fixed)) = '
          f'{(med["long"] - fixed) / (factor * (med["short"] - fixed)):.3f}, fixed cost '
          f'{fixed:.1f} s (the command on a 2-second bag); without taking it off: '
          f'{med["long"] / (factor * med["short"]):.3f} (per repeat {per})')
    print(f'report of the long bag: {work / "report_long"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
