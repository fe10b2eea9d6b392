"""``rv-te ... | head -1``: the reader leaving is no error (issue #15 item 7): exit 0, silent.

The pipe's read end is closed before the command writes, so every write meets EPIPE (the
same as ``head`` exiting after its first line, without the race).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = str(ROOT / 'bags' / 'sample')

COMMANDS = [
    ['presets'],
    ['presets', 'wang2020-2kv'],
    ['presets', 'wang2020-2kv', '--json'],
    ['model', 'wang2020-2kv', '--json'],
    ['compensate', 'hu2020-rv', '--te-arcmin', '1.2'],
    ['identify', SAMPLE, '--no-recommend', '--quiet'],
    ['analyze', SAMPLE, '--no-advice', '--quiet', '--no-db'],   # the repo stays clean (#15)
    ['launch', '--default', '--check'],
    ['--help'],
]


@pytest.mark.timeout(180)
@pytest.mark.parametrize('argv', COMMANDS, ids=[' '.join(a[:2]) for a in COMMANDS])
def test_closed_stdout_is_quiet_and_exit_0(argv: list[str]) -> None:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    read_end, write_end = os.pipe()
    os.close(read_end)   # nobody reads: the first write fails with EPIPE
    try:
        proc = subprocess.run(
            [sys.executable, '-c',
             'import sys; from rv_te_bench.cli.main import main; sys.exit(main())', *argv],
            cwd=ROOT, env=env, stdout=write_end, stderr=subprocess.PIPE, text=True,
            timeout=150, check=False)
    finally:
        os.close(write_end)
    assert proc.returncode == 0, proc.stderr
    assert 'Broken pipe' not in proc.stderr
    assert 'Traceback' not in proc.stderr
    assert 'Exception ignored' not in proc.stderr
