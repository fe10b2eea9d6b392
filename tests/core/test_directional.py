"""A direction's TE over whole output revolutions (core/directional.py), against records
written here whose revolutions differ, so that the worst, the mean, the first and the last
revolution are four different numbers.

The records: TE = A_k sin(s) in revolution k of the output travel s = |phi - phi_0|
(continuous at every revolution's end, where sin(s) = 0), sampled N = 4000 times per
revolution, so each revolution has a sample at s = pi/2 and 3 pi/2 and its p-p is 2 A_k
exactly (closed form; rounding ~1e-15 rad).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rv_te_bench.core.directional import direction_te
from rv_te_bench.errors import TeInputError

RATIO = 79.0
N = 4000   # samples per output revolution (a multiple of 4)


def record(amplitudes: list[float], *, direction: int = 1, offset_rad: float = 0.0,
           extra_fraction: float = 0.0, extra_amplitude: float = 0.0,
           phi0: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """(theta_in, theta_out) of revolutions with TE amplitudes ``amplitudes`` [rad], plus an
    unfinished revolution of ``extra_fraction`` with ``extra_amplitude``."""
    revs = len(amplitudes)
    n = revs * N + round(extra_fraction * N)
    s = 2.0 * math.pi * np.arange(n) / N              # output travel
    k = np.arange(n) // N
    amp = np.asarray([*amplitudes, extra_amplitude])[np.minimum(k, revs)]
    te = offset_rad + amp * np.sin(s)
    phi = phi0 + direction * s
    return RATIO * phi, phi + te


@pytest.mark.parametrize('direction', [1, -1])
@pytest.mark.parametrize('amplitudes', [
    [1e-4, 3e-4, 2e-4],          # worst in the middle: mean 4e-4, first 2e-4, last 4e-4
    [3e-4, 1e-4, 0.5e-4],        # worst first
    [0.5e-4, 1e-4, 3e-4],        # worst last
])
def test_direction_value_is_the_worst_revolution(amplitudes: list[float],
                                                 direction: int) -> None:
    d = direction_te(*record(amplitudes, direction=direction), gear_ratio=RATIO)
    assert d.direction == direction
    assert d.revolutions == 3
    assert_allclose(d.pp_per_rev_rad, [2 * a for a in amplitudes], rtol=1e-9)
    worst = 2 * max(amplitudes)
    assert d.te_pp_rad == pytest.approx(worst, rel=1e-9)
    # the worst is not the mean of the revolutions (nor any other revolution here)
    assert abs(d.te_pp_rad - 2 * float(np.mean(amplitudes))) > 0.2 * worst
    assert d.stats.pp_rad == pytest.approx(worst, rel=1e-9)
    assert d.stats.amplitude_rad == pytest.approx(max(amplitudes), rel=1e-9)


def test_an_unfinished_revolution_is_not_counted() -> None:
    """2.6 revolutions: the last 0.6 (with a TE five times larger) is left out of every
    number, as the catalogue definition counts whole revolutions only."""
    d = direction_te(*record([1e-4, 2e-4], extra_fraction=0.6, extra_amplitude=1e-3),
                     gear_ratio=RATIO)
    assert d.revolutions == 2
    assert_allclose(d.pp_per_rev_rad, [2e-4, 4e-4], rtol=1e-9)
    assert d.te_pp_rad == pytest.approx(4e-4, rel=1e-9)
    assert d.stats.n_samples == 2 * N
    assert d.stats.amplitude_rad == pytest.approx(2e-4, rel=1e-9)


def test_statistics_over_whole_revolutions() -> None:
    """Mean = the offset (sin averages to 0 over whole revolutions), population std =
    sqrt(mean(A_k^2) / 2)."""
    amps = [1e-4, 3e-4]
    d = direction_te(*record(amps, offset_rad=5e-5), gear_ratio=RATIO)
    assert d.stats.mean_rad == pytest.approx(5e-5, rel=1e-9)
    assert d.stats.std_rad == pytest.approx(math.sqrt(np.mean(np.square(amps)) / 2), rel=1e-9)
    assert d.stats.revolutions == 2


def test_curve_by_position_is_the_mean_over_revolutions() -> None:
    """8 position bins of 500 samples: each holds mean(A) times the mean of sin over the
    bin, (cos a - cos b) / (b - a) (closed form; the sampled mean differs by < 1e-3 of A)."""
    amps = [1e-4, 3e-4, 2e-4]
    phi0 = 0.0
    d = direction_te(*record(amps, phi0=phi0), gear_ratio=RATIO, bins=8)
    edges = np.arange(9) * 2 * math.pi / 8
    expected = np.mean(amps) * (np.cos(edges[:-1]) - np.cos(edges[1:])) / (2 * math.pi / 8)
    assert_allclose(d.te_by_position_rad, expected, rtol=0, atol=1e-3 * max(amps))
    assert_allclose(d.position_rad, (edges[:-1] + edges[1:]) / 2, rtol=1e-12)


def test_a_reversal_raises_naming_the_sample() -> None:
    phi = np.r_[0.0, 1.0, 0.5, 2.0, 7.0]
    with pytest.raises(TeInputError, match='reverses at sample 2'):
        direction_te(RATIO * phi, phi, gear_ratio=RATIO)


def test_less_than_one_revolution_raises() -> None:
    th_in, th_out = record([1e-4])
    with pytest.raises(TeInputError, match=r'0\.500 output revolutions; one whole'):
        direction_te(th_in[:N // 2], th_out[:N // 2], gear_ratio=RATIO)


def test_bad_sizes_and_bins_raise() -> None:
    with pytest.raises(TeInputError, match='at least 2 samples'):
        direction_te(np.zeros(1), np.zeros(1), gear_ratio=RATIO)
    with pytest.raises(TeInputError, match='bins must be an integer >= 8'):
        direction_te(*record([1e-4]), gear_ratio=RATIO, bins=4)
