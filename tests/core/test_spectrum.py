"""Order spectrum: injected harmonics at constant and sinusoidally varying speed, Parseval."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.testing import assert_allclose

from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.spectrum import order_spectrum, resample_to_output_angle
from rv_te_bench.core.te import transmission_error_rad
from rv_te_bench.core.units import arcmin_to_rad
from rv_te_bench.errors import TeConfigError, TeInputError
from sim.bench_info import BenchInfoData

# Wang 2020 2K-V (DESIGN.md s.4): i = 79, f_w = 25 f_out, 2nd-stage mesh at 52 f_w.
RATIO = 79.0
CRANK_PER_OUTPUT = 25.0
OMEGA_IN_RAD_S = 300.0 * 2 * math.pi / 60.0  # 300 rpm input
OUTPUT_HZ = 300.0 / 60.0 / RATIO  # 0.063291 Hz, period 15.8 s
ORDERS = OrderSet(gear_ratio=RATIO, crank_per_output=CRANK_PER_OUTPUT, n_crank_harmonics=4,
                  mesh_orders_out=(52 * CRANK_PER_OUTPUT,), mesh_labels=('52 f_w',))

AMP_RTOL = 0.005  # acceptance: every amplitude within 0.5 %
PHASE_TOL_RAD = math.radians(1.0)  # acceptance: every phase within 1 degree


def _injected() -> dict[str, tuple[float, float, float]]:
    """label -> (output order, amplitude rad, phase rad): 0.05' to 2', random phases."""
    rng = np.random.default_rng(20201122)
    lines = ORDERS.lines()
    amps = np.concatenate([[0.05, 2.0], rng.uniform(0.05, 2.0, len(lines) - 2)])
    phases = rng.uniform(-math.pi, math.pi, len(lines))
    return {label: (order, float(arcmin_to_rad(a)), float(p))
            for (order, label), a, p in zip(lines, amps, phases, strict=True)}


INJECTED = _injected()


def _te_of_angle(phi_rad: np.ndarray) -> np.ndarray:
    te = np.full_like(phi_rad, float(arcmin_to_rad(-0.15)))  # a mean, as in Wang Fig. 5a
    for order, amp, phase in INJECTED.values():
        te += amp * np.cos(order * phi_rad + phase)
    return te


def _bench_record(speed_variation: float, samples_per_rev_mean: int, n_rev: float,
                  phi0_rad: float = 1.234) -> tuple[np.ndarray, np.ndarray, float]:
    """Encoder angles sampled uniformly in time; input speed w0 (1 + v sin(B t))."""
    fs_hz = samples_per_rev_mean * OUTPUT_HZ
    t = np.arange(int(n_rev * samples_per_rev_mean)) / fs_hz
    b_rad_s = 2 * math.pi / 3.7  # speed cycle of 3.7 s, unrelated to the rotation
    theta_in = RATIO * phi0_rad + OMEGA_IN_RAD_S * (
        t + speed_variation * (1.0 - np.cos(b_rad_s * t)) / b_rad_s)
    phi = theta_in / RATIO
    theta_out = phi + _te_of_angle(phi)
    return theta_in, theta_out, float(t[-1] - t[0])


@pytest.mark.parametrize('speed_variation', [0.0, 0.5])
def test_injected_lines_recovered(speed_variation: float) -> None:
    # >= 12 samples per period of the mesh order (1300) at the highest speed.
    theta_in, theta_out, duration_s = _bench_record(speed_variation, 32_000, 2.2)
    te = transmission_error_rad(theta_in, theta_out, gear_ratio=RATIO)
    spec = order_spectrum(theta_in / RATIO, te, ORDERS, duration_s=duration_s)
    assert spec.revolutions == 2.0
    assert {ln.label for ln in spec.lines} == set(INJECTED)
    for ln in spec.lines:
        order, amp, phase = INJECTED[ln.label]
        assert ln.output_order == order
        assert_allclose(ln.crank_order, order / CRANK_PER_OUTPUT, rtol=1e-12)
        assert_allclose(ln.amplitude_rad, amp, rtol=AMP_RTOL, err_msg=ln.label)
        dphase = (ln.phase_rad - phase + math.pi) % (2 * math.pi) - math.pi
        assert abs(dphase) < PHASE_TOL_RAD, ln.label
    assert_allclose(spec.mean_rad, arcmin_to_rad(-0.15), rtol=AMP_RTOL)
    # Sharp: every bin that is not an injected line stays below 0.1 % of the largest line.
    line_bins = [round(o * spec.revolutions) for o, _, _ in INJECTED.values()]
    rest = np.delete(spec.amplitude_rad, [0, *line_bins])
    assert rest.max() < 1e-3 * max(a for _, a, _ in INJECTED.values())


def test_mean_speed_frequencies_wang_300rpm() -> None:
    theta_in, theta_out, duration_s = _bench_record(0.0, 2048, 1.5)
    te = transmission_error_rad(theta_in, theta_out, gear_ratio=RATIO)
    spec = order_spectrum(theta_in / RATIO, te, ORDERS, duration_s=duration_s)
    assert_allclose(spec.output_hz, OUTPUT_HZ, rtol=1e-9)
    assert_allclose(spec.crank_hz, 1.582, atol=5e-4)  # DESIGN.md: f_w = 1.582 Hz
    assert_allclose(spec.line('2 f_w').frequency_hz, 2 * 25 * OUTPUT_HZ, rtol=1e-9)
    # the mesh line (order 1300) is above the Nyquist order (1024) of 2048 points per rev
    assert '52 f_w' not in {ln.label for ln in spec.lines}
    assert math.isnan(order_spectrum(theta_in / RATIO, te, ORDERS).output_hz)


def test_ideal_reducer_has_empty_spectrum() -> None:
    theta_in, _, duration_s = _bench_record(0.5, 2048, 1.3)
    te = transmission_error_rad(theta_in, theta_in / RATIO, gear_ratio=RATIO)
    spec = order_spectrum(theta_in / RATIO, te, ORDERS, duration_s=duration_s)
    assert np.all(spec.amplitude_rad == 0.0)


@pytest.mark.parametrize('reverse', [False, True])
@pytest.mark.parametrize(('order', 'phi0_rad'), [(1, 0.0), (7, -3.0), (25, 1e3)])
def test_single_cosine_absolute_phase(order: int, phi0_rad: float, reverse: bool) -> None:
    # TE = a cos(k phi + p) over an arbitrary start angle, either sense of rotation.
    n = 3 * 256
    phi = phi0_rad + 2 * np.pi * 3 * np.arange(n) / n
    a_rad, p_rad = 1e-4, -2.5
    te = a_rad * np.cos(order * phi + p_rad)
    if reverse:
        phi, te = -phi[::-1], (a_rad * np.cos(order * (-phi[::-1]) + p_rad))
    spec = order_spectrum(phi, te, OrderSet(RATIO, 25.0, n_crank_harmonics=1))
    m = order * 3
    assert_allclose(spec.amplitude_rad[m], a_rad, rtol=1e-9)
    assert_allclose(spec.phase_rad[m], p_rad, atol=1e-6)
    assert_allclose(spec.orders[m], order, rtol=0)
    assert np.delete(spec.amplitude_rad, m).max() < 1e-9 * a_rad
    assert not spec.amplitude_rad.flags.writeable


@given(te=hnp.arrays(np.float64, st.integers(8, 300),
                     elements=st.floats(-1e-3, 1e-3, allow_nan=False)),
       revolutions=st.integers(1, 3), phi0=st.floats(-100.0, 100.0))
def test_parseval_for_peak_amplitude_scaling(te: np.ndarray, revolutions: int,
                                             phi0: float) -> None:
    n = te.size - te.size % revolutions
    te = te[:n]
    spr = n // revolutions
    phi = phi0 + 2 * np.pi * revolutions * np.arange(n) / n
    res = resample_to_output_angle(phi, te, samples_per_rev=spr)
    assert res.revolutions == revolutions
    assert_allclose(res.te_rad, te, rtol=0, atol=1e-9 * max(1e-3, float(np.abs(te).max())))
    spec = order_spectrum(phi, te, OrderSet(RATIO, 25.0), samples_per_rev=spr)
    a = spec.amplitude_rad
    nyquist = a[-1] ** 2 if n % 2 == 0 else a[-1] ** 2 / 2
    inner = a[1:-1]   # every bin but the mean and the last (the last is in nyquist above)
    parseval = a[0] ** 2 + np.sum(inner**2) / 2 + nyquist
    assert_allclose(parseval, np.mean(res.te_rad**2), rtol=1e-9, atol=1e-24)
    assert_allclose(abs(spec.mean_rad), a[0], rtol=1e-12)


def test_resampling_error_bound_of_module_docstring() -> None:
    # Smoothly non-uniform spacing (+-30 %), 15 samples per period on average (11.5 at the
    # sparsest): the docstring's 0.015 (2 pi / s)^4 gives 1.3e-3 at s = 11.5.
    n = 15 * 40
    u = 2 * np.pi * np.arange(n + 1) / n
    phi = u + 0.3 * np.sin(u)
    te = np.cos(40 * phi)
    spec = order_spectrum(phi, te, OrderSet(RATIO, 25.0), samples_per_rev=1024,
                          revolutions=1)
    assert_allclose(spec.amplitude_rad[40], 1.0, rtol=1.3e-3)


@pytest.mark.parametrize(('phi', 'te', 'match'), [
    (np.linspace(0, 7, 10), np.zeros(9), 'equal length'),
    (np.array([0.0]), np.array([0.0]), 'at least 2'),
    (np.array([0.0, 1.0, 0.5, 7.0]), np.zeros(4), 'monotonic'),
    (np.array([0.0, 1.0, 1.0, 7.0]), np.zeros(4), 'monotonic'),
    (np.linspace(0, 5, 10), np.zeros(10), 'need at least 1'),
    (np.linspace(0, 7, 10), np.array([0.0] * 9 + [math.nan]), 'NaN'),
])
def test_bad_records_rejected(phi: np.ndarray, te: np.ndarray, match: str) -> None:
    with pytest.raises(TeInputError, match=match):
        order_spectrum(phi, te, ORDERS)


def test_more_revolutions_than_covered_rejected() -> None:
    phi = np.linspace(0, 2 * np.pi * 1.5, 100)
    with pytest.raises(TeInputError, match='fewer than revolutions=2'):
        order_spectrum(phi, np.zeros(100), ORDERS, revolutions=2)
    with pytest.raises(TeInputError, match='duration_s'):
        order_spectrum(phi, np.zeros(100), ORDERS, duration_s=0.0)


def test_order_set_lines_deduplicated() -> None:
    # crank_per_output 1: 1 f_w = f_out, f_w - f_out = 0 (left out), f_w + f_out = 2 f_w
    s = OrderSet(gear_ratio=10.0, crank_per_output=1.0, n_crank_harmonics=3,
                 mesh_orders_out=(3.0, 40.0))
    assert s.lines() == [(1.0, 'f_out'), (2.0, '2 f_w'), (3.0, '3 f_w'), (40.0, 'mesh 2')]


def test_order_set_from_bench_info_wang() -> None:
    info = BenchInfoData(gear_ratio=RATIO, crank_per_input=-25.0 / RATIO, mesh_orders=(1300.0,),
                         mesh_labels=('52 f_w',))
    s = OrderSet.from_bench_info(info, 2)
    assert_allclose(s.crank_per_output, 25.0, rtol=1e-14)
    assert [lbl for _, lbl in s.lines()] == ['f_out', '1 f_w', '2 f_w', 'f_w - f_out',
                                             'f_w + f_out', '52 f_w']


@pytest.mark.parametrize(('kwargs', 'match'), [
    ({'gear_ratio': 0.0, 'crank_per_output': 25.0}, 'gear_ratio'),
    ({'gear_ratio': 79.0, 'crank_per_output': math.nan}, 'crank_per_output'),
    ({'gear_ratio': 79.0, 'crank_per_output': 25.0, 'mesh_orders_out': (-1.0,)},
     r'mesh_orders_out\[0\]'),
    ({'gear_ratio': 79.0, 'crank_per_output': 25.0, 'mesh_orders_out': (1.0,),
      'mesh_labels': ('a', 'b')}, 'mesh_labels'),
    ({'gear_ratio': 79.0, 'crank_per_output': 25.0, 'n_crank_harmonics': -1},
     'n_crank_harmonics'),
])
def test_order_set_validation(kwargs: dict, match: str) -> None:
    with pytest.raises(TeConfigError, match=match):
        OrderSet(**kwargs)


@pytest.mark.parametrize(('nodes_per_rev', 'grid_per_rev'), [(2000, 512), (15800, 4096)])
def test_grid_coarser_than_samples_is_centred(nodes_per_rev: int, grid_per_rev: int) -> None:
    """Jittered samples denser than the angle grid: the 4-node stencil must straddle each
    grid point (closed form cos(k phi), 12 grid points per period of the highest order)."""
    rng = np.random.default_rng(5)
    k = grid_per_rev // 12
    step = 2 * np.pi / nodes_per_rev
    m = int(nodes_per_rev * 1.1)   # a little more than one revolution
    phi = np.cumsum(np.full(m, step) * rng.uniform(0.7, 1.3, m))
    phi -= phi[0]
    amp = 1e-4
    spec = order_spectrum(phi, amp * np.cos(k * phi),
                          OrderSet(gear_ratio=79.0, crank_per_output=float(k),
                                   n_crank_harmonics=1),
                          samples_per_rev=grid_per_rev, revolutions=1)
    line = next(ln for ln in spec.lines if ln.output_order == pytest.approx(k))
    # cubic interpolation error at 12 points per period is ~1e-3 of the amplitude when the
    # stencil is centred; an off-by-one-cell stencil extrapolates and loses ~0.3 %
    assert line.amplitude_rad == pytest.approx(amp, rel=5e-4)
