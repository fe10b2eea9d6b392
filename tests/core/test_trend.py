"""The life-test growth detector (core.trend): the CUSUM recursion against a hand
computation, and the rates the issue asks for from a seeded simulation: a +10 % growth of a
crank-order line flagged within 2 checkpoints on >= 95 % of degraded units, false alarms on
<= 1 % of stable units over 20 checkpoints, at the shipped settings (checkpoint scatter
2 %, 3 baseline checkpoints, h = 1.5); and the limit: at 3 % scatter both cannot be had."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.trend import TrendConfig, cusum_growth, detector_rates
from rv_te_bench.errors import TeConfigError, TeInputError

SHIPPED = TrendConfig(growth_fraction=0.10, noise_rel=0.02, baseline_checkpoints=3,
                      threshold=1.5)


def test_cusum_by_hand() -> None:
    cfg = TrendConfig(growth_fraction=0.1, noise_rel=0.02, baseline_checkpoints=2,
                      threshold=1.5)
    x = [1.0, 1.0, 1.0, 1.08, 1.08, 1.0]
    s = 0.02 * math.sqrt(1.5)
    kappa = 0.1 / (2 * s)
    s3 = max(0.0, 0.0 / s - kappa)
    s4 = max(0.0, s3 + 0.08 / s - kappa)
    s5 = max(0.0, s4 + 0.08 / s - kappa)
    r = cusum_growth(x, cfg)
    assert r.baseline == 1.0
    assert r.statistic[2:5] == pytest.approx((s3, s4, s5))
    assert r.alarm_index == (4 if s5 > 1.5 else -1)
    assert r.alarm_index == 4          # two checkpoints of +8 % at 2 % scatter


def test_stable_series_no_alarm_and_step_flagged() -> None:
    rng = np.random.default_rng(5)
    x = 1.0 + 0.005 * rng.standard_normal(12)
    assert not cusum_growth(x, SHIPPED).alarm
    x[8:] *= 1.10
    assert cusum_growth(x, SHIPPED).alarm_index in (8, 9)


def test_shipped_settings_meet_the_issue_rates() -> None:
    r = detector_rates(SHIPPED, units=20000, checkpoints=20, step_at=10, seed=38)
    assert r.false_alarm_rate <= 0.01
    assert r.detection_rate >= 0.95


def test_at_3_percent_scatter_the_rates_conflict() -> None:
    """What the data cannot do: at 3 % checkpoint scatter no threshold gives both."""
    for h in (0.5, 1.0, 1.5, 2.0, 3.0):
        r = detector_rates(TrendConfig(noise_rel=0.03, threshold=h), units=5000, seed=1)
        assert r.false_alarm_rate > 0.01 or r.detection_rate < 0.95


def test_bad_input() -> None:
    with pytest.raises(TeInputError):
        cusum_growth([1.0, -1.0, 2.0, 3.0])
    with pytest.raises(TeConfigError, match='noise_rel'):
        TrendConfig(noise_rel=0.0)
    r = cusum_growth([1.0, 1.1], SHIPPED)
    assert not r.alarm and math.isnan(r.baseline)
