"""The harmonic fold (core/harmonic_fold.py) on dense and on sparse records.

Expected values are the test's own closed-form curves: y(u) = sum a_k sin(k u + p_k), whose
complex amplitude in the fold's convention (``Re(c_k e^{iku})``) is ``a_k e^{i(p_k - pi/2)}``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.harmonic_fold import HarmonicFold

AS = math.pi / 648000.0
CURVE = ((1, 20.6 * AS, 2.5), (2, 0.45 * AS, 0.3), (3, 0.2 * AS, 1.9), (5, 0.05 * AS, -1.0))


def _curve(u: np.ndarray) -> np.ndarray:
    return sum(a * np.sin(k * u + p) for k, a, p in CURVE)


def _errors_arcsec(fold: HarmonicFold) -> np.ndarray:
    ks = [k for k, _, _ in CURVE]
    h = fold.harmonics(ks)
    want = np.array([a * np.exp(1j * (p - math.pi / 2)) for _, a, p in CURVE])
    return np.abs(h.c[0] - want) / AS


@pytest.mark.parametrize(('samples_per_rev', 'revs'), [
    (3160, 2.28),      # a bench at 2 kHz, output at 38 rpm: 1.5 samples per bin and turn
    (2048.5, 3.1),     # nearly one sample per bin, at the same offset turn after turn
    (200_000, 1.05),   # dense
])
def test_harmonics_of_a_known_curve_from_dense_or_sparse_records(samples_per_rev: float,
                                                                  revs: float) -> None:
    """2048 bins; 0.01" white noise. Every order within 0.01" of the curve's, however few
    samples a bin holds (a bin whose samples sit at nearly one offset used to move its mean
    along a slope that was noise over a tiny spread: errors of 1-2")."""
    rng = np.random.default_rng(36)
    n = round(samples_per_rev * revs)
    u = 0.7 + 2 * math.pi * np.arange(n) / samples_per_rev
    fold = HarmonicFold(1)
    for s in range(0, n, 100):    # blocks of 100, as an EncoderBlock stream
        uu = u[s:s + 100]
        fold.add(uu, (_curve(uu) + 0.01 * AS * rng.standard_normal(uu.size))[None, :])
    err = _errors_arcsec(fold)
    assert err.max() < 0.01, err


def test_stated_uncertainty_matches_the_scatter_on_a_sparse_record() -> None:
    """The stated u of each order (the pooled in-bin noise) against the scatter of the
    estimates over 20 noise draws of a sparse record: ratio within 0.6 .. 1.7."""
    rng = np.random.default_rng(7)
    samples_per_rev, revs, sigma = 3160, 2.28, 0.2 * AS
    n = round(samples_per_rev * revs)
    u = 2 * math.pi * np.arange(n) / samples_per_rev
    c, stated = [], []
    for _ in range(20):
        fold = HarmonicFold(1)
        fold.add(u, (_curve(u) + sigma * rng.standard_normal(n))[None, :])
        h = fold.harmonics([1, 2, 3])
        c.append(h.c[0])
        stated.append(math.sqrt(float(h.cov[0, 0])))
    want = np.array([a * np.exp(1j * (p - math.pi / 2)) for _, a, p in CURVE[:3]])
    err = np.array(c) - want                       # (draws, orders)
    spread = math.sqrt(float(np.mean(np.abs(err) ** 2)) / 2)   # per real / imaginary part
    ratio = spread / float(np.mean(stated))
    assert 0.6 < ratio < 1.7, ratio
