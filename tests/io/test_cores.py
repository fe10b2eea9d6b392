"""The helper-thread decision of the offline analysis (io/_cores.py), on planted inputs:
the affinity mask, the cgroup CPU quota (a container's --cpus), the switch, the bag's size."""

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


@pytest.mark.parametrize(('quota', 'env', 'size', 'helper'), [
    ('max 100000', None, _cores.HELPER_MIN_BAG_BYTES, True),       # two cores, a big bag
    ('max 100000', None, 10 * _cores.HELPER_MIN_BAG_BYTES, True),
    ('max 100000', None, _cores.HELPER_MIN_BAG_BYTES - 1, False),  # too small to pay
    ('max 100000', None, 0, False),
    ('max 100000', '1', 0, True),                                   # forced on
    ('max 100000', ' 1 ', 1000, True),
    ('max 100000', '0', 10 * _cores.HELPER_MIN_BAG_BYTES, False),  # off
    ('100000 100000', None, 10 * _cores.HELPER_MIN_BAG_BYTES, False),   # one CPU
    ('100000 100000', '1', 10 * _cores.HELPER_MIN_BAG_BYTES, False),    # on, one CPU
])
def test_analysis_uses_the_helper_only_for_bags_worth_it(
        machine, monkeypatch: pytest.MonkeyPatch, quota: str, env: str | None, size: int,
        helper: bool) -> None:
    machine(quota)
    if env is not None:
        monkeypatch.setenv(_cores.READ_AHEAD_ENV, env)
    assert _cores.analysis_uses_helper(size) is helper


def test_analysis_path_sizes_the_bag_by_its_files(machine, monkeypatch: pytest.MonkeyPatch,
                                                   tmp_path: Path) -> None:
    """analysis_path sums the bag's storage files (a bag folder and its .mcap alike); a bag
    that cannot be opened gets the one-thread path (the analysis then says why)."""
    import numpy as np

    from rv_te_bench.report.analysis import analysis_path
    from tests.unit_bags import mcap_file, write_unit_bag

    machine('max 100000')
    th = np.linspace(0.0, 2 * np.pi * 79.0, 20_000)
    bag = write_unit_bag(tmp_path / 'bag', th, th / 79.0, rate_hz=1000.0)
    size = mcap_file(bag).stat().st_size
    assert size > 1000
    monkeypatch.setattr(_cores, 'HELPER_MIN_BAG_BYTES', size)
    assert analysis_path(bag) == 'helper'
    assert analysis_path(mcap_file(bag)) == 'helper'
    monkeypatch.setattr(_cores, 'HELPER_MIN_BAG_BYTES', size + 1)
    assert analysis_path(bag) == 'one thread'
    assert analysis_path(tmp_path / 'missing') == 'one thread'
    monkeypatch.setattr(_cores, 'HELPER_MIN_BAG_BYTES', 0)
    assert analysis_path(tmp_path / 'missing') == 'one thread'
