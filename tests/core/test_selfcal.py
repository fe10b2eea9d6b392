"""Self-calibration from head differences, reversal, and the calibration record applied.

Readings from the tests' exact-geometry scale (:mod:`tests.scale_reference`) or sim's
encoder; reducer TE from the paper's equations written out in :mod:`tests.wang2020_reference`;
the truth is the tests' own FFT of their own curves.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.encoder_calibration import calibration_from_estimate
from rv_te_bench.core.heads import HeadLayout
from rv_te_bench.core.selfcal import HeadSelfCalibration, ReversalSession, reversal_separation
from rv_te_bench.errors import TeConfigError, TeInputError
from sim.encoders import SimulatedEncoder, encoder_preset, with_heads
from sim.read_heads import eccentricity_angle_rad, equally_spaced_heads, graduation_from_grade
from tests import wang2020_reference as ref
from tests.scale_reference import ARCSEC_RAD, Scale, harmonics, whole_revolutions_fft

MAX_ORDER = 32


def _random_scale(rng: np.random.Generator, heads_deg: list[float], *,
                  noise_arcsec: float = 0.01, index_rad: float = 0.0) -> Scale:
    grad = graduation_from_grade(1.0, rng)
    n = len(heads_deg)
    return Scale(radius_m=0.05, eccentricity_m=5e-6, psi_rad=rng.uniform(0, 6.28),
                 tilt_rad=2e-3, chi_rad=rng.uniform(0, 3.14), index_rad=index_rad,
                 orders=grad.orders, amplitudes_rad=grad.amplitudes_rad,
                 phases_rad=grad.phases_rad, lines=36_000,
                 heads_rad=tuple(np.radians(heads_deg)),
                 interp_rad=(0.1 * ARCSEC_RAD,) * n,
                 interp_phase_rad=tuple(rng.uniform(0, 6.28, n)),
                 noise_rad=(noise_arcsec * ARCSEC_RAD,) * n)


def _true_harmonics(scale: Scale) -> np.ndarray:
    u = np.linspace(0.0, 2 * math.pi, 16_384, endpoint=False)
    return harmonics(scale.scale_error_rad(u), MAX_ORDER)


def _selfcal(scale: Scale, theta: np.ndarray, rng: np.random.Generator):
    lay = HeadLayout.of(scale.heads_rad)
    cal = HeadSelfCalibration(lay, max_order=MAX_ORDER)
    r = scale.readings(theta, rng)
    for s in range(0, theta.size, 20_000):
        cal.add(r[:, s:s + 20_000])
    return cal.result()


@pytest.mark.parametrize('heads_deg', [[0, 180], [0, 120, 240], [0, 90, 180, 270],
                                       [0, 90, 180]])
def test_self_calibration_finds_the_scale_error_on_its_observable_harmonics(heads_deg) -> None:
    """Target: the scale error from head differences within 0.1" RMS of the true one on
    the orders the layout observes (measured: ~0.001"); the unobservable orders are the
    ones the test expects (multiples of N for equal division)."""
    rng = np.random.default_rng(len(heads_deg) * 100 + heads_deg[1])
    scale = _random_scale(rng, heads_deg)
    theta = rng.uniform(0, 6.28) + np.linspace(0.0, 2 * math.pi * 1.1, 400_000)
    est = _selfcal(scale, theta, rng)
    truth = _true_harmonics(scale)
    ks = np.arange(1, MAX_ORDER + 1)
    beta = np.radians(heads_deg)
    a = np.exp(-1j * ks[:, None] * beta[None, 1:]) - 1.0
    seen = np.sqrt(np.sum(np.abs(a) ** 2, axis=1) / (2 * len(beta))) >= 0.1
    np.testing.assert_array_equal(est.observable, seen)
    err = est.c_rad[seen] - truth[seen]
    rms = math.sqrt(float(np.sum(np.abs(err) ** 2)) / 2) / ARCSEC_RAD
    assert rms <= 0.1, rms
    assert abs(truth[0]) / ARCSEC_RAD > 20       # the eccentricity was there to find


def test_self_calibration_uncertainty_covers_the_error() -> None:
    """With 0.3" head noise dominating, the errors of 24 orders x 6 runs in units of the
    stated u have an RMS between 0.6 and 1.6 (the stated uncertainty is the right size)."""
    z = []
    for seed in range(6):
        rng = np.random.default_rng(seed)
        scale = _random_scale(rng, [0, 90, 180, 270], noise_arcsec=0.3)
        theta = np.linspace(0.0, 2 * math.pi * 1.0, 120_000)
        est = _selfcal(scale, theta, rng)
        truth = _true_harmonics(scale)
        ok = est.observable
        d = (est.c_rad[ok] - truth[ok]) / est.u_rad[ok]
        z.extend(d.real.tolist() + d.imag.tolist())
    rms = math.sqrt(float(np.mean(np.square(z))))
    assert 0.6 < rms < 1.6, rms


def test_self_calibration_needs_a_whole_revolution_and_two_heads() -> None:
    rng = np.random.default_rng(1)
    scale = _random_scale(rng, [0, 180])
    cal = HeadSelfCalibration(HeadLayout.of(scale.heads_rad), max_order=8)
    cal.add(scale.readings(np.linspace(0.0, 5.0, 10_000)))
    with pytest.raises(TeInputError, match=r'spans 0\.796 revolutions'):
        cal.result()
    with pytest.raises(TeConfigError, match='two or more read heads'):
        HeadSelfCalibration(HeadLayout.of([0.0]))
    with pytest.raises(TeInputError, match='readings must be'):
        cal.add(np.zeros((3, 10)))


def _reversal_session(unit: ref.Unit, scale: Scale, rng: np.random.Generator,
                      ) -> ReversalSession:
    """One head; the true output angle from the paper's TE, read through the scale."""
    n = 250_000
    phi = rng.uniform(0, 2 * math.pi) + np.linspace(0.0, 2 * math.pi * 1.15, n)
    te_true = ref.nlte_rad(phi, unit)
    theta_out = phi + te_true
    reading = scale.readings(theta_out, rng)[0]
    theta_in = phi * ref.RATIO + 0.2 * ARCSEC_RAD * rng.standard_normal(n)
    te = reading - theta_in / ref.RATIO
    return ReversalSession.fold(reading, te, index_rad=scale.index_rad, max_order=8)


@pytest.mark.parametrize('index_deg', [180.0, 120.0])
def test_reversal_separates_scale_and_output_wheel_eccentricity(index_deg: float) -> None:
    """Target: a 41" p-p scale eccentricity (5 um on 100 mm) and a ~20" p-p output-wheel
    line (Wang 2020 unit, e_ot chosen for it), separated within 2 % each by two sessions
    with the scale re-mounted at 180 deg (or 120 deg); truth: the tests' FFT of the
    scale's and the reducer's own curves."""
    rng = np.random.default_rng(int(index_deg))
    unit = ref.Unit(e_p1=12e-6, e_p2=9e-6, e_g=6e-6, e_ot=4.1e-6, theta_p1=0.3, theta_p2=2.0,
                    theta_g=-1.0, theta_ot=0.8)
    grad = graduation_from_grade(1.0, rng)

    def scale(index_rad: float) -> Scale:
        return Scale(radius_m=0.05, eccentricity_m=5e-6, psi_rad=2.5, index_rad=index_rad,
                     orders=grad.orders, amplitudes_rad=grad.amplitudes_rad,
                     phases_rad=grad.phases_rad, noise_rad=(0.05 * ARCSEC_RAD,))

    res = reversal_separation([_reversal_session(unit, scale(0.0), rng),
                               _reversal_session(unit, scale(math.radians(index_deg)), rng)])
    # truth of the reducer: FFT of its TE over the shaft angle (one revolution, fine grid)
    phi = np.linspace(0.0, 2 * math.pi * 3, 3 * 65_536, endpoint=False)
    te = ref.nlte_rad(phi, unit)
    reducer1 = whole_revolutions_fft(phi + te, te, 1)[0]
    scale1 = _true_harmonics(scale(0.0))[0]
    assert 19.0 < 2 * abs(reducer1) / ARCSEC_RAD < 21.0     # the ~20" p-p output line
    assert 40.0 < 2 * abs(scale1) / ARCSEC_RAD < 42.0       # the 41" p-p scale line
    assert abs(res.scale.c_rad[0] - scale1) <= 0.02 * abs(scale1)
    assert abs(res.reducer.c_rad[0] - reducer1) <= 0.02 * abs(reducer1)
    want_unobs = (2, 4, 6, 8) if index_deg == 180.0 else (3, 6)
    assert res.scale.unobservable_orders == want_unobs


def test_reversal_at_the_same_index_is_refused() -> None:
    rng = np.random.default_rng(5)
    unit = ref.random_unit(rng)
    s = _reversal_session(unit, Scale(), rng)
    with pytest.raises(TeConfigError, match='make no order observable'):
        reversal_separation([s, s])
    with pytest.raises(TeConfigError, match='two or more sessions'):
        reversal_separation([s])


def test_a_calibration_on_one_head_gives_the_four_head_te() -> None:
    """Target: a scale self-calibrated with its 4 heads; a later run read by head 0 alone
    with that calibration applied gives the TE of the 4-head mean within 0.2" RMS
    (measured ~0.07": what is left is the heads' own interpolation errors). Readings by
    sim's encoder (RON 886 class, 5 um eccentricity); reducer TE from the paper's model."""
    rng = np.random.default_rng(2036)
    ron = encoder_preset('heidenhain-ron886')
    grad = graduation_from_grade(1.0, rng)
    spec = with_heads(ron, equally_spaced_heads(4, rng, interpolation_rad=0.1 * ARCSEC_RAD,
                                                noise_sigma_rad=ron.noise_sigma_rad),
                      graduation_orders=grad.orders,
                      graduation_amplitudes_rad=grad.amplitudes_rad,
                      graduation_phases_rad=grad.phases_rad,
                      eccentricity_amplitude_rad=eccentricity_angle_rad(5e-6, 0.1),
                      eccentricity_phase_rad=1.3, serial='RING-42')
    enc = SimulatedEncoder(spec, rng)
    lay = HeadLayout.of(spec.head_angles_rad)
    unit = ref.random_unit(rng)

    def run(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        phi = rng.uniform(0, 2 * math.pi) + np.linspace(0.0, 2 * math.pi * 1.05, n)
        te = ref.nlte_rad(phi, unit)
        return phi, te, enc.measure_heads(phi + te)

    _, _, r_cal = run(300_000)
    sc = HeadSelfCalibration(lay, max_order=MAX_ORDER)
    sc.add(r_cal)
    cal = calibration_from_estimate(sc.result(), scale_serial='RING-42', date='2026-11-27')
    cal.check_for(spec.serial)
    phi, _te, r = run(200_000)
    te4 = lay.combine(r) - phi
    te1_cal = cal.correct(r[0], head_angle_rad=0.0) - phi
    te1 = r[0] - phi
    rms = float(np.std(te1_cal - te4)) / ARCSEC_RAD
    assert rms <= 0.2, rms
    assert float(np.std(te1 - te4)) / ARCSEC_RAD > 10.0      # without it: the scale's ~15"
    # the other heads, corrected at their own angles, agree as well
    te3_cal = cal.correct(r[3], head_angle_rad=lay.angles_rad[3]) - phi
    assert float(np.std(te3_cal - te4)) / ARCSEC_RAD <= 0.2
