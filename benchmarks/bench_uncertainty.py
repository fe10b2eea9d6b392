"""Validation of the uncertainty budgets (issue 35): Monte Carlo vs GUM, and coverage.

1. **GUM vs Monte Carlo (Supplement 1).** One simulated measurement of the default bench
   (wang2020-2kv, RON 886 on both shafts, errors as the data sheet states them; its
   identified eccentricities) and one hysteresis test (rv-80e-101): every budget's
   U = k u_c beside the half-width of the 95.45 % interval of a Monte Carlo propagation
   through the measurement model itself (``rv_te_bench.core.uncertainty_mc``: the TE
   record with drawn error functions removed, the identification refitted, the hysteresis
   metrics recomputed). Target: within 5 % of U on every metric. The torsional rigidity
   is reported as the smaller of two sides, not a smooth function where they cross: the
   law of propagation is checked on each side, and the minimum's budget (over both sides,
   with its low-side bias) must contain the Monte Carlo interval of the minimum.
2. **Coverage.** ``--units`` simulated units and benches, each with its own reducer
   (assembly phases / free play drawn), encoder errors drawn from the stated distributions
   (a new phase for every graduation and interpolation harmonic, sim.encoders.remounted),
   a DAQ skew drawn in +-100 ns (sim.bench daq_skew_s), a torque sensor zero and gain error
   drawn in their bounds (sim.program torque_zero_nm / torque_gain_error). The true value
   comes from the same procedure on the simulator's true angles (te_true, exact torque);
   a unit is covered when the true value lies in the budget's interval
   [y - U - b, y + U]. Target: >= 94 % per metric.

1b. **A short record** (bags/sample, two output revolutions): every line's repeatability
   rests on two windows, one dof. The same comparison through ``rv-te analyze
   --monte-carlo``'s path, beside the U that Welch-Satterthwaite's k gave before a few-dof
   type A was convolved as the t it is (``--sample-only`` runs just this part).

Run: ``.venv/bin/python benchmarks/bench_uncertainty.py --units 1000 --draws 20000``
(about 25 minutes on a busy 2-core VM); ``--units 50 --draws 2000`` for a quick look. Prints one
markdown table per part (benchmarks/README.md keeps the last run).
"""

from __future__ import annotations

import argparse
import cmath
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rv_te_bench.core.angle_fold import AngleFold
from rv_te_bench.core.bench_uncertainty import BenchUncertainty
from rv_te_bench.core.directional import direction_te
from rv_te_bench.core.hysteresis import HysteresisConfig, dwell_points, hysteresis_metrics
from rv_te_bench.core.hysteresis_uncertainty import hysteresis_budgets
from rv_te_bench.core.identify import identify_folded
from rv_te_bench.core.identify_uncertainty import identification_budgets
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.te_uncertainty import line_budgets, te_pp_budget
from rv_te_bench.core.uncertainty_mc import (
    mc_hysteresis,
    mc_identification,
    mc_line,
    mc_te_pp,
)
from sim.bench import BenchConfig, BenchSimulator
from sim.drive import ConstantSpeed
from sim.encoders import EncoderSpec, remounted
from sim.presets import load_preset
from sim.program import ProgramSimulator, TorqueSegment
from sim.wang2020 import Wang2kvParams

TE_PRESET = 'wang2020-2kv'
HYST_PRESET = 'rv-80e-101'
RATE_HZ = 10_000.0
SPEED_RPM = 3000.0
RATED_NM = 784.0
ENCODER = 'heidenhain-ron886'
AS = 206264.806           # arcsec per rad
SAMPLE_BAG = Path(__file__).resolve().parents[1] / 'bags' / 'sample'
IDENT_LABELS = {'e_ot_m': ('e_ot [um]', 1e6), 'pair1_m': ('|Q1| [um]', 1e6),
                'pair2_m': ('|Q2| [um]', 1e6), 'theta_ot_rad': ('theta_ot [deg]', 180 / math.pi),
                'pair1_phase_rad': ('arg Q1 [deg]', 180 / math.pi),
                'pair2_phase_rad': ('arg Q2 [deg]', 180 / math.pi)}
HYST_LABELS = {'lost_motion_rad': ('lost motion [arcsec]', AS),
               'backlash_rad': ('backlash [arcsec]', AS),
               'hysteresis_loss_j': ('hysteresis loss [J]', 1.0),
               'torsional_rigidity_K_nm_per_rad': ('torsional rigidity K [N m/arcmin]',
                                                   1 / 3437.747)}


def sim_spec(bench: BenchUncertainty, which: str, rng: np.random.Generator) -> EncoderSpec:
    """The simulator's encoder carrying the budget's error model, phases drawn."""
    m = bench.encoder_out if which == 'out' else bench.encoder_in
    orders = [k for k, _ in m.graduation]
    amps = [g for _, g in m.graduation]
    if m.signal_periods and m.interpolation_rad:
        orders.append(m.signal_periods)
        amps.append(m.interpolation_rad)
    ecc = abs(rng.normal(m.eccentricity_rad, m.eccentricity_u_rad)) if (
        m.eccentricity_rad or m.eccentricity_u_rad) else 0.0
    spec = EncoderSpec(name=m.model, counts_per_rev=round(2 * math.pi / m.resolution_rad),
                       graduation_orders=tuple(orders), graduation_amplitudes_rad=tuple(amps),
                       graduation_phases_rad=tuple(0.0 for _ in orders),
                       noise_sigma_rad=m.noise_sigma_rad, source=m.source)
    return remounted(spec, rng, eccentricity_rad=ecc)


# --------------------------------------------------------------------------------------
# TE: one measurement


def te_run(rng: np.random.Generator, bench: BenchUncertainty, *, unit_phases: bool,
           revolutions: int = 2) -> dict:
    overrides = ()
    if unit_phases:
        overrides = tuple(f'{k}={v:.3f}' for k, v in zip(
            ('eccentricity.theta_p1_0_deg', 'eccentricity.theta_p2_0_deg',
             'eccentricity.theta_g_0_deg', 'eccentricity.theta_ot_0_deg'),
            rng.uniform(-180.0, 180.0, 4), strict=True))
    skew = float(rng.uniform(-bench.daq_skew_s, bench.daq_skew_s))
    cfg = BenchConfig(preset=TE_PRESET, overrides=overrides, drive=ConstantSpeed(SPEED_RPM),
                      sample_rate_hz=RATE_HZ, block_size=1000,
                      encoder_in=sim_spec(bench, 'in', rng),
                      encoder_out=sim_spec(bench, 'out', rng),
                      seed=int(rng.integers(2**31)), daq_skew_s=skew)
    sim = BenchSimulator(cfg)
    kin = sim.kinematics
    n = int((revolutions + 0.02) * kin.gear_ratio * 60.0 / SPEED_RPM * RATE_HZ) + 2
    blocks = [sim.next_block() for _ in range(n // 1000 + 1)]
    cat = {f: np.concatenate([getattr(b, f) for b in blocks])[:n] for f in (
        'theta_in_rad', 'theta_out_rad', 'theta_in_true_rad', 'theta_out_true_rad')}
    orders = OrderSet.from_bench_info(sim.info)
    dur = (n - 1) / RATE_HZ
    meas = direction_te(cat['theta_in_rad'], cat['theta_out_rad'], gear_ratio=kin.gear_ratio,
                        orders=orders, duration_s=dur)
    true = direction_te(cat['theta_in_true_rad'], cat['theta_out_true_rad'],
                        gear_ratio=kin.gear_ratio, orders=orders, duration_s=dur)
    phi = cat['theta_in_rad'] / kin.gear_ratio
    te = cat['theta_out_rad'] - phi
    travel = phi - phi[0]
    j = int(np.argmax(meas.pp_per_rev_rad))
    m = (travel >= j * 2 * np.pi) & (travel < (j + 1) * 2 * np.pi)
    ph, tt = phi[m], te[m]
    dom = max(meas.spectrum.lines, key=lambda ln: ln.amplitude_rad)
    pp = te_pp_budget('te_pp_rad', meas.te_pp_rad, phi_max_rad=float(ph[np.argmax(tt)]),
                      phi_min_rad=float(ph[np.argmin(tt)]), gear_ratio=kin.gear_ratio,
                      bench=bench, per_revolution_rad=meas.pp_per_rev_rad,
                      samples_per_rev=float(ph.size),
                      dominant=(dom.amplitude_rad, dom.output_order))
    lines = {}
    for ln in meas.spectrum.lines:
        if ln.label not in ('f_out', dom.label):
            continue
        name = 'f_out' if ln.label == 'f_out' else 'dominant'
        a, p = line_budgets(ln.label, ln.amplitude_rad, ln.phase_rad, ln.output_order,
                            gear_ratio=kin.gear_ratio, bench=bench,
                            output_hz=ln.frequency_hz / ln.output_order,
                            samples_per_rev=meas.spectrum.samples_per_rev, n_samples=phi.size)
        lines[name] = (ln, a, p, true.spectrum.line(ln.label))
    keep = travel < meas.revolutions * 2 * np.pi
    return {'pp': pp, 'pp_true': true.te_pp_rad, 'lines': lines, 'phi': phi[keep] - phi[0],
            'te': te[keep], 'offset': float(phi[0]), 'ratio': kin.gear_ratio,
            **ident_budgets(phi, te, overrides, kin.gear_ratio, bench)}


def ident_budgets(phi: np.ndarray, te: np.ndarray, overrides: tuple[str, ...],
                  gear_ratio: float, bench: BenchUncertainty) -> dict:
    """The identified eccentricities' budgets and their true values (the preset's
    eccentricities at the drawn phases; labels matched to the identification's)."""
    fold = AngleFold()
    fold.add(phi, te)
    folded = fold.result()
    params = Wang2kvParams.from_preset(load_preset(TE_PRESET, list(overrides)))
    ident = identify_folded(folded, params, split=False)
    buds = identification_budgets(ident, folded, gear_ratio=gear_ratio, bench=bench)
    e1, e2, eg, eo = params.e_p1_m, params.e_p2_m, params.e_g_m, params.e_ot_m
    t1, t2, tg, to = (params.theta_p1_0_rad, params.theta_p2_0_rad, params.theta_g_0_rad,
                      params.theta_ot_0_rad)
    q1 = e1 * cmath.exp(1j * t1) + eg * cmath.exp(1j * tg)
    q2 = e2 * cmath.exp(1j * t2) - eg * cmath.exp(1j * tg)
    ee = eo * cmath.exp(1j * to)
    if abs(ident.pair_phasors_m[2] + ee) < abs(ident.pair_phasors_m[2] - ee):
        q1, q2, ee = q2, q1, -ee               # the exact label swap of the model
    truth = {'e_ot_m': abs(ee), 'pair1_m': abs(q1), 'pair2_m': abs(q2),
             'theta_ot_rad': cmath.phase(ee), 'pair1_phase_rad': cmath.phase(q1),
             'pair2_phase_rad': cmath.phase(q2)}
    return {'ident': {n: (b, truth[n]) for n, b in buds.items()},
            'ident_fit': (folded, ident)}


# --------------------------------------------------------------------------------------
# hysteresis: one measurement


def _torque_program(cfg: HysteresisConfig, step_fraction: float = 0.1, dwell_s: float = 0.2,
                    ) -> list[TorqueSegment]:
    tr = cfg.rated_torque_nm
    n = round(1.0 / step_fraction)
    fr = sorted({round(k / n, 12) for k in range(n + 1)}
                | {round(abs(p) / tr, 12) for p in cfg.torque_points_nm()})
    up = [f * tr for f in fr]
    pre = [-0.5 * tr, -tr, -0.5 * tr, 0.0]
    seq = up + up[-2::-1] + [-t for t in up[1:]] + [-t for t in up[-2::-1]]
    return [TorqueSegment(torque_nm=t, duration_s=dwell_s) for t in pre + seq], len(pre)


def _hyst_measure(sim: ProgramSimulator, cfg: HysteresisConfig) -> tuple:
    prog, n_pre = _torque_program(cfg)
    sim.load(tuple(prog))
    seg_blocks = sim.segment_blocks
    first_cycle_block = sum(seg_blocks[:n_pre])
    blocks = []
    while sim.running:
        b, _ = sim.next_block()
        blocks.append(b)
    blocks = blocks[first_cycle_block:]
    th_in = np.concatenate([b.theta_in_rad for b in blocks])
    th_out = np.concatenate([b.theta_out_rad for b in blocks])
    applied = -np.concatenate([b.torque_out_nm for b in blocks])
    angle = th_out - th_in / sim.gear_ratio
    t, a, counts = dwell_points(applied, angle)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    idx = np.repeat(np.arange(counts.size), counts)
    resid = angle - a[idx]
    dof = int(np.sum(counts - 1))
    s = float(np.sqrt(np.sum(resid ** 2) / dof)) if dof > 0 else 0.0
    del starts
    return t, a, counts, (s, dof), float(np.mean(th_out))


def hyst_run(rng: np.random.Generator, bench: BenchUncertainty) -> dict:
    cfg = HysteresisConfig(rated_torque_nm=RATED_NM)
    clearance = float(rng.uniform(0.0, 4e-4))
    over = (f'torsion.clearance_rad={clearance:.6g}',)
    zero = bench.torque_zero_for(RATED_NM)
    kw = {'preset': HYST_PRESET, 'overrides': over, 'sample_rate_hz': 1000.0, 'block_size': 100,
          'te_mode': 'geometric'}
    sim = ProgramSimulator(**kw, encoder_in=sim_spec(bench, 'in', rng),
                           encoder_out=sim_spec(bench, 'out', rng),
                           seed=int(rng.integers(2**31)),
                           torque_zero_nm=float(rng.uniform(-zero, zero)),
                           torque_gain_error=float(rng.uniform(-bench.torque_gain_rel,
                                                               bench.torque_gain_rel)))
    # the output position: turn the output to a random angle first
    from sim.program import DriveSegment

    pos_s = float(rng.uniform(0.05, 1.0)) * sim.gear_ratio * 60.0 / 300.0
    for s in (sim,):
        s.load((DriveSegment(speed_rpm=300.0, duration_s=pos_s),))
        while s.running:
            s.next_block()
    t, a, counts, dwell, theta_out = _hyst_measure(sim, cfg)
    ideal = ProgramSimulator(**kw, encoder_in='ideal', encoder_out='ideal')
    ideal.load((DriveSegment(speed_rpm=300.0, duration_s=pos_s),))
    while ideal.running:
        ideal.next_block()
    tt, at, _, _, _ = _hyst_measure(ideal, cfg)
    m_true = hysteresis_metrics(tt, at, cfg)
    true = {'lost_motion_rad': m_true.lost_motion_rad, 'backlash_rad': m_true.backlash_rad,
            'hysteresis_loss_j': m_true.hysteresis_loss_j,
            'torsional_rigidity_K_nm_per_rad': m_true.rigidity_min_nm_per_rad('K')}
    budgets = hysteresis_budgets(t, a, cfg, bench=bench, theta_out_rad=theta_out, counts=counts,
                                 dwell_sigma_rad=dwell)
    return {'budgets': budgets, 'true': true, 't': t, 'a': a, 'counts': counts,
            'theta_out': theta_out, 'cfg': cfg}


def _ws_k(b) -> float:
    """k as it was before the few-dof type A inputs were convolved: t_p(nu_eff) by
    Welch-Satterthwaite where the bounded inputs make < 10 % of u_c^2, else the budget's."""
    from rv_te_bench.core.uncertainty import t_quantile

    if not b.k_basis.startswith('t (nu_i'):
        return b.k
    return t_quantile(b.coverage_probability, round(b.nu_eff, 2)) if math.isfinite(
        b.nu_eff) else 2.0


def sample_bag_check(draws: int, bag: Path = SAMPLE_BAG) -> list[tuple[str, object, float]]:
    """``rv-te analyze BAG --monte-carlo N`` on a short record (bags/sample: two output
    revolutions, so every line's repeatability rests on two windows, one dof): each
    result's MC result and the U that Welch-Satterthwaite's k would give."""
    from rv_te_bench.report.analysis import analyze_bag
    from rv_te_bench.report.uncertainty import monte_carlo_check

    res = analyze_bag(bag, with_advice=False)
    unc = res.uncertainty
    check = monte_carlo_check(unc, res.trace, res.spectrum, gear_ratio=res.bench.gear_ratio,
                              draws=draws)
    rows = []
    for name, r in check.results.items():
        b = unc.budgets[name]
        amp = unc.budgets.get(name.replace(' phase', ' amplitude'))
        if name.startswith('line ') and not (amp is not None and amp.value > 10 * amp.u95):
            continue              # at the noise floor: a phase is not linear in its inputs
        rows.append((name, r, _ws_k(b) * b.u_c))
    return rows


def _covered(b, true: float, *, phase: bool = False) -> bool:
    if phase:
        return abs(math.remainder(true - b.value, 2 * math.pi)) <= b.u95
    lo, hi = b.interval
    return lo <= true <= hi


def _sample_table(draws: int) -> None:
    """Part 1b: a short record (bags/sample), every line's type A from two windows (1 dof)."""
    print(f'## bags/sample (two output revolutions): GUM vs Monte Carlo, {draws} draws\n')
    print('| result | k | U (GUM) | U (MC) | MC - GUM | U with WS k (before) | MC - WS |')
    print('|---|---:|---:|---:|---:|---:|---:|')
    worst_s = worst_ws = 0.0
    for name, r, u_ws in sample_bag_check(draws):
        sc = 180 / math.pi if name.endswith('phase') else AS
        d_ws = r.u_mc / u_ws - 1.0
        worst_s, worst_ws = max(worst_s, abs(r.difference)), max(worst_ws, abs(d_ws))
        k = r.u_gum / r.u_c if r.u_c > 0 else math.nan
        print(f'| {name} | {k:.3f} | {r.u_gum * sc:.4g} | {r.u_mc * sc:.4g} | '
              f'{100 * r.difference:+.1f} % | {u_ws * sc:.4g} | {100 * d_ws:+.1f} % |')
    print(f'\nlargest |U_MC - U_GUM| / U_GUM: {100 * worst_s:.2f} % (with the WS k: '
          f'{100 * worst_ws:.2f} %)\n')


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--units', type=int, default=1000, help='simulated units for coverage')
    ap.add_argument('--draws', type=int, default=20000, help='Monte Carlo draws per budget')
    ap.add_argument('--seed', type=int, default=35)
    ap.add_argument('--sample-only', action='store_true',
                    help='only the short-record check on bags/sample (part 1b)')
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    bench = BenchUncertainty.defaults(ENCODER, ENCODER)
    t0 = time.monotonic()

    if args.sample_only:
        _sample_table(args.draws)
        return 0
    # ---- 1. GUM vs Monte Carlo on one measurement of each kind
    rows = []
    r = te_run(rng, bench, unit_phases=False)
    mc = mc_te_pp(r['pp'], r['phi'], r['te'], gear_ratio=r['ratio'], bench=bench,
                  draws=args.draws, rng=rng, theta_out_offset_rad=r['offset'])
    rows.append(('TE p-p [arcsec]', mc, AS, r['pp']))
    for name, (ln, a, p, _) in r['lines'].items():
        ma, mp = mc_line(a, p, r['phi'], r['te'], ln.output_order, gear_ratio=r['ratio'],
                         bench=bench, draws=args.draws, rng=rng,
                         theta_out_offset_rad=r['offset'])
        rows.append((f'line {ln.label} ({name}) amplitude [arcsec]', ma, AS, a))
        rows.append((f'line {ln.label} ({name}) phase [deg]', mp, 180 / math.pi, p))
    fit = r['ident_fit']
    mi = mc_identification({n: b for n, (b, _) in r['ident'].items()}, fit[0], fit[1],
                           gear_ratio=r['ratio'], bench=bench,
                           draws=max(args.draws // 10, 300), rng=rng)
    for n, res in mi.items():
        label, sc = IDENT_LABELS[n]
        rows.append((f'identified {label}', res, sc, r['ident'][n][0]))
    h = hyst_run(rng, bench)
    mh = mc_hysteresis(h['budgets'], h['t'], h['a'], h['cfg'], bench=bench,
                       theta_out_rad=h['theta_out'], draws=max(args.draws // 10, 500), rng=rng,
                       counts=h['counts'])
    hb = dict(h['budgets'])
    for b in h['budgets'].values():
        hb.update({p.measurand: p for p in b.parts})
    for n, res in mh.items():
        base, _, side = n.partition(' ')
        label, sc = HYST_LABELS[base]
        rows.append((f'{label} {side}'.strip(), res, sc, hb[n]))
    print('## GUM law of propagation vs Monte Carlo (GUM Supplement 1)\n')
    print('| result | value | u_c | k | U (GUM) | U (MC) | MC - GUM | draws |')
    print('|---|---:|---:|---:|---:|---:|---:|---:|')
    worst = 0.0
    for label, res, sc, b in rows:
        if b.parts:       # a minimum: its budget's interval must contain the MC interval
            lo, hi = b.interval
            print(f'| {label} (the smaller side) | {b.value * sc:.4g} | {b.u_c * sc:.3g} | '
                  f'{b.k:.3f} | [{lo * sc:.4g}, {hi * sc:.4g}] | [{res.low * sc:.4g}, '
                  f'{res.high * sc:.4g}] | {"contained" if res.contained else "NOT contained"} '
                  f'| {res.draws} |')
            continue
        worst = max(worst, abs(res.difference))
        print(f'| {label} | {b.value * sc:.4g} | {b.u_c * sc:.3g} | {b.k:.3f} | '
              f'{res.u_gum * sc:.3g} | {res.u_mc * sc:.3g} | {100 * res.difference:+.2f} % | '
              f'{res.draws} |')
    print(f'\nlargest |U_MC - U_GUM| / U_GUM: {100 * worst:.2f} %\n')

    _sample_table(args.draws)

    # ---- 2. coverage
    hits: dict[str, list[bool]] = {}
    ratio: dict[str, list[float]] = {}
    for u in range(args.units):
        r = te_run(rng, bench, unit_phases=True)
        checks = [('TE p-p', r['pp'], r['pp_true'], False)]
        for name, (_ln, a, p, tl) in r['lines'].items():
            checks.append((f'line {name} amplitude', a, tl.amplitude_rad, False))
            checks.append((f'line {name} phase', p, tl.phase_rad, True))
        for name, (b, true) in r['ident'].items():
            checks.append((f'identified {name}', b, true, name.endswith('_rad')))
        h = hyst_run(rng, bench)
        for n, b in h['budgets'].items():
            checks.append((n, b, h['true'][n], False))
        for name, b, true, phase in checks:
            hits.setdefault(name, []).append(_covered(b, true, phase=phase))
            err = abs(math.remainder(true - b.value, 2 * math.pi)) if phase else abs(true - b.value)
            ratio.setdefault(name, []).append(err / b.u95 if b.u95 > 0 else math.inf)
        if (u + 1) % 100 == 0:
            print(f'  {u + 1} units, {time.monotonic() - t0:.0f} s', file=sys.stderr)
    print(f'## Coverage over {args.units} simulated units and benches\n')
    print('| result | covered | |y - true| / U: median | 95th percentile |')
    print('|---|---:|---:|---:|')
    for name, hs in hits.items():
        rr = np.array(ratio[name])
        print(f'| {name} | {100 * np.mean(hs):.1f} % | {np.median(rr):.2f} | '
              f'{np.quantile(rr, 0.95):.2f} |')
    print(f'\n{time.monotonic() - t0:.0f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
