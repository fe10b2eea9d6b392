"""Shared test set-up: hypothesis profiles, ROS isolation (own domain id, localhost only),
and a guard that no test leaves files in the repository (issue #15)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile('dev', deadline=None, max_examples=60)
settings.register_profile('ci', deadline=None, max_examples=100,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile('ci' if os.environ.get('CI') else 'dev')

# Every test run gets its own DDS domain derived from the process id, so that two runs on one
# machine (or a run beside the demo) never see each other's messages; discovery stays on
# this host. Set before any test imports rclpy.
os.environ.setdefault('ROS_DOMAIN_ID', str(100 + os.getpid() % 100))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)


@pytest.fixture
def ros_domain_id() -> int:
    """The DDS domain id of this test run."""
    return int(os.environ['ROS_DOMAIN_ID'])


@pytest.fixture
def ros_context(ros_domain_id: int):
    """An initialised rclpy Context of its own, shut down after the test."""
    rclpy = pytest.importorskip('rclpy')
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=ros_domain_id)
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)


# --------------------------------------------------------------------------------------
# The repository stays clean (issue #15): a test that analysed bags/sample without --no-db
# left bags/rv-te-results.sqlite behind (ignored by .gitignore, so nobody saw it). The
# session compares the untracked and ignored entries at the repository's root and under
# bags/ before and after the run and fails the run, naming them, when new ones appeared.
# Caches of the tools themselves are not counted.

REPO = Path(__file__).resolve().parents[1]
_CACHES = ('__pycache__', '.pytest_cache', '.hypothesis', '.egg-info', '.coverage',
           '.ruff_cache', '.mypy_cache')


def repo_litter() -> set[str] | None:
    """Untracked or ignored entries at the repository's root or under bags/ (directories
    collapsed), without tool caches; None when this is no git checkout."""
    try:
        out = subprocess.run(
            ['git', '-C', str(REPO), 'status', '--porcelain=v1', '-z', '--ignored=traditional',
             '--untracked-files=normal', '--', '.'],
            capture_output=True, timeout=60, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    found = set()
    for entry in out.split(b'\0'):
        if entry[:3] not in (b'?? ', b'!! '):
            continue
        path = os.fsdecode(entry[3:])
        if any(c in path for c in _CACHES):
            continue
        if '/' not in path.rstrip('/') or path.startswith('bags/'):
            found.add(path)
    return found


def pytest_sessionstart(session: pytest.Session) -> None:
    session.config.stash[_LITTER_KEY] = repo_litter()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    before = session.config.stash.get(_LITTER_KEY, None)
    after = repo_litter()
    if before is None or after is None:
        return
    new = sorted(after - before)
    if new:
        reporter = session.config.pluginmanager.get_plugin('terminalreporter')
        text = (f'tests left {len(new)} new file(s) in the repository (use tmp_path, '
                f'--no-db or --db in tests): {", ".join(new)}')
        if reporter is not None:
            reporter.write('\n')
            reporter.write_line(f'ERROR: {text}', red=True, bold=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


_LITTER_KEY = pytest.StashKey[set[str] | None]()
