"""Li 2023 paper vs suite: the rows of docs/DESIGN_NOTES.md "Paper vs suite" (issue #18).

Li, Huang, Ding, Guo, Niu, Machines 2023, 11, 626, s.4. The paper leaves the damping and the
composite cycloid-pin error E_cr open; the preset calibrates them to the paper's two DTE
results (0.78" without errors, 17.25" with errors, peak-to-peak per output revolution) and
takes the paper's mean equivalent pressure angle (31.9 deg) for the dynamic model.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.li2023 import build_te_model, ltca, params_from_preset
from sim.presets import load_preset
from sim.units import rad_to_arcsec, rpm_to_rad_s

PAPER_PP_NO_ERR_ARCSEC = 0.78
PAPER_PP_ERR_ARCSEC = 17.25
PAPER_BETA_DEG = 31.9


def _pp_arcsec(overrides: dict[str, str], fs_hz: float) -> float:
    """DTE p-p over one output revolution (4.84 s at 1500 rpm) after 0.5 s, 450 N m."""
    model = build_te_model(load_preset('li2023-rv', overrides), 'dte')
    warm, nrev = round(0.5 * fs_hz), round(fs_hz * 121 / 25.0)
    n = warm + nrev
    t = np.arange(n) / fs_hz
    w = float(rpm_to_rad_s(1500.0))
    te = model.te_rad(t, w * t, np.full(n, w), np.full(n, 450.0))
    return float(np.ptp(rad_to_arcsec(te[warm:])))


def test_preset_calibration_values() -> None:
    preset = load_preset('li2023-rv')
    assert preset['damping.zeta'] == 0.09
    assert preset['errors.pin_composite_m'] == 1.78e-6
    assert preset['tca.pressure_angle_deg'] == PAPER_BETA_DEG


def test_dte_without_errors_calibrated_damping() -> None:
    """Paper 0.78" (Fig. 11a). Damping is not given; stiffness-proportional (Rayleigh) zeta
    0.09 at f_ref = 1 kHz, beta 31.9 deg, gives 0.774" at 1 kHz samples (-0.8 %) and 0.786" at
    10 kHz (+0.8 %); tolerance 2 %. The earlier assumption zeta 0.05 (same f_ref) gives
    0.823" at 1 kHz / 0.870" at 10 kHz with beta 31.9 deg, and 0.851" / 0.895" with the
    LTCA's beta 32.9 deg (DESIGN_NOTES; the 1 kHz values are pinned here, +-0.005", as the
    suite's own: the p-p depends on the damping and beta, both outside the paper's 2 %)."""
    assert _pp_arcsec({'errors.enabled': 'false'}, 1000.0) == pytest.approx(
        PAPER_PP_NO_ERR_ARCSEC, rel=0.02)
    z05 = {'errors.enabled': 'false', 'damping.zeta': '0.05'}
    pp_paper_beta = _pp_arcsec(z05, 1000.0)
    pp_ltca_beta = _pp_arcsec({**z05, 'tca.pressure_angle_deg': '0'}, 1000.0)
    assert pp_paper_beta == pytest.approx(0.823, abs=0.005)
    assert pp_ltca_beta == pytest.approx(0.851, abs=0.005)
    assert pp_paper_beta > 1.05 * PAPER_PP_NO_ERR_ARCSEC


@pytest.mark.slow
def test_dte_without_errors_calibrated_damping_10khz() -> None:
    assert _pp_arcsec({'errors.enabled': 'false'}, 10_000.0) == pytest.approx(
        PAPER_PP_NO_ERR_ARCSEC, rel=0.02)


def test_dte_with_errors_calibrated_composite_error() -> None:
    """Paper 17.25" (Fig. 11b). E_cr is not given; 1.78 um gives 17.26" (tolerance 2 %), the
    2 um assumed before 19.30". The p-p is linear in E_cr (9.25"/um), and the Table 3 errors
    alone add nothing to the p-p:
    with E_cr = 0 it is the error-free value (three in-phase cranks, opposed discs)."""
    with_err = _pp_arcsec({}, 1000.0)
    assert with_err == pytest.approx(PAPER_PP_ERR_ARCSEC, rel=0.02)
    no_ecr = _pp_arcsec({'errors.pin_composite_m': '0.0'}, 1000.0)
    ideal = _pp_arcsec({'errors.enabled': 'false'}, 1000.0)
    assert no_ecr == pytest.approx(ideal, rel=0.01)
    half = _pp_arcsec({'errors.pin_composite_m': '0.89e-6'}, 1000.0)
    assert (with_err - half) / 0.89 == pytest.approx(9.25, rel=0.03)
    # the 2 um the preset assumed before the calibration: 19.30" (+12 %)
    assert _pp_arcsec({'errors.pin_composite_m': '2e-6'}, 1000.0) == pytest.approx(19.30,
                                                                                  abs=0.01)


def test_equivalent_pressure_angle() -> None:
    """Paper: 31.5..32.1 deg, mean 31.9 deg (s.4.1). The suite's LTCA (Eqs 2-7, Hertz stiffness
    per pin from the tooth curvature) gives a mean of 32.9 deg (+1.0 deg); the rigid limit
    with equal linear pin springs (F ~ l) gives 32.3..32.6 deg, computed here independently.
    The dynamic model uses the paper's 31.9 deg (tca.pressure_angle_deg), as it uses the
    paper's mean stiffness."""
    params = params_from_preset(load_preset('li2023-rv'))
    beta = np.degrees(ltca(params).pressure_angle_rad)
    assert beta.mean() == pytest.approx(32.88, abs=0.02)
    k1 = params.eccentricity_m * params.z_pin / params.pin_circle_radius_m
    rigid = []
    for phi0 in (1e-3, math.pi / params.z_pin):
        th = 2 * np.pi * np.arange(params.z_pin) / params.z_pin - phi0
        lever = -np.sin(th) / np.sqrt(1 + k1**2 - 2 * k1 * np.cos(th))
        lever = lever[lever > 0]
        rigid.append(math.degrees(math.atan(np.sum(lever * np.sqrt(1 - lever**2))
                                            / np.sum(lever**2))))
    assert 32.2 < min(rigid) < max(rigid) < 32.7
    model = build_te_model(load_preset('li2023-rv'), 'dte')
    assert math.degrees(model.beta_rad) == pytest.approx(PAPER_BETA_DEG, abs=1e-12)
    ltca_model = build_te_model(load_preset('li2023-rv', ['tca.pressure_angle_deg=0']), 'dte')
    assert math.degrees(ltca_model.beta_rad) == pytest.approx(beta.mean(), abs=1e-9)
