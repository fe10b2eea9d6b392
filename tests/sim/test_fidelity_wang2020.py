"""Wang 2020 paper vs suite: the rows of docs/DESIGN_NOTES.md "Paper vs suite" (issue #18).

Every test states the paper's value and the tolerance; where the suite cannot reach the
paper, the test pins the evidence the note gives (what the suite computes, checked against an
independent computation, and why the paper's number lies outside what the model can give).
Values in arcmin. Paper: G. Wang, L. Su, S. Zou, SV-JME 66 (2020) 2.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim.presets import load_preset
from sim.units import rad_to_arcmin
from sim.wang2020 import Wang2kvDynamics, Wang2kvParams, nlte_rad, static_te_rad
from tests import wang2020_reference as ref

THETA = np.linspace(0.0, 2.0 * math.pi, 158_000, endpoint=False)   # one output revolution


@pytest.fixture(scope='module')
def params() -> Wang2kvParams:
    return Wang2kvParams.from_preset(load_preset('wang2020-2kv'))


def _nlte_arcmin(params: Wang2kvParams, phases_deg: tuple[float, ...]) -> np.ndarray:
    ph = tuple(math.radians(v) for v in phases_deg)
    return rad_to_arcmin(nlte_rad(THETA, params, phases_rad=ph))


# ----------------------------------------------------------------- Table 3 / Fig. 13

# Table 3 lists the phases in the order planet 1, revolution, output wheel, planet 2; here
# (theta_p1, theta_p2, theta_g, theta_ot) as Eq. 21. Group 3's output-wheel phase is missing
# from the paper's text: 130 deg (see test_table3_group3_output_wheel_phase).
TABLE3 = {
    1: ((0.0, -50.0, 130.0, 120.0), (4.49, 2.24, 1.26)),
    2: ((-60.0, 130.0, 100.0, 50.0), (0.79, 0.16, 0.32)),
    3: ((90.0, 90.0, 180.0, 130.0), (1.78, 0.05, 0.88)),
}


@pytest.mark.parametrize('group', [1, 2, 3])
def test_table3_groups(params: Wang2kvParams, group: int) -> None:
    """Section 2.4.1 / Fig. 13: maximum amplitude, mean and standard deviation of the NLTE of
    each Table 3 group over one output revolution. Tolerance: the paper's rounding (two
    decimals, +-0.005') plus 1 % of the value."""
    phases, (amp, mean, std) = TABLE3[group]
    te = _nlte_arcmin(params, phases)
    for got, want in ((np.max(np.abs(te)), amp), (np.mean(te), mean), (np.std(te), std)):
        assert float(got) == pytest.approx(want, abs=0.005 + 0.01 * abs(want))
    # and the suite's curve is the paper's Eqs 1-8, computed independently of sim
    unit = ref.Unit(*ref.TABLE2_E_M, *(math.radians(v) for v in phases))
    assert np.max(np.abs(rad_to_arcmin(ref.nlte_rad(THETA, unit)) - te)) < 1e-3


def test_table3_group3_output_wheel_phase(params: Wang2kvParams) -> None:
    """Group 3's theta_ot is blank in Table 3. On the paper's 10 deg grid only 120 and 130 deg
    reproduce all three of its statistics (amplitude and std within 2 %, mean within 0.01')."""
    fits = []
    for ot in range(-180, 180, 10):
        te = _nlte_arcmin(params, (90.0, 90.0, 180.0, float(ot)))
        got = (np.max(np.abs(te)), np.mean(te), np.std(te))
        if all(abs(g - w) <= 0.005 + 0.01 * abs(w) for g, w in zip(got, TABLE3[3][1],
                                                                  strict=True)):
            fits.append(ot)
    assert fits == [120, 130]


# ----------------------------------------------------------------- Fig. 15 vs Table 4

OPT_DEG = (-70.0, 120.0, 110.0, 40.0)                   # Eq. 21 optimum (theta_p1, p2, g, ot)


def _with_phases(params: Wang2kvParams, phases_deg: tuple[float, ...]) -> Wang2kvParams:
    ph = [math.radians(v) for v in phases_deg]
    return dataclasses.replace(params, theta_p1_0_rad=ph[0], theta_p2_0_rad=ph[1],
                               theta_g_0_rad=ph[2], theta_ot_0_rad=ph[3])


def _ste_reference_arcmin(phases_deg: tuple[float, ...], load_nm: float,
                          k_n_m: float) -> np.ndarray:
    """Eq. 18 written out from the paper on the independent Eqs 1-2 of tests/wang2020_reference."""
    unit = ref.Unit(*ref.TABLE2_E_M, *(math.radians(v) for v in phases_deg))
    d1, d2 = ref.mesh_line_increments_m(THETA, unit)
    d = load_nm / (ref.R_P_M * k_n_m)
    x = np.where(np.abs(d1 - d2) >= d, np.maximum(d1, d2) - d, 0.5 * (d1 + d2) - 0.5 * d)
    return rad_to_arcmin(x / ref.R_P_M)


def test_fig15_means_after_optimisation(params: Wang2kvParams) -> None:
    """Fig. 15's mean for 300 N m after optimisation (-1.59659'), read as the STE panel's,
    lies above the maximum that Table 4's STE row implies (amplitude 2.219', p-p 0.603':
    max = -2.219 + 0.603 = -1.616'), so the two cannot describe one curve. With the k that
    gives Fig. 5b's means before optimisation (0.3 %), Eq. 18 after optimisation stays below
    Table 4's bound and 0.03' to 0.33' below Fig. 15's means; 1.25 k fits 300 N m but not
    100 and 30 N m."""
    assert -2.219 + 0.603 < -1.59659                         # the paper's own inconsistency
    k = params.mesh_stiffness_n_m
    # Fig. 5b (the 100 N m mean is printed without its minus sign)
    for load, mean in ((30.0, -0.44858), (100.0, -1.0321), (300.0, -2.19511)):
        got = float(np.mean(_ste_reference_arcmin(ref.TABLE2_PHASES_DEG, load, k)))
        assert got == pytest.approx(mean, rel=0.003)
    p = _with_phases(params, OPT_DEG)
    fig15 = {0.0: 0.15845, 30.0: -0.03031, 100.0: -0.55823, 300.0: -1.59659}
    gaps = []
    for load, mu in fig15.items():
        want = _ste_reference_arcmin(OPT_DEG, load, k)
        got = rad_to_arcmin(static_te_rad(THETA, load, p))
        assert np.max(np.abs(got - want)) < 1e-5        # the suite is Eq. 18 (r_p rounded)
        gaps.append(mu - float(np.mean(got)))
    assert np.max(rad_to_arcmin(static_te_rad(THETA, 300.0, p))) < -1.616
    # the gap grows with the load: 0.027', 0.146', 0.207', 0.332' (0.005')
    assert gaps == pytest.approx([0.027, 0.146, 0.207, 0.332], abs=0.005)
    # and no single k closes it: 1.25 k fits 300 N m, not 100 and 30 N m
    means = [float(np.mean(_ste_reference_arcmin(OPT_DEG, t, 1.25 * k))) for t in (300, 100, 30)]
    assert means == pytest.approx([-1.601, -0.614, -0.118], abs=0.002)
    assert abs(means[0] / -1.59659 - 1) < 0.01
    assert abs(means[1] / -0.55823 - 1) > 0.05 and abs(means[2] / -0.03031 - 1) > 0.05


# ----------------------------------------------------------------- Table 4: DTE rows

TABLE2_DEG = (90.0, 180.0, -135.0, 90.0)
#: Table 4 (arcmin): (phases, load) -> (p-p, amplitude, std) of the STE and the DTE rows
TABLE4_STE = {
    ('before', 30.0): (2.084, 1.393, 0.627), ('before', 100.0): (1.707, 1.770, 0.536),
    ('before', 300.0): (1.308, 2.848, 0.462), ('after', 30.0): (1.074, 0.764, 0.294),
    ('after', 100.0): (0.697, 1.141, 0.195), ('after', 300.0): (0.603, 2.219, 0.213),
}
TABLE4_DTE = {
    ('before', 30.0): (2.088, 1.338, 0.595), ('before', 100.0): (1.899, 1.670, 0.530),
    ('before', 300.0): (2.580, 2.731, 0.468), ('after', 30.0): (1.045, 0.653, 0.262),
    ('after', 100.0): (1.056, 1.086, 0.203), ('after', 300.0): (1.968, 2.126, 0.255),
}
PHASES = {'before': TABLE2_DEG, 'after': OPT_DEG}
FS_HZ, OMEGA_IN = 10_000.0, 2.0 * math.pi * 5.0          # 300 rpm, as `rv-te model`


TABLE4_START = {'equivalent_mass_kg': 5.0, 'mesh_damping_n_s_m': 12318.3,
                'dte_start': 'unloaded-step'}           # sim.wang2020.TABLE4_DTE_START


def _dte_arcmin(params: Wang2kvParams, load_nm: float) -> np.ndarray:
    """DTE over one output revolution at 10 kHz from the first sample (t0) on."""
    n = THETA.size
    t = np.arange(n) / FS_HZ
    dyn = Wang2kvDynamics(params)
    return rad_to_arcmin(dyn.te_rad(t, OMEGA_IN * t, np.full(n, OMEGA_IN), np.full(n, load_nm)))


def _stats(te: np.ndarray) -> tuple[float, float, float]:
    return float(np.ptp(te)), float(np.max(np.abs(te))), float(np.std(te))


@pytest.fixture(scope='module')
def table4_runs(params: Wang2kvParams) -> dict[tuple[str, str, float], np.ndarray]:
    """The six Table 4 DTE rows with the start options 'loaded', 'unloaded' and 'table4'
    (the 'unloaded-step' start with m_e 5 kg, damping ratio 0.3)."""
    out = {}
    for start in ('loaded', 'unloaded', 'table4'):
        for (when, load) in TABLE4_DTE:
            p = _with_phases(params, PHASES[when])
            p = dataclasses.replace(p, **(TABLE4_START if start == 'table4'
                                          else {'dte_start': start}))
            out[start, when, load] = _dte_arcmin(p, load)
    return out


#: The 9 Table 4 DTE cells (of 18) the suite reproduces within 5 % with the loaded start
#: (the preset's): (phases, load, quantity 0 p-p / 1 amp / 2 std).
DTE_REPRODUCED = [('before', 30.0, 0), ('before', 30.0, 1), ('before', 100.0, 1),
                  ('before', 100.0, 2), ('before', 300.0, 1), ('before', 300.0, 2),
                  ('after', 30.0, 0), ('after', 100.0, 1), ('after', 300.0, 1)]
#: The other 9: 'evidence only: not reproduced' in docs/DESIGN_NOTES.md. The suite's value
#: with the loaded start (the table's 'suite, loaded start' column, arcmin).
DTE_NOT_REPRODUCED = {('before', 30.0, 2): 0.557, ('before', 100.0, 0): 1.744,
                      ('before', 300.0, 0): 1.259, ('after', 30.0, 1): 0.743,
                      ('after', 30.0, 2): 0.290, ('after', 100.0, 0): 0.640,
                      ('after', 100.0, 2): 0.190, ('after', 300.0, 0): 0.580,
                      ('after', 300.0, 2): 0.205}


def test_table4_dte_where_the_suite_matches(table4_runs: dict) -> None:
    """The Table 4 DTE cells the suite reproduces: the paper's value within 5 % (loaded
    start). The 18 cells are these 9 and the 9 of the next test."""
    assert len(set(DTE_REPRODUCED) | set(DTE_NOT_REPRODUCED)) == 18
    for when, load, q in DTE_REPRODUCED:
        got = _stats(table4_runs['loaded', when, load])[q]
        assert got == pytest.approx(TABLE4_DTE[when, load][q], rel=0.05), (when, load, q)


def test_table4_dte_cells_not_reproduced_pin_the_suite(table4_runs: dict,
                                                       params: Wang2kvParams) -> None:
    """The 9 cells the loaded start does not reproduce: the suite's value is pinned against
    an independent computation, the quasi-static Eq. 18 written out in this file (the mesh
    mode at ~2 kHz is far above the excitation), within 0.5 %, and against the number
    within 0.002'; and each is more than 5 % from the paper with the 'loaded' and 'unloaded'
    starts (the 'table4' start reproduces three of them: test_table4_dte_start_reading).
    The unloaded start's p-p
    of the rows where it differs is the independent STE amplitude (the record holds TE = 0
    and the STE minimum: 2.824', 1.125'), or above it by the load step's overshoot at 300 N m
    after optimisation (2.751' >= 2.218'; the overshoot is the suite's own value)."""
    k = params.mesh_stiffness_n_m
    for (when, load, q), noted in DTE_NOT_REPRODUCED.items():
        independent = _stats(_ste_reference_arcmin(PHASES[when], load, k))[q]
        got = _stats(table4_runs['loaded', when, load])[q]
        assert got == pytest.approx(independent, rel=0.005), (when, load, q)
        assert got == pytest.approx(noted, abs=0.002), (when, load, q)
        paper = TABLE4_DTE[when, load][q]
        for start in ('loaded', 'unloaded'):
            assert abs(_stats(table4_runs[start, when, load])[q] / paper - 1) > 0.05, \
                (start, when, load, q)
    for when, load, noted in (('before', 300.0, 2.824), ('after', 100.0, 1.125)):
        amp = _stats(_ste_reference_arcmin(PHASES[when], load, k))[1]
        got = _stats(table4_runs['unloaded', when, load])[0]
        assert got == pytest.approx(amp, rel=0.005)
        assert got == pytest.approx(noted, abs=0.002)
    amp = _stats(_ste_reference_arcmin(OPT_DEG, 300.0, k))[1]
    got = _stats(table4_runs['unloaded', 'after', 300.0])[0]
    assert amp == pytest.approx(2.218, abs=0.002)
    assert got > amp
    assert got == pytest.approx(2.751, abs=0.002)


def test_table4_dte_follows_eq18(table4_runs: dict, params: Wang2kvParams) -> None:
    """The suite's DTE rows are the quasi-static Eq. 18 (written out independently here) once
    the start is over: p-p, amplitude and std of the loaded start within 0.5 % of it (the
    mesh mode is at 2.07 kHz, the excitation at the crank harmonics); the unloaded start adds
    its first sample, TE = 0 (Eqs 1-4: Delta_i(t0) = 0), and its transient."""
    k = params.mesh_stiffness_n_m
    for (when, load) in TABLE4_DTE:
        ste = _ste_reference_arcmin(PHASES[when], load, k)
        loaded = table4_runs['loaded', when, load]
        for got, want in zip(_stats(loaded), _stats(ste), strict=True):
            assert got == pytest.approx(want, rel=0.005), (when, load)
        unloaded = table4_runs['unloaded', when, load]
        assert abs(unloaded[0]) < 1e-12
        assert np.min(unloaded) <= np.min(ste) + 1e-3       # a transient can only add


def test_table4_dte_amplitudes_cannot_reach_the_paper(table4_runs: dict,
                                                      params: Wang2kvParams) -> None:
    """Why no start option closes the amplitude rows: Table 4 puts every DTE amplitude 4-15 %
    below the STE amplitude of the same row, while Eq. 19 with any start, damping or
    stiffness ripple gives a DTE that reaches the STE minimum later in the revolution (a
    ripple only deepens it). The suite's STE amplitudes are within 5 % of Table 4's, so the
    DTE amplitude stays at or above them: after optimisation at 30 N m 0.743' against the
    paper's 0.653' (+13.7 %) whatever the start."""
    for row, (_, amp_dte, _) in TABLE4_DTE.items():
        assert amp_dte < TABLE4_STE[row][1]                      # the paper's own rows
    for (start, when, load), te in table4_runs.items():
        ste = _ste_reference_arcmin(PHASES[when], load, params.mesh_stiffness_n_m)
        assert np.max(np.abs(te)) >= np.max(np.abs(ste)) - 1e-3, (start, when, load)
    amp = _stats(table4_runs['unloaded', 'after', 30.0])[1]
    assert amp / 0.653 - 1 == pytest.approx(0.137, abs=0.005)
    # other damping (zeta 0.02 .. 1) and a 10 % ripple: never below the STE amplitude
    c1 = 2.0 * math.sqrt(params.mesh_stiffness_n_m * params.equivalent_mass_kg)
    p = _with_phases(params, OPT_DEG)
    floor = np.max(np.abs(_ste_reference_arcmin(OPT_DEG, 30.0, params.mesh_stiffness_n_m)))
    for zeta, ripple, start in ((0.02, 0.0, 'unloaded'), (1.0, 0.0, 'unloaded'),
                                (0.05, 0.1, 'loaded')):
        q = dataclasses.replace(p, mesh_damping_n_s_m=zeta * c1, dte_start=start,
                                stiffness_harmonic_ratio=(ripple,))
        assert np.max(np.abs(_dte_arcmin(q, 30.0))) >= floor - 1e-3


def test_table4_dte_start_reading(table4_runs: dict, params: Wang2kvParams) -> None:
    """Table 4's 300 N m DTE rows have p-p below the amplitude (2.580' < 2.731',
    1.968' < 2.126'): the record's maximum is -0.151' / -0.158', no sample of the unloaded
    state (TE = 0 at t0) but one shortly after it. The 'unloaded' start (TE = 0 in the record)
    gives p-p >= amplitude (2.824', +9.4 %), the 'loaded' start the STE's p-p (1.259', -51 %).
    The 'table4' start (unloaded one 100 us step before the first sample, m_e 5 kg, damping
    ratio 0.3) puts the first sample at -0.23' and reproduces the 300 N m p-p before (+0.5 %,
    the cell m_e is fitted on) and after (+0.9 %) and the 100 N m p-p after (-0.8 %); every
    other cell equals the loaded start's within 0.002'. Cells within 5 %: loaded 9, unloaded
    8 (its overshoot costs the 300 N m amplitude after optimisation), table4 12 of 18."""
    for when, (pp, amp, _) in (('before', TABLE4_DTE['before', 300.0]),
                               ('after', TABLE4_DTE['after', 300.0])):
        assert pp < amp and -amp + pp < -0.15                 # max of the paper's record
        got_pp, got_amp, _ = _stats(table4_runs['unloaded', when, 300.0])
        assert got_pp >= got_amp                              # the record holds TE = 0
        assert got_pp / pp - 1 > 0.09
        assert _stats(table4_runs['loaded', when, 300.0])[0] / pp - 1 < -0.5
    assert _stats(table4_runs['unloaded', 'before', 300.0])[0] == pytest.approx(2.824, abs=0.005)
    moved = {('before', 300.0): 2.594, ('after', 300.0): 1.986, ('after', 100.0): 1.048}
    for (when, load), want in moved.items():
        te = table4_runs['table4', when, load]
        assert _stats(te)[0] == pytest.approx(want, abs=0.002)
        assert _stats(te)[0] == pytest.approx(TABLE4_DTE[when, load][0], rel=0.01)
        assert te[0] == pytest.approx(-0.23 if load == 300.0 else -0.078, abs=0.005)
        # p-p = first sample - STE minimum (independent Eq. 18): the start adds that sample
        ste = _ste_reference_arcmin(PHASES[when], load, params.mesh_stiffness_n_m)
        assert _stats(te)[0] == pytest.approx(te[0] - np.min(ste), abs=0.002)
    for (when, load) in TABLE4_DTE:
        for q in range(3):
            if q == 0 and (when, load) in moved:
                continue
            assert _stats(table4_runs['table4', when, load])[q] == pytest.approx(
                _stats(table4_runs['loaded', when, load])[q], abs=0.002), (when, load, q)
    within = {start: sum(abs(_stats(table4_runs[start, w, t])[q] / TABLE4_DTE[w, t][q] - 1)
                         <= 0.05 for (w, t) in TABLE4_DTE for q in range(3))
              for start in ('loaded', 'unloaded', 'table4')}
    assert within == {'loaded': 9, 'unloaded': 8, 'table4': 12}


def test_table4_dte_start_family(params: Wang2kvParams) -> None:
    """The start reading is not tied to m_e 5 kg, damping ratio 0.3: at m_e 4 and 5 kg with
    damping ratios 0.3 to 1 the three p-p cells stay within 4 % of Table 4."""
    cells = {('before', 300.0): 2.580, ('after', 300.0): 1.968, ('after', 100.0): 1.056}
    for m_e in (4.0, 5.0):
        for zeta in (0.3, 0.5, 0.7, 1.0):
            c_g = 2.0 * zeta * math.sqrt(params.mesh_stiffness_n_m * m_e)
            for (when, load), paper in cells.items():
                p = dataclasses.replace(_with_phases(params, PHASES[when]), equivalent_mass_kg=m_e,
                                        mesh_damping_n_s_m=c_g, dte_start='unloaded-step')
                pp = _stats(_dte_arcmin(p, load))[0]
                assert abs(pp / paper - 1) < 0.04, (m_e, zeta, when, load, pp)


def test_ripple_hurts_the_amplitude(params: Wang2kvParams) -> None:
    """Issue #18: the 10 % mesh-stiffness ripple the preset assumed before raised the 300 N m
    DTE amplitude from 2.824' to 3.005' (paper 2.731', below its STE 2.848') and added a
    mesh-frequency oscillation; the preset now has none (mesh.stiffness_harmonic_ratio = 0)."""
    assert params.stiffness_harmonic_ratio == (0.0,)
    ripple = dataclasses.replace(params, stiffness_harmonic_ratio=(0.1,))
    te0, te1 = _dte_arcmin(params, 300.0), _dte_arcmin(ripple, 300.0)
    amp0, amp1 = _stats(te0)[1], _stats(te1)[1]
    assert amp0 == pytest.approx(2.824, abs=0.005)
    assert amp1 == pytest.approx(3.005, abs=0.005)
    assert abs(amp1 / 2.731 - 1) > abs(amp0 / 2.731 - 1)

    def mesh_line(te: np.ndarray) -> float:      # 52 f_w = order 52 x 25 of the output
        return float(np.abs(np.fft.rfft(te - te.mean()))[52 * 25] * 2.0 / te.size)

    assert mesh_line(te0) < 0.001 < 0.1 < mesh_line(te1)


# ----------------------------------------------------------------- NLTE rows, Fig. 14

def _nlte_rates_arcmin(phi: np.ndarray, phases_deg: tuple[float, ...],
                       rates: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Eqs 1-2 and 5 with the planet phases turning at rates[0], the revolution phase at
    rates[1] and the output-wheel phase at rates[2] x the output angle (the suite's reading:
    -25, -25, 1), written out here for the comparison of readings."""
    a = ref.ALPHA_RAD
    p1, p2, g, ot = (math.radians(v) for v in phases_deg)
    e_p1, e_p2, e_g, e_ot = ref.TABLE2_E_M

    def term(e: float, th0: float, rate: float, off: float) -> np.ndarray:
        return e * (np.sin(th0 + rate * phi + off) - np.sin(th0 + off))

    rp, rg, ro = rates
    d1 = term(e_p1, p1, rp, -a) + term(e_g, g, rg, -a) + term(e_ot, ot, ro, -a)
    d2 = (term(e_p2, p2, rp, -a) + term(e_g, g, rg, -a + math.pi)
          + term(e_ot, ot, ro, -a + math.pi))
    return rad_to_arcmin(d1 / ref.R_P_M), rad_to_arcmin(d2 / ref.R_P_M)


def test_table4_nlte_rows(params: Wang2kvParams) -> None:
    """Table 4 NLTE rows. Before optimisation p-p 2.245' (suite 2.274', +1.3 %), amplitude
    1.231' (1.168', -5.1 %), std 0.637' (0.565', -11 %); after: 1.072' (1.177', +9.8 %),
    0.604' (0.608', +0.7 %), 0.263' (0.316', +20 %). Reproduced within 5 %: the p-p before
    and the amplitude after; the other four are not (unexplained in docs/DESIGN_NOTES.md;
    the amplitude before is 4.3 % from Fig. 5a's 1.22' but 5.1 % from Table 4's 1.231').
    Not a sampling effect: sampled at 10 Hz the p-p after optimisation is still 1.149' and
    the std 0.319'. The std convention is the paper's own: Table 3's stds are reproduced to
    2 % (test_table3_groups)."""
    paper = {'before': (2.245, 1.231, 0.637), 'after': (1.072, 0.604, 0.263)}
    suite = {'before': (2.274, 1.168, 0.565), 'after': (1.177, 0.608, 0.316)}
    reproduced = {('before', 0), ('after', 1)}
    for when in ('before', 'after'):
        te = _nlte_arcmin(params, PHASES[when])
        got = _stats(te)
        assert got == pytest.approx(suite[when], abs=0.002)
        unit = ref.Unit(*ref.TABLE2_E_M, *(math.radians(v) for v in PHASES[when]))
        assert _stats(rad_to_arcmin(ref.nlte_rad(THETA, unit))) == pytest.approx(got, abs=1e-3)
        for q in range(3):
            assert (abs(got[q] / paper[when][q] - 1) <= 0.05) == ((when, q) in reproduced)
    coarse = _stats(_nlte_arcmin(params, PHASES['after'])[::1000])       # 10 Hz
    assert coarse[0] == pytest.approx(1.149, abs=0.001)
    assert coarse[2] == pytest.approx(0.319, abs=0.001)


READINGS = {'suite (-25, -25, 1)': (-25.0, -25.0, 1.0), 'planet -26': (-26.0, -25.0, 1.0),
            'revolution -26': (-25.0, -26.0, 1.0), 'planet spin +1': (1.0, -25.0, 1.0)}


def test_fig14_wave_peaks_and_angle_readings() -> None:
    """Fig. 14 shows ~10 NLTE peaks in the first 3 s after optimisation (2 per crank turn:
    the pairs alternate), the suite none. At the Eq. 21 optimum [-70, 120, 110, 40] deg the
    crank-rate terms of pair 1 cancel exactly (e_p1 = e_g, theta_p1 - theta_g = -180 deg), so
    pair 1 carries only the slow output-wheel term and stays in contact through 0-3 s. That
    holds whenever planet and revolution phases turn at one rate. Readings where they turn
    at different rates give peaks but lose the paper's other results: Fig. 5a's p-p
    (2.23'), Table 3 group 1's amplitude (4.49') and the optimum itself."""
    from scipy.signal import find_peaks

    phi = np.linspace(0.0, 2.0 * math.pi, 15_800, endpoint=False)   # 1 kHz over 15.8 s
    first3s = phi < 2.0 * math.pi * 3.0 / 15.8
    e_p1, _, e_g, _ = ref.TABLE2_E_M
    q1 = e_p1 * np.exp(1j * math.radians(-70.0)) + e_g * np.exp(1j * math.radians(110.0))
    assert abs(q1) < 1e-20
    results = {}
    for name, rates in READINGS.items():
        n1, n2 = _nlte_rates_arcmin(phi, OPT_DEG, rates)
        nlte = np.maximum(n1, n2)
        peaks = len(find_peaks(nlte[first3s])[0])
        before = np.maximum(*_nlte_rates_arcmin(phi, TABLE2_DEG, rates))
        group1 = np.maximum(*_nlte_rates_arcmin(phi, TABLE3[1][0], rates))
        results[name] = (peaks, float(np.ptp(before)), float(np.max(np.abs(group1))),
                         float(np.max(np.abs(nlte))))
    peaks, pp5a, amp_g1, _ = results['suite (-25, -25, 1)']
    assert peaks == 0
    assert pp5a == pytest.approx(2.23, rel=0.05) and amp_g1 == pytest.approx(4.49, rel=0.01)
    for name in ('planet -26', 'revolution -26', 'planet spin +1'):
        peaks, pp5a, amp_g1, _ = results[name]
        assert peaks >= 5, name                                    # peaks appear ...
        assert abs(pp5a / 2.23 - 1) > 0.2 or abs(amp_g1 / 4.49 - 1) > 0.2, name   # ... but
    # under 'planet -26' the paper's phases are far from optimal: S = 1.53' there against
    # 0.985' at [80, -170, 140, -100] deg, the optimum of the 10 deg grid with that reading
    # (scripts/wang2020_readings.py --grid; tests/sim/test_wang2020_readings.py)
    s_paper = results['planet -26'][3]
    other = np.max(np.abs(np.maximum(*_nlte_rates_arcmin(phi, (80.0, -170.0, 140.0, -100.0),
                                                         READINGS['planet -26']))))
    assert s_paper == pytest.approx(1.53, abs=0.01)
    assert other == pytest.approx(0.985, abs=0.002)
