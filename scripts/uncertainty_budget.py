"""The uncertainty budgets of the default bench, as docs/UNCERTAINTY.md shows them.

The default session (``rv-te launch --default``; rv_te_bench/launch/default_session.yaml):
wang2020-2kv at 300 rpm input, no load, Heidenhain RON 886 on both shafts, 1 kHz, two
output revolutions. The record is simulated with the session's seed; the budgets are those
of the suite's core (rv_te_bench.core.te_uncertainty) with the data-sheet defaults of the
RON 886 (rv_te_bench.core.bench_uncertainty). Prints markdown.

Run: ``.venv/bin/python scripts/uncertainty_budget.py``.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rv_te_bench.core.bench_uncertainty import BenchUncertainty
from rv_te_bench.core.directional import direction_te
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.te_uncertainty import line_budgets, te_pp_budget
from rv_te_bench.core.uncertainty import Budget
from sim.bench import BenchConfig, BenchSimulator
from sim.drive import ConstantSpeed

AS = 180 * 3600 / math.pi


def default_record() -> tuple[np.ndarray, np.ndarray, float, OrderSet, float]:
    """theta_in, theta_out of the default session (two output revolutions)."""
    cfg = BenchConfig(preset='wang2020-2kv', drive=ConstantSpeed(300.0),
                      sample_rate_hz=1000.0, block_size=100, encoder_in='heidenhain-ron886',
                      encoder_out='heidenhain-ron886', seed=1)
    sim = BenchSimulator(cfg)
    kin = sim.kinematics
    n = int(2.0 * kin.gear_ratio * 60.0 / 300.0 * 1000.0) + 2
    blocks = [sim.next_block() for _ in range(n // 100 + 1)]
    th_in = np.concatenate([b.theta_in_rad for b in blocks])[:n]
    th_out = np.concatenate([b.theta_out_rad for b in blocks])[:n]
    orders = OrderSet.from_bench_info(sim.info)
    return th_in, th_out, kin.gear_ratio, orders, (n - 1) / 1000.0


def budgets() -> dict[str, Budget]:
    """TE p-p, the dominant line (amplitude, phase) and the output-order line."""
    bench = BenchUncertainty.defaults('heidenhain-ron886', 'heidenhain-ron886')
    th_in, th_out, ratio, orders, dur = default_record()
    d = direction_te(th_in, th_out, gear_ratio=ratio, orders=orders, duration_s=dur)
    phi = th_in / ratio
    te = th_out - phi
    j = int(np.argmax(d.pp_per_rev_rad))
    m = (phi - phi[0] >= j * 2 * np.pi) & (phi - phi[0] < (j + 1) * 2 * np.pi)
    ph, tt = phi[m], te[m]
    dom = max(d.spectrum.lines, key=lambda ln: ln.amplitude_rad)
    out = {'TE p-p': te_pp_budget('te_pp_rad', d.te_pp_rad, phi_max_rad=float(ph[np.argmax(tt)]),
                                  phi_min_rad=float(ph[np.argmin(tt)]), gear_ratio=ratio,
                                  bench=bench, per_revolution_rad=d.pp_per_rev_rad,
                                  samples_per_rev=float(ph.size),
                                  dominant=(dom.amplitude_rad, dom.output_order))}
    # the line in each revolution (the analysis's windows of one revolution): type A
    per_rev = []
    for k in range(d.revolutions):
        w = (phi - phi[0] >= k * 2 * np.pi) & (phi - phi[0] < (k + 1) * 2 * np.pi)
        w[np.flatnonzero(w)[-1] + 1:np.flatnonzero(w)[-1] + 2] = True   # close the revolution
        per_rev.append(direction_te(th_in[w], th_out[w], gear_ratio=ratio, orders=orders,
                                    duration_s=dur / 2).spectrum)
    for ln in d.spectrum.lines:
        if ln.label in (dom.label, 'f_out'):
            wins = [sp.line(ln.label) for sp in per_rev]
            a, p = line_budgets(ln.label, ln.amplitude_rad, ln.phase_rad, ln.output_order,
                                gear_ratio=ratio, bench=bench,
                                output_hz=ln.frequency_hz / ln.output_order,
                                samples_per_rev=d.spectrum.samples_per_rev, n_samples=phi.size,
                                window_amplitudes_rad=[x.amplitude_rad for x in wins],
                                window_phases_rad=[x.phase_rad for x in wins])
            out[f'line {ln.label} amplitude'] = a
            out[f'line {ln.label} phase'] = p
    return out


def table(name: str, b: Budget) -> list[str]:
    """One budget as a markdown table (arcsec, or deg for a phase)."""
    sc, unit = (180 / math.pi, 'deg') if name.endswith('phase') else (AS, 'arcsec')
    lines = [f'### {name}: {b.value * sc:.4f} {unit}, U = {b.u95 * sc:.3g} {unit} '
             f'(k = {b.k:.3f}, {b.k_basis}; u_c = {b.u_c * sc:.3g} {unit}'
             + (f'; nu_eff = {b.nu_eff:.3g}' if math.isfinite(b.nu_eff) else '')
             + (f'; + bias bound {b.bias_bound * sc:.3g} {unit}' if b.bias_bound else '')
             + ')', '',
             '| input | type | distribution | u(x) | unit | c | c u [' + unit
             + '] | share | source |', '|---|---|---|---:|---|---:|---:|---:|---|']
    for x, s in zip(b.inputs, b.shares, strict=True):
        if x.contribution == 0:
            continue
        if x.unit == 'rad' and name.endswith('phase') and x.kind == 'A':
            ux, uu, c = x.u * 180 / math.pi, 'deg', x.sensitivity   # a phase itself
        elif x.unit == 'rad':
            ux, uu, c = x.u * AS, 'arcsec', x.sensitivity / AS * sc
        else:
            ux, uu, c = x.u, x.unit, x.sensitivity * sc
        src = _short_source(x.source)
        lines.append(f'| {x.name} | {x.kind} | {x.distribution} | {ux:.4g} | {uu} | {c:.4g} | '
                     f'{x.contribution * sc:.3g} | {100 * s:.1f} % | {src} |')
    lines += ['', *[f'* {n}' for n in b.notes], '']
    return lines


def _short_source(text: str) -> str:
    """The source's first clause (the full text is listed under the tables)."""
    return text.split(',')[0].split(';')[0].split(':')[0].strip()[:60]


def main() -> int:
    sources: dict[str, None] = {}
    for name, b in budgets().items():
        print('\n'.join(table(name, b)))
        sources.update(dict.fromkeys(x.source for x in b.inputs if x.source))
    print('Sources:\n')
    print('\n'.join(f'* {s}' for s in sources))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
