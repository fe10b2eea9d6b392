"""Bench descriptions and simulated benches with several read heads per scale (issue 36)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.errors import BenchDescriptionError
from rv_te_bench.io.bench_description import parse_bench_description
from sim.bench import BenchConfig, BenchSimulator
from sim.drive import ConstantSpeed
from sim.encoders import encoder_preset
from sim.scales import mounted_scale

BASE = {'bench_id': 'b1', 'sample_rate_hz': 5000, 'preset': 'wang2020-2kv'}


def _desc(output: dict, joints: dict | None = None):
    data = dict(BASE, encoders={'input': {'model': 'heidenhain-ron886'}, 'output': output})
    if joints is not None:
        data['joints'] = joints
    return parse_bench_description(data, 'bench.yaml')


def test_heads_serial_and_run_out_reach_bench_info() -> None:
    d = _desc({'model': 'renishaw-resm', 'serial': 'RESM-1', 'heads_deg': [0, 90, 180, 270],
               'scale': {'diameter_mm': 100.0, 'runout_um': 10.0, 'index_deg': 180.0}},
              {'input': 'in', 'output': 'h0', 'output_heads': ['h0', 'h1', 'h2', 'h3']})
    info = d.bench_info()
    assert info.encoder_out_head_angles_rad == pytest.approx(
        tuple(math.radians(a) for a in (0, 90, 180, 270)))
    assert info.encoder_out_scale_serial == 'RESM-1'
    assert info.encoder_out_scale_diameter_m == pytest.approx(0.1)
    assert info.encoder_out_scale_eccentricity_m == pytest.approx(5e-6)   # TIR / 2
    assert info.encoder_out_scale_index_rad == pytest.approx(math.pi)
    assert info.encoder_in_head_angles_rad == ()
    assert d.encoder_out.head_joints == ('h0', 'h1', 'h2', 'h3')


@pytest.mark.parametrize(('output', 'joints', 'match'), [
    ({'model': 'x', 'heads_deg': [0, 'a']}, None, 'heads_deg must be a list'),
    ({'model': 'x', 'heads_deg': [90]}, None, r'with one head must be \[0\]'),
    ({'model': 'x', 'scale': {'runout_um': 4}}, None, 'diameter_mm is required'),
    ({'model': 'x', 'scale': {'diameter_mm': 100, 'runout_um': 4, 'eccentricity_um': 2}}, None,
     'give one'),
    ({'model': 'x', 'scale': {'diameter': 100}}, None, 'unknown key'),
    ({'model': 'x', 'heads_deg': [0, 180]}, {'input': 'i', 'output_heads': ['a']},
     'must list 2 different joint names'),
    ({'model': 'x', 'heads_deg': [0, 180]}, {'input': 'a', 'output_heads': ['a', 'b']},
     'must not name joints.input'),
])
def test_bad_scale_entries_are_named(output, joints, match) -> None:
    with pytest.raises(BenchDescriptionError, match=match):
        _desc(output, joints)


def _bench(encoder_out) -> BenchSimulator:
    return BenchSimulator(BenchConfig(preset='wang2020-2kv', drive=ConstantSpeed(300.0),
                                      encoder_out=encoder_out, block_size=500, seed=3))


def test_simulated_bench_publishes_every_head_and_its_scale_record() -> None:
    ron = encoder_preset('heidenhain-ron886')
    scale = mounted_scale(ron, np.random.default_rng(1), heads_deg=[0, 120, 240],
                          eccentricity_m=5e-6, diameter_m=0.1, serial='R-9')
    sim = _bench(scale)
    b = sim.next_block()
    assert b.theta_out_heads_rad is not None and b.theta_out_heads_rad.shape == (3, 500)
    np.testing.assert_array_equal(b.theta_out_heads_rad[0], b.theta_out_rad)
    assert b.theta_in_heads_rad is None
    info = sim.info
    assert info.encoder_out_scale_serial == 'R-9'
    assert info.encoder_out_scale_eccentricity_m == pytest.approx(5e-6)
    assert len(info.encoder_out_head_angles_rad) == 3
    # the heads see the eccentricity 120 deg apart: their spread is tens of arcseconds
    spread = np.ptp(b.theta_out_heads_rad - b.theta_out_true_rad, axis=0).max()
    assert spread * 206264.8 > 20


def test_a_one_head_bench_reads_as_before() -> None:
    """A bench without heads draws exactly what it did before issue 36 (same seed, same
    numbers): the plain preset and a 'mounted' preset with no scale settings agree."""
    a = _bench('heidenhain-ron886').next_block()
    b = _bench(mounted_scale(encoder_preset('heidenhain-ron886'),
                             np.random.default_rng(0))).next_block()
    np.testing.assert_array_equal(a.theta_out_rad, b.theta_out_rad)
    assert a.theta_out_heads_rad is None
