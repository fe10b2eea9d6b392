"""core.advice: the advice chosen for a bench, and the plain-data records."""

from __future__ import annotations

import math

import pytest

from rv_te_bench.core.advice import Modification, advice_kind, modification_value
from sim.presets import load_preset


@pytest.mark.parametrize(('preset', 'kind'), [('wang2020-2kv', 'assembly-phases'),
                                              ('hu2020-rv', 'tooth-profile')])
def test_advice_of_the_shipped_presets(preset: str, kind: str) -> None:
    assert advice_kind(load_preset(preset, []).model) == kind


def test_a_model_without_compensation_gets_none() -> None:
    assert advice_kind('li2023-rv') is None
    assert advice_kind('') is None


def test_modification_json_turns_nan_into_none() -> None:
    m = Modification('pin radius', 'r_rp', 'm', 1e-3, 1.01e-3)
    d = m.to_json_dict()
    assert d['current_value'] == 1e-3
    assert d['sensitivity_index'] is None
    assert math.isnan(m.sensitivity_index)


@pytest.mark.parametrize(('x', 'unit', 'text', 'html'), [
    (math.pi / 2, 'rad', '1.5708 rad (90.00 deg)', '1.5708 (90.00&deg;)'),
    (2.5e-5, 'm', '2.5e-05 m (0.0250 mm)', '2.5e-05 (0.0250 mm)'),
    (3.0, 'N m', '3 N m', '3'),
])
def test_modification_value_for_text_and_html(x: float, unit: str, text: str, html: str) -> None:
    """One formatter for the analyze text and the HTML table (the HTML unit has its column)."""
    assert modification_value(x, unit) == text
    assert modification_value(x, unit, html=True) == html
