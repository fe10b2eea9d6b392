"""The test files' times from the last `make test` (kept in .pytest_cache by tests/conftest.py):
rewrites the committed table tests/seconds_per_file.json (it orders a fresh clone's parallel
run longest-first) and prints the files that took most wall and CPU seconds.

    .venv/bin/python scripts/test_seconds.py [--top N] [--print-only]   (make test-seconds)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / '.pytest_cache' / 'v' / 'rv_te_bench'
TABLE = ROOT / 'tests' / 'seconds_per_file.json'


def _kept(name: str) -> dict[str, float]:
    path = CACHE / name
    return json.loads(path.read_text(encoding='utf-8')) if path.is_file() else {}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--top', type=int, default=25, help='files listed (default 25)')
    parser.add_argument('--print-only', action='store_true',
                        help='list the files; leave the committed table as it is')
    args = parser.parse_args()
    seconds, cpu = _kept('seconds_per_file'), _kept('cpu_seconds_per_file')
    if not seconds:
        parser.error(f'no times in {CACHE}: run `make test` first')
    table = {f: round(s, 1) for f, s in sorted(seconds.items()) if (ROOT / f).is_file()}
    if not args.print_only:
        TABLE.write_text(json.dumps(table, indent=0) + '\n', encoding='utf-8')
    done = '' if args.print_only else ' rewritten'
    cpu_s = sum(cpu.get(f, 0.0) for f in table)
    print(f'{TABLE.relative_to(ROOT)}{done}: {len(table)} files, '
          f'{sum(table.values()):.0f} s summed, {cpu_s:.0f} CPU s')
    print(f'{"wall s":>8} {"CPU s":>8}  file')
    for f in sorted(table, key=table.__getitem__, reverse=True)[:args.top]:
        c = f'{cpu[f]:8.1f}' if f in cpu else f'{"-":>8}'
        print(f'{table[f]:8.1f} {c}  {f}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
