"""Ctrl-C works while a command starts (issue #16): reading a bag before playback included.

``rv-te replay`` and ``rv-te record`` build their node inside :func:`run_node`, whose signal
handler only requested a stop: a SIGINT while the node was still being built (a large
metadata.yaml being read) waited for the whole start-up, and before that a SIGINT while the
subcommands imported ended in a traceback.
"""

from __future__ import annotations

import os
import select
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
    from rv_te_bench.nodes.common import run_node

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


def _swallowed_ctrl_c() -> None:
    """A Ctrl-C whose KeyboardInterrupt is lost where it lands, as in a ``__del__`` (Python
    ignores exceptions there: seen in rclpy's logger finaliser while a replay read its bag)."""
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.2)   # the handler runs here
    except KeyboardInterrupt:
        pass


@pytest.mark.timeout(60)
@pytest.mark.parametrize('start_up_then', ['fails', 'succeeds'])
def test_a_ctrl_c_lost_during_start_up_still_stops_the_node(
        ros_domain_id: int, capsys: pytest.CaptureFixture[str], start_up_then: str) -> None:
    from rclpy.node import Node

    from rv_te_bench.errors import RvTeError
    from rv_te_bench.nodes.common import run_node

    built: list[Node] = []

    def factory(ctx: object) -> Node:
        _swallowed_ctrl_c()
        if start_up_then == 'fails':   # what the replay did next: missing files, exit 1
            msg = 'files listed in metadata.yaml are missing'
            raise RvTeError(msg)
        built.append(Node('lost_ctrl_c', context=ctx))
        built[0].finished = True   # a stop not remembered: it would end at once with 0
        return built[0]

    t0 = time.monotonic()
    code = run_node(factory, ['test'])
    assert code == 130
    assert time.monotonic() - t0 < 10.0
    err = capsys.readouterr().err
    assert 'interrupted while starting' in err and 'missing' not in err, err


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


def _replay(bag: Path) -> subprocess.Popen[str]:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    return subprocess.Popen(
        [sys.executable, '-c', 'import sys; from rv_te_bench.cli.main import main; '
                               'sys.exit(main())', 'replay', str(bag)],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.timeout(180)
def test_replay_stops_on_ctrl_c_while_reading_the_bag(tmp_path: Path) -> None:
    bag = big_metadata_bag(tmp_path / 'bag')
    # Uninterrupted, the replay imports (~1 s) and reads the 4 MiB metadata.yaml (seconds,
    # with the machine's load) before it fails on the missing files: measure that start-up
    # under the same load, then interrupt it half-way (a fixed delay raced a quiet machine).
    t0 = time.monotonic()
    proc = _replay(bag)
    _, err = proc.communicate(timeout=120)
    startup_s = time.monotonic() - t0
    assert proc.returncode == 1, err
    # one bounded line (it once listed all ~100,000 missing files: 10 MB of error)
    assert err.count('\n') == 1 and len(err) < 1000, err[:2000]
    assert 'file(s) listed in metadata.yaml are missing' in err and 'more' in err, err
    assert startup_s > 1.0, startup_s

    # The second start-up can be faster than the first (the load changed): a process that
    # has ended before the signal tested nothing, so it is tried again, interrupted earlier.
    for fraction in (0.6, 0.3, 0.15):
        proc = _replay(bag)
        try:
            time.sleep(fraction * startup_s)
            # ended, or already past its start-up: its one line (the missing files) is out
            # and it is only tearing down (a full run with four workers sent the Ctrl-C
            # there: exit 1 with that line, a signal that came after the decision)
            if proc.poll() is not None or select.select([proc.stderr], [], [], 0)[0]:
                proc.communicate(timeout=20)
                continue
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
        break
    else:
        pytest.fail(f'the replay ended its start-up before 0.15 x {startup_s:.1f} s every time')
    assert proc.returncode == 130, err[:2000]
    assert 'Traceback' not in err, err[:2000]
    assert stopped_after_s < 3.0, err[:2000]
