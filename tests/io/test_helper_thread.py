"""The analysis's helper thread held until the machine decides (io/_helper.py, issue 41).

The decision itself is tested on planted /proc readings in test_cores.py; here the readings
(``_cores.sample_machine``) and the clock (``_helper._now``) are planted, so what the
executor does with a decision is checked without timing: the jobs it holds until then,
the thread it starts or never starts, the jobs the caller takes back."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from rv_te_bench.io import _cores, _helper
from rv_te_bench.io._helper import HelperThread

_IDLE_CORE = 'idle core'
_BUSY_CORE = 'busy core'


def plant_machine(monkeypatch: pytest.MonkeyPatch, machine: str | None,
                  step_s: float = 0.010) -> list[float]:
    """Plant the clock (each call ``step_s`` later) and the machine: the other core idle
    (one idle tick per 10 ms), busy beside a thread never kept waiting, or unreadable
    (None). Returns the list of the clock's readings."""
    readings: list[float] = []

    def now() -> float:
        readings.append(len(readings) * step_s)
        return readings[-1]

    def sample(proc: object = None) -> _cores.MachineSample | None:
        if machine is None:
            return None
        t = readings[-1] if readings else 0.0     # (a reading does not move the clock)
        idle = round(t * 100) if machine == _IDLE_CORE else 0
        return _cores.MachineSample(t_s=t, idle_ticks=idle, run_delay_ns=0, procs_running=2)

    monkeypatch.setattr(_helper, '_now', now)
    monkeypatch.setattr(_cores, 'sample_machine', sample)
    monkeypatch.setattr(_cores, 'DECIDE_AFTER_S', 0.030)
    return readings


def _helpers() -> list[str]:
    return [t.name for t in threading.enumerate() if t.name == 'te-helper']


@pytest.fixture
def pool() -> Iterator[list[HelperThread]]:
    made: list[HelperThread] = []
    yield made
    for p in made:
        p.shutdown(wait=True, cancel_futures=True)
    assert not _helpers()


def _where() -> str:
    return threading.current_thread().name


def test_started_at_once_when_not_deciding(pool: list[HelperThread],
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    plant_machine(monkeypatch, _BUSY_CORE)       # (not looked at)
    pool.append(h := HelperThread(decide=False))
    assert h.started and h.decision == 'helper from the start'
    assert h.submit(_where).result(timeout=10) == 'te-helper'


def test_holds_jobs_then_starts_when_the_other_core_is_idle(
        pool: list[HelperThread], monkeypatch: pytest.MonkeyPatch) -> None:
    plant_machine(monkeypatch, _IDLE_CORE)
    pool.append(h := HelperThread(decide=True))
    first = h.submit(_where)                     # 10 ms: not decided yet, held
    second = h.submit(_where)                    # 20 ms
    assert not h.started and not _helpers()
    assert not first.done() and not second.done()
    assert second.cancel()                       # the caller takes one back
    third = h.submit(_where)                     # 30 ms: decided, started
    assert h.started and h.decision.startswith('helper after 40 ms ('), h.decision
    assert first.result(timeout=10) == 'te-helper'
    assert third.result(timeout=10) == 'te-helper'
    assert second.cancelled()
    boom = h.submit(lambda: 1 / 0)
    assert isinstance(boom.exception(timeout=10), ZeroDivisionError)


def test_does_without_beside_a_busy_core(pool: list[HelperThread],
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    plant_machine(monkeypatch, _BUSY_CORE)
    pool.append(h := HelperThread(decide=True))
    held = h.submit(_where)
    h.poll()                                     # 20 ms
    assert not held.done()
    h.poll()                                     # 30 ms: decided
    assert not h.started and h.decision.startswith('one thread after 40 ms (0.00 cores')
    assert held.cancelled()                      # the caller does it (cancel() is True)
    later = h.submit(_where)
    assert later.cancelled() and later.cancel()
    assert list(h.watch(range(3))) == [0, 1, 2]
    assert not h.started and not _helpers()


def test_watch_decides_between_items(pool: list[HelperThread],
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """A small bag hands all its jobs over at the start: the reading loop decides."""
    plant_machine(monkeypatch, _IDLE_CORE)
    pool.append(h := HelperThread(decide=True))
    held = h.submit(_where)
    seen = []
    for item in h.watch('abcd'):
        seen.append((item, h.started))
    assert seen == [('a', False), ('b', False), ('c', True), ('d', True)]
    assert held.result(timeout=10) == 'te-helper'


@pytest.mark.parametrize('readable', ['never', 'not the second time'])
def test_an_unreadable_machine_starts_the_helper_as_before(
        pool: list[HelperThread], monkeypatch: pytest.MonkeyPatch, readable: str) -> None:
    plant_machine(monkeypatch, None if readable == 'never' else _BUSY_CORE)
    pool.append(h := HelperThread(decide=True))
    if readable == 'never':
        assert h.started and 'cannot be read' in h.decision
        return
    monkeypatch.setattr(_cores, 'sample_machine', lambda proc=None: None)
    h.poll()
    h.poll()
    assert not h.started
    h.poll()                                     # 30 ms: the second reading fails
    assert h.started and 'cannot be read' in h.decision


def test_shutdown_cancels_what_was_held(monkeypatch: pytest.MonkeyPatch) -> None:
    plant_machine(monkeypatch, _IDLE_CORE)
    h = HelperThread(decide=True)
    held = h.submit(_where)
    h.shutdown(wait=True)
    assert held.cancelled() and not h.started
    assert h.submit(_where).cancelled()
    assert not _helpers()
