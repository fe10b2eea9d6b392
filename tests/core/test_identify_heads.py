"""Identification with the encoder's error separated (issue 36 target).

Random 2K-V units as in tests/core/test_identify_units.py (the paper's equations written
out in :mod:`tests.wang2020_reference`), but the output angle is read through a scale
mounted 5 um off centre on 100 mm (41" p-p at once per output revolution, the order of
e_ot) with a +-1" graduation, by the tests' exact-geometry model
(:mod:`tests.scale_reference`). Targets: with two or four heads averaged (or one head with
a calibration of the scale applied), e_ot and the pair sums Q1, Q2 within 1 % of the
largest and the phases within 1 deg where the split is well posed, as without scale
errors; with one head and nothing applied they absorb the scale's line (shown, so that
the test can fail).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.angle_fold import AngleFold
from rv_te_bench.core.encoder_calibration import calibration_from_estimate
from rv_te_bench.core.heads import HeadLayout
from rv_te_bench.core.identify import Identification, identify_folded
from rv_te_bench.core.phases import PHASE_NAMES, EccentricGeometry
from rv_te_bench.core.selfcal import HeadSelfCalibration
from sim.read_heads import graduation_from_grade
from tests import wang2020_reference as ref
from tests.scale_reference import ARCSEC_RAD, Scale

pytestmark = pytest.mark.slow

N_UNITS = 10
#: Pairs touching less of the record are poorly determined whatever the encoder.
MIN_CONTACT = 0.05
RATE_HZ = 10_000.0
DURATION_S = 20.5
NOISE_ARCSEC = 0.2
BLOCK = 10_000


def _scale(rng: np.random.Generator, heads_deg: tuple[float, ...]) -> Scale:
    grad = graduation_from_grade(1.0, rng)
    return Scale(radius_m=0.05, eccentricity_m=5e-6, psi_rad=rng.uniform(0, 6.28),
                 orders=grad.orders, amplitudes_rad=grad.amplitudes_rad,
                 phases_rad=grad.phases_rad, heads_rad=tuple(np.radians(heads_deg)),
                 noise_rad=(NOISE_ARCSEC * ARCSEC_RAD,) * len(heads_deg))


def _identify(u: ref.Unit, scale: Scale, rng: np.random.Generator, mode: str,
              ) -> Identification:
    n = round(DURATION_S * RATE_HZ)
    revs = DURATION_S * 300.0 / 60.0 / ref.RATIO
    start = rng.uniform(0, 2 * math.pi * ref.RATIO)
    theta_in = start + np.arange(n) * (2 * math.pi * ref.RATIO * revs / n)
    phi = theta_in / ref.RATIO
    theta_out = phi + ref.nlte_rad(phi, u)
    heads = scale.readings(theta_out, rng)
    lay = HeadLayout.of(scale.heads_rad)
    if mode == 'average':
        out = lay.combine(heads)
    elif mode == 'calibrated':
        # calibrated earlier in the same mounting from all heads; the run uses head 0 only
        sc = HeadSelfCalibration(lay)
        sc.add(heads)
        cal = calibration_from_estimate(sc.result(), scale_serial='S', date='2026-11-27')
        out = cal.correct(heads[0])
    else:
        out = heads[0]
    theta_in = theta_in + NOISE_ARCSEC * ARCSEC_RAD * rng.standard_normal(n)
    fold = AngleFold()
    for s in range(0, n, BLOCK):
        fold.add_encoders(theta_in[s:s + BLOCK], out[s:s + BLOCK], gear_ratio=ref.RATIO)
    params = EccentricGeometry((u.e_p1, u.e_p2, u.e_g, 1e-5), (0.0, 0.0, 0.0, 0.0),
                               alpha_rad=ref.ALPHA_RAD, r_p_m=ref.R_P_M,
                               crank_order=ref.CRANK_ORDER)
    return identify_folded(fold.result(), params, rng=rng)


def _run(heads_deg: tuple[float, ...], mode: str, seed: int):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(N_UNITS):
        u = ref.random_unit(rng)
        idf = _identify(u, _scale(rng, heads_deg), rng, mode)
        out.append((u, idf, ref.split_well_posed(u, rng)))
    return out


@pytest.mark.parametrize(('heads_deg', 'mode'), [
    ((0.0, 180.0), 'average'),
    ((0.0, 90.0, 180.0, 270.0), 'average'),
    ((0.0, 90.0, 180.0, 270.0), 'calibrated'),
])
def test_separated_encoder_error_leaves_e_ot_and_q_within_1_percent(heads_deg, mode) -> None:
    """Two heads leave the scale's even orders (order 2 of a +-1" grade: ~0.12"): a unit
    whose pair touches ~1 % of the record (its sum poorly determined whatever the encoder)
    then comes out ~2 % off (benchmarks/bench_heads.py shows one); here the 2-head bound
    holds for units whose pairs both carry >= 5 % of the record, the 4-head and calibrated
    bounds for every unit."""
    units = _run(heads_deg, mode, 36_015)
    errors = [ref.vector_error(u, idf.pair_phasors_m)[0] for u, idf, _ in units
              if len(heads_deg) > 2 or min(idf.contact_fraction) >= MIN_CONTACT]
    assert len(errors) >= N_UNITS // 2
    assert max(errors) <= 0.01, errors
    posed = [(u, idf) for u, idf, ok in units if ok]
    assert len(posed) >= N_UNITS // 2
    for u, idf in posed:
        truth = (u.theta_p1, u.theta_p2, u.theta_g, u.theta_ot)
        errs = [ref.dphase_deg(idf.phases_rad[n], t)
                for n, t in zip(PHASE_NAMES, truth, strict=True)]
        assert max(errs) < 1.0, errs


def test_one_head_absorbs_the_scale_eccentricity() -> None:
    """The same units read by one head: the 20.6" scale line lands in E (today's
    behaviour the issue describes); the error is many times the 1 % target."""
    units = _run((0.0,), 'one', 36_015)
    errors = [ref.vector_error(u, idf.pair_phasors_m)[0] for u, idf, _ in units]
    assert max(errors) > 0.05, errors
