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
from sim.wang2020 import Wang2kvParams, nlte_rad, static_te_rad
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
    """Fig. 15's mean for 300 N m after optimisation (-1.59659') lies above the maximum that
    Table 4's row implies (amplitude 2.219', p-p 0.603': max = -2.219 + 0.603 = -1.616'), so
    the two cannot describe one curve. With the k that gives Fig. 5b's means before
    optimisation (0.3 %), Eq. 18 after optimisation stays below Table 4's bound and 0.03' to
    0.33' below Fig. 15's means."""
    assert -2.219 + 0.603 < -1.59659                         # the paper's own inconsistency
    k = params.mesh_stiffness_n_m
    for load, mean in ((30.0, -0.44858), (100.0, -1.0321), (300.0, -2.19511)):     # Fig. 5b
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
