"""analyze_bag starts its helper thread only once the machine has room for it (issue 41),
and the analysis is the same whenever (or whether) the helper starts.

The machine and the clock are planted (tests/io/test_helper_thread.py: ``plant_machine``),
so the decision falls at a chosen point of the analysis, not on timing. The reference is the
analysis on one thread (``RV_TE_READ_AHEAD=0``), compared as its JSON document (every
number, the spectra's lines, the advice) but for ``generated_utc`` and ``elapsed_s``, on
the repository's sample bag and on a 58-s session at 10 kHz (>= 8 MiB, the size from which
the helper is considered at all; our writer, zstd, as the recorder writes)."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import pytest

from rv_te_bench.io import _cores, _helper
from rv_te_bench.report.analysis import analyze_bag
from tests.io.test_helper_thread import _BUSY_CORE, _IDLE_CORE, plant_machine
from tests.report.analysis_doc import analysis_doc

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / 'bags' / 'sample'


@pytest.fixture(scope='module')
def big_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    sys.path.insert(0, str(ROOT / 'bags'))
    try:
        from make_sample import write_sample
    finally:
        sys.path.remove(str(ROOT / 'bags'))
    bag = tmp_path_factory.mktemp('helper') / 'session_58s'
    write_sample(bag, duration_s=58.0, sample_rate_hz=10_000.0, block_size=1000)
    assert sum(f.stat().st_size for f in bag.glob('*.mcap')) >= 8 * 2**20
    return bag


@pytest.fixture
def two_cores(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Two cores allowed, the switch unset; returns the names of the threads started."""
    monkeypatch.delenv(_cores.READ_AHEAD_ENV, raising=False)
    monkeypatch.setattr('os.sched_getaffinity', lambda _pid: {0, 1})
    monkeypatch.setattr(_cores, 'allowed_cores', lambda: 2.0)
    started: list[str] = []
    real = threading.Thread.start

    def start(thread: threading.Thread) -> None:
        started.append(thread.name)
        real(thread)
    monkeypatch.setattr(threading.Thread, 'start', start)
    return started


def _decisions(monkeypatch: pytest.MonkeyPatch) -> list[_helper.HelperThread]:
    made: list[_helper.HelperThread] = []
    real = _helper.HelperThread.__init__

    def init(self: _helper.HelperThread, *, decide: bool) -> None:
        real(self, decide=decide)
        made.append(self)
    monkeypatch.setattr(_helper.HelperThread, '__init__', init)
    return made


def test_beside_a_busy_core_a_big_bag_is_analysed_on_one_thread(
        big_bag: Path, two_cores: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """One CPU-bound process on the other core (planted: no idle tick, this thread never
    kept waiting): no helper thread is started at all. Fails on the code before, which
    started it for every bag of >= 8 MiB on two cores."""
    plant_machine(monkeypatch, _BUSY_CORE)
    made = _decisions(monkeypatch)
    analyze_bag(big_bag, with_advice=False)
    assert [t for t in two_cores if t.startswith('te-helper')] == []
    assert len(made) == 1
    assert made[0].decision.startswith('one thread after'), made[0].decision


def test_with_the_other_core_idle_the_helper_starts(
        big_bag: Path, two_cores: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    plant_machine(monkeypatch, _IDLE_CORE)
    made = _decisions(monkeypatch)
    analyze_bag(big_bag, with_advice=False)
    assert [t for t in two_cores if t.startswith('te-helper')] == ['te-helper']
    assert made[0].decision.startswith('helper after'), made[0].decision
    assert not [t.name for t in threading.enumerate() if t.name.startswith('te-helper')]


@pytest.mark.parametrize('bag_name', ['sample', 'big'])
def test_the_analysis_is_the_same_whenever_the_helper_starts(
        bag_name: str, big_bag: Path, two_cores: list[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The helper started at the first job handed over, at points through the analysis,
    or never (declined beside a busy core, or the bag over before the decision): the JSON
    of the analysis is that of one thread, bit for bit. (A declined helper's jobs come back
    cancelled: the spectra thread once reused such a window's arrays for the next window
    before computing its spectrum, and lost it: n_windows 1 instead of 2 on the sample.)"""
    bag = SAMPLE if bag_name == 'sample' else big_bag
    monkeypatch.setattr(_cores, 'HELPER_MIN_BAG_BYTES', 0)   # (the sample bag: 0.5 MB)
    monkeypatch.setenv(_cores.READ_AHEAD_ENV, '0')
    want = analysis_doc(bag)
    assert not two_cores
    monkeypatch.delenv(_cores.READ_AHEAD_ENV)
    # never decided (the bag over before): how many times the helper read its clock
    clock = plant_machine(monkeypatch, _IDLE_CORE)
    monkeypatch.setattr(_cores, 'DECIDE_AFTER_S', 1e9)
    assert analysis_doc(bag) == want
    assert not two_cores
    n = len(clock)               # (the sample bag: 5, the 58-s session: 26)
    assert n >= 4
    # decided at the first job handed over, in the middle, at the last reading; declined
    points = sorted({1, 2, n // 4, n // 2, (3 * n) // 4, n - 1})
    for machine, at in [*((_IDLE_CORE, k) for k in points), (_BUSY_CORE, 2)]:
        two_cores.clear()
        plant_machine(monkeypatch, machine)
        monkeypatch.setattr(_cores, 'DECIDE_AFTER_S', at * 0.010 - 0.001)
        made = _decisions(monkeypatch)
        got = analysis_doc(bag)
        decision = made[0].decision
        assert ('te-helper' in two_cores) is (machine == _IDLE_CORE), (machine, at, decision)
        assert got == want, (machine, at, decision)
