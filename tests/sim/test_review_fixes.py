"""Regression tests for review findings in sim/ (each names what it guards)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.errors import ModelInputError, PresetError
from sim.presets import load_preset


@pytest.mark.parametrize('nu', ['0.7', '1.0', '0.5'])
def test_li2023_rejects_impossible_poisson_ratio(nu: str) -> None:
    from sim.li2023 import build_te_model  # noqa: PLC0415

    with pytest.raises(PresetError, match='material.poisson'):
        build_te_model(load_preset('li2023-rv', [f'material.poisson={nu}']), 'dte')


def test_hu2020_tca_at_a_torque_too_small_to_close_any_clearance() -> None:
    from sim.hu2020 import HuRvParams, tooth_contact_analysis  # noqa: PLC0415

    params = HuRvParams.from_preset(load_preset('hu2020-rv'))
    with pytest.raises(ModelInputError, match='no pin closes'):
        tooth_contact_analysis(params, torque_nm=1e-3)


def test_wang2020_dte_far_from_t0_equals_dte_near_t0() -> None:
    """Float64 timestamps jitter far from t = 0; the DTE must not depend on that (the
    integrator used to split such blocks into hundreds of runs)."""
    from sim.wang2020 import build_te_model  # noqa: PLC0415

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
