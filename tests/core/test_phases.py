"""Tests of the Wang 2020 Eq. 21 assembly-phase optimisation (rv_te_bench.core.phases).

Expected values come from the paper (Table 4, Section 2.4.2, Fig. 5), from closed forms,
or from an independent evaluation with sim.wang2020 (the physics module), never from the
code under test.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rv_te_bench.core.phases import (
    PHASE_NAMES,
    EccentricGeometry,
    PhaseOptimisation,
    grid_search_phases,
    nlte_from_phases_rad,
    optimise_phases,
    phase_objective_rad,
    static_te_from_phases_rad,
)
from rv_te_bench.errors import CompensationError
from sim import presets
from sim import wang2020 as wang
from sim.units import arcmin_to_rad, deg_to_rad, rad_to_arcmin, rad_to_deg

ALPHA = float(deg_to_rad(35.266))
R_P = 0.06108


@pytest.fixture(scope='module')
def params():
    return wang.Wang2kvParams.from_preset(presets.load_preset('wang2020-2kv'))


@pytest.fixture(scope='module')
def geom(params) -> EccentricGeometry:
    return EccentricGeometry.from_params(params)


@pytest.fixture(scope='module')
def paper_result(params) -> PhaseOptimisation:
    """The full 37^4 grid of Eq. 21 (~2-4 s here), run once for the module."""
    return optimise_phases(params)


#: Bytes of one (phase sets, samples) array per sim.wang2020 call. ~1 MB stays on malloc's
#: heap; the 32-130 MB arrays of 256-500 sets at once are above glibc's largest mmap
#: threshold (32 MiB), so every operation mapped and faulted in a fresh one.
_CHUNK_BYTES = 1 << 20


def _ref_objective(params, phases_rad: np.ndarray, n: int = 2**15) -> np.ndarray:
    """Independent S = max|NLTE| with sim.wang2020.nlte_rad, phase sets (m, 4) (evaluated
    a few sets at a time: each set's row is computed on its own, the chunking changes no
    number)."""
    phi = np.arange(n) * (2 * math.pi / n)
    sets = np.asarray(phases_rad)
    step = max(1, _CHUNK_BYTES // (8 * n))
    return np.concatenate([
        np.abs(wang.nlte_rad(phi, params, phases_rad=tuple(sets[i:i + step, k, None]
                                                           for k in range(4)))).max(-1)
        for i in range(0, len(sets), step)])


# ---------------------------------------------------------------- model vs sim.wang2020


def test_fast_nlte_matches_sim_wang2020(params, geom) -> None:
    """The basis form equals Eqs 1-8 as sim.wang2020 implements them (to 1e-12 rad)."""
    rng = np.random.default_rng(20200221)
    phi = np.linspace(-1.0, 2 * math.pi + 1.0, 4001)
    ph = rng.uniform(-math.pi, math.pi, size=(6, 4))
    ref = wang.nlte_rad(phi, params, phases_rad=tuple(ph[:, k, None] for k in range(4)))
    got = nlte_from_phases_rad(phi, geom, phases_rad=ph)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(nlte_from_phases_rad(phi, geom), wang.nlte_rad(phi, params),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize('load_nm', [0.0, 30.0, 100.0, 300.0])
def test_static_te_matches_sim_wang2020(params, geom, load_nm: float) -> None:
    phi = np.linspace(0, 2 * math.pi, 5001)
    np.testing.assert_allclose(static_te_from_phases_rad(phi, load_nm, geom),
                               wang.static_te_rad(phi, load_nm, params), rtol=0, atol=1e-12)


def test_zero_load_ste_is_nlte(geom) -> None:
    """Eq. 18 with T = 0: |D1 - D2| >= 0 always, so STE = max(D1, D2)/r_p = NLTE."""
    phi = np.linspace(0, 2 * math.pi, 3001)
    np.testing.assert_array_equal(static_te_from_phases_rad(phi, 0.0, geom),
                                  nlte_from_phases_rad(phi, geom))


def test_ideal_reducer_has_zero_nlte() -> None:
    g = EccentricGeometry((0.0,) * 4, (0.3, -1.0, 2.0, 0.5), alpha_rad=ALPHA, r_p_m=R_P)
    phi = np.linspace(0, 2 * math.pi, 1001)
    assert np.all(nlte_from_phases_rad(phi, g) == 0.0)
    assert float(phase_objective_rad(np.zeros(4), g)) == 0.0


@given(ph=st.lists(st.floats(-math.pi, math.pi), min_size=4, max_size=4),
       e=st.lists(st.floats(0.0, 3e-5), min_size=4, max_size=4))
def test_pair_exchange_symmetry(ph: list[float], e: list[float]) -> None:
    """Swapping the two planets and turning e_g, e_ot by pi swaps D1 and D2: S unchanged."""
    g = EccentricGeometry(tuple(e), tuple(ph), alpha_rad=ALPHA, r_p_m=R_P)  # type: ignore[arg-type]
    swapped = EccentricGeometry((e[1], e[0], e[2], e[3]),
                                (ph[1], ph[0], ph[2] + math.pi, ph[3] + math.pi),
                                alpha_rad=ALPHA, r_p_m=R_P)
    phi = np.linspace(0, 2 * math.pi, 2001)
    np.testing.assert_allclose(nlte_from_phases_rad(phi, swapped),
                               nlte_from_phases_rad(phi, g), rtol=0, atol=1e-15)


# ---------------------------------------------------------------- closed-form optimum


def test_output_wheel_only_closed_form() -> None:
    """Only e_ot: NLTE = |e_ot (sin(th + phi - a) - sin(th - a))| / r_p, whose maximum over a
    revolution is e_ot (1 + |sin(th - a)|) / r_p: the best grid phase is the one nearest to
    a (mod pi), 40 deg or -140 deg (both 4.734 deg from a = 35.266 deg on a 20 deg grid)."""
    e_ot = 1e-5
    g = EccentricGeometry((0.0, 0.0, 0.0, e_ot), (0.0,) * 4, alpha_rad=ALPHA, r_p_m=R_P)
    res = optimise_phases(g, step_deg=20.0)
    expected = e_ot * (1 + math.sin(deg_to_rad(40.0) - ALPHA)) / R_P
    assert res.objective_after_rad == pytest.approx(expected, rel=1e-6)
    th_ot = float(rad_to_deg(res.phases_after_rad[3]))
    assert min(abs(th_ot - 40.0), abs(th_ot + 140.0)) < 1e-9
    # before: th_ot = 0 -> e_ot (1 + sin a) / r_p
    assert res.objective_before_rad == pytest.approx(e_ot * (1 + math.sin(ALPHA)) / R_P,
                                                     rel=1e-6)


def test_output_wheel_only_refined_reaches_alpha() -> None:
    """Refinement below the grid step reaches th_ot = a (mod pi) within the final step
    (20 -> 4 -> 0.8 deg)."""
    e_ot = 1e-5
    g = EccentricGeometry((0.0, 0.0, 0.0, e_ot), (0.0,) * 4, alpha_rad=ALPHA, r_p_m=R_P)
    res = optimise_phases(g, step_deg=20.0, refine=True, refine_tol_deg=1.0)
    assert res.refined
    # 1 + |sin(d)| with |d| <= 0.4 deg (half of the final 0.8 deg step)
    assert res.objective_after_rad <= e_ot * (1 + math.sin(deg_to_rad(0.4))) / R_P * (1 + 1e-9)
    assert res.objective_after_rad >= e_ot / R_P * (1 - 1e-9)


def test_grid_search_equals_brute_force(params, geom) -> None:
    """120 deg grid (4^4 = 256 sets): the winner's S equals the brute-force minimum of the
    independent sim.wang2020 evaluation (2^15 samples per revolution; a sampled maximum
    is low by at most L h / 2 = 0.2 % of S here, so rel. 2e-3)."""
    axis = np.deg2rad(np.arange(-180.0, 181.0, 120.0))
    best, s_best, n = grid_search_phases(geom, [axis] * 4)
    assert n == 4**4
    mesh = np.meshgrid(axis, axis, axis, axis, indexing='ij')
    sets = np.stack([m.ravel() for m in mesh], axis=-1)
    ref = _ref_objective(params, sets)
    assert s_best == pytest.approx(ref.min(), rel=2e-3)
    assert float(_ref_objective(params, np.array([best]))[0]) == pytest.approx(ref.min(),
                                                                                rel=2e-3)


@pytest.mark.parametrize('e_um', [
    (10.0, 20.0, 10.0, 10.0),     # Table 2 magnitudes
    (3.0, 4.0, 25.0, 2.0),        # revolution eccentricity dominates
    (25.0, 1.0, 0.0, 18.0),       # no revolution eccentricity: theta_g ties exactly
    (0.0, 0.0, 0.0, 12.0),        # output wheel alone: three phases tie
    (14.0, 14.0, 14.0, 14.0),     # equal magnitudes (label symmetry)
    (7.5, 22.0, 16.0, 0.0),       # no output-wheel eccentricity
])
def test_grid_search_equals_brute_force_on_other_units(params, e_um) -> None:
    """The grid search prunes most combinations by bounds before evaluating them; on
    units unlike the preset (ties, one dominant part) its winner still equals the
    brute-force minimum of the independent sim.wang2020 evaluation over every one of the
    8^4 = 4096 phase sets of a 45 deg grid (2^14 samples per revolution: a sampled
    maximum is low by at most L h / 2, the tolerance)."""
    from dataclasses import replace
    e_m = tuple(x * 1e-6 for x in e_um)
    unit = replace(params, e_p1_m=e_m[0], e_p2_m=e_m[1], e_g_m=e_m[2], e_ot_m=e_m[3])
    g = EccentricGeometry.from_params(unit)
    axis = np.deg2rad(np.arange(-180.0, 180.0, 45.0))
    best, s_best, n = grid_search_phases(g, [axis] * 4)
    assert n == 8**4
    sets = np.stack([m.ravel() for m in np.meshgrid(axis, axis, axis, axis, indexing='ij')],
                    axis=-1)
    n_s = 2**14
    ref = _ref_objective(unit, sets, n=n_s)
    tol = g.lipschitz_m_per_rad * (math.pi / n_s) / g.r_p_m
    assert abs(s_best - ref.min()) <= tol
    assert float(_ref_objective(unit, np.array([best]), n=n_s)[0]) <= ref.min() + tol


# ---------------------------------------------------------------- the paper's numbers


@pytest.mark.slow
def test_paper_optimum_phases(paper_result: PhaseOptimisation) -> None:
    """Section 2.4.2: [theta_p1, theta_p2, theta_g, theta_ot] = [-70, 120, 110, 40] deg."""
    got = np.round(rad_to_deg(np.array(paper_result.phases_after_rad)), 9)
    np.testing.assert_array_equal(got, [-70.0, 120.0, 110.0, 40.0])
    assert paper_result.n_combinations == 37**4


@pytest.mark.slow
def test_paper_optimised_amplitude(paper_result: PhaseOptimisation, params) -> None:
    """Table 4: NLTE amplitude after optimisation 0.604' (+-3 %); before 1.231' (Fig. 5a:
    1.22') within 6 % (the paper's own two values differ by 1 %)."""
    after = float(rad_to_arcmin(paper_result.objective_after_rad))
    assert after == pytest.approx(0.604, rel=0.03)
    assert float(rad_to_arcmin(paper_result.nlte_after.amplitude_rad)) == pytest.approx(
        0.604, rel=0.03)
    assert float(rad_to_arcmin(paper_result.objective_before_rad)) == pytest.approx(
        1.231, rel=0.06)
    # the reported objective is S at the reported phases, independently evaluated
    ref = _ref_objective(params, np.array([paper_result.phases_after_rad]), n=2**17)[0]
    assert paper_result.objective_after_rad == pytest.approx(ref, rel=1e-4)


@pytest.mark.slow
def test_paper_nlte_pp(paper_result: PhaseOptimisation) -> None:
    """Table 4 NLTE peak-to-peak: 2.245' before, 1.072' after; Fig. 5a before: 2.23'.
    Tolerance 10 % (after: +9.8 % here, not a sampling effect: docs/DESIGN_NOTES.md 'Paper vs
    suite')."""
    assert float(rad_to_arcmin(paper_result.nlte_before.pp_rad)) == pytest.approx(2.245,
                                                                                  rel=0.10)
    assert float(rad_to_arcmin(paper_result.nlte_after.pp_rad)) == pytest.approx(1.072,
                                                                                 rel=0.10)
    assert float(rad_to_arcmin(paper_result.nlte_before.mean_rad)) == pytest.approx(-0.15,
                                                                                    abs=0.02)


# Table 4 (arcmin): load -> (pp before, amplitude before, pp after, amplitude after)
TABLE4_STE = {30.0: (2.084, 1.393, 1.074, 0.764), 100.0: (1.707, 1.770, 0.697, 1.141),
              300.0: (1.308, 2.848, 0.603, 2.219)}


@pytest.mark.slow
@pytest.mark.parametrize('load_nm', sorted(TABLE4_STE))
def test_paper_ste_rows(paper_result: PhaseOptimisation, load_nm: float) -> None:
    """Table 4 STE rows: amplitude within 5 %, peak-to-peak within 10 %."""
    row = next(c for c in paper_result.ste if c.load_nm == load_nm)
    pp_b, amp_b, pp_a, amp_a = TABLE4_STE[load_nm]
    assert float(rad_to_arcmin(row.before.amplitude_rad)) == pytest.approx(amp_b, rel=0.05)
    assert float(rad_to_arcmin(row.after.amplitude_rad)) == pytest.approx(amp_a, rel=0.05)
    assert float(rad_to_arcmin(row.before.pp_rad)) == pytest.approx(pp_b, rel=0.10)
    assert float(rad_to_arcmin(row.after.pp_rad)) == pytest.approx(pp_a, rel=0.10)


@pytest.mark.slow
def test_paper_ste_means(paper_result: PhaseOptimisation) -> None:
    """Fig. 5b STE means (before): 100 N m 1.0321' (printed without its minus sign), 300 N m
    -2.19511' within 1 % (k was set from the 30 N m mean, so that one is not tested)."""
    means = {c.load_nm: float(rad_to_arcmin(c.before.mean_rad)) for c in paper_result.ste}
    assert means[100.0] == pytest.approx(-1.0321, rel=0.01)
    assert means[300.0] == pytest.approx(-2.19511, rel=0.01)


@pytest.mark.slow
def test_refinement_improves_and_is_consistent(params) -> None:
    """Refining a 30 deg grid never worsens S, and the reported S is S at the reported
    phases (independent evaluation, 2^17 samples: rel. 1e-4)."""
    plain = optimise_phases(params, step_deg=30.0)
    res = optimise_phases(params, step_deg=30.0, refine=True, refine_tol_deg=2.0)
    assert res.objective_after_rad <= plain.objective_after_rad
    ref = _ref_objective(params, np.array([res.phases_after_rad]), n=2**17)[0]
    assert res.objective_after_rad == pytest.approx(ref, rel=1e-4)
    assert res.n_combinations == 13**4 + 2 * 11**4


# ---------------------------------------------------------------- advice, progress, errors


def test_to_advice_fields(paper_result: PhaseOptimisation) -> None:
    adv = paper_result.to_advice('wang2020-2kv')
    assert adv.method == 'assembly-phases'
    assert adv.te_metric == 'amplitude'
    assert adv.preset == 'wang2020-2kv'
    assert [m.symbol for m in adv.modifications] == list(PHASE_NAMES)
    assert all(m.unit == 'rad' for m in adv.modifications)
    np.testing.assert_allclose([m.recommended_value for m in adv.modifications],
                               deg_to_rad([-70.0, 120.0, 110.0, 40.0]), atol=1e-12)
    np.testing.assert_allclose([m.current_value for m in adv.modifications],
                               deg_to_rad([90.0, 180.0, -135.0, 90.0]), atol=1e-12)
    assert adv.te_after_rad < adv.te_before_rad
    d = adv.to_json_dict()
    assert d['te_after_arcmin'] == pytest.approx(float(rad_to_arcmin(adv.te_after_rad)))


def test_progress_is_monotone_and_complete() -> None:
    g = EccentricGeometry((1e-5, 2e-5, 1e-5, 1e-5), (0.0,) * 4, alpha_rad=ALPHA, r_p_m=R_P)
    seen: list[float] = []
    optimise_phases(g, step_deg=30.0, refine=True, refine_tol_deg=7.0, progress=seen.append)
    assert seen
    assert all(b >= a for a, b in itertools.pairwise(seen))
    assert seen[-1] == 1.0
    assert all(0.0 <= f <= 1.0 for f in seen)


@pytest.mark.parametrize('step', [0.0, -10.0, math.nan, math.inf, 200.0])
def test_bad_step_rejected(step: float) -> None:
    g = EccentricGeometry((1e-5,) * 4, (0.0,) * 4, alpha_rad=ALPHA, r_p_m=R_P)
    with pytest.raises(CompensationError, match='step_deg'):
        optimise_phases(g, step_deg=step)


@pytest.mark.parametrize(('kwargs', 'name'), [
    ({'e_m': (-1e-5, 0.0, 0.0, 0.0)}, 'e_p1'),
    ({'e_m': (0.0, math.nan, 0.0, 0.0)}, 'e_p2'),
    ({'phases_rad': (0.0, 0.0, math.inf, 0.0)}, 'theta_g'),
    ({'r_p_m': 0.0}, 'r_p_m'),
    ({'crank_order': 0.5}, 'crank_order'),
    ({'mesh_stiffness_n_m': -1.0}, 'mesh_stiffness_n_m'),
])
def test_bad_geometry_rejected(kwargs: dict, name: str) -> None:
    base = {'e_m': (1e-5,) * 4, 'phases_rad': (0.0,) * 4, 'alpha_rad': ALPHA, 'r_p_m': R_P}
    with pytest.raises(CompensationError, match=name):
        EccentricGeometry(**{**base, **kwargs})


def test_ste_needs_stiffness() -> None:
    g = EccentricGeometry((1e-5,) * 4, (0.0,) * 4, alpha_rad=ALPHA, r_p_m=R_P)
    with pytest.raises(CompensationError, match='mesh_stiffness'):
        static_te_from_phases_rad(np.zeros(3), 30.0, g)
    assert optimise_phases(g, step_deg=60.0).ste == ()


def test_units_at_edges(paper_result: PhaseOptimisation) -> None:
    d = paper_result.to_json_dict()
    assert d['objective_after_arcmin'] == pytest.approx(
        float(rad_to_arcmin(paper_result.objective_after_rad)))
    assert float(arcmin_to_rad(d['objective_after_arcmin'])) == pytest.approx(
        paper_result.objective_after_rad)
