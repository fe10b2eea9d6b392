"""Acceptance tests of sim.wang2020 against Wang 2020 (Figs 4-7, Table 4) and closed forms.

Paper values (arcmin) come from the text of Wang, Su, Zou (2020), section 2.2.2 and Table 4;
tolerances are stated at each assertion. Reference dynamics are computed independently
in this file (fixed-step RK4 on the flank positions of Eqs 1-4).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sim.errors import ModelInputError, PresetError
from sim.models import build_te_model as registry_build
from sim.presets import load_preset
from sim.units import arcmin_to_rad, rad_to_arcmin
from sim.wang2020 import (
    Wang2kvDynamics,
    Wang2kvParams,
    backlash_pairs_rad,
    backlash_rad,
    build_te_model,
    contact_forces_n,
    mesh_increments_m,
    nlte_curves,
    nlte_pairs_rad,
    nlte_rad,
    static_te_rad,
    stiffness_n_m,
)

N_REV = 158_000                         # one output revolution (15.8 s) at 10 kHz
THETA = np.linspace(0.0, 2.0 * math.pi, N_REV, endpoint=False)
OMEGA_IN = 2.0 * math.pi * 5.0          # 300 rpm


@pytest.fixture(scope='module')
def params() -> Wang2kvParams:
    return Wang2kvParams.from_preset(load_preset('wang2020-2kv'))


@pytest.fixture(scope='module')
def params_const_k(params: Wang2kvParams) -> Wang2kvParams:
    return dataclasses.replace(params, stiffness_harmonic_ratio=(0.0,))


@pytest.fixture(scope='module')
def params_ripple(params: Wang2kvParams) -> Wang2kvParams:
    """A 10 % mesh-stiffness ripple at the stage-2 mesh order (Eq. 20; the preset has none)."""
    return dataclasses.replace(params, stiffness_harmonic_ratio=(0.1,),
                               stiffness_harmonic_phase_rad=(0.0,))


def _stats(te_rad: np.ndarray) -> tuple[float, float, float]:
    a = rad_to_arcmin(te_rad)
    return float(np.ptp(a)), float(np.max(np.abs(a))), float(np.mean(a))


# ----------------------------------------------------------------- Eqs 1-9 (NLTE)

def test_preset_values(params: Wang2kvParams) -> None:
    assert params.kinematics.gear_ratio == pytest.approx(79.0, rel=1e-12)
    assert params.r_p_m == pytest.approx(0.065 * math.cos(math.radians(20.0)), rel=1e-3)
    assert params.pressure_angle_rad == pytest.approx(math.radians(35.266), rel=1e-12)
    assert params.phases_rad == pytest.approx(tuple(map(math.radians, (90, 180, -135, 90))))


def test_total_nlte_fig5a(params: Wang2kvParams) -> None:
    # Fig. 5a: p-p 2.23', amplitude 1.22', mean -0.15'
    pp, amp, mean = _stats(nlte_rad(THETA, params))
    assert pp == pytest.approx(2.23, rel=0.05)
    assert amp == pytest.approx(1.22, rel=0.06)
    assert mean == pytest.approx(-0.15, abs=0.02)
    # Table 4 (before optimisation): p-p 2.245', amplitude 1.231'
    assert pp == pytest.approx(2.245, rel=0.05)
    assert amp == pytest.approx(1.231, rel=0.06)


def test_pair_nlte_fig4(params: Wang2kvParams) -> None:
    # Fig. 4a/b: pair 1 p-p 2.06', amp 1.89', mean -0.86'; pair 2 2.89', 1.74', -0.29'.
    # Reproduced ~4 % low for both pairs (same r_p as Fig. 5a): 6 % / 0.05' tolerance.
    n1, n2 = nlte_pairs_rad(THETA, params)
    pp1, amp1, mean1 = _stats(n1)
    pp2, amp2, mean2 = _stats(n2)
    assert (pp1, amp1) == pytest.approx((2.06, 1.89), rel=0.06)
    assert mean1 == pytest.approx(-0.86, abs=0.05)
    assert (pp2, amp2) == pytest.approx((2.89, 1.74), rel=0.06)
    assert mean2 == pytest.approx(-0.29, abs=0.05)


def test_nlte_closed_form_single_eccentricity(params: Wang2kvParams) -> None:
    # Only the output wheel eccentric: Delta_1 = e [sin(th_ot + th - a) - sin(th_ot - a)],
    # Delta_2 = -Delta_1 (the +pi terms), so NLTE = |Delta_1| / r_p.
    p = dataclasses.replace(params, e_p1_m=0.0, e_p2_m=0.0, e_g_m=0.0, e_ot_m=1e-5)
    a, ot = p.pressure_angle_rad, p.theta_ot_0_rad
    d1 = 1e-5 * (np.sin(ot + THETA - a) - np.sin(ot - a))
    n1, n2 = nlte_pairs_rad(THETA, p)
    assert_allclose(n1, d1 / p.r_p_m, atol=1e-15)
    assert_allclose(n2, -d1 / p.r_p_m, atol=1e-15)
    assert_allclose(nlte_rad(THETA, p), np.abs(d1) / p.r_p_m, atol=1e-15)


def test_nlte_zero_at_t0_and_period(params: Wang2kvParams) -> None:
    inc = mesh_increments_m(np.array([0.0, 2 * math.pi]), params)
    for arr in inc:
        assert_allclose(arr, 0.0, atol=1e-18)


def test_largest_spectral_line_at_crank_frequency(params: Wang2kvParams) -> None:
    # Fig. 16a: the main line of the NLTE spectrum is f_w (25 per output revolution)
    te = nlte_rad(THETA, params)
    amp = np.abs(np.fft.rfft(te - te.mean()))
    assert int(np.argmax(amp)) == 25


def test_phase_broadcasting_matches_loop(params: Wang2kvParams) -> None:
    th = np.linspace(0.0, 2 * math.pi, 500)
    combos = np.deg2rad(np.array([[90, 180, -135, 90], [-70, 120, 110, 40], [0, -50, 130, 120]]))
    phases = tuple(combos[:, k:k + 1] for k in range(4))
    got = nlte_rad(th, params, phases_rad=phases)
    assert got.shape == (3, 500)
    for row, c in zip(got, combos, strict=True):
        p = dataclasses.replace(params, theta_p1_0_rad=c[0], theta_p2_0_rad=c[1],
                                theta_g_0_rad=c[2], theta_ot_0_rad=c[3])
        assert_allclose(row, nlte_rad(th, p), atol=1e-16)
    with pytest.raises(ModelInputError, match='phases_rad'):
        nlte_rad(th, params, phases_rad=(0.0, 0.0))


def test_optimised_phases_reduce_nlte(params: Wang2kvParams) -> None:
    # Table 4: after optimisation [-70, 120, 110, 40] deg the NLTE p-p is 1.072' and the
    # amplitude 0.604' (10 % tolerance: the paper optimises on a grid, values rounded)
    ph = tuple(np.deg2rad(v) for v in (-70.0, 120.0, 110.0, 40.0))
    pp, amp, _ = _stats(nlte_rad(THETA, params, phases_rad=ph))
    assert pp == pytest.approx(1.072, rel=0.10)
    assert amp == pytest.approx(0.604, rel=0.10)


def test_backlash_eqs_7_and_9(params: Wang2kvParams) -> None:
    c = nlte_curves(THETA, params)
    b1, b2 = backlash_pairs_rad(THETA, params)
    assert_allclose(c.backlash1_rad, b1)
    # B_i(t0) is the preset value (Eq. 7 at t = t0)
    assert b1[0] == pytest.approx(params.backlash1_t0_rad, abs=1e-15)
    assert b2[0] == pytest.approx(params.backlash2_t0_rad, abs=1e-15)
    # Eq. 9 == gap from the touching drive flank to the nearest tooth back:
    # min_i(NLTE_i + B_i) - max_i(NLTE_i)
    gap = np.minimum(c.nlte1_rad + b1, c.nlte2_rad + b2) - np.maximum(c.nlte1_rad, c.nlte2_rad)
    assert_allclose(backlash_rad(THETA, params), gap, atol=1e-15)
    # the preset's B(t0) keeps the total backlash positive (see the preset note)
    assert rad_to_arcmin(c.backlash_rad.min()) == pytest.approx(0.167, abs=0.01)


# ----------------------------------------------------------------- Eqs 10-18 (STE)

@pytest.mark.parametrize(('load_nm', 'mean_arcmin'), [
    (30.0, -0.44858), (100.0, -1.0321), (300.0, -2.19511)])
def test_ste_means_fig5b(params: Wang2kvParams, load_nm: float, mean_arcmin: float) -> None:
    # Fig. 5b: STE means -0.44858', -1.0321' (printed without its minus), -2.19511' (3 %)
    _, _, mean = _stats(static_te_rad(THETA, load_nm, params))
    assert mean == pytest.approx(mean_arcmin, rel=0.03)


@pytest.mark.parametrize(('load_nm', 'pp', 'amp'), [
    (30.0, 2.084, 1.393), (100.0, 1.707, 1.770), (300.0, 1.308, 2.848)])
def test_ste_table4(params: Wang2kvParams, load_nm: float, pp: float, amp: float) -> None:
    # Table 4, before optimisation: STE p-p and amplitude (5 %)
    got_pp, got_amp, _ = _stats(static_te_rad(THETA, load_nm, params))
    assert got_pp == pytest.approx(pp, rel=0.05)
    assert got_amp == pytest.approx(amp, rel=0.05)


def test_ste_zero_load_is_nlte_and_closed_forms(params: Wang2kvParams) -> None:
    assert_allclose(static_te_rad(THETA, 0.0, params), nlte_rad(THETA, params), atol=1e-15)
    inc = mesh_increments_m(THETA, params)
    k, r = params.mesh_stiffness_n_m, params.r_p_m
    d = 100.0 / (r * k)
    ste = static_te_rad(THETA, 100.0, params) * r
    both = np.abs(inc.delta1_m - inc.delta2_m) < d
    # Eq. 14 where both pairs touch, Eq. 17 elsewhere
    assert_allclose(ste[both], 0.5 * (inc.delta1_m + inc.delta2_m)[both] - 0.5 * d, atol=1e-15)
    one = ~both
    assert_allclose(ste[one], np.maximum(inc.delta1_m, inc.delta2_m)[one] - d, atol=1e-15)
    assert both.any() and one.any()


def test_contact_forces_balance(params: Wang2kvParams) -> None:
    load = np.array([0.0, 30.0, 100.0, 300.0])[:, None]
    f1, f2 = contact_forces_n(THETA[::100], load, params)
    assert np.all(f1 >= 0) and np.all(f2 >= 0)
    assert_allclose(f1 + f2, np.broadcast_to(load / params.r_p_m, f1.shape), rtol=1e-12)
    # 30 N m: one pair carries everything most of the time (Fig. 9b); 300 N m: both touch
    # with uneven forces (Fig. 10b)
    assert np.mean((f1[1] == 0) | (f2[1] == 0)) > 0.5
    assert np.mean((f1[3] > 0) & (f2[3] > 0)) > 0.9
    assert np.ptp(f1[3] - f2[3]) > 0


def test_stiffness_fourier(params_ripple: Wang2kvParams) -> None:
    params = params_ripple
    k = stiffness_n_m(THETA, params)
    assert k.mean() == pytest.approx(params.mesh_stiffness_n_m, rel=1e-9)
    assert np.ptp(k) / 2 == pytest.approx(0.1 * params.mesh_stiffness_n_m, rel=1e-3)
    # one line at the stage-2 mesh order 1300 per output revolution
    spec = np.abs(np.fft.rfft(k - k.mean()))
    assert int(np.argmax(spec)) == 1300


# ----------------------------------------------------------------- Eqs 19-20 (DTE)

def _run(params: Wang2kvParams, load: np.ndarray, n: int, fs: float = 10_000.0,
         blocks: int = 1) -> np.ndarray:
    t = np.arange(n) / fs
    dyn = Wang2kvDynamics(params)
    parts = np.array_split(np.arange(n), blocks)
    return np.concatenate([dyn.te_rad(t[p], OMEGA_IN * t[p], np.full(p.size, OMEGA_IN),
                                      load[p]) for p in parts])


@pytest.mark.parametrize('load_nm', [30.0, 300.0])
def test_dte_slow_constant_load_equals_ste(params_const_k: Wang2kvParams,
                                           load_nm: float) -> None:
    # Constant load, constant stiffness: the DTE is quasi-static; within 2 % of STE p-p
    n = N_REV
    dte = _run(params_const_k, np.full(n, load_nm), n)
    ste = static_te_rad(OMEGA_IN * np.arange(n) / 1e4 / 79.0, load_nm, params_const_k)
    assert np.max(np.abs(dte - ste)) <= 0.02 * np.ptp(ste)


def test_dte_30nm_table4(params: Wang2kvParams) -> None:
    # Table 4 (before optimisation), 30 N m DTE: p-p 2.088', amplitude 1.338' (5 %).
    # The other Table 4 DTE rows: tests/sim/test_fidelity_wang2020.py (docs/DESIGN_NOTES.md).
    pp, amp, _ = _stats(_run(params, np.full(N_REV, 30.0), N_REV))
    assert pp == pytest.approx(2.088, rel=0.05)
    assert amp == pytest.approx(1.338, rel=0.05)


def test_dte_with_stiffness_ripple_follows_quasi_static(params_ripple: Wang2kvParams) -> None:
    params = params_ripple
    # Independent quasi-static solution with k(t) at 300 N m (both pairs touch):
    # x = (D1 + D2)/2 - T / (2 r_p k(t)); the mesh-frequency ripple is 16x below f_n.
    n = 20_000
    t = np.arange(n) / 1e4
    th = OMEGA_IN * t / 79.0
    dte = _run(params, np.full(n, 300.0), n)
    inc = mesh_increments_m(th, params)
    k = stiffness_n_m(th, params)
    qs = (0.5 * (inc.delta1_m + inc.delta2_m) - 300.0 / (2 * params.r_p_m * k)) / params.r_p_m
    # dynamic amplification of the ripple response (f_mesh / f_n2)^2 ~ 0.2 %: 0.01' bound
    assert np.max(np.abs(rad_to_arcmin(dte - qs))) < 0.01


def test_dte_block_by_block_equals_one_shot(params_ripple: Wang2kvParams) -> None:
    params = params_ripple
    n = 30_000
    t = np.arange(n) / 1e4
    fw = params.kinematics.frequencies(5.0)['crank_hz']
    load = 30.0 * np.sin(2 * math.pi * 8 * fw * t)      # reversals -> impacts inside
    one = _run(params, load, n)
    many = _run(params, load, n, blocks=37)
    # The state is carried exactly; what differs is where the integrator's stretches are
    # cut (Picard passes converge to 1e-10 m, i.e. 6e-6 arcmin, per stretch, and the
    # impacts amplify that a little): 1e-4 arcmin (0.006 arcsec).
    assert np.max(np.abs(rad_to_arcmin(one - many))) < 1e-4
    assert np.ptp(rad_to_arcmin(one)) > 1.0              # it did cross the backlash


def _rk4_reference(params: Wang2kvParams, t_end: float, h: float, load_fn, *,
                   unloaded: bool = False) -> tuple:
    """Independent fixed-step RK4 of m x'' = sum k(u-x) + c(u'-x') - T/r_p over flanks.

    Starts at t = 0 quasi-static under load_fn(0), or (``unloaded``) at the unloaded contact
    state x = max(Delta_1, Delta_2) = 0 moving with the faster drive flank.
    """
    n = round(t_end / h)
    tf = np.arange(2 * n + 1) * (h / 2)                 # half steps for RK4 stages
    th = OMEGA_IN * tf / 79.0
    inc = mesh_increments_m(th, params)
    r = params.r_p_m
    u = np.stack([inc.delta1_m, inc.delta2_m, inc.delta_b1_m + params.backlash1_t0_rad * r,
                  inc.delta_b2_m + params.backlash2_t0_rad * r])
    ud = np.gradient(u, tf, axis=1)
    k = stiffness_n_m(th, params)
    ft = load_fn(tf) / r
    ul, udl, kl, fl = u.T.tolist(), ud.T.tolist(), k.tolist(), ft.tolist()
    m, c = params.equivalent_mass_kg, params.mesh_damping_n_s_m
    sgn = (1.0, 1.0, -1.0, -1.0)

    def acc(i: int, x: float, v: float) -> float:
        f = -fl[i]
        for j in range(4):
            if sgn[j] * (ul[i][j] - x) > 0:
                f += kl[i] * (ul[i][j] - x) + c * (udl[i][j] - v)
        return f / m

    if unloaded:
        x, v = max(ul[0][0], ul[0][1]), max(udl[0][0], udl[0][1])
    else:               # quasi-static at t = 0 (drive flank(s) under load)
        x = float(static_te_rad(0.0, load_fn(0.0), params)) * r
        act = [j for j in range(2) if ul[0][j] >= x]
        v = float(np.mean([udl[0][j] for j in act]))
    xs = [x]
    for s in range(n):
        i = 2 * s
        a1 = acc(i, x, v)
        a2 = acc(i + 1, x + 0.5 * h * v, v + 0.5 * h * a1)
        a3 = acc(i + 1, x + 0.5 * h * (v + 0.5 * h * a1), v + 0.5 * h * a2)
        a4 = acc(i + 2, x + h * (v + 0.5 * h * a2), v + h * a3)
        x, v = (x + h * v + h * h / 6 * (a1 + a2 + a3),
                v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4))
        xs.append(x)
    return np.arange(n + 1) * h, np.array(xs) / r


def test_dte_matches_independent_rk4_through_impacts(params_ripple: Wang2kvParams) -> None:
    params = params_ripple
    # Load reversing at the mesh frequency (Fig. 7b): free flight across the backlash and
    # impacts. RK4 at 1 us (f_n2 * h = 0.002) vs the model at its default step on 15 ms;
    # the first impact happens near 7 ms.
    fm = params.kinematics.frequencies(5.0)['mesh_stage2_hz']

    def load_fn(t):
        return 30.0 * np.sin(2 * math.pi * fm * np.asarray(t))

    t_ref, x_ref = _rk4_reference(params, 0.015, 1e-6, load_fn)
    n = 150
    t = np.arange(n) / 1e4
    ref = np.interp(t, t_ref, x_ref)
    assert np.ptp(rad_to_arcmin(ref)) > 2.0               # crossed the backlash
    # RK4 at 1 us agrees with RK4 at 0.5 us to ~0.0015 arcmin here; a fine internal step
    # (2.5 us) must agree to 0.005 arcmin ...
    fine = _run(dataclasses.replace(params, max_step_s=2.5e-6), load_fn(t), n)
    err = np.abs(rad_to_arcmin(fine - ref))
    assert err.max() < 0.005, f'max error {err.max():.4f} arcmin'
    # ... and the preset step (25 us, chosen for speed) to 0.1 arcmin, 3 % of the 3.3 arcmin
    # swing, in this impact-dominated case (errors in impact timing, first order in step)
    got = _run(params, load_fn(t), n)
    err = np.abs(rad_to_arcmin(got - ref))
    assert err.max() < 0.1, f'max error {err.max():.4f} arcmin'


def test_dte_start_unloaded_step_matches_rk4(params: Wang2kvParams) -> None:
    """dte_start 'unloaded-step': the run starts unloaded one sample interval before the
    first sample, the load a step from there. With samples at t = 0.1, 0.2, ... ms it is an
    integration started unloaded at t = 0 under 300 N m: an independent RK4 at 1 us agrees
    within 0.005 arcmin at the preset step (25 us) and 0.001 arcmin at 2.5 us over the
    start-up transient (m_e 5 kg, damping ratio 0.3: the first sample at -0.23', the
    overshoot to -2.0'); a first block of one sample is refused."""
    p = dataclasses.replace(params, equivalent_mass_kg=5.0, mesh_damping_n_s_m=12318.3,
                            dte_start='unloaded-step', stiffness_harmonic_ratio=(0.0,))
    t_ref, x_ref = _rk4_reference(p, 0.02, 1e-6, lambda t: np.full_like(np.asarray(t,
                                  dtype=float), 300.0), unloaded=True)
    t = (np.arange(200) + 1) * 1e-4
    got = Wang2kvDynamics(p).te_rad(t, OMEGA_IN * t, np.full(t.size, OMEGA_IN),
                                    np.full(t.size, 300.0))
    ref = np.interp(t, t_ref, x_ref)
    assert np.max(np.abs(rad_to_arcmin(got - ref))) < 0.005
    fine = Wang2kvDynamics(dataclasses.replace(p, max_step_s=2.5e-6)).te_rad(
        t, OMEGA_IN * t, np.full(t.size, OMEGA_IN), np.full(t.size, 300.0))
    assert np.max(np.abs(rad_to_arcmin(fine - ref))) < 0.001
    assert rad_to_arcmin(got[0]) == pytest.approx(-0.23, abs=0.01)
    assert rad_to_arcmin(np.min(got)) == pytest.approx(-2.01, abs=0.02)
    with pytest.raises(ModelInputError, match='at least two samples'):
        Wang2kvDynamics(p).te_rad([0.0], [0.0], [OMEGA_IN], [300.0])


def test_dte_sinusoidal_load_at_crank_frequency_fig7a(params_ripple: Wang2kvParams) -> None:
    params = params_ripple
    # Fig. 7a: DTE lies between NLTE and NLTE + backlash, apart from the load deflection
    # (|T|/(r_p k_min) at most) and short impacts; it visits both edges.
    n = N_REV
    t = np.arange(n) / 1e4
    fw = params.kinematics.frequencies(5.0)['crank_hz']
    load = 30.0 * np.sin(2 * math.pi * fw * t)
    dte = _run(params, load, n)
    c = nlte_curves(OMEGA_IN * t / 79.0, params)
    kmin = params.mesh_stiffness_n_m * (1 - sum(params.stiffness_harmonic_ratio))
    defl = np.abs(load) / (params.r_p_m * kmin) / params.r_p_m
    tol = arcmin_to_rad(0.01)
    outside = (dte < c.nlte_rad - defl - tol) | (dte > c.nlte_rad + c.backlash_rad + defl + tol)
    assert outside.mean() < 0.02                     # impacts: under 2 % of the samples
    upper = dte > c.nlte_rad + c.backlash_rad - arcmin_to_rad(0.05)
    lower = dte < c.nlte_rad + arcmin_to_rad(0.05)
    assert upper.mean() > 0.3 and lower.mean() > 0.3
    # upper edge while the load pulls the other way, lower edge while it resists
    assert np.mean(load[upper] < 0) > 0.95 and np.mean(load[lower] > 0) > 0.95


def test_dte_input_validation(params: Wang2kvParams) -> None:
    dyn = Wang2kvDynamics(params)
    with pytest.raises(ModelInputError, match='strictly increasing'):
        dyn.te_rad([0.0, 0.0], [0.0, 0.0], [1.0, 1.0], [0.0, 0.0])
    with pytest.raises(ModelInputError, match='load_nm'):
        dyn.te_rad([0.0, 1.0], [0.0, 0.0], [1.0, 1.0], [0.0])
    with pytest.raises(ModelInputError, match='finite'):
        dyn.te_rad([0.0, 1.0], [0.0, np.nan], [1.0, 1.0], [0.0, 0.0])
    dyn.te_rad([0.0, 1e-4], [0.0, 1e-4], [1.0, 1.0], [30.0, 30.0])
    with pytest.raises(ModelInputError, match='continue after'):
        dyn.te_rad([1e-4], [0.0], [1.0], [30.0])


# ----------------------------------------------------------------- factory / TeModel

def test_build_te_model_modes() -> None:
    preset = load_preset('wang2020-2kv')
    t = np.arange(2000) / 1e4
    th = OMEGA_IN * t
    om = np.full(t.size, OMEGA_IN)
    load = np.full(t.size, 30.0)
    p = Wang2kvParams.from_preset(preset)
    nl = registry_build(preset, 'nlte')
    assert nl.kinematics.gear_ratio == pytest.approx(79.0)
    assert_allclose(nl.te_rad(t, th, om, load), nlte_rad(th / 79.0, p), atol=1e-15)
    ste = build_te_model(preset, 'ste')
    assert_allclose(ste.te_rad(t, th, om, load), static_te_rad(th / 79.0, 30.0, p), atol=1e-15)
    dte = build_te_model(preset, 'dte')
    a = dte.te_rad(t, th, om, load)
    dte.reset()
    b = dte.te_rad(t, th, om, load)
    assert_allclose(a, b, atol=0.0)
    with pytest.raises(ModelInputError, match="'fem'"):
        build_te_model(preset, 'fem')


def test_params_validation_names_key() -> None:
    bad = [
        ('stage2.r_p_m=-1.0', 'stage2.r_p_m'),
        ('eccentricity.e_p1_m=-1e-5', 'eccentricity.e_p1_m'),
        ('mesh.stiffness_n_m=0.0', 'mesh.stiffness_n_m'),
        ('mesh.stiffness_harmonic_ratio=0.7,0.5', 'mesh.stiffness_harmonic_phase_deg'),
        ('mesh.equivalent_mass_kg=0.0', 'mesh.equivalent_mass_kg'),
        ('stage2.pressure_angle_deg=95.0', 'stage2.pressure_angle_deg'),
        ('kinematics.z_ring=48', 'kinematics.z_ring'),
    ]
    for item, key in bad:
        with pytest.raises(PresetError, match=key.replace('.', r'\.')):
            Wang2kvParams.from_preset(load_preset('wang2020-2kv', [item]))
    with pytest.raises(PresetError, match="'2kv'"):
        Wang2kvParams.from_preset(load_preset('wang2020-2kv', ['kinematics.kind=rv',
                                                               'kinematics.z_ring=51']))


def test_wang2020_dte_far_from_t0_equals_dte_near_t0() -> None:
    """Float64 timestamps jitter far from t = 0; the DTE must not depend on that (the
    integrator used to split such blocks into hundreds of runs)."""
    from sim.wang2020 import build_te_model

    preset = load_preset('wang2020-2kv')
    n, fs = 5000, 10_000.0
    omega = 2 * np.pi * 300 / 60
    k = np.arange(n)
    out = []
    for t0 in (0.0, 1.0e6):
        model = build_te_model(preset, 'dte')
        t = t0 + k / fs
        th = omega * (k / fs)          # the same shaft angles in both runs
        out.append(model.te_rad(t, th, np.full(n, omega), np.full(n, 30.0)))
    np.testing.assert_allclose(out[1], out[0], rtol=0, atol=1e-9)
