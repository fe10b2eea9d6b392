"""The demo summary's recommendation lines (issue #15 item 8): the recommendation for this
unit and the preset's nominal optimum, said which is which and why the first applies.

The advice objects are real: the preset's Eq. 21 optimum, and the identified advice of a
record generated with the independent model in tests/wang2020_reference.py (a 30 deg grid
for speed, the same for both as in the compensation node)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from rv_te_bench.cli.demo import recommendation_lines
from rv_te_bench.core.identify import identified_advice
from rv_te_bench.core.phases import optimise_phases
from rv_te_bench.report.analysis import Recommendation
from sim.presets import load_preset
from sim.wang2020 import Wang2kvParams
from tests import wang2020_reference as ref

STEP_DEG = 30.0


@pytest.fixture(scope='module')
def params() -> Wang2kvParams:
    return Wang2kvParams.from_preset(load_preset('wang2020-2kv'))


@pytest.fixture(scope='module')
def nominal(params: Wang2kvParams):
    return optimise_phases(params, step_deg=STEP_DEG).to_advice('wang2020-2kv')


def _identified(unit: ref.Unit, params: Wang2kvParams):
    th_in, th_out = ref.encoder_record(unit, np.random.default_rng(8), n_samples=20_000)
    advice = identified_advice(th_in / ref.RATIO, th_out - th_in / ref.RATIO, params,
                               preset_name='wang2020-2kv', step_deg=STEP_DEG)
    return Recommendation(available=True, reason='identified', advice=advice)


def test_this_unit_first_nominal_beside_it_and_why(params, nominal) -> None:
    """A unit assembled at other phases than the preset's (same part magnitudes)."""
    t2 = ref.table2_unit()
    unit = ref.Unit(t2.e_p1, t2.e_p2, t2.e_g, t2.e_ot, 0.3, -2.0, 1.1, 2.5)
    text = '\n'.join(recommendation_lines(_identified(unit, params),
                                          {'assembly-phases': nominal}))
    first, second = text.index('recommendation for this unit'), text.index('nominal optimum')
    assert first < second
    assert 'identified-assembly-phases' in text[:second]
    assert 'of the TE variance' in text[:second]          # the fit quality goes with it
    assert 'why the first: both search the same phase grid with the same part magnitudes' in text
    assert "only it says how far to turn each part of this unit" in text
    # this unit's phases are not the preset's (0.3, -2.0, 1.1, 2.5 rad vs 90, 180, -135, 90)
    want = max(ref.dphase_deg(math.radians(n), u) for n, u in zip(
        ref.TABLE2_PHASES_DEG, (unit.theta_p1, unit.theta_p2, unit.theta_g, unit.theta_ot),
        strict=True))
    got = re.search(r'here up to ([0-9.]+) deg from the nominal ones', text)
    assert got is not None
    assert float(got.group(1)) == pytest.approx(want, abs=0.1)
    assert '[' + ', '.join(f'{math.degrees(m.recommended_value):.1f}'
                           for m in nominal.modifications) + '] deg' in text


def test_the_preset_unit_itself(params, nominal) -> None:
    """The preset's own unit measured: target and current phases agree, the text says so."""
    text = '\n'.join(recommendation_lines(_identified(ref.table2_unit(), params),
                                          {'assembly-phases': nominal}))
    assert 'their target phases agree' in text
    assert 'here within 0.' in text and 'of the nominal ones' in text


def test_withheld_advice_keeps_the_nominal_optimum_apart(nominal) -> None:
    rec = Recommendation(available=False, reason='re-assembly advice withheld: poor fit')
    text = '\n'.join(recommendation_lines(rec, {'assembly-phases': nominal}))
    assert 'recommendation for this unit: none (re-assembly advice withheld: poor fit)' in text
    assert 'it is not a recommendation for this unit' in text
