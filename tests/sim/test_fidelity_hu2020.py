"""Hu 2020 paper vs suite: the rows of docs/DESIGN_NOTES.md "Paper vs suite" (issue #18).

Hu, Li, Zhu, Cui, Appl. Sci. 2020, 10, 481, s.4-5. The elastic TE of the cycloid-pin stage
(the disc turning by delta_max / r_c' under the torque, Eqs 35-37) is checked against Eqs
38-40 evaluated here by hand at the TCA's converged force; before/after predictions of the
initial and the modified prototype against the paper's -41 % (Adams) and -47 % (bench).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.tooth_compensation import compensate_preset
from sim.hu2020 import HuRvParams, build_te_model, elastic_te_rad, tooth_contact_analysis
from sim.presets import load_preset
from sim.units import arcmin_to_rad, rad_to_arcmin


@pytest.fixture(scope='module')
def initial() -> HuRvParams:
    return HuRvParams.from_preset(load_preset('hu2020-rv'))


@pytest.fixture(scope='module')
def modified() -> HuRvParams:
    return HuRvParams.from_preset(load_preset('hu2020-rv-modified'))


def _delta_max_by_hand(p: HuRvParams, f_n: float) -> float:
    """Eqs 38-40 at phi_0 = arccos K1 (written out here)."""
    k = p.a_m * p.z_p / p.r_p_m
    rho = abs(p.r_p_m * (1 + k * k - 2 * k * k) ** 1.5 / (k * (p.z_p + 1) * k - (1 + p.z_p * k * k))
              + p.r_rp_m)
    nu, e, b, r = p.poisson, p.e_pa, p.face_width_m, p.r_rp_m
    c = 4.99e-3 * math.sqrt(4 * (1 - nu * nu) * f_n * rho * r / (e * b * (rho + r)))
    return 2 * f_n * (1 - nu * nu) / (math.pi * e * b) * (2 / 3 + math.log(16 * r * rho / c**2))


def test_elastic_te_is_the_disc_rotation(initial: HuRvParams) -> None:
    """TE_el = -sign(T) delta_max / r_c' at the TCA's converged F_max (0.2 %: table
    interpolation); 0.680' for the initial prototype at the preset's 1094 N m (paper:
    delta_max 0.0116 mm over r_c' = 58.5 mm = 0.682')."""
    tca = tooth_contact_analysis(initial)
    want = _delta_max_by_hand(initial, tca.f_max_n) / (initial.a_m * initial.z_c)
    got = elastic_te_rad(initial, [initial.torque_nm, -initial.torque_nm, 0.0])
    assert -got[0] == pytest.approx(want, rel=2e-3)
    assert got[1] == pytest.approx(-got[0], rel=1e-12)
    assert got[2] == 0.0
    assert rad_to_arcmin(-got[0]) == pytest.approx(0.0116e-3 / 58.5e-3 * 10800 / math.pi,
                                                   rel=0.01)
    # monotone in the load and smaller at lower torque (Hertz: less than linear)
    betas = -elastic_te_rad(initial, np.array([100.0, 300.0, 784.0, 1094.0, 2000.0]))
    assert np.all(np.diff(betas) > 0)


def test_modified_prototype_before_after(initial: HuRvParams, modified: HuRvParams) -> None:
    """`rv-te model hu2020-rv[-modified] --kind elastic` under a load reversing between
    +-1094 N m: TE p-p 2.946' -> 2.647' (-10.2 %); geometric alone (--kind geometric)
    1.611' -> 1.595' (-1.0 %). The paper: -41.35 % (Adams) and -47.22 % (bench). The elastic
    part falls only as delta_max does (0.680' -> 0.536', -21 %; paper 0.0116 -> 0.0088 mm,
    -24 %), so no share of elastic TE in the total can give -41 %: the rest of the paper's
    reduction is not in what its equations give (DESIGN_NOTES)."""
    fin = 2.0 * math.pi * 50.0                               # 3000 rpm input
    t = np.arange(20_000) / 1e3
    th, om = fin * t, np.full(t.size, fin)
    load = 1094.0 * np.sin(2 * math.pi * 0.5 * t)
    pp = {}
    for name in ('hu2020-rv', 'hu2020-rv-modified'):
        for kind in ('geometric', 'elastic'):
            model = build_te_model(load_preset(name), kind)
            pp[name, kind] = float(rad_to_arcmin(np.ptp(model.te_rad(t, th, om, load))))
    assert pp['hu2020-rv', 'elastic'] == pytest.approx(2.946, abs=0.005)
    assert pp['hu2020-rv-modified', 'elastic'] == pytest.approx(2.647, abs=0.005)
    change = pp['hu2020-rv-modified', 'elastic'] / pp['hu2020-rv', 'elastic'] - 1
    assert change == pytest.approx(-0.102, abs=0.003)
    geo = pp['hu2020-rv-modified', 'geometric'] / pp['hu2020-rv', 'geometric'] - 1
    assert geo == pytest.approx(-0.010, abs=0.002)
    b0 = -elastic_te_rad(initial, 1094.0)
    b1 = -elastic_te_rad(modified, 1094.0)
    assert 1 - b1 / b0 == pytest.approx(0.211, abs=0.005)
    assert 1 - b1 / b0 < 0.4135                              # cannot reach the paper's -41 %
    # the elastic part adds 2 beta to the p-p under the reversing load (within 2 %)
    assert (pp['hu2020-rv', 'elastic'] - pp['hu2020-rv', 'geometric']) == pytest.approx(
        2 * rad_to_arcmin(b0), rel=0.02)


def test_compensate_predicts_a_physical_te() -> None:
    """`rv-te compensate hu2020-rv --te-arcmin 1.4559`: the linear model alone predicted 0;
    with the elastic part of the TCA (reversing load of +-1094 N m) 1.292' (-11 %) with Eq. 27
    as written, 1.073' (-26 %) at the Table 6 scale (paper: 0.8538', -41 %, Adams)."""
    te = float(arcmin_to_rad(1.4559))
    preset = load_preset('hu2020-rv')
    for scale, after in (('eq27', 1.292), ('table6', 1.073)):
        adv = compensate_preset(preset, te, scale=scale)
        assert float(rad_to_arcmin(adv.te_after_rad)) == pytest.approx(after, abs=0.002)
        d = adv.details
        assert adv.te_after_rad >= d['elastic_pp_after_rad'] > 0
        assert d['elastic_pp_before_rad'] == pytest.approx(2 * d['elastic_beta_before_rad'])
        assert d['te_after_linear_model_rad'] == 0.0
    half = compensate_preset(preset, te, fraction=0.5)
    d = half.details
    assert half.te_after_rad == pytest.approx(0.5 * d['geometric_part_rad']
                                              + d['elastic_pp_after_rad'], rel=1e-12)


def test_tca_start_and_iterations(initial: HuRvParams, modified: HuRvParams) -> None:
    """Eqs 45-47 at the preset's T = 1094 N m start from F_max_0 = 3552.5 N; the paper's
    Table 4 starts from 2545.1 N (= F_max_1 + 1224.80), which Eqs 45-47 give for T = 784 N m
    (RV-80E rated torque), at which the TCA would converge to 1504 N, not 1910.3 N. The
    iteration converges in 9 steps here (8 from 2545.1 N); the paper needs 22 (its first step
    1320.3 N where Eq. 44 gives 1727.7 N: not reproducible from the printed equations).
    F_max falls 21.9 % from the initial to the modified prototype (paper 24.83 %), pins in mesh
    9 -> 13 (paper 9 -> 17)."""
    tca0, tca1 = tooth_contact_analysis(initial), tooth_contact_analysis(modified)
    assert tca0.history_n[0] == pytest.approx(3552.5, abs=0.5)
    t = 1094.0
    assert abs(2.2 * t / (39 * 0.076) - 0.55 * t / 0.076) / 2 == pytest.approx(3552.5, abs=0.5)
    t_paper = 2 * 2545.1 / (0.55 / 0.076 - 2.2 / (39 * 0.076))
    assert t_paper == pytest.approx(784.0, abs=0.5)
    assert tooth_contact_analysis(initial, t_paper).f_max_n == pytest.approx(1504.4, abs=1.0)
    assert tca0.iterations == 9
    assert tca0.f_max_n == pytest.approx(1910.3, rel=0.002)
    assert 1 - tca1.f_max_n / tca0.f_max_n == pytest.approx(0.219, abs=0.002)
    assert (tca0.pins_in_mesh, tca1.pins_in_mesh) == (9, 13)
