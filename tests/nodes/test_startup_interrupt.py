"""Ctrl-C works while a command starts (issue #16): reading a bag before playback included.

``rv-te replay`` and ``rv-te record`` build their node inside :func:`run_node`, whose signal
handler only requested a stop: a SIGINT while the node was still being built (a large
metadata.yaml being read) waited for the whole start-up, and before that a SIGINT while the
subcommands imported ended in a traceback.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.ros


@pytest.mark.timeout(60)
def test_sigint_while_the_node_is_built_stops_at_once(ros_domain_id: int,
                                                      capsys: pytest.CaptureFixture[str],
                                                      ) -> None:
    from rv_te_bench.nodes.common import run_node  # noqa: PLC0415

    deadline = time.monotonic() + 20.0

    def slow_factory(_ctx: object) -> object:   # a start-up that takes 20 s
        while time.monotonic() < deadline:
            time.sleep(0.01)
        msg = 'start-up was not interrupted'
        raise AssertionError(msg)

    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    t0 = time.monotonic()
    timer.start()
    try:
        code = run_node(slow_factory, ['test'])
    finally:
        timer.cancel()
    assert code == 130
    assert time.monotonic() - t0 < 5.0
    assert 'interrupted' in capsys.readouterr().err


def big_metadata_bag(folder: Path, size_bytes: int = 4 << 20) -> Path:
    """A bag folder whose metadata.yaml is as large as allowed (~24,000 listed files)."""
    folder.mkdir()
    lines = ['rosbag2_bagfile_information:', '  version: 9', '  storage_identifier: mcap',
             '  relative_file_paths:']
    size = sum(len(x) + 1 for x in lines)
    i = 0
    while size < size_bytes - 200:
        lines.append(f'    - rv_te_20260101_000000_{i}.mcap')
        size += len(lines[-1]) + 1
        i += 1
    (folder / 'metadata.yaml').write_text('\n'.join(lines) + '\n', encoding='utf-8')
    return folder


@pytest.mark.timeout(120)
def test_replay_stops_on_ctrl_c_while_reading_the_bag(tmp_path: Path) -> None:
    bag = big_metadata_bag(tmp_path / 'bag')
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    proc = subprocess.Popen(
        [sys.executable, '-c', 'import sys; from rv_te_bench.cli.main import main; '
                               'sys.exit(main())', 'replay', str(bag)],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(2.0)   # imports done (~1 s); the 4 MiB metadata.yaml takes ~4 s
        assert proc.poll() is None
        first = time.monotonic()
        proc.send_signal(signal.SIGINT)   # one Ctrl-C, wherever start-up is
        while proc.poll() is None and time.monotonic() - first < 10.0:
            time.sleep(0.05)
        stopped_after_s = time.monotonic() - first
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert 'Traceback' not in err, err
    assert stopped_after_s < 3.0, err
