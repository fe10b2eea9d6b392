"""Runs of constant input speed and load, and locked runs, found in a record written here."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.segments import RAD_S_PER_RPM, RunSettings, find_runs
from rv_te_bench.errors import TeConfigError, TeInputError

FS = 1000.0


def record(parts: list[tuple[float, float, float]], rng: np.random.Generator | None = None,
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """(duration s, input rpm, load N m) parts -> time, input angle, torque, part starts."""
    speeds, loads, starts = [], [], []
    for dur, rpm, load in parts:
        starts.append(sum(len(s) for s in speeds))
        n = round(dur * FS)
        speeds.append(np.full(n, rpm * RAD_S_PER_RPM))
        loads.append(np.full(n, load))
    w = np.concatenate(speeds)
    tq = np.concatenate(loads)
    if rng is not None:   # drive speed ripple 0.3 %, torque noise 0.4 N m
        w = w * (1 + 0.003 * np.sin(2 * math.pi * 7.0 * np.arange(w.size) / FS))
        tq = tq + rng.normal(0, 0.4, tq.size)
    theta = np.cumsum(w) / FS
    return np.arange(w.size) / FS, theta, tq, starts


@pytest.mark.parametrize('noisy', [False, True])
def test_runs_of_a_plan_like_record(noisy: bool) -> None:
    parts = [(1.0, 0.0, 0.0), (3.0, 1500.0, 200.0), (3.0, -1500.0, -200.0),
             (2.0, 0.0, 0.0), (2.0, 300.0, 0.0), (3.0, 750.0, 0.0), (3.0, 750.0, 450.0)]
    t, th, tq, starts = record(parts, np.random.default_rng(1) if noisy else None)
    runs = find_runs(t, th, tq, RunSettings(load_resolution_nm=5.0))
    assert len(runs) == len(parts)
    for r, (dur, rpm, load), s in zip(runs, parts, starts, strict=True):
        assert abs(r.start - s) <= (2 if noisy else 0)
        assert r.locked == (rpm == 0.0)
        assert r.speed_rpm == pytest.approx(rpm, rel=2e-3, abs=1e-9)
        assert r.load_nm == pytest.approx(load, abs=0.1)
        assert r.duration_s == pytest.approx(dur, abs=0.01)


def test_locked_run_keeps_its_torque_cycle_whole() -> None:
    """The input locked while the torque steps: one locked run (torque changes do not
    split it), and the speed run after it."""
    t = np.arange(5000) / FS
    th = np.where(t < 4.0, 0.0, (t - 4.0) * 100 * RAD_S_PER_RPM)
    tq = np.where(t < 4.0, 50.0 * np.round(4 * np.sin(t)), 0.0)
    runs = find_runs(t, th, tq, RunSettings())
    assert [r.locked for r in runs] == [True, False]
    # the input leaves at sample 4000 (the first step of angle is 4000 -> 4001)
    assert runs[0].start == 0 and runs[0].stop in (4000, 4001)
    assert runs[1].start == runs[0].stop and runs[1].stop == 5000


def test_runs_end_at_breaks() -> None:
    t, th, tq, _ = record([(4.0, 600.0, 0.0)])
    runs = find_runs(t, th, tq, RunSettings(), breaks=[1500])
    assert [(r.start, r.stop) for r in runs] == [(0, 1500), (1500, 4000)]


def test_without_torque_only_the_speed_counts() -> None:
    t, th, _, _ = record([(2.0, 600.0, 0.0), (2.0, 600.0, 300.0)])
    runs = find_runs(t, th, None, RunSettings())
    assert len(runs) == 1 and math.isnan(runs[0].load_nm)


def test_bad_input() -> None:
    with pytest.raises(TeInputError, match='sample times must increase; sample 2'):
        find_runs([0.0, 1.0, 1.0], [0.0, 0.0, 0.0], None, RunSettings())
    with pytest.raises(TeInputError, match='differ in length'):
        find_runs([0.0, 1.0], [0.0], None, RunSettings())
    with pytest.raises(TeConfigError, match='speed_tolerance must be finite and > 0'):
        RunSettings(speed_tolerance=0.0)
