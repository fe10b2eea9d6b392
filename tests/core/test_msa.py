"""MSA: gauge R&R by ANOVA equal to the AIAG MSA manual's worked example, type 1 study by
hand (issue 35).

Reference: AIAG, *Measurement Systems Analysis Reference Manual*, 4th ed. (2010), chapter
III section B, the variable gauge study example (10 parts, appraisers A, B, C, 3 trials;
the same data as its Average and Range example) and its ANOVA tables (Table III-B 6:
"ANOVA Table"; Table III-B 6a: "ANOVA Analysis % Variation & Contribution"). The data
below are typed in from the manual; the expected values are the printed ones (to the
digits printed), not this module's output.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.msa import gauge_rr_anova, type1_study
from rv_te_bench.errors import MsaError

# appraiser -> trials 1..3, each parts 1..10 (AIAG MSA 4th ed., ch. III-B data sheet)
AIAG = {
    'A': [[0.29, -0.56, 1.34, 0.47, -0.80, 0.02, 0.59, -0.31, 2.26, -1.36],
          [0.41, -0.68, 1.17, 0.50, -0.92, -0.11, 0.75, -0.20, 1.99, -1.25],
          [0.64, -0.58, 1.27, 0.64, -0.84, -0.21, 0.66, -0.17, 2.01, -1.31]],
    'B': [[0.08, -0.47, 1.19, 0.01, -0.56, -0.20, 0.47, -0.63, 1.80, -1.68],
          [0.25, -1.22, 0.94, 1.03, -1.20, 0.22, 0.55, 0.08, 2.12, -1.62],
          [0.07, -0.68, 1.34, 0.20, -1.28, 0.06, 0.83, -0.34, 2.19, -1.50]],
    'C': [[0.04, -1.38, 0.88, 0.14, -1.46, -0.29, 0.02, -0.46, 1.77, -1.49],
          [-0.11, -1.13, 1.09, 0.20, -1.07, -0.67, 0.01, -0.56, 1.45, -1.77],
          [-0.15, -0.96, 0.67, 0.11, -1.45, -0.49, 0.21, -0.49, 1.87, -2.16]],
}


def _aiag() -> np.ndarray:
    """(parts, appraisers, trials)."""
    return np.transpose(np.array([AIAG[a] for a in 'ABC']), (2, 0, 1))


def test_anova_table_is_aiag_table_iii_b6() -> None:
    g = gauge_rr_anova(_aiag())
    rows = {r.source: r for r in g.anova}
    # Table III-B 6: source, DF, SS, MS (printed to 4-5 digits)
    ref = {'operators': (2, 3.1673, 1.58363), 'parts': (9, 88.3619, 9.81799),
           'parts x operators': (18, 0.3590, 0.01994),
           'repeatability (equipment)': (60, 2.7589, 0.04598)}
    for src, (dof, ss, ms) in ref.items():
        assert rows[src].dof == dof
        assert rows[src].ss == pytest.approx(ss, abs=5e-5)
        assert rows[src].ms == pytest.approx(ms, abs=5e-6)
    assert rows['total'].dof == 89 and rows['total'].ss == pytest.approx(94.6471, abs=5e-5)
    # the interaction is not significant (F 0.434): pooled, as the manual does
    assert rows['parts x operators'].f == pytest.approx(0.434, abs=5e-4)
    assert g.interaction_pooled


def test_variance_components_are_aiag_table_iii_b6a() -> None:
    g = gauge_rr_anova(_aiag())
    # Table III-B 6a: estimate of variance, std. dev. and % of total variation
    assert g.var['repeatability'] == pytest.approx(0.039973, abs=5e-7)
    assert g.var['reproducibility'] == pytest.approx(0.051455, abs=5e-7)
    assert g.var['interaction'] == 0.0
    assert g.var['part'] == pytest.approx(1.086447, abs=5e-7)
    assert g.ev == pytest.approx(0.199933, abs=5e-6)
    assert g.av == pytest.approx(0.226838, abs=5e-6)
    assert g.grr == pytest.approx(0.302373, abs=5e-6)
    assert g.pv == pytest.approx(1.042327, abs=5e-6)
    assert g.tv == pytest.approx(1.085300, abs=5e-6)
    # % contribution (of the total variance)
    total = sum(g.var.values())
    assert [round(100 * v / total, 1) for v in (g.var['repeatability'],
            g.var['reproducibility'], g.grr ** 2, g.var['part'])] == [3.4, 4.4, 7.8, 92.2]
    assert round(100 * g.ev / g.tv, 1) == 18.4
    assert round(100 * g.av / g.tv, 1) == 20.9
    assert round(g.pct_process, 1) == 27.9
    assert round(100 * g.pv / g.tv, 1) == 96.0
    assert g.ndc == 4
    assert g.verdict() == 'conditional'


def test_grr_of_tolerance_and_of_a_stated_process_sigma() -> None:
    g = gauge_rr_anova(_aiag(), tolerance=6.0, process_sigma=2.0)
    assert g.pct_tolerance == pytest.approx(100 * 6 * 0.302373 / 6.0, abs=1e-3)
    assert g.pct_process == pytest.approx(100 * 0.302373 / 2.0, abs=1e-3)
    assert g.verdict() == 'unacceptable'       # of the tolerance: 30.2 %
    # ndc from the part variation the stated process sigma leaves beside the GRR
    assert g.ndc == math.floor(1.41 * math.sqrt(4.0 - 0.302373 ** 2) / 0.302373)


def test_significant_interaction_is_kept() -> None:
    """A constructed case worked by hand: two parts, two operators who swap the parts'
    order (interaction), three repeats each at +-1 around the cell mean."""
    cells = np.array([[10.0, 14.0], [14.0, 10.0]])
    y = cells[:, :, None] + np.array([-1.0, 0.0, 1.0])
    g = gauge_rr_anova(y)
    # SS_P = SS_O = 0, SS_PO = 3 * 4 * 2^2 = 48 (1 dof), SS_E = 4 cells * 2 = 8 (8 dof)
    rows = {r.source: r for r in g.anova}
    assert rows['parts x operators'].ss == pytest.approx(48.0)
    assert rows['repeatability (equipment)'].ms == pytest.approx(1.0)
    assert not g.interaction_pooled
    assert g.var['interaction'] == pytest.approx((48.0 - 1.0) / 3)
    assert g.var['part'] == 0.0 and g.var['reproducibility'] == 0.0


def test_type1_study_by_hand() -> None:
    """Bosch booklet 10 procedure 1 formulas on 25 values written here: 20 at 5.000 and
    5 at 5.010 (mean 5.002, s = sqrt(20 * 0.002^2 + 5 * 0.008^2) / 24 ...)."""
    x = np.r_[np.full(20, 5.000), np.full(5, 5.010)]
    mean = (20 * 5.0 + 5 * 5.01) / 25
    s = math.sqrt((20 * (5.0 - mean) ** 2 + 5 * (5.01 - mean) ** 2) / 24)
    st = type1_study(x, tolerance=0.3, reference=5.001)
    assert st.mean == pytest.approx(5.002)
    assert st.std == pytest.approx(s)
    assert st.cg == pytest.approx(0.2 * 0.3 / (6 * s))
    assert st.cgk == pytest.approx((0.1 * 0.3 - 0.001) / (3 * s))
    assert st.bias == pytest.approx(0.001)
    assert st.t_bias == pytest.approx(0.001 / (s / 5))
    assert st.capable is True
    no_ref = type1_study(x, tolerance=0.3)
    assert math.isnan(no_ref.cgk) and no_ref.capable is None


def test_bad_studies_are_named() -> None:
    with pytest.raises(MsaError, match='at least 25 repeats, got 24'):
        type1_study(np.arange(24.0), tolerance=1.0)
    with pytest.raises(MsaError, match='tolerance'):
        type1_study(np.arange(30.0), tolerance=0.0)
    with pytest.raises(MsaError, match=r'\(parts, operators, repeats\)'):
        gauge_rr_anova(np.zeros((3, 3)))
    with pytest.raises(MsaError, match='>= 2 repeats'):
        gauge_rr_anova(np.zeros((3, 2, 1)))
    bad = np.ones((2, 2, 2))
    bad[1, 0, 1] = np.nan
    with pytest.raises(MsaError, match=r'\(1, 0, 1\)'):
        gauge_rr_anova(bad)
