"""Issue 34: hysteresis metrics of *measured* records (0.4 N m torque noise, RON 886 angle
errors, loader ramps and ripple, a preload and several cycles) within 2 % of the truth of
the closed-form curve of tests/core/hysteresis_records.py; the exact-equality dwell grouping
and first-crossing reading the suite used before (``dwell_points`` + ``hysteresis_metrics``)
do not meet that on the same records."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.hysteresis import (
    HysteresisConfig,
    RigidityRegion,
    dwell_points,
    hysteresis_metrics,
)
from rv_te_bench.core.hysteresis_measured import (
    HysteresisReading,
    find_dwells,
    measured_hysteresis,
    split_cycles,
    torque_noise_nm,
)
from rv_te_bench.errors import TeConfigError, TeInputError
from tests.core.hysteresis_records import (
    Unit,
    constant_speed_record,
    step_torques,
    torque_step_record,
)

UNIT = Unit()
REGIONS = {'K': (0.5, 1.0), 'K1': (0.1, 0.35)}
CONFIG = HysteresisConfig(rated_torque_nm=UNIT.rated_nm, rigidity_regions=tuple(
    RigidityRegion(k, *v) for k, v in REGIONS.items()))
TRUTH = {**UNIT.truth(regions=REGIONS), 'hysteresis_loss_j': UNIT.loop_area_j()}
STEPS = HysteresisReading('torque_steps', min_dwell_samples=150,
                          resolution_nm=0.25 * 0.03 * UNIT.rated_nm)   # a quarter of 3 % T_R
SEEDS = range(10)


def rel_errors(values: dict[str, float]) -> dict[str, float]:
    return {k: values[k] / TRUTH[k] - 1.0 for k in TRUTH}


def old_reading(torque: np.ndarray, angle: np.ndarray) -> dict[str, float]:
    """The reading of the suite before issue 34: runs of exactly equal torque, then the
    first crossing of each torque (TeInputError propagates)."""
    t, a, _ = dwell_points(torque, angle)
    m = hysteresis_metrics(t, a, CONFIG)
    return {'backlash_rad': m.backlash_rad, 'lost_motion_rad': m.lost_motion_rad,
            'hysteresis_loss_j': m.hysteresis_loss_j,
            **{f'torsional_rigidity_{k}_nm_per_rad': m.rigidity_min_nm_per_rad(k)
               for k in REGIONS}}


def test_truth_of_the_closed_form() -> None:
    """The truth as the catalogue formulas give it for a linear flank (K1 region)."""
    b, tf, k1, t = UNIT.b_rad, UNIT.tf_nm, UNIT.k1, 0.03 * UNIT.rated_nm
    assert TRUTH['backlash_rad'] == pytest.approx(b + 2 * tf / k1, rel=1e-12)
    assert TRUTH['lost_motion_rad'] == pytest.approx(b + 2 * t / k1, rel=1e-12)
    assert TRUTH['torsional_rigidity_K_nm_per_rad'] == pytest.approx(UNIT.k2, rel=1e-12)
    assert TRUTH['torsional_rigidity_K1_nm_per_rad'] == pytest.approx(k1, rel=1e-12)
    # the loop of a friction play operator: 2 T_f over the angle travelled one way
    travel = float(UNIT.phi_up(UNIT.rated_nm - tf) - UNIT.phi_down(-UNIT.rated_nm + tf))
    assert TRUTH['hysteresis_loss_j'] == pytest.approx(2 * tf * travel, rel=2e-3)


@pytest.mark.parametrize('seed', SEEDS)
def test_torque_steps_three_cycles_within_2_percent(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rec = torque_step_record(UNIT, step_torques(UNIT, regions=(0.1, 0.35, 0.5, 1.0),
                                                cycles=3), rng)
    m = measured_hysteresis(rec.time_s, rec.torque_nm, rec.angle_rad, CONFIG, STEPS)
    assert len(m.cycles) == 3 and not m.missing
    assert m.torque_noise_nm == pytest.approx(0.4, rel=0.1)
    for name, err in rel_errors(m.values).items():
        assert abs(err) <= 0.02, (name, err)
    # the spread over the cycles is reported, and is the noise's, not the curve's
    assert all(math.isfinite(v) for v in m.spread.values())
    assert m.spread['backlash_rad'] < 0.01 * TRUTH['backlash_rad']


@pytest.mark.parametrize('seed', SEEDS)
def test_constant_speed_two_cycles_within_2_percent(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rec = constant_speed_record(UNIT, rng, cycles=2)
    m = measured_hysteresis(rec.time_s, rec.torque_nm, rec.angle_rad, CONFIG,
                            HysteresisReading('constant_speed'))
    assert len(m.cycles) == 2 and not m.missing
    for name, err in rel_errors(m.values).items():
        assert abs(err) <= 0.02, (name, err)


def test_the_old_reading_misses_2_percent_on_the_same_records() -> None:
    """Constant speed, one clean cycle: the first crossing of noisy samples overstates the
    backlash beyond 2 % on every seed. Torque steps: exact-equality grouping finds no
    dwell in a noisy record, so single noisy samples are read at their first crossing:
    one cycle misses 2 % on some seeds, the full record (preload, three cycles) on most
    (or cannot be read at all: its minimum may lie in the preload)."""
    cs = []
    one_cycle, full = [], []
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        rec = constant_speed_record(UNIT, rng, cycles=1, preload=False)
        cs.append(rel_errors(old_reading(rec.torque_nm, rec.angle_rad))['backlash_rad'])
        rec = torque_step_record(UNIT, step_torques(UNIT, regions=(0.1, 0.35, 0.5, 1.0),
                                                    preload=False), rng)
        assert dwell_points(rec.torque_nm, rec.angle_rad)[0].size == rec.torque_nm.size
        one_cycle.append(max(abs(e) for e in rel_errors(
            old_reading(rec.torque_nm, rec.angle_rad)).values()))
        rec = torque_step_record(UNIT, step_torques(UNIT, regions=(0.1, 0.35, 0.5, 1.0),
                                                    cycles=3), rng)
        try:
            full.append(max(abs(e) for e in rel_errors(
                old_reading(rec.torque_nm, rec.angle_rad)).values()))
        except TeInputError:
            full.append(math.inf)
    assert min(cs) > 0.02, cs                                # biased high every time
    assert sum(e > 0.02 for e in one_cycle) >= 3, one_cycle
    assert sum(e > 0.02 for e in full) >= 7, full


def test_dwells_of_exact_steps_are_the_steps() -> None:
    """A simulated loader (torque read exactly constant, instant steps): every dwell found,
    its torque exact and its angle the dwell's; the loop area as from the dwell means."""
    torques = step_torques(UNIT, preload=False)
    t = np.repeat(torques, 200)
    phi = UNIT.respond(t)
    d = find_dwells(t, phi, min_samples=60, resolution_nm=1.25)
    np.testing.assert_allclose(d.torque_nm, torques, rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(d.angle_rad, phi[::200], rtol=0, atol=1e-15)
    assert d.noise_nm == 0.0
    m = measured_hysteresis(np.arange(t.size) / 1e3, t, phi, CONFIG,
                            HysteresisReading('torque_steps', min_dwell_samples=60,
                                              resolution_nm=1.25))
    ref = hysteresis_metrics(*dwell_points(t, phi)[:2], CONFIG)
    assert m.values['backlash_rad'] == pytest.approx(ref.backlash_rad, rel=1e-12)
    assert m.values['lost_motion_rad'] == pytest.approx(ref.lost_motion_rad, rel=1e-12)
    assert m.values['hysteresis_loss_j'] == pytest.approx(ref.hysteresis_loss_j, rel=1e-9)


def test_split_cycles_of_a_record_with_preload() -> None:
    t = step_torques(UNIT, cycles=2)
    cycles = split_cycles(t, UNIT.rated_nm)
    assert len(cycles) == 2
    c0, c1 = cycles
    assert t[c0.peak] == UNIT.rated_nm and t[c0.trough] == -UNIT.rated_nm
    assert t[c0.up_start] == -UNIT.rated_nm            # the preload's -T_R
    assert c1.up_start == c0.trough and c0.back_end == c1.peak
    assert c1.back_end == len(t) - 1


def test_torque_noise_estimate_ignores_steps_and_ramps() -> None:
    rng = np.random.default_rng(5)
    rec = torque_step_record(UNIT, step_torques(UNIT), rng, noise_nm=0.25)
    assert torque_noise_nm(rec.torque_nm) == pytest.approx(0.25, rel=0.08)


def test_no_cycle_is_named() -> None:
    t = np.r_[np.zeros(500), np.full(500, 80.0), np.zeros(500)]
    with pytest.raises(TeInputError,
                       match=r'no complete load cycle .* reaches \+80 / \+0 N m.*3 held torques'):
        measured_hysteresis(np.arange(t.size) / 1e3, t, t / 1e5, CONFIG,
                            HysteresisReading('torque_steps', min_dwell_samples=60))


def test_noise_too_large_for_the_steps() -> None:
    rng = np.random.default_rng(2)
    t = np.repeat(step_torques(UNIT), 100) + rng.normal(0, 5.0, 100 * len(step_torques(UNIT)))
    with pytest.raises(TeInputError, match=r'torque noise .* too large to tell torque steps'):
        find_dwells(t, t, min_samples=30, resolution_nm=1.0)


@pytest.mark.parametrize(('kwargs', 'match'), [
    ({'method': 'hammer'}, "method must be 'torque_steps'"),
    ({'method': 'torque_steps', 'min_dwell_samples': 2}, 'min_dwell_samples must be'),
    ({'method': 'torque_steps', 'resolution_nm': 0.0}, 'resolution_nm must be'),
])
def test_bad_reading_settings(kwargs: dict, match: str) -> None:
    with pytest.raises(TeConfigError, match=match):
        HysteresisReading(**kwargs)
