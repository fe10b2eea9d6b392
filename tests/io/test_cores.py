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
    that cannot be opened gets the one-thread path (the analysis then says why). A bag big
    enough: the machine decides, unless RV_TE_READ_AHEAD=1 starts the helper at once."""
    import numpy as np

    from rv_te_bench.report.analysis import analysis_path
    from tests.unit_bags import mcap_file, write_unit_bag

    machine('max 100000')
    th = np.linspace(0.0, 2 * np.pi * 79.0, 20_000)
    bag = write_unit_bag(tmp_path / 'bag', th, th / 79.0, rate_hz=1000.0)
    size = mcap_file(bag).stat().st_size
    assert size > 1000
    monkeypatch.setattr(_cores, 'HELPER_MIN_BAG_BYTES', size)
    assert analysis_path(bag) == 'machine decides'
    assert analysis_path(mcap_file(bag)) == 'machine decides'
    monkeypatch.setenv(_cores.READ_AHEAD_ENV, '1')
    assert analysis_path(bag) == 'helper'
    monkeypatch.setenv(_cores.READ_AHEAD_ENV, '0')
    assert analysis_path(bag) == 'one thread'
    monkeypatch.delenv(_cores.READ_AHEAD_ENV)
    monkeypatch.setattr(_cores, 'HELPER_MIN_BAG_BYTES', size + 1)
    assert analysis_path(bag) == 'one thread'
    assert analysis_path(tmp_path / 'missing') == 'one thread'
    monkeypatch.setattr(_cores, 'HELPER_MIN_BAG_BYTES', 0)
    assert analysis_path(tmp_path / 'missing') == 'one thread'


# --- the machine's say (issue 41): planted /proc readings, not timing ----------------------

def _plant_proc(root: Path, *, idle: tuple[int, ...], iowait: tuple[int, ...] = (0, 0, 0),
                running: int = 1, delay_ns: int | None = 0) -> Path:
    """A /proc with a stat of three CPUs (cpu2 outside the planted affinity {0, 1}) and this
    thread's schedstat (``delay_ns`` None: none)."""
    root.mkdir(parents=True, exist_ok=True)
    lines = [f'cpu  100 0 50 {sum(idle)} {sum(iowait)} 0 0 0 0 0']
    lines += [f'cpu{i} 40 0 20 {idle[i]} {iowait[i]} 0 3 0 0 0' for i in range(3)]
    lines += ['intr 9 0 0', 'ctxt 42', f'procs_running {running}', 'procs_blocked 0']
    (root / 'stat').write_text('\n'.join(lines) + '\n')
    sched = root / 'thread-self' / 'schedstat'
    sched.parent.mkdir(exist_ok=True)
    if delay_ns is None:
        sched.unlink(missing_ok=True)
    else:
        sched.write_text(f'123456789 {delay_ns} 77\n')
    return root


def _readings(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, dt_s: float,
              before: dict, after: dict) -> tuple[_cores.MachineSample, _cores.MachineSample]:
    monkeypatch.setattr('os.sched_getaffinity', lambda _pid: {0, 1})
    clock = iter([1000.0, 1000.0 + dt_s])
    monkeypatch.setattr(_cores, '_now', lambda: next(clock))
    a = _cores.sample_machine(_plant_proc(tmp_path / 'a', **before))
    b = _cores.sample_machine(_plant_proc(tmp_path / 'b', **after))
    assert a is not None and b is not None
    return a, b


def test_sample_machine_reads_the_allowed_cpus_and_this_threads_wait(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr('os.sched_getaffinity', lambda _pid: {0, 1})
    proc = _plant_proc(tmp_path, idle=(500, 700, 9000), iowait=(3, 4, 800), running=5,
                       delay_ns=31_000_000)
    s = _cores.sample_machine(proc)
    assert s is not None
    assert s.idle_ticks == 500 + 3 + 700 + 4          # cpu2 is not this process's
    assert s.run_delay_ns == 31_000_000
    assert s.procs_running == 5
    _plant_proc(tmp_path, idle=(1, 1, 1), delay_ns=None)
    s = _cores.sample_machine(proc)
    assert s is not None and s.run_delay_ns is None and s.idle_ticks == 2


@pytest.mark.parametrize('stat', [None, '', 'cpu  1 2 3\n', 'cpu0 1 2 3 x 5\n',
                                  'cpu0 1 2\n', '\x00\xff' * 40])
def test_sample_machine_never_raises(tmp_path: Path, stat: str | None) -> None:
    """No /proc, an empty or damaged stat: None (the analysis then does as before)."""
    if stat is not None:
        (tmp_path / 'stat').write_text(stat)
    assert _cores.sample_machine(tmp_path) is None
    assert _cores.sample_machine(tmp_path / 'missing') is None


# 40 ms between the readings: one idle CPU is 4 ticks of USER_HZ 100; this thread waiting
# the whole time is 40e6 ns
@pytest.mark.parametrize(('before', 'after', 'room'), [
    # the other core idle (one thread runs on this one): the helper
    ({'idle': (10, 10, 0)}, {'idle': (10, 14, 0)}, True),
    ({'idle': (10, 10, 0)}, {'idle': (10, 12, 0)}, True),               # half a core
    ({'idle': (10, 10, 0), 'iowait': (0, 0, 0)},
     {'idle': (10, 11, 0), 'iowait': (0, 1, 0)}, True),                 # iowait is idle too
    # one CPU-bound process on the other core: no idle tick, this thread not kept waiting
    ({'idle': (10, 10, 0), 'delay_ns': 5_000_000},
     {'idle': (10, 10, 0), 'delay_ns': 6_000_000}, False),
    ({'idle': (10, 10, 0)}, {'idle': (10, 11, 0), 'delay_ns': 4_000_000}, False),
    # idle elsewhere on the machine, not on this process's CPUs
    ({'idle': (10, 10, 0)}, {'idle': (10, 10, 8)}, False),
    # overloaded: no idle, this thread waited 40 % / 20 % of the time for a CPU
    ({'idle': (10, 10, 0)}, {'idle': (10, 10, 0), 'delay_ns': 16_000_000}, True),
    ({'idle': (10, 10, 0)}, {'idle': (10, 10, 0), 'delay_ns': 8_000_000}, True),
    ({'idle': (10, 10, 0)}, {'idle': (10, 10, 0), 'delay_ns': 7_000_000}, False),
    # no schedstat: the runnable tasks besides this one, averaged over the two readings
    ({'idle': (10, 10, 0), 'delay_ns': None, 'running': 2},
     {'idle': (10, 10, 0), 'delay_ns': None, 'running': 2}, False),
    ({'idle': (10, 10, 0), 'delay_ns': None, 'running': 3},
     {'idle': (10, 10, 0), 'delay_ns': None, 'running': 2}, False),
    ({'idle': (10, 10, 0), 'delay_ns': None, 'running': 3},
     {'idle': (10, 10, 0), 'delay_ns': None, 'running': 3}, True),
    ({'idle': (10, 10, 0), 'delay_ns': None, 'running': 9},
     {'idle': (10, 10, 0), 'delay_ns': None, 'running': 6}, True),
])
def test_helper_has_room_from_planted_readings(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               before: dict, after: dict, room: bool) -> None:
    a, b = _readings(tmp_path, monkeypatch, 0.040, before, after)
    got, why = _cores.helper_has_room(a, b)
    assert got is room, why
    assert why


def test_helper_has_room_needs_an_interval(tmp_path: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    a, b = _readings(tmp_path, monkeypatch, 0.0, {'idle': (10, 10, 0)}, {'idle': (10, 14, 0)})
    assert _cores.helper_has_room(a, b)[0] is False
