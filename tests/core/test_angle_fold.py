"""Tests of the angle-domain fold (rv_te_bench.core.angle_fold) against direct computation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.angle_fold import AngleFold
from rv_te_bench.errors import TeInputError

ARCSEC = math.pi / 648000.0


def _record(rng: np.random.Generator, n: int = 60_000, revs: float = 2.3,
            sigma: float = 0.2 * ARCSEC) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """phi, a smooth periodic TE with a kink every crank turn, and that TE plus noise."""
    phi = 0.7 + np.arange(n) * (revs * 2 * math.pi / n)
    clean = 1e-4 * np.maximum(np.sin(25 * phi + 0.3), 0.4 * np.cos(25 * phi)) \
        + 3e-5 * np.sin(phi + 1.0)
    return phi, clean, clean + 0.01 + sigma * rng.standard_normal(n)


def _model(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The clean TE of ``_record`` without the offset, and its slope dTE/dphi."""
    s, c = np.sin(25 * phi + 0.3), 0.4 * np.cos(25 * phi)
    first = s >= c
    val = 1e-4 * np.where(first, s, c) + 3e-5 * np.sin(phi + 1.0)
    slope = 1e-4 * np.where(first, 25 * np.cos(25 * phi + 0.3), -10 * np.sin(25 * phi)) \
        + 3e-5 * np.cos(phi + 1.0)
    return val, slope


def test_sample_level_residual_from_the_fold(rng: np.random.Generator) -> None:
    """The fold's RSS of a model equals the RSS computed sample by sample (within the
    model's curvature inside a bin and the kink bins: 1e-3 relative), and the totals
    (mean, standard deviation, span) equal numpy's over the raw samples."""
    phi, _, te = _record(rng)
    fold = AngleFold()
    for part in np.array_split(np.arange(phi.size), 7):    # streamed in pieces
        fold.add(phi[part], te[part])
    r = fold.result()
    assert r.n_samples == phi.size
    assert int(r.counts.sum()) == phi.size
    assert r.te_mean_rad == pytest.approx(float(np.mean(te)), rel=1e-12)
    assert r.te_std_rad == pytest.approx(float(np.std(te)), rel=1e-9)
    assert r.output_revolutions == pytest.approx((phi[-1] - phi[0]) / (2 * math.pi), rel=1e-12)
    for offset in (0.01, 0.01 + 1e-6):        # the true model, and one off by 0.2"
        m_bins, s_bins = _model(np.asarray(r.phi_rad))
        direct = float(np.sum((te - _model(phi)[0] - offset) ** 2))
        assert r.rss_rad2(m_bins + offset, s_bins) == pytest.approx(direct, rel=1e-3)


def test_noise_estimate(rng: np.random.Generator) -> None:
    """White noise of 0.2" is estimated within 5 % from the second differences; a record
    decimated to 64 samples per crank turn (signal curvature dominates) withholds it."""
    phi, _, te = _record(rng, n=200_000)
    fold = AngleFold()
    fold.add(phi, te)
    curv = 1e-4 * 625 + 3e-5
    assert fold.result().noise_rms_rad(curv) == pytest.approx(0.2 * ARCSEC, rel=0.05)
    coarse = AngleFold()
    coarse.add(phi[::125], te[::125])
    assert math.isnan(coarse.result().noise_rms_rad(curv))


def test_add_encoders_folds_on_the_input_angle(rng: np.random.Generator) -> None:
    """add_encoders forms Eq. 22 TE and folds it at theta_in / i, not at theta_out."""
    phi, clean, _ = _record(rng, sigma=0.0)
    ratio = 79.0
    theta_in = phi * ratio
    theta_out = phi + clean
    a, b = AngleFold(n_bins=4096), AngleFold(n_bins=4096)
    a.add_encoders(theta_in, theta_out, gear_ratio=ratio)
    b.add(phi, clean)
    ra, rb = a.result(), b.result()
    np.testing.assert_array_equal(ra.counts, rb.counts)
    np.testing.assert_allclose(ra.phi_rad, rb.phi_rad, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ra.te_rad, rb.te_rad, rtol=0, atol=1e-15)


def test_non_finite_samples_skipped_and_counted() -> None:
    fold = AngleFold(n_bins=64)
    phi = np.linspace(0, 10, 100)
    te = np.zeros(100)
    te[[3, 50]] = np.nan
    phi[7] = np.inf
    fold.add(phi, te)
    assert fold.skipped == 3
    assert fold.result().n_samples == 97


@pytest.mark.parametrize('bins', [0, 7, 2.5, True])
def test_bad_bins(bins: object) -> None:
    with pytest.raises(TeInputError, match='n_bins'):
        AngleFold(n_bins=bins)  # type: ignore[arg-type]


def test_bad_shapes() -> None:
    with pytest.raises(TeInputError, match='equal length'):
        AngleFold().add(np.zeros(3), np.zeros(4))
    with pytest.raises(TeInputError, match='gear_ratio'):
        AngleFold().add_encoders(np.zeros(3), np.zeros(3), gear_ratio=0.0)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(2015)
