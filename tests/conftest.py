"""Shared test set-up: hypothesis profiles, ROS isolation (own domain id, localhost only),
and a guard that no test leaves files in the repository (issue #15)."""

from __future__ import annotations

import atexit
import json
import os
import resource
import shutil
import subprocess
import tempfile
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, settings

from rv_te_bench.allocator import tune_for_batch_work
from rv_te_bench.nodes.middleware import use_quick_acknowledgements

# One BLAS / OpenMP thread per test process and per process a test starts, unless set (as
# the node processes, rv_te_bench.launch.session.NODE_THREAD_ENV, and the batch commands,
# rv_te_bench.allocator, have it). The suite runs cores + 1 workers: OpenBLAS's pool of one
# spinning thread per core in each only burns CPU the other workers need (issue 39 s.4:
# tests/core/test_uncertainty_validation.py 36.2 / 43.0 -> 28.2 / 14.4 CPU s, side by side
# on the 2-core VM at load 9-25). Set before anything imports numpy.
for _var in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')
# And the batch commands' malloc settings (rv_te_bench.allocator; per process, not inherited):
# the tests evaluate models on arrays of megabytes, which glibc's defaults map and fault in
# afresh on every operation (tests/core/test_phases.py spent 7.7 of its 17.8 CPU s in the
# kernel; 0.3 s tuned). A test process that ran `rv-te analyze` in process had them already.
tune_for_batch_work()

settings.register_profile('dev', deadline=None, max_examples=60)
settings.register_profile('ci', deadline=None, max_examples=100,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile('ci' if os.environ.get('CI') else 'dev')

# ROS isolation. Every test process gets a DDS domain of its own, so that two runs on one
# machine (or a run beside the demo), and the pytest-xdist workers of one run, never see each
# other's messages; discovery stays on this host. Set before any test imports rclpy.
#
# The run is named by the pid of its first pytest process (the xdist controller, whose
# environment the workers inherit). Worker k of n (k = 0 without xdist) takes
#   ROS_DOMAIN_ID given:  that id + k (give a parallel run a block of n free ids);
#   else:                 100 + (run pid % (100 // n)) * n + k   (a block of n in 100..199).
_MAX_DOMAIN_ID = 232   # Fast DDS's port arithmetic (7400 + 250 * id + ...) ends there


def _ros_domain_id() -> int:
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    k = int(worker[2:]) if worker.startswith('gw') else 0
    n = max(1, int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1')))
    given = os.environ.get('RV_TE_TEST_GIVEN_DOMAIN_ID', '')
    if given:
        if not given.isdigit():
            msg = f'ROS_DOMAIN_ID must be a whole number, got {given!r}'
            raise pytest.UsageError(msg)
        domain = int(given) + k
    else:
        slots = max(1, 100 // n)
        domain = 100 + int(os.environ['RV_TE_TEST_RUN_PID']) % slots * n + k
    if domain > _MAX_DOMAIN_ID:
        raise pytest.UsageError(_too_high(int(given or 0), n))
    return domain


def _too_high(given: int, n: int) -> str:
    return (f'ROS_DOMAIN_ID={given} with {n} workers needs ROS domains up to {given + n - 1}, '
            f'above {_MAX_DOMAIN_ID}: give at most {_MAX_DOMAIN_ID - n + 1}, or fewer workers')


def pytest_configure(config: pytest.Config) -> None:
    """The controller refuses a domain block past the last id before starting workers."""
    n = getattr(config.option, 'numprocesses', None)
    given = os.environ.get('RV_TE_TEST_GIVEN_DOMAIN_ID', '')
    if not os.environ.get('PYTEST_XDIST_WORKER') and isinstance(n, int) and n > 1 and \
            given.isdigit() and int(given) + n - 1 > _MAX_DOMAIN_ID:
        raise pytest.UsageError(_too_high(int(given), n))


if 'RV_TE_TEST_RUN_PID' not in os.environ:        # the run's first pytest process
    os.environ['RV_TE_TEST_RUN_PID'] = str(os.getpid())
    os.environ['RV_TE_TEST_GIVEN_DOMAIN_ID'] = os.environ.get('ROS_DOMAIN_ID', '')
os.environ['ROS_DOMAIN_ID'] = str(_ros_domain_id())

# The results store (issue 33): the commands' default is the user's own store under
# ~/.local/share (XDG_DATA_HOME). Tests never write there: every test process gets a data
# folder of its own (removed at exit) and a developer's RV_TE_DB is not inherited; a test
# that checks the default store points XDG_DATA_HOME at its tmp_path. The session also
# fails when the real default store changed during the run (pytest_sessionfinish).
REAL_DEFAULT_STORE = Path(os.environ.get('RV_TE_TEST_REAL_XDG_DATA_HOME')
                          or os.environ.get('XDG_DATA_HOME')
                          or Path.home() / '.local' / 'share') / 'rv-te' / 'results.sqlite'
os.environ.setdefault('RV_TE_TEST_REAL_XDG_DATA_HOME', str(REAL_DEFAULT_STORE.parents[1]))
_TEST_DATA_HOME = tempfile.mkdtemp(prefix='rv-te-test-data-')
atexit.register(shutil.rmtree, _TEST_DATA_HOME, ignore_errors=True)
os.environ['XDG_DATA_HOME'] = _TEST_DATA_HOME
os.environ.pop('RV_TE_DB', None)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
# The nodes a test runs in this process get the middleware settings of a node process
# (rv_te_bench.nodes.middleware: acknowledgements within ~0.1 s, not Fast DDS's 3 s).
use_quick_acknowledgements(os.environ)

#: Fixtures that start ROS (in process or in a child): a test using one is a ``ros`` test.
ROS_FIXTURES = frozenset({'ros_domain_id', 'ros_context', 'graph'})


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test that uses a ROS fixture ``ros`` (before ``-m`` selects), so that
    ``-m "not ros"`` (``make test-fast``) cannot pick up a test that starts nodes."""
    for item in items:
        if ROS_FIXTURES & set(getattr(item, 'fixturenames', ())) and \
                item.get_closest_marker('ros') is None:
            item.add_marker(pytest.mark.ros)
    _heaviest_files_first(config, items)


# --------------------------------------------------------------------------------------
# Order for parallel runs (make test: pytest-xdist, --dist loadfile hands out whole files in
# collection order): the files that took longest last time start first, so that no long
# file starts last and runs alone at the end (longest-processing-time-first scheduling).
# The seconds per file are kept in pytest's cache (.pytest_cache) by the run that measured
# them; where the cache has none (a fresh clone: CI), the table committed in
# tests/seconds_per_file.json gives them (`make test-seconds` rewrites it from the cache of
# the last full run). Files without a time (a new file, or one the measuring run left out)
# go first, those with slow ROS tests first, then slow, then ROS tests. Tests keep their
# order within a file.

_SECONDS_KEY = 'rv_te_bench/seconds_per_file'
SECONDS_TABLE = Path(__file__).with_name('seconds_per_file.json')


def committed_seconds() -> dict[str, float]:
    """The committed seconds per file ({} when the table is missing or unreadable)."""
    try:
        table = json.loads(SECONDS_TABLE.read_text(encoding='utf-8'))
    except (OSError, ValueError):
        return {}
    return {str(f): float(s) for f, s in table.items()} if isinstance(table, dict) else {}


def _heaviest_files_first(config: pytest.Config, items: list[pytest.Item]) -> None:
    cache = getattr(config, 'cache', None)
    seconds = committed_seconds()
    seconds.update((cache.get(_SECONDS_KEY, {}) if cache is not None else {}) or {})
    weight: dict[str, tuple[float, int]] = {}
    for item in items:
        f = item.nodeid.split('::', 1)[0]
        kind = 2 * bool(item.get_closest_marker('slow')) + bool(item.get_closest_marker('ros'))
        w, k = weight.get(f, (seconds.get(f, 0.0), 0))
        weight[f] = (w, max(k, kind))
    first = {f: i for i, f in reversed(list(enumerate(
        item.nodeid.split('::', 1)[0] for item in items)))}

    def key(item: pytest.Item) -> tuple[int, float, int]:
        f = item.nodeid.split('::', 1)[0]
        if f not in seconds:   # new, or left out of the measuring run (make test-fast leaves
            return (0, -weight[f][1], first[f])   # out the ROS and slow ones): likely long
        return (1, -weight[f][0], first[f])

    items.sort(key=key)


def _cpu_s() -> float:
    """CPU seconds (user + system) of this process and of its children waited for."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(
        resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


_CPU_KEY = pytest.StashKey[float]()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Generator[None, None, None]:
    item.stash[_CPU_KEY] = _cpu_s()
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item,
                              call: pytest.CallInfo[None]) -> Generator[None, Any, None]:
    """Each phase's report carries the CPU seconds the test used since its setup began
    (user_properties travel from an xdist worker to the controller)."""
    outcome = yield
    if call.when == 'teardown' and _CPU_KEY in item.stash:
        outcome.get_result().user_properties.append(
            ('cpu_s', _cpu_s() - item.stash[_CPU_KEY]))


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Seconds and CPU seconds per file of this run (under xdist the controller gets every
    worker's reports)."""
    if os.environ.get('PYTEST_XDIST_WORKER'):
        return
    f = report.nodeid.split('::', 1)[0]
    _RUN_SECONDS[f] = _RUN_SECONDS.get(f, 0.0) + report.duration
    for name, value in report.user_properties:
        if name == 'cpu_s':
            _RUN_CPU[f] = _RUN_CPU.get(f, 0.0) + float(value)


_RUN_SECONDS: dict[str, float] = {}
_RUN_CPU: dict[str, float] = {}
_CPU_SECONDS_KEY = 'rv_te_bench/cpu_seconds_per_file'


def _store_seconds(session: pytest.Session) -> None:
    cache = getattr(session.config, 'cache', None)
    if cache is None or not _RUN_SECONDS:
        return
    for key, run in ((_SECONDS_KEY, _RUN_SECONDS), (_CPU_SECONDS_KEY, _RUN_CPU)):
        kept = dict(cache.get(key, {}) or {})
        kept.update({f: round(s, 2) for f, s in run.items()})
        cache.set(key, kept)


@pytest.fixture
def ros_domain_id() -> int:
    """The DDS domain id of this test process (see above)."""
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
           '.ruff_cache', '.mypy_cache', '.import_linter_cache')


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


@pytest.fixture(autouse=True)
def default_store(monkeypatch: pytest.MonkeyPatch,
                  tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Every test has a data folder of its own: the commands' default results store
    (XDG_DATA_HOME/rv-te/results.sqlite, the path returned) starts empty in each test."""
    home = tmp_path_factory.mktemp('data-home')
    monkeypatch.setenv('XDG_DATA_HOME', str(home))
    monkeypatch.delenv('RV_TE_DB', raising=False)
    return home / 'rv-te' / 'results.sqlite'


def _real_store_state() -> tuple[int, int] | None:
    try:
        st = REAL_DEFAULT_STORE.stat()
    except OSError:
        return None
    return st.st_size, st.st_mtime_ns


def pytest_sessionstart(session: pytest.Session) -> None:
    session.config.stash[_REAL_STORE_KEY] = _real_store_state()
    # under pytest-xdist the controller checks (a worker would see another's files in flight);
    # a mutation run (mutmut) runs a copy of the tree in mutants/, many sessions a second
    if not os.environ.get('PYTEST_XDIST_WORKER') and 'MUTANT_UNDER_TEST' not in os.environ:
        session.config.stash[_LITTER_KEY] = repo_litter()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    _store_seconds(session)
    if session.config.stash.get(_REAL_STORE_KEY, None) != _real_store_state():
        reporter = session.config.pluginmanager.get_plugin('terminalreporter')
        if reporter is not None:
            reporter.write_line(f'ERROR: tests wrote to the real results store '
                                f'{REAL_DEFAULT_STORE} (use tmp_path, --db or --no-db)',
                                red=True, bold=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
    before = session.config.stash.get(_LITTER_KEY, None)
    if before is None:
        return
    after = repo_litter()
    if after is None:
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
_REAL_STORE_KEY = pytest.StashKey[tuple[int, int] | None]()
