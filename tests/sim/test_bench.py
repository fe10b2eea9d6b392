"""Tests of sim.bench.BenchSimulator with a closed-form fake TE model (and the real presets).

Fake model: TE = A sin(k theta_in / i + phi) + c * load, on the Wang 2020 2K-V kinematics
(i = 79), so the expected TE is known in closed form at every sample.
"""

from __future__ import annotations

import math
import tracemalloc
from dataclasses import dataclass, field

import numpy as np
import pytest
import yaml

from sim.bench import BenchConfig, BenchSimulator
from sim.drive import ConstantLoad, ConstantSpeed, SinusoidalLoad, SinusoidalSpeed, drive_from_spec
from sim.encoders import encoder_preset, encoder_spec_with
from sim.errors import ModelInputError, PresetError
from sim.kinematics import ReducerKinematics, kinematics_from_preset
from sim.presets import Preset, preset_from_text

GEAR_RATIO = 79.0  # 1 + (36/12) * 52/(52-50), DESIGN.md s.4
ARCMIN = math.pi / 10800.0

FAKE_TOML = """
name = "fake-2kv"
model = "fake"
description = "Wang 2020 2K-V kinematics with a closed-form TE, for bench tests"
[kinematics]
kind = "2kv"
z_sun = { value = 12, unit = "1", source = "Wang 2020 Table 1" }
z_planet = { value = 36, unit = "1", source = "Wang 2020 Table 1" }
z_gear = { value = 50, unit = "1", source = "Wang 2020 Table 1" }
z_ring = { value = 52, unit = "1", source = "Wang 2020 Table 1" }
[te]
amplitude_rad = { value = 3.0e-4, unit = "rad", source = "test" }
order_out = { value = 25.0, unit = "1", source = "test: crank order" }
"""


@dataclass
class FakeTeModel:
    """TE = A sin(k theta_in / i + phi) + c * load; records its calls."""

    kinematics: ReducerKinematics
    amplitude_rad: float
    order_out: float
    phase_rad: float = 0.4
    compliance_rad_per_nm: float = 1e-7
    calls: list = field(default_factory=list)
    resets: int = 0

    def te_rad(self, t_s, theta_in_rad, omega_in_rad_s, load_nm):
        self.calls.append((t_s.copy(), omega_in_rad_s.copy(), load_nm.copy()))
        del self.calls[:-1]  # keep only the last call (flat memory)
        return self.expected(theta_in_rad, load_nm)

    def expected(self, theta_in_rad, load_nm):
        i = self.kinematics.gear_ratio
        return (self.amplitude_rad * np.sin(self.order_out * theta_in_rad / i + self.phase_rad)
                + self.compliance_rad_per_nm * load_nm)

    def reset(self) -> None:
        self.resets += 1


def fake_preset() -> Preset:
    return preset_from_text(FAKE_TOML, 'fake')


def make_sim(**cfg) -> tuple[BenchSimulator, FakeTeModel]:
    preset = fake_preset().with_overrides(list(cfg.get('overrides', ())))
    model = FakeTeModel(kinematics_from_preset(preset), preset['te.amplitude_rad'],
                        preset['te.order_out'])
    base = {'preset': 'fake-2kv', 'drive': ConstantSpeed(300.0), 'encoder_in': 'ideal',
            'encoder_out': 'ideal', 'sample_rate_hz': 10_000.0, 'block_size': 1000, 'seed': 1}
    base.update(cfg)
    return BenchSimulator(BenchConfig(**base), preset=fake_preset(), model=model), model


def run(sim: BenchSimulator, n_blocks: int) -> dict[str, np.ndarray]:
    blocks = [sim.next_block() for _ in range(n_blocks)]
    out = {name: np.concatenate([getattr(b, name) for b in blocks])
           for name in ('time_offset_s', 'theta_in_rad', 'theta_out_rad', 'torque_out_nm',
                        'te_true_rad', 'theta_in_true_rad', 'theta_out_true_rad')}
    out['t_s'] = np.concatenate([b.t0_s + b.time_offset_s for b in blocks])
    out['seq'] = np.array([b.seq for b in blocks])
    return out


@pytest.mark.parametrize('start_time_s', [0.0, 1.0e6])
@pytest.mark.parametrize('drive', [
    ConstantSpeed(300.0),
    SinusoidalSpeed(amplitude_rpm=100.0, angular_freq_rad_s=7.0, mean_rpm=300.0),
])
def test_ideal_encoders_give_the_model_te(start_time_s: float, drive) -> None:
    """TE from the readings, theta_out - theta_in / 79, equals the closed-form TE within
    1e-9 rad, also 1e6 s (11.6 days, theta_in ~ 3e7 rad) into a session."""
    sim, model = make_sim(drive=drive, start_time_s=start_time_s,
                          load=SinusoidalLoad(30.0, 10.0, 1.5))
    d = run(sim, 5)
    theta_in_true = drive.theta_in_rad(d['t_s'])
    np.testing.assert_allclose(d['theta_in_true_rad'], theta_in_true, rtol=1e-15, atol=0)
    load = 30.0 + 10.0 * np.sin(2 * math.pi * 1.5 * d['t_s'])
    np.testing.assert_allclose(d['torque_out_nm'], load, rtol=0, atol=1e-12)
    te_expected = model.expected(theta_in_true, load)
    np.testing.assert_allclose(d['te_true_rad'], te_expected, rtol=0, atol=1e-12)
    te_measured = d['theta_out_rad'] - d['theta_in_rad'] / GEAR_RATIO
    np.testing.assert_allclose(te_measured, te_expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(d['theta_in_rad'], d['theta_in_true_rad'])
    # the model saw the drive's speed and the load on the same clock
    t_last, omega_last, load_last = model.calls[-1]
    np.testing.assert_allclose(omega_last, drive.omega_in_rad_s(t_last), rtol=1e-15)
    np.testing.assert_allclose(load_last, 30.0 + 10.0 * np.sin(2 * math.pi * 1.5 * t_last),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(t_last, d['t_s'][-1000:], rtol=0, atol=0)


def test_quantisation_only_te_error_statistics() -> None:
    """RON 886 counts (q = 2 pi / 36e6) with every error term off. Per shaft the floor error
    is uniform on (-q, 0]: TE error mean = -q/2 + q/(2 i), std = sqrt(q^2/12 + q^2/(12 i^2)).
    20,000 samples: std within 3 % (sampling ~0.5 %), mean within 0.02 q (sampling 0.002 q)."""
    spec = encoder_spec_with(encoder_preset('heidenhain-ron886'), graduation_orders=(),
                             graduation_amplitudes_rad=(), graduation_phases_rad=(),
                             eccentricity_amplitude_rad=0.0, noise_sigma_rad=0.0)
    sim, _ = make_sim(drive=ConstantSpeed(2371.3), encoder_in=spec, encoder_out=spec)
    d = run(sim, 20)
    q = 2 * math.pi / 36e6
    diff = (d['theta_out_rad'] - d['theta_in_rad'] / GEAR_RATIO) - d['te_true_rad']
    assert diff.std() == pytest.approx(math.sqrt(q * q / 12 + q * q / (12 * GEAR_RATIO**2)),
                                       rel=0.03)
    assert diff.mean() == pytest.approx(-q / 2 + q / (2 * GEAR_RATIO), abs=0.02 * q)


def test_ron886_te_error_rms() -> None:
    """Full RON 886 preset on both shafts, exactly about one output revolution (2371.3 rpm:
    f_out = 0.50027 Hz, 19,989 samples; 20,000 taken). Expected variance of the TE error,
    computed from the preset fields (orders 2, 3, 4, 36000 distinct, 1/rev eccentricity):
    v = q^2/12 + sum a^2/2 + e^2/2 + sigma^2 for the output, the same / i^2 for the input.
    Tolerance 3 % on the standard deviation (one revolution, sampled harmonics + noise)."""
    spec = encoder_preset('heidenhain-ron886')
    sim, _ = make_sim(drive=ConstantSpeed(2371.3), encoder_in='heidenhain-ron886',
                      encoder_out='heidenhain-ron886', seed=5)
    d = run(sim, 20)
    q = 2 * math.pi / 36e6
    per_shaft = (q * q / 12 + sum(a * a for a in spec.graduation_amplitudes_rad) / 2
                 + spec.eccentricity_amplitude_rad ** 2 / 2 + spec.noise_sigma_rad ** 2)
    expected_std = math.sqrt(per_shaft * (1 + 1 / GEAR_RATIO ** 2))
    diff = (d['theta_out_rad'] - d['theta_in_rad'] / GEAR_RATIO) - d['te_true_rad']
    assert diff.std() == pytest.approx(expected_std, rel=0.03)
    # ~0.36 arcsec: an arcsecond-class encoder against an arcminute-class TE
    assert 0.3 * math.pi / 648000 < diff.std() < 0.4 * math.pi / 648000


def test_same_seed_same_data_other_seed_other_noise() -> None:
    kw = {'encoder_in': 'heidenhain-ron886', 'encoder_out': 'renishaw-resm', 'block_size': 300}
    a = run(make_sim(seed=11, **kw)[0], 3)
    b = run(make_sim(seed=11, **kw)[0], 3)
    c = run(make_sim(seed=12, **kw)[0], 3)
    for key, arr in a.items():
        np.testing.assert_array_equal(arr, b[key])
    np.testing.assert_array_equal(a['te_true_rad'], c['te_true_rad'])
    assert not np.array_equal(a['theta_out_rad'], c['theta_out_rad'])
    assert not np.array_equal(a['theta_in_rad'], c['theta_in_rad'])


def test_data_do_not_depend_on_the_block_size() -> None:
    """Ten blocks of 100 = one block of 1000: true angles within 1e-12 rad (t0 + offset
    rounding), readings within one count (the noise stream is drawn in the same order)."""
    kw = {'encoder_in': 'heidenhain-ron886', 'encoder_out': 'renishaw-resm', 'seed': 3}
    a = run(make_sim(block_size=100, **kw)[0], 10)
    b = run(make_sim(block_size=1000, **kw)[0], 1)
    for key in ('theta_in_true_rad', 'theta_out_true_rad', 'te_true_rad', 't_s'):
        np.testing.assert_allclose(a[key], b[key], rtol=0, atol=1e-12)
    q = 2 * math.pi / 36e6
    np.testing.assert_allclose(a['theta_in_rad'], b['theta_in_rad'], rtol=0, atol=1.01 * q)
    np.testing.assert_allclose(a['theta_out_rad'], b['theta_out_rad'], rtol=0, atol=1.01 * q)


def test_sequence_and_time_are_contiguous() -> None:
    sim, _ = make_sim(block_size=250, sample_rate_hz=250.0, start_time_s=1.0e5)
    blocks = [sim.next_block() for _ in range(8)]
    assert [b.seq for b in blocks] == list(range(8))
    for b in blocks:
        assert b.time_offset_s[0] == 0.0
        assert b.time_offset_s.size == 250
        assert not b.theta_out_rad.flags.writeable
    t = np.concatenate([b.t0_s + b.time_offset_s for b in blocks])
    dt = np.diff(t)
    assert np.all(dt > 0)
    # float64 at 1e5 s has an ulp of 1.46e-11 s: each difference is within two ulps of 4 ms
    np.testing.assert_allclose(dt, 1 / 250.0, rtol=0, atol=3e-11)
    assert blocks[3].t0_s == pytest.approx(1.0e5 + 3.0, abs=1e-9)
    assert sim.seq == 8


def test_reset_restarts_the_session() -> None:
    sim, model = make_sim(encoder_in='heidenhain-ron886', encoder_out='heidenhain-ron886')
    first = sim.next_block()
    sim.next_block()
    sim.reset()
    assert model.resets == 1
    again = sim.next_block()
    assert again.seq == 0
    np.testing.assert_array_equal(again.theta_out_rad, first.theta_out_rad)
    np.testing.assert_array_equal(again.theta_in_rad, first.theta_in_rad)


def test_memory_is_flat_over_a_long_session() -> None:
    """300 blocks of 1000 samples (9 arrays x 8 kB each: 21 MB if kept) add < 200 kB."""
    sim, _ = make_sim(encoder_in='renishaw-resolute', encoder_out='renishaw-resolute')
    for _ in range(5):
        sim.next_block()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for _ in range(300):
            sim.next_block()
        after = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert after - before < 200_000


def test_info_describes_the_bench() -> None:
    sim, _ = make_sim(overrides=('te.amplitude_rad=2e-4',), encoder_in='heidenhain-ron886',
                      encoder_out='renishaw-resolute', bench_id='cell-3', block_size=500)
    info = sim.info
    assert info.bench_id == 'cell-3'
    assert info.preset == 'fake-2kv'
    assert info.reducer_type == '2kv'
    assert info.gear_ratio == pytest.approx(79.0, rel=1e-15)
    # absolute crank -25 x output, relative -26 x output (DESIGN.md s.4)
    assert info.crank_per_input == pytest.approx(-25 / 79, rel=1e-14)
    assert info.crank_rel_per_input == pytest.approx(-26 / 79, rel=1e-14)
    # stage 1: 36 teeth x 26 crank rel. revs per output rev; stage 2: 52 x 25
    assert info.mesh_orders == pytest.approx((36 * 26, 52 * 25), rel=1e-14)
    assert len(info.mesh_labels) == 2
    assert info.encoder_in_model == 'heidenhain-ron886'
    assert info.encoder_out_model == 'renishaw-resolute'
    assert info.encoder_in_resolution_rad == pytest.approx(2 * math.pi / 36e6, rel=1e-15)
    assert info.encoder_out_resolution_rad == pytest.approx(2 * math.pi / 2**32, rel=1e-15)
    assert info.sample_rate_hz == 10_000.0
    assert info.block_size == 500
    rec = yaml.safe_load(info.parameters_yaml)
    values = rec['preset']['values']
    assert set(values) == set(fake_preset().keys())
    assert values['te.amplitude_rad'] == 2e-4  # override applied
    assert values['kinematics.z_ring'] == 52
    assert rec['bench']['overrides'] == ['te.amplitude_rad=2e-4']
    assert rec['bench']['drive'] == {'kind': 'constant', 'speed_rpm': 300.0}
    assert rec['bench']['sample_rate_hz'] == 10_000.0
    assert rec['bench']['encoder_in']['counts_per_rev'] == 36_000_000


@pytest.mark.parametrize(('changes', 'exc', 'pattern'), [
    ({'sample_rate_hz': 0.0}, ModelInputError, r'sample_rate_hz must be finite and > 0, got 0.0'),
    ({'sample_rate_hz': -10.0}, ModelInputError, r'sample_rate_hz must be finite and > 0'),
    ({'sample_rate_hz': float('nan')}, ModelInputError, 'sample_rate_hz must be finite'),
    ({'block_size': 0}, ModelInputError, r'block_size must be an integer >= 1, got 0'),
    ({'block_size': 2.5}, ModelInputError, 'block_size must be an integer'),
    ({'seed': -1}, ModelInputError, 'seed must be an integer >= 0'),
    ({'te_mode': ''}, ModelInputError, 'te_mode must be a non-empty string'),
    ({'bench_id': ' '}, ModelInputError, 'bench_id must be a non-empty string'),
    ({'encoder_in': 'ron999'}, PresetError, "unknown encoder 'ron999'; known encoders"),
    ({'encoder_out': 'x'}, PresetError, "unknown encoder 'x'"),
    ({'drive': 'fast'}, ModelInputError, 'BenchConfig.drive must be a drive profile'),
    ({'load': 30.0}, ModelInputError, 'BenchConfig.load must be a load profile'),
    ({'overrides': 'a=1'}, ModelInputError, 'overrides must be a sequence'),
    ({'overrides': ('nokey',)}, PresetError, "override 'nokey' is not of the form key=value"),
    ({'start_time_s': float('inf')}, ModelInputError, 'start_time_s must be finite'),
])
def test_bad_configs_raise_naming_the_field(changes: dict, exc: type, pattern: str) -> None:
    base = {'preset': 'wang2020-2kv', 'drive': ConstantSpeed(300.0)}
    base.update(changes)
    with pytest.raises(exc, match=pattern):
        BenchConfig(**base)


def test_nonsense_drive_and_unknown_preset() -> None:
    with pytest.raises(ModelInputError, match='speed_rpm must be non-zero'):
        BenchConfig(preset='wang2020-2kv', drive=drive_from_spec('constant', speed_rpm=0.0))
    cfg = BenchConfig(preset='no-such-reducer', drive=ConstantSpeed(300.0))
    with pytest.raises(PresetError, match="unknown preset 'no-such-reducer'; known presets"):
        BenchSimulator(cfg)
    with pytest.raises(PresetError, match="unknown model 'fake'"):
        BenchSimulator(BenchConfig(preset='fake-2kv', drive=ConstantSpeed(300.0)),
                       preset=fake_preset())
    with pytest.raises(PresetError, match=r"has no key 'te\.amplitude'"):
        make_sim(overrides=('te.amplitude=1',))


def test_model_returning_a_wrong_shape_is_reported() -> None:
    sim, model = make_sim()
    model.expected = lambda th, load: np.zeros(3)  # type: ignore[method-assign]
    with pytest.raises(ModelInputError, match=r'TE model returned shape \(3,\)'):
        sim.next_block()


def test_default_load_is_zero() -> None:
    cfg = BenchConfig(preset='wang2020-2kv', drive=ConstantSpeed(300.0))
    assert cfg.load == ConstantLoad(0.0)
    assert cfg.encoder_in == 'heidenhain-ron886'


# --------------------------------------------------------------- the real wang2020-2kv preset

ARCMIN_PER_RAD = 10800.0 / math.pi


@pytest.fixture
def wang() -> None:
    """The Wang 2020 model (part of the tree: an import error fails the test)."""
    import sim.wang2020  # noqa: F401 - in the tree: an import error must fail


def wang_sim(mode: str, **cfg) -> BenchSimulator:
    base = {'preset': 'wang2020-2kv', 'te_mode': mode, 'drive': ConstantSpeed(300.0),
            'encoder_in': 'ideal', 'encoder_out': 'ideal', 'sample_rate_hz': 1000.0,
            'block_size': 1580, 'seed': 0}
    base.update(cfg)
    return BenchSimulator(BenchConfig(**base))


@pytest.mark.usefixtures('wang')
@pytest.mark.parametrize('mode', ['nlte', 'ste', 'dte'])
def test_wang2020_ideal_encoders_give_the_model_te(mode: str) -> None:
    sim = wang_sim(mode, load=ConstantLoad(30.0), sample_rate_hz=10_000.0, block_size=500,
                   start_time_s=3.6e4)
    d = run(sim, 4)
    np.testing.assert_allclose(d['theta_out_rad'] - d['theta_in_rad'] / 79.0, d['te_true_rad'],
                               rtol=0, atol=1e-9)
    assert np.ptp(d['te_true_rad']) > 1e-5  # a real TE signal (tens of arcsec), not zeros


@pytest.mark.usefixtures('wang')
def test_wang2020_nlte_through_the_bench() -> None:
    """300 rpm, 1 kHz: one output revolution = 15.8 s = 15,800 samples (10 blocks of 1580).
    Measured with RON 886 on both shafts, the TE p-p over a revolution is the paper's Fig. 5a
    2.23 arcmin (DESIGN.md s.4: reproduced within a few percent; encoder error adds < 0.03');
    tolerance 5 %. NLTE depends on the angle only: revolution 2 repeats revolution 1."""
    sim = wang_sim('nlte', encoder_in='heidenhain-ron886', encoder_out='heidenhain-ron886')
    d = run(sim, 20)
    rev = 15_800
    te_meas = d['theta_out_rad'] - d['theta_in_rad'] / 79.0
    assert np.ptp(te_meas[:rev]) * ARCMIN_PER_RAD == pytest.approx(2.23, rel=0.05)
    np.testing.assert_allclose(d['te_true_rad'][rev:], d['te_true_rad'][:rev], rtol=0,
                               atol=1e-12)


@pytest.mark.usefixtures('wang')
def test_wang2020_static_te_mean_under_30_nm() -> None:
    """The bench hands the load to the model: STE mean over one output revolution at 30 N m
    is the paper's -0.44858 arcmin (the preset's stiffness is chosen for it); tolerance 1 %."""
    d = run(wang_sim('ste', load=ConstantLoad(30.0)), 10)
    assert d['te_true_rad'].mean() * ARCMIN_PER_RAD == pytest.approx(-0.44858, rel=0.01)
    np.testing.assert_array_equal(d['torque_out_nm'], 30.0)


@pytest.mark.usefixtures('wang')
def test_wang2020_dte_state_is_carried_across_blocks() -> None:
    """20 blocks of 100 vs 2 blocks of 1000 at 10 kHz: the DTE agrees within 1e-7 rad
    (measured ~4e-10), far below the dynamic part (DTE - STE ~1e-5 rad with a 10 % mesh
    stiffness ripple; the preset has none since issue #18) that a restart at each block would
    disturb."""
    kw = {'load': ConstantLoad(30.0), 'sample_rate_hz': 10_000.0,
          'overrides': ('mesh.stiffness_harmonic_ratio=0.1',)}
    a = run(wang_sim('dte', block_size=100, **kw), 20)
    b = run(wang_sim('dte', block_size=1000, **kw), 2)
    np.testing.assert_allclose(a['te_true_rad'], b['te_true_rad'], rtol=0, atol=1e-7)
    s = run(wang_sim('ste', block_size=1000, **kw), 2)
    assert np.max(np.abs(b['te_true_rad'] - s['te_true_rad'])) > 1e-6


@pytest.mark.usefixtures('wang')
def test_wang2020_info() -> None:
    info = wang_sim('nlte', overrides=('mesh.damping_n_s_m=500.0',)).info
    assert info.preset == 'wang2020-2kv'
    assert info.reducer_type == '2kv'
    assert info.gear_ratio == pytest.approx(79.0, rel=1e-15)
    assert info.crank_per_input == pytest.approx(-25 / 79, rel=1e-14)
    values = yaml.safe_load(info.parameters_yaml)['preset']['values']
    assert values['mesh.stiffness_n_m'] == 8.43e7
    assert values['mesh.damping_n_s_m'] == 500.0
