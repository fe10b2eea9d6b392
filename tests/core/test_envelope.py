"""MinMaxEnvelope: every sample lies in its bucket's band, in bounded memory, gaps kept.

The reference is brute force over the raw samples: a bucket holds the samples whose phase
lies from its start phase up to the next bucket's start phase in the same segment (the
phase is monotonic within a segment), and its min/max must be theirs exactly.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from rv_te_bench.core.envelope import MinMaxEnvelope
from rv_te_bench.core.offline import analyze_blocks
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.stream_records import EncoderBlockData, TeAnalysisConfig


def _brute_force_check(env: MinMaxEnvelope, segments: list[tuple[np.ndarray, np.ndarray]],
                       sign: float) -> None:
    d = env.data()
    assert d.n_samples == sum(phi.size for phi, _ in segments)
    assert np.unique(d.segment).size == len(segments)   # never merged across a gap
    for s, (phi, te) in enumerate(segments):
        rows = np.flatnonzero(d.segment == s)
        starts = d.phi_rad[rows]
        assert starts[0] == phi[0]
        # bucket k: samples from starts[k] (inclusive) to starts[k + 1] (exclusive)
        idx = np.searchsorted(sign * phi, sign * starts)
        assert (phi[idx] == starts).all()      # buckets start on samples
        bounds = [*idx.tolist(), phi.size]
        sizes = np.diff(bounds)
        assert sizes.min() >= 1 and sizes.max() <= d.bucket_samples
        for k, (a, b) in enumerate(itertools.pairwise(bounds)):
            assert d.min_rad[rows[k]] == te[a:b].min()
            assert d.max_rad[rows[k]] == te[a:b].max()


@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_buckets_hold_exactly_their_samples_across_halvings_and_gaps(sign: float) -> None:
    rng = np.random.default_rng(7)
    env = MinMaxEnvelope(max_buckets=64, bucket_samples=4, fine_samples=2)
    segments = []
    for n_seg in (5000, 37, 2600):      # three stretches between gaps
        phi = sign * np.cumsum(rng.uniform(0.5, 1.5, n_seg))
        te = rng.normal(size=n_seg)
        segments.append((phi, te))
        a = 0
        while a < n_seg:                 # windows of uneven length, as the analyzer closes
            b = min(n_seg, a + int(rng.integers(1, 900)))
            lo, hi = env.add(phi[a:b], te[a:b])
            assert (lo, hi) == (te[a:b].min(), te[a:b].max())
            a = b
        env.gap()
    d = env.data()
    assert d.size <= 64
    assert d.bucket_samples > 4          # it had to halve
    _brute_force_check(env, segments, sign)


@pytest.mark.parametrize('fine', [1, 8])
def test_folded_band_holds_every_sample_in_its_bin(fine: int) -> None:
    """Per-sample binning by brute force: with runs of one sample the folded band is
    exactly it; with longer runs every sample lies in its own bin's band or, where its run
    began in the bin before, in that one's."""
    rng = np.random.default_rng(3)
    bins = 36
    env = MinMaxEnvelope(max_buckets=16, bucket_samples=16, fine_samples=fine, fold_bins=bins)
    phi = 0.4 - np.cumsum(rng.uniform(0.0005, 0.003, 30_000))   # ~12 revolutions, reversed
    te = np.sin(7 * phi) + 0.1 * rng.normal(size=phi.size)
    for a in range(0, phi.size, 2500):
        env.add(phi[a:a + 2500], te[a:a + 2500])
    d = env.data()
    b = np.floor(np.mod(np.abs(phi - phi[0]), 2 * np.pi) / (2 * np.pi / bins)).astype(int)
    want_lo = np.array([te[b == k].min() for k in range(bins)])
    want_hi = np.array([te[b == k].max() for k in range(bins)])
    if fine == 1:
        np.testing.assert_array_equal(d.fold_min_rad, want_lo)
        np.testing.assert_array_equal(d.fold_max_rad, want_hi)
    else:
        prev = (b - 1) % bins
        inside = (((te >= d.fold_min_rad[b]) & (te <= d.fold_max_rad[b]))
                  | ((te >= d.fold_min_rad[prev]) & (te <= d.fold_max_rad[prev])))
        assert inside.all()
        assert np.nanmax(d.fold_max_rad) == te.max() and np.nanmin(d.fold_min_rad) == te.min()


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match='powers of two'):
        MinMaxEnvelope(bucket_samples=3)
    with pytest.raises(ValueError, match='fine <= bucket'):
        MinMaxEnvelope(bucket_samples=4, fine_samples=8)
    with pytest.raises(ValueError, match='max_buckets'):
        MinMaxEnvelope(max_buckets=1)


def test_analyzer_fills_the_envelope_with_every_clean_sample() -> None:
    """Through analyze_blocks: the band's extremes are the record's, its count the samples."""
    ratio, fs = 79.0, 2000.0
    n = 40_000
    t = np.arange(n) / fs
    theta_in = 2 * np.pi * 2.0 * ratio * t
    phi = theta_in / ratio
    te = 3e-4 * np.cos(25 * phi) + 1e-4 * np.sin(7 * phi)
    blocks = [EncoderBlockData(seq=k + (3 if k >= 200 else 0), stamp_s=float(t[a]),
                               sample_rate_hz=fs, time_offset_s=t[a:a + 100] - t[a],
                               theta_in_rad=theta_in[a:a + 100],
                               theta_out_rad=phi[a:a + 100] + te[a:a + 100])
              for k, a in enumerate(range(0, n, 100))]
    config = TeAnalysisConfig(orders=OrderSet(ratio, 25.0))
    env = MinMaxEnvelope(max_buckets=100, bucket_samples=8, fine_samples=4)
    res = analyze_blocks(blocks, config, envelope=env)
    d = env.data()
    assert res.counters['gaps'] == 1
    assert d.n_samples == n
    assert np.unique(d.segment).tolist() == [0, 1]
    # independent: TE from the written angles (rounding of theta_out - theta_in / i)
    te_back = (phi + te) - theta_in / ratio
    assert d.min_rad.min() == te_back.min()
    assert d.max_rad.max() == te_back.max()
    assert d.max_rad.max() - d.min_rad.min() == pytest.approx(res.cumulative.pp_rad, abs=0)
