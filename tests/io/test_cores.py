"""The helper-thread decision of the offline analysis (io/_cores.py), on planted inputs:
the affinity mask, the cgroup CPU quota (a container's --cpus), the switch."""

from __future__ import annotations

from pathlib import Path

import pytest

from rv_te_bench.io import _cores


@pytest.fixture
def machine(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """A 2-core machine whose cgroup cpu.max the test writes."""
    cpu_max = tmp_path / 'cpu.max'
    monkeypatch.setattr(_cores, '_CPU_MAX', cpu_max)
    monkeypatch.setattr('os.sched_getaffinity', lambda _pid: {0, 1})
    monkeypatch.delenv(_cores.READ_AHEAD_ENV, raising=False)

    def set_quota(quota: str) -> None:
        cpu_max.write_text(quota + '\n')
    return set_quota


@pytest.mark.parametrize(('quota', 'env', 'cores', 'helper'), [
    ('max 100000', None, 2.0, True),
    ('100000 100000', None, 1.0, False),     # a container limited to one CPU
    ('150000 100000', None, 1.5, False),     # 1.5 CPUs: no whole core for the helper
    ('200000 100000', None, 2.0, True),
    ('400000 100000', None, 2.0, True),      # a quota above the mask: the mask counts
    ('max 100000', '1', 2.0, True),
    ('100000 100000', '1', 1.0, False),      # on, but not on one CPU
    ('max 100000', '0', 2.0, False),         # off (a fleet worker per core)
    ('max 100000', ' 0 ', 2.0, False),
])
def test_helper_thread_only_with_two_cores(machine, monkeypatch: pytest.MonkeyPatch,
                                           quota: str, env: str | None, cores: float,
                                           helper: bool) -> None:
    machine(quota)
    if env is not None:
        monkeypatch.setenv(_cores.READ_AHEAD_ENV, env)
    assert _cores.allowed_cores() == cores
    assert _cores.helper_threads_allowed() is helper


def test_one_core_by_affinity(machine, monkeypatch: pytest.MonkeyPatch) -> None:
    machine('max 100000')
    monkeypatch.setattr('os.sched_getaffinity', lambda _pid: {1})
    assert _cores.allowed_cores() == 1.0
    assert _cores.helper_threads_allowed() is False


def test_no_cgroup_file_means_the_mask(machine, monkeypatch: pytest.MonkeyPatch,
                                      tmp_path: Path) -> None:
    monkeypatch.setattr(_cores, '_CPU_MAX', tmp_path / 'missing')
    assert _cores.allowed_cores() == 2.0
    assert _cores.helper_threads_allowed() is True
