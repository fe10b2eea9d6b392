"""Identification speed: `rv-te identify` vs `rv-te analyze` on the same long bag (issue #15).

Writes a wang2020-2kv bench session (default 10 minutes at 10 kHz, RON 886, blocks of 100:
the bench node's default) with the same code as bags/make_sample.py, then runs, side by
side and interleaved in one run, as whole commands in fresh processes (interpreter start
and imports included; what a user waits for):

  * `rv-te analyze BAG --json --quiet` (statistics, spectra and its default advice) and
    `rv-te identify BAG --json --quiet` (identification and re-assembly advice);
  * the same without advice: `analyze --no-advice` and `identify --no-recommend`.

Each command's wall time and peak resident memory (ru_maxrss of that child, from wait4) are
recorded; the table gives the medians and the ratio identify / analyze per pair. The target
is identify <= 1.5 x analyze; the memory column shows that identify does not hold the
record (the fold keeps 2^15 bins whatever the length).

    .venv/bin/python benchmarks/bench_identify.py [--minutes 10] [--rate-hz 10000]
        [--block 100] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'bags'))

PAIRS = (
    ('with advice', ['analyze', '--json', '--quiet'], ['identify', '--json', '--quiet']),
    ('no advice', ['analyze', '--json', '--quiet', '--no-advice'],
     ['identify', '--json', '--quiet', '--no-recommend']),
)


def _run(cmd: list[str]) -> tuple[float, float]:
    """(wall time [s], peak RSS [MB]) of one command in a fresh process."""
    env = {k: v for k, v in os.environ.items() if k != '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT,
                            env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ''
    if proc.returncode != 0:
        msg = f'{" ".join(cmd)} exited {proc.returncode}: {err}'
        raise RuntimeError(msg)
    return wall, usage.ru_maxrss / 1024.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--minutes', type=float, default=10.0)
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--block', type=int, default=100)
    ap.add_argument('--repeats', type=int, default=3)
    args = ap.parse_args(argv)

    from make_sample import write_sample

    tmp = Path(tempfile.mkdtemp(prefix='rv-te-identify-bench-'))
    bag = tmp / 'bag'
    t0 = time.perf_counter()
    info = write_sample(bag, duration_s=args.minutes * 60.0, sample_rate_hz=args.rate_hz,
                        block_size=args.block)
    size_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
    print(f'bag: {info["blocks"]} blocks of {args.block}, {info["samples"]} samples, '
          f'{size_mb:.1f} MB (written in {time.perf_counter() - t0:.1f} s)', file=sys.stderr)
    exe = [sys.executable, '-m', 'rv_te_bench.cli.main']
    runs: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for _ in range(args.repeats):          # interleaved, so machine noise hits all alike
        for label, analyze, identify in PAIRS:
            for name, sub in (('analyze', analyze), ('identify', identify)):
                cmd = [*exe, sub[0], str(bag), *sub[1:]]
                runs.setdefault((label, name), []).append(_run(cmd))

    print(f'\nmachine: {platform.node()} {platform.machine()}, {os.cpu_count()} cores, '
          f'python {platform.python_version()}, date {time.strftime("%Y-%m-%d")}; '
          f'{args.minutes:g} min at {args.rate_hz:g} Hz ({info["samples"]} samples, blocks of '
          f'{args.block}, {size_mb:.0f} MB), median of {args.repeats}\n')
    print('| pair | `rv-te analyze` [s] | `rv-te identify` [s] | identify / analyze '
          '(per repeat) | peak RSS analyze / identify [MB] |')
    print('|---|---|---|---|---|')
    for label, _, _ in PAIRS:
        a = runs[(label, 'analyze')]
        i = runs[(label, 'identify')]
        ratios = sorted(x[0] / y[0] for x, y in zip(i, a, strict=True))
        wa = statistics.median(x[0] for x in a)
        wi = statistics.median(x[0] for x in i)
        print(f'| {label} | {wa:.2f} | {wi:.2f} | {wi / wa:.2f} ({ratios[0]:.2f}..'
              f'{ratios[-1]:.2f}) | {max(x[1] for x in a):.0f} / {max(x[1] for x in i):.0f} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
