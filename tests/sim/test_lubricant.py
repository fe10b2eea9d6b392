"""The viscosity-temperature law (ASTM D341 Walther equation) of sim.lubricant."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.errors import ModelInputError, PresetError
from sim.lubricant import Lubricant, walther_constants, walther_viscosity_mm2_s
from sim.presets import available_presets, load_preset


def test_worked_example_of_the_standard() -> None:
    """The ASTM D341 two-point worked example (32 cSt at 40 degC, 5.4 cSt at 100 degC,
    T = t + 273 as in the example): A = 9.5259, B = 3.7449, 8.5 cSt at 80 degC (the
    'Viscosity vs Temperature Calculator' sheet that quotes D341; values as printed)."""
    a, b = walther_constants(32.0, 313.0, 5.4, 373.0)
    assert a == pytest.approx(9.5259, abs=5e-5)
    assert b == pytest.approx(3.7449, abs=5e-5)
    assert float(walther_viscosity_mm2_s(353.0, a, b)) == pytest.approx(8.5, abs=0.05)


def test_line_in_walther_coordinates_computed_here() -> None:
    """Independently of the module: log10 log10(nu + 0.7) is linear in log10 T, through
    both data-sheet points of an ISO VG 100 oil."""
    oil = Lubricant(100.0, 11.0)
    temps_c = np.array([-10.0, 0.0, 20.0, 40.0, 60.0, 100.0, 120.0])
    nu = oil.viscosity_mm2_s(temps_c)
    y = np.log10(np.log10(nu + 0.7))
    x = np.log10(temps_c + 273.15)
    slope, icpt = np.polyfit(x, y, 1)
    assert np.max(np.abs(y - (slope * x + icpt))) < 1e-12
    assert nu[3] == pytest.approx(100.0, rel=1e-12)
    assert nu[5] == pytest.approx(11.0, rel=1e-12)
    # own two-point solution
    y40, y100 = math.log10(math.log10(100.7)), math.log10(math.log10(11.7))
    b = (y40 - y100) / (math.log10(373.15) - math.log10(313.15))
    assert oil.walther_b == pytest.approx(b, rel=1e-12)
    assert np.all(np.diff(nu) < 0)      # thins as it warms


def test_presets_carry_a_lubricant() -> None:
    for name in available_presets():
        oil = Lubricant.from_preset(load_preset(name))
        assert oil.viscosity_mm2_s(40.0) == pytest.approx(oil.nu40_mm2_s)


@pytest.mark.parametrize(('args', 'pattern'), [
    ((100.0, 120.0), 'must be below nu40'),
    ((1.5, 1.0), r'>= 2\.0 mm\^2/s'),
    ((float('nan'), 10.0), 'nu40_mm2_s must be finite'),
    ((-1.0, 10.0), r'nu40_mm2_s must be finite and > 0'),
])
def test_bad_lubricants_named(args: tuple[float, float], pattern: str) -> None:
    with pytest.raises(ModelInputError, match=pattern):
        Lubricant(*args)


def test_outside_the_law_refused() -> None:
    oil = Lubricant(10.0, 2.5)
    with pytest.raises(ModelInputError, match=r'below 2\.0 mm'):
        oil.viscosity_mm2_s(150.0)
    with pytest.raises(ModelInputError, match='finite and > 0 K'):
        walther_viscosity_mm2_s([-300.0], *oil_ab(oil))
    with pytest.raises(ModelInputError, match='two different points'):
        walther_constants(10.0, 300.0, 10.0, 350.0)


def oil_ab(oil: Lubricant) -> tuple[float, float]:
    return oil.walther_a, oil.walther_b


def test_preset_without_lubricant_named() -> None:
    from sim.presets import preset_from_text

    p = preset_from_text('name = "x"\nmodel = "wang2020-2kv"\n[lubricant]\nnu40_mm2_s = 10.0\n')
    with pytest.raises(PresetError, match=r"'x' has no lubricant\.nu100_mm2_s"):
        Lubricant.from_preset(p)
