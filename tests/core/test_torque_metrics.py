"""Efficiency, no-load torque and breakaway metrics (core.torque_metrics) against truths
computed here, not by the metric code:

* efficiency: the energy balance of the simulated bench, eta = 1 - P_loss / P_in, with the
  loss power summed from the loss laws (a separate path from the input torque in sim);
  with class transducers the measured eta lies within its expanded uncertainty;
* no-load torque: Palmgren M0 + churning + seal computed in this file from the preset's
  numbers and the Walther viscosity law;
* starting / back-driving torque: the friction model's static values, within the ramp's
  detection bias (ramp rate x time to travel the threshold, bounded here in closed form).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.torque_metrics import (
    breakaway_torque,
    class_uncertainty_nm,
    efficiency_point,
    no_load_torque,
)
from rv_te_bench.errors import TeInputError
from sim.breakaway import back_driving_ramp, ramp_breakaway, starting_ramp
from sim.loss_bench import LossConfig
from sim.losses import LossModel
from sim.presets import load_preset
from sim.program import DriveSegment, ProgramSimulator

RPM = 2 * math.pi / 60
IDEAL = LossConfig(torque_in='ideal-torque', torque_out='ideal-torque',
                   temperature='ideal-temperature')


def _run(losses: LossConfig, speed_rpm: float, load_nm: float, seconds: float = 2.0,
         preset: str = 'rv-80e-101') -> dict[str, np.ndarray]:
    sim = ProgramSimulator(preset=preset, te_mode='nlte' if preset.startswith('wang')
                           else 'elastic', sample_rate_hz=1000.0, block_size=100, seed=3,
                           losses=losses)
    sim.load([DriveSegment(speed_rpm=speed_rpm, duration_s=seconds, load_nm=load_nm)])
    blocks = []
    while sim.running:
        blocks.append(sim.next_block()[0])
    keys = ('theta_in_rad', 'theta_out_rad', 'torque_in_nm', 'torque_in_true_nm',
            'torque_out_meas_nm', 'torque_out_nm', 'temp_case_degc', 'power_loss_w')
    out = {k: np.concatenate([getattr(b, k) for b in blocks]) for k in keys}
    out['time_s'] = np.concatenate([b.t0_s + b.time_offset_s for b in blocks])
    out['sim'] = sim
    return out


@pytest.mark.parametrize(('speed_rpm', 'load_nm'), [(1000.0, 784.0), (1000.0, 447.0),
                                                    (-500.0, -300.0), (2000.0, 100.0)])
def test_efficiency_energy_balance_ideal_sensors(speed_rpm: float, load_nm: float) -> None:
    """Ideal transducers: eta = 1 - mean(P_loss) / mean(P_in) to 1e-6 (the TE ripple of
    the output speed averages out over the window)."""
    d = _run(IDEAL, speed_rpm, load_nm)
    p = efficiency_point(d['time_s'], d['theta_in_rad'], d['theta_out_rad'],
                         d['torque_in_nm'], d['torque_out_meas_nm'], u_class_in_nm=0.0,
                         u_class_out_nm=0.0)
    w = speed_rpm * RPM
    p_in = float(np.mean(d['torque_in_true_nm'] * w))
    truth = 1.0 - float(np.mean(d['power_loss_w'])) / p_in
    assert p.efficiency == pytest.approx(truth, abs=1e-4)
    assert 0.0 < p.efficiency < 1.0
    assert p.omega_in_rad_s == pytest.approx(w, rel=1e-6)
    assert p.power_loss_w == pytest.approx(float(np.mean(d['power_loss_w'])), rel=2e-3)


def test_efficiency_at_the_calibration_point_is_the_catalogue_78_percent() -> None:
    """The preset's calibration identity (HFUC-20-80 example: 78 % at rated, 1000 rpm,
    20 degC) read back through the bench's channels and the metric."""
    d = _run(IDEAL, 1000.0, 784.0, seconds=0.5)
    p = efficiency_point(d['time_s'], d['theta_in_rad'], d['theta_out_rad'],
                         d['torque_in_nm'], d['torque_out_meas_nm'], u_class_in_nm=0.0,
                         u_class_out_nm=0.0)
    assert p.efficiency == pytest.approx(0.78, abs=0.002)


def test_efficiency_uncertainty_covers_class_sensor_errors() -> None:
    """Class-0.05 transducers (sim: zero c/4, gain c/4, noise c/2 at 3 sigma): the
    measured eta lies within its k=2 uncertainty of the energy-balance truth, and the
    uncertainty is the propagation computed here from c FS / sqrt(3)."""
    d = _run(LossConfig(), 1000.0, 392.0)
    ch = d['sim'].losses.specs
    u_in = class_uncertainty_nm(ch['torque_in'].full_scale, ch['torque_in'].accuracy_class_pct)
    u_out = class_uncertainty_nm(ch['torque_out'].full_scale,
                                 ch['torque_out'].accuracy_class_pct)
    p = efficiency_point(d['time_s'], d['theta_in_rad'], d['theta_out_rad'],
                         d['torque_in_nm'], d['torque_out_meas_nm'], u_class_in_nm=u_in,
                         u_class_out_nm=u_out)
    w = 1000.0 * RPM
    truth = 1.0 - float(np.mean(d['power_loss_w'])) / float(np.mean(d['torque_in_true_nm'] * w))
    assert abs(p.efficiency - truth) < p.expanded_efficiency
    assert abs(p.efficiency - truth) > 1e-5          # the sensors did err
    rel = math.hypot(u_in / p.torque_in_nm, u_out / p.torque_out_nm)
    assert p.u_efficiency == pytest.approx(p.efficiency * rel, rel=0.05)


def test_efficiency_refuses_standstill_and_reverse_power() -> None:
    t = np.linspace(0, 1, 100)
    with pytest.raises(TeInputError, match='did not turn'):
        efficiency_point(t, np.zeros(100), np.zeros(100), np.ones(100), np.ones(100),
                         u_class_in_nm=0, u_class_out_nm=0)
    with pytest.raises(TeInputError, match='no power'):
        efficiency_point(t, t * 100, t, -np.ones(100), np.ones(100), u_class_in_nm=0,
                         u_class_out_nm=0)
    with pytest.raises(TeInputError, match='torque_out_nm has 99'):
        efficiency_point(t, t, t, t, t[:99], u_class_in_nm=0, u_class_out_nm=0)


def _walther_nu(temp_degc: float, nu40: float, nu100: float) -> float:
    """ASTM D341 written out here (log log (nu + 0.7) linear in log T)."""
    y = [math.log10(math.log10(v + 0.7)) for v in (nu40, nu100)]
    x = [math.log10(t + 273.15) for t in (40.0, 100.0)]
    b = (y[0] - y[1]) / (x[1] - x[0])
    a = y[0] + b * x[0]
    return 10 ** 10 ** (a - b * math.log10(temp_degc + 273.15)) - 0.7


@pytest.mark.parametrize('speed_rpm', [250.0, 1000.0, 2000.0, 3000.0])
def test_no_load_torque_against_the_loss_laws_written_out(speed_rpm: float) -> None:
    d = _run(IDEAL, speed_rpm, 0.0, seconds=0.5)
    p = no_load_torque(d['time_s'], d['theta_in_rad'], d['torque_in_nm'], u_class_nm=0.0,
                       temp_case_degc=d['temp_case_degc'])
    pre = load_preset('rv-80e-101')
    ls, lub = pre.section('losses'), pre.section('lubricant')
    from sim.kinematics import kinematics_from_preset

    rb = abs(float(kinematics_from_preset(pre).crank_rel_per_input))
    nu = _walther_nu(p.temp_case_degc, lub['nu40_mm2_s'], lub['nu100_mm2_s'])
    nu_ref = _walther_nu(ls['reference_temp_degc'], lub['nu40_mm2_s'], lub['nu100_mm2_s'])
    n_b = speed_rpm * rb
    m0 = 1e-7 * ls['bearing_f0'] * max(nu * n_b, 160 ** 1.5) ** (2 / 3) \
        * (ls['bearing_dm_m'] * 1e3) ** 3 * 1e-3
    churn = ls['churn_torque_ref_nm'] * (speed_rpm / ls['reference_speed_rpm']) \
        ** ls['churn_speed_exp'] * (nu / nu_ref) ** ls['churn_visc_exp']
    truth = rb * ls['bearing_count'] * m0 + churn + ls['seal_torque_nm']
    assert p.torque_nm == pytest.approx(truth, rel=1e-3)
    assert p.temp_case_degc == pytest.approx(20.0, abs=0.5)


def _detection_bias_nm(ts: float, tk: float, j: float, rate: float, thr: float,
                       fs: float) -> float:
    """Upper bound of the torque added between breakaway and detection: the shaft travels
    at least (T_s - T_k) d^2 / (2 J) in a time d after breakaway, so it passes the
    threshold by d = sqrt(2 J thr / (T_s - T_k)), plus one sample."""
    return rate * (math.sqrt(2.0 * j * thr / (ts - tk)) + 1.0 / fs)


@pytest.mark.parametrize('direction', [1, -1])
def test_starting_torque_is_the_friction_models_static_value(direction: int) -> None:
    model = LossModel.from_preset(load_preset('rv-80e-101'))
    ts = float(model.starting_torque_nm(0.0))
    rate, fs, thr = 0.2, 2000.0, 2e-4
    rec = starting_ramp(model, ramp_rate_nm_s=rate, sample_rate_hz=fs,
                        duration_s=2 * ts / rate, direction=direction)
    b = breakaway_torque(rec.time_s, rec.torque_nm, rec.angle_rad, threshold_rad=thr)
    assert b.found
    bias = _detection_bias_nm(ts, ts / model.params.static_to_kinetic,
                              model.params.inertia_in_kgm2, rate, thr, fs)
    assert ts <= b.torque_nm <= ts + bias
    assert b.torque_before_nm < b.torque_nm
    assert b.ramp_rate_nm_s == pytest.approx(rate, rel=1e-9)
    assert bias < 0.01 * ts          # the stated ramp and threshold: < 1 % bias


def test_back_driving_torque_is_the_friction_models_value() -> None:
    model = LossModel.from_preset(load_preset('rv-80e-101'))
    tbd = model.back_driving_torque_nm()
    assert math.isfinite(tbd)
    rate, fs, thr = 20.0, 2000.0, 2e-5
    rec = back_driving_ramp(model, ramp_rate_nm_s=rate, sample_rate_hz=fs,
                            duration_s=1.5 * tbd / rate)
    b = breakaway_torque(rec.time_s, rec.torque_nm, rec.angle_rad, threshold_rad=thr)
    j = model.params.inertia_in_kgm2 * model.params.gear_ratio ** 2
    bias = _detection_bias_nm(tbd, tbd / model.params.static_to_kinetic, j, rate, thr, fs)
    assert tbd <= b.torque_nm <= tbd + bias
    assert bias < 0.02 * tbd


def test_self_locking_gear_never_breaks_away() -> None:
    rec = ramp_breakaway(breakaway_nm=math.inf, kinetic_nm=0.0, inertia_kgm2=1.0,
                         ramp_rate_nm_s=10.0, sample_rate_hz=100.0, duration_s=5.0)
    b = breakaway_torque(rec.time_s, rec.torque_nm, rec.angle_rad, threshold_rad=1e-4)
    assert not b.found and math.isnan(b.torque_nm)
    assert b.max_torque_nm == pytest.approx(50.0)


def test_breakaway_angle_is_the_closed_form() -> None:
    """One sample checked against J theta'' = r t - T_k integrated numerically here."""
    rec = ramp_breakaway(breakaway_nm=2.0, kinetic_nm=1.0, inertia_kgm2=0.01,
                         ramp_rate_nm_s=1.0, sample_rate_hz=1000.0, duration_s=3.0)
    tb = 2.0
    tt = np.linspace(tb, 3.0, 200001)
    acc = (tt - 1.0) / 0.01
    vel = np.concatenate(([0.0], np.cumsum(0.5 * (acc[1:] + acc[:-1]) * np.diff(tt))))
    ang = np.concatenate(([0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * np.diff(tt))))
    assert rec.angle_rad[-1] == pytest.approx(ang[-1], rel=1e-6)
    assert np.all(rec.angle_rad[rec.time_s <= tb] == 0.0)


def test_threshold_must_be_positive() -> None:
    t = np.linspace(0, 1, 10)
    with pytest.raises(TeInputError, match='threshold_rad'):
        breakaway_torque(t, t, t, threshold_rad=0.0)
