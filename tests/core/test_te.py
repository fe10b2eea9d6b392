"""Eq. 22 TE, TE statistics and RunningStats: closed forms, paper numbers, properties."""

from __future__ import annotations

import doctest
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.testing import assert_allclose

import rv_te_bench.core.orders
import rv_te_bench.core.spectrum
import rv_te_bench.core.stream
import rv_te_bench.core.te
from rv_te_bench.core.te import (
    RunningStats,
    TeStats,
    output_phase_and_te,
    te_statistics,
    transmission_error_rad,
)
from rv_te_bench.core.units import arcmin_to_rad, rad_to_arcmin
from rv_te_bench.errors import TeInputError

WANG_RATIO = 1.0 + (36.0 / 12.0) * 52.0 / (52.0 - 50.0)  # 79, DESIGN.md s.4

angles = st.floats(-1.0e3, 1.0e3, allow_nan=False, allow_infinity=False)


@pytest.mark.parametrize('module', [rv_te_bench.core.te, rv_te_bench.core.orders,
                                    rv_te_bench.core.spectrum, rv_te_bench.core.stream])
def test_doctests(module: object) -> None:
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)  # type: ignore[arg-type]
    assert result.attempted > 0
    assert result.failed == 0


def test_wang_ratio_matches_the_kinematics() -> None:
    from sim.kinematics import kinematics_2kv

    assert kinematics_2kv(12, 36, 50, 52).gear_ratio == WANG_RATIO == 79.0


def test_ideal_reducer_gives_zero_te() -> None:
    rng = np.random.default_rng(1)
    theta_in = np.cumsum(rng.uniform(0.0, 0.5, 10_000)) * 37.0
    te = transmission_error_rad(theta_in, theta_in / WANG_RATIO, gear_ratio=WANG_RATIO)
    assert np.all(te == 0.0)
    s = te_statistics(te, revolutions=3.0)
    assert (s.pp_rad, s.amplitude_rad, s.mean_rad, s.std_rad) == (0.0, 0.0, 0.0, 0.0)


def test_sign_convention_output_leading_is_positive() -> None:
    theta_in = np.array([0.0, 10.0, 20.0])
    lead_rad = float(arcmin_to_rad(1.5))
    te = transmission_error_rad(theta_in, theta_in / WANG_RATIO + lead_rad,
                                gear_ratio=WANG_RATIO)
    assert_allclose(rad_to_arcmin(te), 1.5, rtol=0, atol=1e-9)


def test_equals_consistent_mesh_line_form() -> None:
    # DESIGN.md s.4: TE = (r_p theta_2 - r_g theta_1) / r_p for one mesh, r_g / r_p = 1 / i.
    r_p_m = 0.065 * math.cos(math.radians(20.0))
    r_g_m = r_p_m / WANG_RATIO
    rng = np.random.default_rng(2)
    theta_1 = rng.uniform(-50, 50, 100)
    theta_2 = theta_1 / WANG_RATIO + rng.normal(0, 1e-3, 100)
    mesh_line = (r_p_m * theta_2 - r_g_m * theta_1) / r_p_m
    te = transmission_error_rad(theta_1, theta_2, gear_ratio=WANG_RATIO)
    assert_allclose(te, mesh_line, rtol=0, atol=1e-15)


@pytest.mark.parametrize('ratio', [0.0, -79.0, math.nan, math.inf])
def test_bad_ratio_rejected(ratio: float) -> None:
    with pytest.raises(TeInputError, match='gear_ratio'):
        transmission_error_rad([0.0], [0.0], gear_ratio=ratio)


def test_shape_mismatch_rejected() -> None:
    with pytest.raises(TeInputError, match='shape mismatch'):
        transmission_error_rad(np.zeros(3), np.zeros(4), gear_ratio=79.0)


@given(theta_in=hnp.arrays(np.float64, st.integers(1, 50), elements=angles),
       data=st.data(), c=angles, ratio=st.floats(1.0, 200.0))
def test_te_unchanged_by_common_rotation(theta_in: np.ndarray, data: st.DataObject, c: float,
                                         ratio: float) -> None:
    # Adding c to theta_out and i*c to theta_in is a rigid rotation of an ideal train.
    theta_out = data.draw(hnp.arrays(np.float64, theta_in.shape, elements=angles))
    te0 = transmission_error_rad(theta_in, theta_out, gear_ratio=ratio)
    te1 = transmission_error_rad(theta_in + ratio * c, theta_out + c, gear_ratio=ratio)
    assert_allclose(te1, te0, rtol=0, atol=1e-9)  # rounding of values up to ~2e5 rad


@given(theta_in=hnp.arrays(np.float64, st.integers(1, 50), elements=angles),
       data=st.data(), ratio=st.floats(1.0, 200.0))
def test_swapping_shafts_with_inverse_ratio(theta_in: np.ndarray, data: st.DataObject,
                                            ratio: float) -> None:
    # theta_in - theta_out / (1/i) = -i (theta_out - theta_in / i)
    theta_out = data.draw(hnp.arrays(np.float64, theta_in.shape, elements=angles))
    te = transmission_error_rad(theta_in, theta_out, gear_ratio=ratio)
    swapped = transmission_error_rad(theta_out, theta_in, gear_ratio=1.0 / ratio)
    assert_allclose(swapped, -ratio * te, rtol=1e-12, atol=1e-9)


def test_statistics_of_a_cosine_closed_form() -> None:
    a_rad = float(arcmin_to_rad(1.22))
    phi = 2 * np.pi * np.arange(1000) / 1000
    s = te_statistics(a_rad * np.cos(phi) - 0.1 * a_rad, revolutions=1.0)
    assert_allclose(s.pp_rad, 2 * a_rad, rtol=1e-12)
    assert_allclose(s.amplitude_rad, 1.1 * a_rad, rtol=1e-12)
    assert_allclose(s.mean_rad, -0.1 * a_rad, rtol=1e-12)
    assert_allclose(s.std_rad, a_rad / math.sqrt(2), rtol=1e-12)
    assert (s.revolutions, s.n_samples) == (1.0, 1000)


def test_json_dict_has_arcmin_and_rad_keys() -> None:
    s = TeStats(pp_rad=1.0, amplitude_rad=0.5, mean_rad=-0.25, std_rad=0.125,
                revolutions=2.0, n_samples=7)
    d = s.to_json_dict()
    assert_allclose(d['te_pp_arcmin'], 10800 / math.pi, rtol=1e-15)
    assert_allclose(d['te_mean_arcmin'], -0.25 * 10800 / math.pi, rtol=1e-15)
    assert d['te_std_rad'] == 0.125
    assert (d['revolutions'], d['n_samples']) == (2.0, 7)
    assert {'te_amplitude_arcmin', 'te_std_arcmin', 'te_amplitude_rad'} <= set(d)
    assert TeStats.empty().to_json_dict()['te_pp_arcmin'] is None


def test_statistics_empty_and_non_finite() -> None:
    assert te_statistics([]).n_samples == 0
    assert math.isnan(te_statistics([]).pp_rad)
    with pytest.raises(TeInputError, match=r'te_rad\[1\]'):
        te_statistics([0.0, math.nan])
    rs = RunningStats()
    assert math.isnan(rs.stats().mean_rad)
    with pytest.raises(TeInputError):
        rs.update([1.0, math.inf])
    assert rs.n_samples == 0


finite = st.floats(-1e-2, 1e-2, allow_nan=False)


@given(chunks=st.lists(hnp.arrays(np.float64, st.integers(0, 40), elements=finite),
                       min_size=1, max_size=6),
       offset=st.floats(-10.0, 10.0))
def test_running_stats_merge_equals_concatenation(chunks: list[np.ndarray],
                                                  offset: float) -> None:
    chunks = [c + offset for c in chunks]
    whole = np.concatenate(chunks)
    seq = RunningStats()
    merged = RunningStats()
    for c in chunks:
        seq.update(c)
        part = RunningStats()
        part.update(c)
        merged.merge(part)
    if whole.size == 0:
        assert seq.stats().n_samples == merged.stats().n_samples == 0
        return
    # independent reference: two-pass numpy on the concatenation
    ref_std = math.sqrt(float(np.mean((whole - whole.mean()) ** 2)))
    for rs in (seq, merged):
        s = rs.stats(revolutions=1.5)
        assert s.n_samples == whole.size
        assert s.pp_rad == float(whole.max() - whole.min())
        assert s.amplitude_rad == float(np.abs(whole).max())
        assert_allclose(s.mean_rad, whole.mean(), rtol=1e-12, atol=1e-15)
        assert_allclose(s.std_rad, ref_std, rtol=1e-9, atol=1e-12)
        assert s.revolutions == 1.5


def test_running_stats_no_cancellation_at_large_offset() -> None:
    # Sum-of-squares would lose all digits here; Chan's update keeps them.
    rng = np.random.default_rng(3)
    blocks = [1.0e4 + 1e-6 * rng.standard_normal(1000) for _ in range(50)]
    rs = RunningStats()
    for b in blocks:
        rs.update(b)
    whole = np.concatenate(blocks)
    assert_allclose(rs.stats().std_rad, np.std(whole), rtol=1e-6)


def test_output_phase_and_te_into_given_arrays_is_bit_identical() -> None:
    """The streaming analysis writes Wang 2020 Eq. 22 into its window buffer through
    ``out=``: the same values, bit for bit, as the arrays the function makes itself."""
    rng = np.random.default_rng(7)
    theta_in = np.cumsum(rng.uniform(0.0, 0.01, 5000))
    theta_out = theta_in / 79.0 + rng.normal(0.0, 1e-4, 5000)
    phi_new, te_new = output_phase_and_te(theta_in, theta_out, gear_ratio=79.0)
    buf_phi, buf_te = np.full(6000, np.nan), np.full(6000, np.nan)
    phi, te = output_phase_and_te(theta_in, theta_out, gear_ratio=79.0, check=False,
                                  out=(buf_phi[100:5100], buf_te[100:5100]))
    assert np.shares_memory(phi, buf_phi) and np.shares_memory(te, buf_te)
    assert np.array_equal(buf_phi[100:5100], phi_new)
    assert np.array_equal(buf_te[100:5100], te_new)
    assert np.array_equal(te_new, theta_out - theta_in / 79.0)
    assert np.isnan(buf_phi[:100]).all() and np.isnan(buf_te[5100:]).all()
