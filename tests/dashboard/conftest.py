"""Fixtures of the live page's tests: chromium (skipped with the reason when it is missing,
failed instead when RV_TE_REQUIRE_CHROMIUM=1, as .ci/run sets), free ports, a dashboard
process and its printed link."""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.dashboard.chromium import missing_reason

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='session')
def need_chromium() -> None:
    """Skip (or fail under RV_TE_REQUIRE_CHROMIUM=1) when chromium cannot run."""
    reason = missing_reason()
    if reason is None:
        return
    if os.environ.get('RV_TE_REQUIRE_CHROMIUM') == '1':
        pytest.fail(reason)
    pytest.skip(reason)


def free_port() -> int:
    """A TCP port free on loopback right now."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


def env() -> dict[str, str]:
    """The environment of a child rv-te (no ROS wheel bootstrap marker)."""
    e = dict(os.environ)
    e.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    e['PYTHONUNBUFFERED'] = '1'
    return e


class DashboardProcess:
    """``rv-te dashboard`` in a child process; ``url`` from the line it prints."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, '-m', 'rv_te_bench.cli.main', 'dashboard',
                                      *args], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                     text=True, env=env(), cwd=REPO)
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, daemon=True)
        self._t.start()
        end = time.monotonic() + 60
        while time.monotonic() < end and not any('dashboard: http' in ln for ln in self.lines):
            if self.proc.poll() is not None:
                break
            time.sleep(0.05)
        urls = [ln.split('dashboard: ', 1)[1].strip() for ln in self.lines
                if 'dashboard: http' in ln]
        assert urls, f'the dashboard did not start: {self.lines}'
        self.url = next((u for u in urls if '127.0.0.1' in u), urls[0])
        time.sleep(1.0)   # the bridge node's subscriptions discovered

    def _read(self) -> None:
        for line in self.proc.stderr:
            self.lines.append(line)

    def token(self) -> str | None:
        m = re.search(r'token=([\w-]+)', self.url)
        return m.group(1) if m else None

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
