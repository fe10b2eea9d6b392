"""Envelopes of the live page: every sample inside the min/max of its bin, at every level.

Truth is computed here sample by sample (plain Python loops over a few thousand samples),
not with the module's vectorised grouping.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.dashboard.envelope import AngleEnvelopes, TimeEnvelopes


def _stream(rng: np.random.Generator, n: int, *, reverse_at: int | None = None):
    t = np.arange(n) / 10_000.0
    speed = np.full(n, 2 * math.pi * 3.0)            # 3 output rev/s: several revolutions
    if reverse_at is not None:
        speed[reverse_at:] *= -1
    theta_out = 0.3 + np.concatenate(([0.0], np.cumsum(speed[1:] * np.diff(t))))
    te = 1e-4 * np.sin(25 * theta_out) + rng.normal(0, 1e-6, n)
    te[rng.integers(0, n, 7)] += 5e-3                # one-sample spikes
    return t, theta_out, te


@pytest.mark.parametrize('reverse_at', [None, 6000])
def test_angle_envelope_holds_every_sample_of_the_kept_revolutions(reverse_at):
    rng = np.random.default_rng(3)
    t, th, te = _stream(rng, 12_000, reverse_at=reverse_at)
    te[100] = np.nan                                  # a bad sample is skipped, not drawn
    env = AngleEnvelopes(n_bins=512, keep=2)
    start = 0
    for size in rng.integers(1, 900, 100):
        env.push(th[start:start + size], te[start:start + size], start, gen=start + 1)
        start += size
        if start >= len(t):
            break
    assert len(env.revs) == 2
    n_checked = 0
    for k, (lo, hi, _) in env.revs.items():
        truth_lo = [math.inf] * 512
        truth_hi = [-math.inf] * 512
        for x, y in zip(th.tolist(), te.tolist(), strict=True):
            rel = (x - 0.3) / (2 * math.pi)
            if math.floor(rel) != k or math.isnan(y):
                continue
            b = min(int((rel - math.floor(rel)) * 512), 511)
            truth_lo[b] = min(truth_lo[b], y)
            truth_hi[b] = max(truth_hi[b], y)
            n_checked += 1
        np.testing.assert_array_equal(lo, truth_lo)
        np.testing.assert_array_equal(hi, truth_hi)
    assert n_checked > 3000
    assert env.current == math.floor((th[-1] - 0.3) / (2 * math.pi))


def test_time_pyramid_bins_hold_min_max_first_last_at_every_level():
    rng = np.random.default_rng(5)
    t, th, te = _stream(rng, 9_000)
    torque = rng.normal(0, 1, len(t))
    env = TimeEnvelopes(base_samples=4, levels=6, ring=4096, max_columns=2048)
    start = 0
    for size in rng.integers(1, 700, 200):
        stop = min(start + size, len(t))
        env.push(t[start:stop], th[start:stop] * 79, th[start:stop], te[start:stop],
                 torque[start:stop], gen=stop)
        start = stop
        if start >= len(t):
            break
    for level in range(6):
        spb = 4 << level
        nbins = math.ceil(len(t) / spb)
        from rv_te_bench.dashboard.envelope import TimeView

        view = TimeView(level, spb, 0, nbins - 1)
        first, cols = env.rows(view, 0)
        assert first == 0
        for b in range(nbins):
            seg = slice(b * spb, min((b + 1) * spb, len(t)))
            assert cols['te_min'][b] == te[seg].min()
            assert cols['te_max'][b] == te[seg].max()
            assert cols['torque_min'][b] == torque[seg].min()
            assert cols['torque_max'][b] == torque[seg].max()
            assert cols['t_first'][b] == t[seg][0]
            assert cols['t_last'][b] == t[seg][-1]
            assert cols['theta_out_last'][b] == th[seg][-1]


def test_time_view_picks_the_finest_level_that_fits_and_rows_are_the_changed_suffix():
    env = TimeEnvelopes(base_samples=8, levels=8, ring=64, max_columns=32)
    n = 8 * 100
    x = np.arange(n, dtype=float)
    env.push(x[:500], x[:500], x[:500], x[:500], None, gen=1)
    env.push(x[500:], x[500:], x[500:], x[500:], None, gen=2)
    view = env.view(0)
    assert view.level == 2 and view.samples_per_bin == 32     # 800 samples / 32 <= 32 bins
    first, cols = env.rows(view, 1)                           # changed in gen 2 only
    assert first == 500 // 32                                 # the bin holding sample 500
    assert cols['te_min'][0] == 500 // 32 * 32                # whole bin, combined
    assert np.isnan(cols['torque_min']).all()                 # no torque sensor
    assert env.rows(view, 2) == (view.last_bin + 1, {})


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match='power of two'):
        TimeEnvelopes(base_samples=6)
    with pytest.raises(ValueError, match='n_bins'):
        AngleEnvelopes(n_bins=0)
