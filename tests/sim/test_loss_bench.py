"""The loss channels wired into the bench and program simulators (sim.loss_bench).

* Off by default, and off means unchanged: the committed sample session (written by an
  earlier build, read back here with rosbags) is reproduced bit for bit; switching losses
  on changes no angle or TE sample either.
* On: the channels obey the energy balance, the case temperature follows the analytic step
  response when the losses do not depend on it, a locked program segment dissipates
  nothing and the case cools exponentially, and the transducers add their stated errors.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sim.bench import BenchConfig, BenchSimulator
from sim.bench_sensors import torque_sensor
from sim.drive import ConstantLoad, ConstantSpeed, SinusoidalSpeed
from sim.errors import ModelInputError, PresetError
from sim.loss_bench import LossConfig
from sim.losses import LossModel
from sim.presets import load_preset
from sim.program import DriveSegment, ProgramSimulator, TorqueSegment
from sim.thermal import ThermalParams

SAMPLE = Path(__file__).resolve().parents[2] / 'bags' / 'sample'
RPM = 2 * math.pi / 60
IDEAL = LossConfig(torque_in='ideal-torque', torque_out='ideal-torque',
                   temperature='ideal-temperature')


@pytest.mark.skipif(not SAMPLE.is_dir(), reason='bags/sample not generated')
def test_sample_session_reproduced_bit_for_bit() -> None:
    """bags/sample (bags/make_sample.py's settings) against today's simulator, losses off
    and on: every theta and torque sample identical."""
    from rosbags.highlevel import AnyReader

    from rv_te_bench.io.msgdefs import rv_te_typestore

    blocks = []
    with AnyReader([SAMPLE], default_typestore=rv_te_typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == '/bench/encoders']
        for conn, _, raw in reader.messages(connections=conns):
            blocks.append(reader.deserialize(raw, conn.msgtype))
    assert len(blocks) == 320
    for losses in (None, LossConfig()):
        sim = BenchSimulator(BenchConfig(
            preset='wang2020-2kv', drive=ConstantSpeed(300.0), te_mode='nlte',
            sample_rate_hz=1000.0, block_size=100, seed=2020, bench_id='sample-bench',
            losses=losses))
        for msg in blocks[:40]:
            b = sim.next_block()
            assert b.seq == msg.seq
            assert np.array_equal(b.theta_in_rad, msg.theta_in_rad)
            assert np.array_equal(b.theta_out_rad, msg.theta_out_rad)
            assert np.array_equal(b.torque_out_nm, msg.torque_out_nm)
            assert (b.power_loss_w is None) == (losses is None)


@pytest.mark.parametrize(('preset', 'mode'), [('rv-80e-101', 'geometric'),
                                              ('li2023-rv', 'dte')])
def test_losses_change_no_angle_or_te(preset: str, mode: str) -> None:
    kw = {'preset': preset, 'te_mode': mode, 'drive': ConstantSpeed(1500.0),
          'load': ConstantLoad(200.0), 'sample_rate_hz': 2000.0, 'block_size': 200, 'seed': 3}
    off, on = BenchSimulator(BenchConfig(**kw)), BenchSimulator(BenchConfig(
        **kw, losses=LossConfig()))
    for _ in range(5):
        a, b = off.next_block(), on.next_block()
        for f in ('theta_in_rad', 'theta_out_rad', 'te_true_rad', 'torque_out_nm'):
            assert np.array_equal(getattr(a, f), getattr(b, f))
        assert a.torque_in_nm is None and b.torque_in_nm is not None


def test_bench_energy_balance_and_efficiency() -> None:
    """Constant 1000 rpm against the rated torque, ideal transducers: per sample
    T_in w - T_out w / i = P_loss, and the efficiency at the first sample (20 degC) is the
    preset's calibration value."""
    sim = BenchSimulator(BenchConfig(
        preset='rv-80e-101', te_mode='geometric', drive=ConstantSpeed(1000.0),
        load=ConstantLoad(784.0), sample_rate_hz=1000.0, block_size=500, losses=IDEAL))
    i = sim.kinematics.gear_ratio
    w = 1000.0 * RPM
    b = sim.next_block()
    p_in, p_out = b.torque_in_true_nm * w, b.torque_out_nm * w / i
    np.testing.assert_allclose(p_in - p_out, b.power_loss_w, rtol=1e-12)
    np.testing.assert_array_equal(b.torque_in_nm, b.torque_in_true_nm)
    assert p_out[0] / p_in[0] == pytest.approx(0.78, abs=1e-4)
    assert b.temp_case_true_degc[0] == 20.0


def test_case_temperature_follows_the_step_response() -> None:
    """With the viscosity dependence switched off the loss is constant, so the bench's
    case temperature must be T_amb + P/G (1 - exp(-t/tau)) (written out here)."""
    overrides = ('losses.bearing_f0=0.0', 'losses.mesh_visc_exp=0.0',
                 'losses.churn_visc_exp=0.0')
    cfg = BenchConfig(preset='rv-80e-101', te_mode='geometric', overrides=overrides,
                      drive=ConstantSpeed(1500.0), load=ConstantLoad(600.0),
                      sample_rate_hz=100.0, block_size=1000, losses=IDEAL)
    sim = BenchSimulator(cfg)
    th = ThermalParams.from_preset(load_preset('rv-80e-101'))
    n_blocks = round(2 * th.time_constant_s * 100 / 1000)
    temp = np.concatenate([sim.next_block().temp_case_true_degc for _ in range(n_blocks)])
    p = sim.next_block().power_loss_w[0]
    t = np.arange(temp.size) / 100.0
    want = 20.0 + p / th.conductance_w_k * (1 - np.exp(-t / th.time_constant_s))
    np.testing.assert_allclose(temp, want, atol=1e-9)
    sim.reset()
    assert sim.next_block().temp_case_true_degc[0] == 20.0


def test_warm_case_lowers_the_loss() -> None:
    """Full model: as the case warms the viscosity falls and so does the loss power."""
    sim = BenchSimulator(BenchConfig(
        preset='rv-80e-101', te_mode='geometric', drive=ConstantSpeed(1500.0),
        load=ConstantLoad(784.0), sample_rate_hz=200.0, block_size=2000, losses=IDEAL))
    first = sim.next_block()
    for _ in range(30):
        last = sim.next_block()
    assert last.temp_case_true_degc[-1] > first.temp_case_true_degc[0] + 5.0
    assert last.power_loss_w[-1] < first.power_loss_w[0]


def test_program_locked_segment_cools_and_reads_the_reaction() -> None:
    ps = ProgramSimulator(preset='rv-80e-101', te_mode='geometric', sample_rate_hz=100.0,
                          block_size=100, losses=IDEAL)
    ps.load((DriveSegment(1500.0, 120.0, 784.0), TorqueSegment(300.0, 60.0)))
    drive, locked = [], []
    while ps.running:
        b, k = ps.next_block()
        (drive if k == 0 else locked).append(b)
    assert all(np.all(b.power_loss_w > 0) for b in drive)
    t0 = locked[0].temp_case_true_degc[0]
    temp = np.concatenate([b.temp_case_true_degc for b in locked])
    tau = ThermalParams.from_preset(load_preset('rv-80e-101')).time_constant_s
    np.testing.assert_allclose(temp, 20.0 + (t0 - 20.0) * np.exp(-np.arange(temp.size) / 100
                                                                 / tau), atol=1e-9)
    i = ps.gear_ratio
    for b in locked:
        np.testing.assert_array_equal(b.power_loss_w, 0.0)
        np.testing.assert_allclose(b.torque_in_true_nm, b.torque_out_nm / i)
        np.testing.assert_array_equal(b.torque_out_meas_nm, b.torque_out_nm)


def test_transducers_add_their_errors_and_are_seeded() -> None:
    spec = torque_sensor(20.0, 0.1)
    cfg = BenchConfig(preset='rv-80e-101', te_mode='geometric', drive=ConstantSpeed(1000.0),
                      load=ConstantLoad(400.0), sample_rate_hz=1000.0, block_size=20_000,
                      seed=11, losses=LossConfig(torque_in=spec))
    a, b = BenchSimulator(cfg).next_block(), BenchSimulator(cfg).next_block()
    np.testing.assert_array_equal(a.torque_in_nm, b.torque_in_nm)
    err = a.torque_in_nm - a.torque_in_true_nm
    bias = spec.zero_offset + spec.gain_error * a.torque_in_true_nm.mean()
    assert err.mean() == pytest.approx(bias, abs=5 * spec.noise_rms / math.sqrt(err.size))
    assert err.std() == pytest.approx(spec.noise_rms, rel=0.03)


def test_inertia_shows_in_the_input_torque() -> None:
    """Hu 2020's sinusoidal input: T_in - steady part = J_in dw/dt (dw/dt of the profile)."""
    drive = SinusoidalSpeed(amplitude_rpm=200.0, angular_freq_rad_s=30.0, mean_rpm=1000.0)
    sim = BenchSimulator(BenchConfig(
        preset='rv-80e-101', te_mode='geometric', drive=drive, load=ConstantLoad(300.0),
        sample_rate_hz=5000.0, block_size=1000, losses=IDEAL))
    b = sim.next_block()
    t = b.t0_s + b.time_offset_s
    m = LossModel.from_preset(load_preset('rv-80e-101'))
    w = drive.omega_in_rad_s(t)
    steady = m.input_torque_nm(w, 300.0, 20.0)
    alpha = 200.0 * RPM * 30.0 * np.cos(30.0 * t)
    inner = slice(1, -1)   # the block's end samples use one-sided differences
    np.testing.assert_allclose((b.torque_in_true_nm - steady)[inner],
                               m.params.inertia_in_kgm2 * alpha[inner], rtol=2e-4, atol=1e-9)


def test_config_errors_and_record() -> None:
    with pytest.raises(ModelInputError, match=r'BenchConfig\.losses must be a LossConfig'):
        BenchConfig(preset='rv-80e-101', drive=ConstantSpeed(10.0), losses=True)  # type: ignore[arg-type]
    with pytest.raises(PresetError, match="unknown sensor 'hbm-x'"):
        LossConfig(torque_in='hbm-x')
    with pytest.raises(ModelInputError, match=r'accuracy_class_pct must be finite and > 0'):
        LossConfig(accuracy_class_pct=0.0)
    plain = BenchConfig(preset='rv-80e-101', drive=ConstantSpeed(10.0)).to_plain()
    assert 'losses' not in plain
    rec = BenchConfig(preset='rv-80e-101', drive=ConstantSpeed(10.0),
                      losses=LossConfig(ambient_degc=25.0)).to_plain()['losses']
    assert rec['ambient_degc'] == 25.0 and rec['temperature'] == 'pt100-class-a'
    with pytest.raises(ModelInputError, match='losses must be a LossConfig'):
        ProgramSimulator(preset='rv-80e-101', te_mode='geometric', losses='yes')  # type: ignore[arg-type]
