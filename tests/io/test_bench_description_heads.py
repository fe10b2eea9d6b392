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


def test_scale_tilt_from_axial_run_out_or_stated() -> None:
    """A scale face running out 50 um (TIR) at its 100 mm graduation is tilted 0.5 mrad."""
    d = _desc({'model': 'x', 'scale': {'diameter_mm': 100.0, 'axial_runout_um': 50.0}})
    assert d.encoder_out.scale_tilt_rad == pytest.approx(5e-4)
    assert d.to_plain()['encoder_out']['scale_tilt_rad'] == pytest.approx(5e-4)
    d = _desc({'model': 'x', 'scale': {'tilt_mrad': 2.0}})
    assert d.encoder_out.scale_tilt_rad == pytest.approx(2e-3)
    assert _desc({'model': 'x'}).encoder_out.scale_tilt_rad == 0.0


@pytest.mark.parametrize(('scale', 'match'), [
    ({'axial_runout_um': 50.0}, 'diameter_mm is required with an axial run-out'),
    ({'diameter_mm': 100, 'axial_runout_um': 5, 'tilt_mrad': 0.05}, 'give one'),
    ({'tilt_mrad': -1.0}, r'tilt_mrad must be between 0 and 100.*-1'),
    ({'diameter_mm': 100, 'axial_runout_um': -3.0}, r'axial_runout_um must be >= 0.*-3'),
])
def test_bad_tilt_entries_are_named(scale, match) -> None:
    with pytest.raises(BenchDescriptionError, match=match):
        _desc({'model': 'x', 'scale': scale})


def _reading_error_harmonics(values: dict, orders: tuple[int, ...]) -> dict[str, np.ndarray]:
    """The bench node's simulated output readings minus the true output angle, least-squares
    amplitudes at ``orders`` of the true angle (the test's own fit), for head 0 and the mean
    of the heads."""
    from rv_te_bench.nodes.bench_node import bench_config_from_params
    from rv_te_bench.nodes.params.bench import BenchParams
    from rv_te_bench.params import params_record

    sim = BenchSimulator(bench_config_from_params(params_record(BenchParams, values)))
    th, err0, errm = [], [], []
    while not th or th[-1][-1] - th[0][0] < 2.2 * math.pi:
        b = sim.next_block()
        th.append(b.theta_out_true_rad)
        heads = b.theta_out_heads_rad if b.theta_out_heads_rad is not None else \
            b.theta_out_rad[None, :]
        err0.append(heads[0] - b.theta_out_true_rad)
        errm.append(heads.mean(axis=0) - b.theta_out_true_rad)
    t = np.concatenate(th)
    cols = [np.ones_like(t)] + [f(k * t) for k in orders for f in (np.cos, np.sin)]
    a = np.column_stack(cols)
    out = {}
    for name, e in (('head0', np.concatenate(err0)), ('mean', np.concatenate(errm))):
        c = np.linalg.lstsq(a, e, rcond=None)[0][1:]
        out[name] = np.hypot(c[0::2], c[1::2])
    return out


def test_bench_node_scale_tilt_reads_tau_squared_over_four_at_order_two() -> None:
    """A 10 mrad tilt of the output scale: every head reads tau^2/4 = 2.5e-5 rad (5.16") at
    order 2 of the output angle and nothing at orders 1, 3, 4; three heads 120 deg apart
    cancel it (2 is not a multiple of 3), two heads 180 deg apart keep it all."""
    tau = 10e-3
    base = {'preset': 'wang2020-2kv', 'speed_rpm': 6000.0, 'encoder_in': 'ideal',
            'encoder_out': 'ideal', 'encoder_out_scale_tilt_mrad': tau * 1e3,
            'sample_rate_hz': 2000.0, 'block_size': 1000, 'seed': 4}
    amp = _reading_error_harmonics(base, (1, 2, 3, 4))['head0']
    assert amp[1] == pytest.approx(tau**2 / 4, rel=1e-3)
    assert max(amp[0], amp[2], amp[3]) < 1e-3 * tau**2 / 4
    three = _reading_error_harmonics({**base, 'encoder_out_heads_deg': [0.0, 120.0, 240.0]},
                                     (2,))
    assert three['head0'][0] == pytest.approx(tau**2 / 4, rel=1e-3)
    assert three['mean'][0] < 1e-3 * tau**2 / 4
    two = _reading_error_harmonics({**base, 'encoder_out_heads_deg': [0.0, 180.0]}, (2,))
    assert two['mean'][0] == pytest.approx(tau**2 / 4, rel=1e-3)
