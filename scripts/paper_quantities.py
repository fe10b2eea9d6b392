"""What the suite gives for each quantity of docs/paper_vs_suite.toml (Wang 2020, Hu 2020, Li 2023).

Each public function here is named by a row's ``calc`` and takes the row's ``args``; it returns
the suite's value in the row's unit, or for a qualitative row ``(holds, detail)``. The model
runs are cached (one per parameter set), so the whole table costs a few model runs. Used by
``scripts/paper_vs_suite.py`` and ``tests/sim/test_paper_vs_suite.py``; nothing here knows
the paper's values.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from sim.kinematics import kinematics_from_preset
from sim.presets import load_preset
from sim.units import rad_to_arcmin, rad_to_arcsec

W = 'wang2020-2kv'
PHASE_KEYS = ('eccentricity.theta_p1_0_deg', 'eccentricity.theta_p2_0_deg',
              'eccentricity.theta_g_0_deg', 'eccentricity.theta_ot_0_deg')
#: Wang 2020 phase sets (theta_p1, theta_p2, theta_g, theta_ot) [deg]: Table 2, the Eq. 21
#: optimum, Table 3's groups (group 3's theta_ot, not printed, is 130 deg).
PHASES = {'table2': (90.0, 180.0, -135.0, 90.0), 'optimum': (-70.0, 120.0, 110.0, 40.0),
          'g1': (0.0, -50.0, 130.0, 120.0), 'g2': (-60.0, 130.0, 100.0, 50.0),
          'g3': (90.0, 90.0, 180.0, 130.0)}
N_REV = 158_000                          # one output revolution at 10 kHz (15.8 s)
FS_HZ = 10_000.0
PEAK_PROMINENCE_ARCMIN = 0.02


def _stat(te: np.ndarray, stat: str) -> float:
    return float({'pp': np.ptp, 'amp': lambda a: np.max(np.abs(a)), 'mean': np.mean,
                  'std': np.std}[stat](te))


# ------------------------------------------------------------------------------ Wang 2020


@functools.cache
def _wang(phases: str, overrides: tuple[tuple[str, str], ...] = ()) -> Any:
    from sim.wang2020 import Wang2kvParams
    ov = dict(overrides)
    ov.update({k: repr(v) for k, v in zip(PHASE_KEYS, PHASES[phases], strict=True)})
    return Wang2kvParams.from_preset(load_preset(W, ov))


def _theta() -> np.ndarray:
    return np.linspace(0.0, 2.0 * math.pi, N_REV, endpoint=False)


@functools.cache
def _wang_curve(kind: str, phases: str, load: float) -> np.ndarray:
    """NLTE / STE / DTE (Table 4 start) over one output revolution at 10 kHz [arcmin]."""
    from sim.wang2020 import TABLE4_DTE_START, Wang2kvDynamics, nlte_rad, static_te_rad
    if kind == 'nlte':
        return rad_to_arcmin(nlte_rad(_theta(), _wang(phases)))
    if kind == 'ste':
        return rad_to_arcmin(static_te_rad(_theta(), load, _wang(phases)))
    p = _wang(phases, tuple(TABLE4_DTE_START.items()))
    t = np.arange(N_REV) / FS_HZ
    w = 2.0 * math.pi * p.input_speed_rpm / 60.0
    te = Wang2kvDynamics(p).te_rad(t, w * t, np.full(N_REV, w), np.full(N_REV, load))
    return rad_to_arcmin(te)


def wang_te(kind: str, phases: str, stat: str, load: float = 0.0) -> float:
    """Statistic of ``rv-te model wang2020-2kv --kind KIND`` over one output revolution."""
    return _stat(_wang_curve(kind, phases, float(load)), stat)


def wang_pair(pair: int, stat: str) -> float:
    """Fig. 4: NLTE of gear pair 1 or 2 (Wang 2020 Eq. 5), Table 2 phases [arcmin]."""
    from sim.wang2020 import nlte_pairs_rad
    return _stat(rad_to_arcmin(nlte_pairs_rad(_theta(), _wang('table2'))[pair - 1]), stat)


def wang_period_s() -> float:
    """Output period at the preset's 300 rpm input [s]."""
    kin = kinematics_from_preset(load_preset(W))
    return float(kin.output_period_s(load_preset(W)['drive.input_speed_rpm'] / 60.0))


def wang_peaks(phases: str) -> float:
    """NLTE peaks in the first 3 s (prominence 0.02')."""
    from scipy.signal import find_peaks
    te = _wang_curve('nlte', phases, 0.0)[:round(3.0 * FS_HZ)]
    return float(len(find_peaks(te, prominence=PEAK_PROMINENCE_ARCMIN)[0]))


def wang_amp_difference() -> float:
    """s.2.4.1: largest difference of the Table 3 groups' amplitudes [arcmin]."""
    amps = [wang_te('nlte', g, 'amp') for g in ('g1', 'g2', 'g3')]
    return max(amps) - min(amps)


@functools.cache
def _optimum_deg() -> tuple[float, ...]:
    from rv_te_bench.core.phases import optimise_phases
    res = optimise_phases(_wang('table2'), loads_nm=())
    return tuple(round(math.degrees(v), 6) for v in res.phases_after_rad)


def wang_optimum(index: int) -> float:
    """Wang 2020 Eq. 21 optimum on the 10 deg grid (``rv-te optimize-phases``) [deg]."""
    return _optimum_deg()[index]


def _lines(phases: str) -> np.ndarray:
    te = _wang_curve('nlte', phases, 0.0)
    return np.abs(np.fft.rfft(te - te.mean())) * 2.0 / te.size      # bin k: order k


def wang_largest_line(phases: str) -> tuple[bool, str]:
    """Fig. 16: is the largest NLTE line the crank line f_w (order 25 of the output)?"""
    amp = _lines(phases)
    k = int(np.argmax(amp[1:]) + 1)
    return k == 25, f'largest: order {k} ({amp[k]:.3f}\u2032), f_w {amp[25]:.3f}\u2032'


def wang_lines_lower() -> tuple[bool, str]:
    """Fig. 16: is every crank harmonic h f_w (h = 1..5) lower after optimisation?"""
    before, after = _lines('table2'), _lines('optimum')
    h = np.arange(1, 6) * 25
    up = [int(k // 25) for k in h if after[k] >= before[k]]
    if not up:
        return True, 'all five lower'
    k = up[0] * 25
    return False, f'{up[0]} f_w: {before[k]:.3f}\u2032 \u2192 {after[k]:.3f}\u2032'


def wang_all_lower() -> tuple[bool, str]:
    """Table 4 text: p-p, amplitude and std of every row lower after optimisation."""
    rows = [('nlte', 0.0)] + [(k, t) for k in ('ste', 'dte') for t in (30.0, 100.0, 300.0)]
    worse = [(k, t, s) for k, t in rows for s in ('pp', 'amp', 'std')
             if wang_te(k, 'optimum', s, t) >= wang_te(k, 'table2', s, t)]
    return not worse, 'all 21 lower' if not worse else f'not lower: {worse}'


def wang_load_nonlinear() -> tuple[bool, str]:
    """Figs 5b/6b: the mean TE per N m is larger at light load (one pair) than at heavy."""
    m = {t: wang_te('ste', 'table2', 'mean', t) for t in (30.0, 100.0, 300.0)}
    light, heavy = (m[100.0] - m[30.0]) / 70.0, (m[300.0] - m[100.0]) / 200.0
    return abs(light) > abs(heavy), f'{light * 1e3:.2f} vs {heavy * 1e3:.2f} m\u2032/N m'


def wang_one_pair_share(load: float, seconds: float = 0.0) -> float:
    """Share of the time with exactly one pair loaded (Eqs 10, 15) [%]; 0 s: the revolution."""
    from sim.wang2020 import contact_forces_n
    th = _theta() if not seconds else _theta()[:round(seconds * FS_HZ)]
    f1, f2 = contact_forces_n(th, load, _wang('table2'))
    return 100.0 * float(np.mean((f1 > 0) != (f2 > 0)))


def wang_both_pairs_share(load: float) -> float:
    """Share of the revolution with both pairs loaded (Eqs 10, 15) [%]."""
    from sim.wang2020 import contact_forces_n
    f1, f2 = contact_forces_n(_theta(), load, _wang('table2'))
    return 100.0 * float(np.mean((f1 > 0) & (f2 > 0)))


def wang_share_threshold_arcmin(load: float) -> float:
    """T / (r_p k) of Eq. 18 as an angle: the pair difference below which both touch."""
    p = _wang('table2')
    return float(rad_to_arcmin(load / (p.r_p_m * p.mesh_stiffness_n_m) / p.r_p_m))


def wang_line(phases: str, order: int) -> float:
    """Amplitude of one NLTE line (order per output revolution) [arcmin]."""
    return float(_lines(phases)[order])


def wang_pair1_crank_sum_m() -> float:
    """|e_p1 exp(i theta_p1) + e_g exp(i theta_g)| at the Eq. 21 optimum [m]."""
    p = _wang('optimum')
    return abs(p.e_p1_m * np.exp(1j * p.theta_p1_0_rad) + p.e_g_m * np.exp(1j * p.theta_g_0_rad))


def wang_first_sample(phases: str, load: float) -> float:
    """First sample of the DTE with the Table 4 start [arcmin]."""
    return float(_wang_curve('dte', phases, float(load))[0])


def wang_dte_mean_gap() -> float:
    """Largest |DTE mean - STE mean| after optimisation (30, 100, 300 N m) [arcmin]."""
    return max(abs(wang_te('dte', 'optimum', 'mean', t) - wang_te('ste', 'optimum', 'mean', t))
               for t in (30.0, 100.0, 300.0))


def wang_ste_mean_k(load: float, k_scale: float) -> float:
    """STE mean after optimisation with the mesh stiffness scaled [arcmin]."""
    import dataclasses

    from sim.wang2020 import static_te_rad
    p = _wang('optimum')
    q = dataclasses.replace(p, mesh_stiffness_n_m=k_scale * p.mesh_stiffness_n_m)
    return float(np.mean(rad_to_arcmin(static_te_rad(_theta(), load, q))))


def wang_phases_te(phases: list[float], stat: str) -> float:
    """NLTE statistic over one output revolution for other phases [arcmin]."""
    from rv_te_bench.core.phases import EccentricGeometry, nlte_from_phases_rad
    g = EccentricGeometry.from_params(_wang('table2'))
    te = rad_to_arcmin(nlte_from_phases_rad(_theta(), g, phases_rad=np.radians(phases)))
    return _stat(te, stat)


def wang_phases_peaks(phases: list[float]) -> float:
    """NLTE peaks in the first 3 s for other phases (prominence 0.02')."""
    from scipy.signal import find_peaks

    from rv_te_bench.core.phases import EccentricGeometry, nlte_from_phases_rad
    g = EccentricGeometry.from_params(_wang('table2'))
    th = _theta()[:round(3.0 * FS_HZ)]
    te = rad_to_arcmin(nlte_from_phases_rad(th, g, phases_rad=np.radians(phases)))
    return float(len(find_peaks(te, prominence=PEAK_PROMINENCE_ARCMIN)[0]))


def _readings() -> Any:
    import importlib.util
    from pathlib import Path
    spec = importlib.util.spec_from_file_location(
        'wang2020_readings', Path(__file__).with_name('wang2020_readings.py'))
    mod = importlib.util.module_from_spec(spec)     # type: ignore[arg-type]
    spec.loader.exec_module(mod)                    # type: ignore[union-attr]
    return mod


@functools.cache
def _window() -> dict[str, float]:
    return _readings().window_scan()


def wang_window_std(bound: str) -> float:
    """Smallest / largest NLTE std over the records [0, T], T = 3..31.6 s [arcmin]."""
    return _window()['std_min_arcmin' if bound == 'min' else 'std_max_arcmin']


def wang_reading_score(rates: list[int]) -> float:
    """Largest relative error over the paper's NLTE numbers for one angle law [%]."""
    mod = _readings()
    return 100.0 * float(mod.score(mod.reading_errors(np.array([rates], dtype=float)))[0])


def arith_ratio(a: float, b: float) -> float:
    """a / b (arithmetic on the paper's numbers)."""
    return a / b


def arith_ratio_pct(a: float, b: float) -> float:
    """100 a / b [%]."""
    return 100.0 * a / b


def arith_share_pct(a: float, b: float, c: float) -> float:
    """100 (a - b) / c [%]."""
    return 100.0 * (a - b) / c


# ------------------------------------------------------------------------------ Hu 2020


@functools.cache
def _hu(preset: str) -> Any:
    from sim.hu2020 import HuRvParams
    return HuRvParams.from_preset(load_preset(preset))


@functools.cache
def _tca(preset: str) -> Any:
    from sim.hu2020 import tooth_contact_analysis
    return tooth_contact_analysis(_hu(preset))


def hu_sensitivity(symbol: str) -> float:
    """Table 2 sensitivity index (``sim.hu2020.sensitivity_table``)."""
    from sim.hu2020 import sensitivity_table
    return next(r.sensitivity_index for r in sensitivity_table(_hu('hu2020-rv'))
                if r.symbol == symbol)


def hu_k1_prime(preset: str) -> float:
    """K1' of Hu 2020 Eq. 3."""
    return float(_hu(preset).k1_prime)


@functools.cache
def _compensation() -> dict[str, float]:
    from rv_te_bench.core.tooth_compensation import compensate_preset
    from sim.units import arcmin_to_rad
    adv = compensate_preset(load_preset('hu2020-rv'), float(arcmin_to_rad(1.4559)))
    out = {m.symbol: (m.recommended_value - m.current_value) * 1e3 for m in adv.modifications}
    d = adv.details
    out['elastic_share_pct'] = 100.0 * d['elastic_pp_before_rad'] / float(arcmin_to_rad(1.4559))
    return out


def hu_table6_change_mm(symbol: str) -> float:
    """Change of a Table 6 parameter by ``rv-te compensate hu2020-rv --te-arcmin 1.4559`` [mm]."""
    return _compensation()[symbol]


def hu_compensate_elastic_share() -> float:
    """Share of the 1.4559' that ``rv-te compensate`` takes as elastic (2 beta) [%]."""
    return _compensation()['elastic_share_pct']


def hu_tca(preset: str, field: str) -> float:
    """Converged TCA (Hu 2020 Eqs 28-48): f_max_n, delta_max_mm, pins, iterations, f0_n."""
    tca = _tca(preset)
    return float({'f_max_n': tca.f_max_n, 'delta_max_mm': tca.delta_max_m * 1e3,
                  'pins': tca.pins_in_mesh, 'iterations': tca.iterations,
                  'f0_n': tca.history_n[0]}[field])


def hu_eq38_mm(preset: str, f_n: float) -> float:
    """Hu 2020 Eqs 38-40 at a force [mm] (``sim.hu2020.max_deformation_m``)."""
    from sim.hu2020 import max_deformation_m
    return max_deformation_m(_hu(preset), f_n) * 1e3


def hu_eq44_n(preset: str, delta_mm: float) -> float:
    """Hu 2020 Eq. 44 at a deformation [N] (``sim.hu2020.max_contact_force_n``)."""
    from sim.hu2020 import max_contact_force_n
    return max_contact_force_n(_hu(preset), delta_mm * 1e-3)[0]


def hu_pin_deformation_mm(preset: str, phi_deg: float) -> float:
    """Hu 2020 Eq. 37 at a pin angle with the converged delta_max [mm] (< 0: l_i < 0)."""
    p, tca = _hu(preset), _tca(preset)
    k, phi = p.k1, math.radians(phi_deg)
    lever = math.sin(phi) / math.sqrt(1.0 + k * k - 2.0 * k * math.cos(phi))
    return lever * tca.delta_max_m * 1e3


def hu_tca_at(preset: str, torque_nm: float) -> float:
    """Converged F_max at another torque [N]."""
    from sim.hu2020 import tooth_contact_analysis
    return float(tooth_contact_analysis(_hu(preset), torque_nm).f_max_n)


def hu_torque_for_f0(f0_n: float) -> float:
    """The torque at which Eqs 45-47 give F_max0 [N m]."""
    p = _hu('hu2020-rv')
    per_nm = abs(2.2 / (p.z_c * p.r_p_m) - p.load_share / p.r_p_m) / 2.0
    return f0_n / per_nm


def hu_eq44_after_eq38_n(preset: str, f_n: float) -> float:
    """One step of the printed scheme: Eq. 44 at Eq. 38 of a force [N]."""
    return hu_eq44_n(preset, hu_eq38_mm(preset, f_n))


def hu_force_for_eq38_n(preset: str, delta_mm: float) -> float:
    """The force at which Eq. 38 gives delta_max (bisection) [N]."""
    lo, hi = 1.0, 1e6
    for _ in range(100):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if hu_eq38_mm(preset, mid) < delta_mm else (lo, mid)
    return math.sqrt(lo * hi)


def hu_kn_mm(reading: str) -> float:
    """Hu 2020 Eq. 14 in mm: 'printed' k_n, or 'flipped' (last term's sign, not / s)."""
    p = _hu('hu2020-rv')
    a, rp, zc = p.a_m * 1e3, p.r_p_m * 1e3, p.z_c
    d_rrp, d_rp = p.delta_r_rp_m * 1e3, p.delta_r_p_m * 1e3
    s = math.sqrt(1.0 - p.k1_prime ** 2)
    t1, t2, t3 = d_rrp / (a * a * zc), zc * d_rp / (a * rp * rp * s), d_rp * s / (a * a * zc)
    return t1 - (t2 + t3) if reading == 'printed' else t1 - t2 + t3


def hu_pin_overlap_um(preset: str, phi_deg: float) -> float:
    """Deformation minus initial clearance of the pin at phi (TCA) [um]."""
    tca = _tca(preset)
    i = int(np.argmin(np.abs(np.degrees(tca.pin_angle_rad) - phi_deg)))
    return float((tca.deformation_m[i] - tca.clearance_m[i]) * 1e6)


def hu_two_beta_arcmin(preset: str) -> float:
    """2 beta: the elastic part of a TE p-p under a load reversing +-1094 N m [arcmin]."""
    from sim.hu2020 import elastic_te_rad
    return 2.0 * float(rad_to_arcmin(-elastic_te_rad(_hu(preset), 1094.0)))


def hu_two_beta_change_pct() -> float:
    """Initial -> modified change of 2 beta [%]."""
    return 100.0 * (hu_two_beta_arcmin('hu2020-rv-modified') / hu_two_beta_arcmin('hu2020-rv')
                    - 1.0)


def hu_reduction_pct(field: str) -> float:
    """Initial -> modified reduction of F_max or delta_max [%]."""
    return 100.0 * (1.0 - hu_tca('hu2020-rv-modified', field) / hu_tca('hu2020-rv', field))


def hu_adams_input_deg() -> float:
    """Input angle after 0.4 s of V = A sin(B t) + C (the preset's [drive]) [deg]."""
    pr = load_preset('hu2020-rv')
    a, b = pr['drive.speed_amplitude_rad_s'], pr['drive.speed_angular_freq_rad_s']
    c = pr['drive.speed_offset_rad_s']
    return math.degrees(c * 0.4 + a / b * (1.0 - math.cos(b * 0.4)))


def hu_adams_output_deg(preset: str = 'hu2020-rv') -> float:
    """Output angle after 0.4 s: input / i [deg]."""
    return hu_adams_input_deg() / kinematics_from_preset(load_preset(preset)).gear_ratio


@functools.cache
def hu_model_pp(preset: str, kind: str) -> float:
    """TE p-p [arcmin], 3000 rpm, 20 s at 1 kHz, load reversing +-1094 N m at 0.5 Hz."""
    from sim.hu2020 import build_te_model
    w = 2.0 * math.pi * 50.0
    t = np.arange(20_000) / 1e3
    load = 1094.0 * np.sin(2.0 * math.pi * 0.5 * t)
    model = build_te_model(load_preset(preset), kind)
    return float(rad_to_arcmin(np.ptp(model.te_rad(t, w * t, np.full(t.size, w), load))))


def hu_change_pct(kind: str) -> float:
    """Initial -> modified change of the TE p-p [%]."""
    return 100.0 * (hu_model_pp('hu2020-rv-modified', kind) / hu_model_pp('hu2020-rv', kind)
                    - 1.0)


def hu_elastic_share_pct() -> float:
    """Elastic part 2 beta of the initial prototype's TE p-p (elastic mode) [%]."""
    from sim.hu2020 import elastic_te_rad
    two_beta = 2.0 * float(rad_to_arcmin(-elastic_te_rad(_hu('hu2020-rv'), 1094.0)))
    return 100.0 * two_beta / hu_model_pp('hu2020-rv', 'elastic')


def hu_elastic_te_arcmin() -> float:
    """beta = delta_max / r_c' of the initial prototype at the preset torque [arcmin]."""
    from sim.hu2020 import elastic_te_rad
    return float(rad_to_arcmin(-elastic_te_rad(_hu('hu2020-rv'), 1094.0)))


# ------------------------------------------------------------------------------ Li 2023


@functools.cache
def _ltca(modified: bool) -> Any:
    from sim.li2023 import ltca, params_from_preset
    mod = (-0.05e-3, -0.01e-3) if modified else (0.0, 0.0)
    return ltca(params_from_preset(load_preset('li2023-rv')), modification_m=mod)


def li_ratio() -> float:
    """Overall ratio of the Table 1 teeth."""
    return float(kinematics_from_preset(load_preset('li2023-rv')).gear_ratio)


def li_beta_deg(stat: str, modified: bool = False) -> float:
    """Equivalent pressure angle of the LTCA (Li 2023 Eq. 7): mean / min / max [deg]."""
    b = np.degrees(_ltca(modified).pressure_angle_rad)
    return float({'mean': b.mean, 'min': b.min, 'max': b.max}[stat]())


def li_contacts(modified: bool = False) -> float:
    """Largest number of loaded pins over the mesh period."""
    return float(np.max(_ltca(modified).contacts))


def li_k_n_m(modified: bool = False) -> float:
    """Mean equivalent mesh stiffness of the LTCA (Li 2023 Eq. 7) [N/m]."""
    return float(_ltca(modified).mesh_stiffness_n_m.mean())


@functools.cache
def _li_dte(errors: bool, direction: float = 1.0) -> np.ndarray:
    """DTE over one output revolution after 0.5 s, 1500 rpm, 450 N m, 1 kHz [arcsec]."""
    from sim.li2023 import build_te_model
    ov = {} if errors else {'errors.enabled': 'false'}
    model = build_te_model(load_preset('li2023-rv', ov), 'dte')
    fs = 1000.0
    warm, nrev = round(0.5 * fs), round(fs * 121 / 25.0)
    t = np.arange(warm + nrev) / fs
    w = direction * 2.0 * math.pi * 25.0
    te = model.te_rad(t, w * t, np.full(t.size, w), np.full(t.size, direction * 450.0))
    return rad_to_arcsec(te[warm:])


def li_dte_pp_arcsec(errors: bool, direction: float = 1.0) -> float:
    """DTE p-p per output revolution [arcsec] (direction -1: reverse rotation and load)."""
    return float(np.ptp(_li_dte(bool(errors), float(direction))))


def li_more_lines() -> tuple[bool, str]:
    """Fig. 11: do the errors add lines at more frequency ratios (lines above 0.01")?"""
    def lines(te: np.ndarray) -> set[int]:
        amp = np.abs(np.fft.rfft(te - te.mean())) * 2.0 / te.size
        return {int(k) for k in np.nonzero(amp > 0.01)[0]}
    without, with_err = lines(_li_dte(False, 1.0)), lines(_li_dte(True, 1.0))
    added = sorted(with_err - without)
    return len(added) > 1, f'added orders {added} ({len(without)} \u2192 {len(with_err)} lines)'
