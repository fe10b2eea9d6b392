"""Measured backlash, lost motion and rigidity of simulated units against their models.

The table of docs/ACCEPTANCE.md: each unit runs the hysteresis step (equal torque steps of
10 %, dwell 0.2 s, RON 886 encoders) offline; the model values are the closed forms and the
papers' own functions of tests/acceptance/test_unit_accuracy.py. Run:
``python scripts/acceptance_accuracy.py``.
"""

from __future__ import annotations

import math

import numpy as np

from rv_te_bench.acceptance import load_tolerance, parse_plan, run_plan_offline
from sim import hu2020, li2023
from sim.presets import load_preset
from sim.program import ProgramSimulator

AM = 10800 / math.pi
NO_ECC = ['eccentricity.e_p1_m=0', 'eccentricity.e_p2_m=0', 'eccentricity.e_g_m=0',
          'eccentricity.e_ot_m=0']


def measure(preset: str, mode: str, over: list[str], rated: float) -> dict[str, float]:
    sim = ProgramSimulator(preset=preset, overrides=tuple(over), te_mode=mode, seed=1)
    plan = parse_plan({'plan': 'h', 'steps': [{'kind': 'hysteresis', 'rated_torque_nm': rated,
                                               'dwell_s': 0.2}]})
    r = run_plan_offline(plan, load_tolerance(preset)[0], serial='s', operator='o', sim=sim)
    return {m['name']: m['value'] for m in r['metrics']}


def row(name: str, m: dict[str, float], bl: float, lm: float, k: float) -> None:
    mb, ml, mk = m['backlash_rad'], m['lost_motion_rad'], m['torsional_rigidity_K_nm_per_rad']
    print(f'| {name} | {bl * AM:.4f} / {mb * AM:.4f} ({100 * (mb / bl - 1):+.2f} %) | '
          f'{lm * AM:.4f} / {ml * AM:.4f} ({100 * (ml / lm - 1):+.2f} %) | '
          f'{k / AM:.1f} / {mk / AM:.1f} ({100 * (mk / k - 1):+.2f} %) |')


def main() -> None:
    print('| unit | backlash model / measured [arcmin] | lost motion model / measured '
          '[arcmin] | rigidity model / measured [N m/arcmin] |')
    print('|---|---|---|---|')
    r_p = load_preset('wang2020-2kv')['stage2.r_p_m']
    for b_am, kn, tf in ((1.0, 5e7, 0.0), (2.0, 8.43e7, 4.5), (3.0, 1.2e8, 4.5)):
        b = b_am / AM
        k = 2 * kn * r_p * r_p
        m = measure('wang2020-2kv', 'nlte', [*NO_ECC, f'mesh.stiffness_n_m={kn}',
                                             f'backlash.b1_t0_rad={b}', f'backlash.b2_t0_rad={b}',
                                             f'torsion.friction_torque_nm={tf}'], 300.0)
        row(f'2K-V B={b_am:g}\', k={kn:.3g} N/m, T_f={tf:g} N m', m, b + 2 * tf / k,
            b + 18.0 / k, k)
    for c_am, km in ((0.3, 0.6e9), (0.6, 1.24e9), (1.2, 2.5e9)):
        c = c_am / AM
        over = [f'torsion.clearance_rad={c}', f'stiffness.pin_mesh_n_m={km}']
        model = li2023.build_te_model(load_preset('li2023-rv', over), 'dte')
        i = model.state_index('output')
        k = 100.0 / (model.static_response(0.0, 0.0)[i] - model.static_response(0.0, 100.0)[i])
        m = measure('li2023-rv', 'dte', over, 450.0)
        row(f'Li RV play {c_am:g}\', k_pin={km:.3g} N/m, T_f=6.75 N m', m, c + 13.5 / k,
            c + 27.0 / k, k)
    for c_am, bw in ((0.2, 0.008), (0.5, 0.011), (1.0, 0.015)):
        c = c_am / AM
        over = [f'torsion.clearance_rad={c}', f'tca.face_width_m={bw}',
                'torsion.friction_torque_nm=0.0']
        params = hu2020.HuRvParams.from_preset(load_preset('hu2020-rv', over))

        def beta(t: float, params: hu2020.HuRvParams = params) -> tuple[float, float]:
            tca = hu2020.tooth_contact_analysis(params, t)
            return (tca.delta_max_m / params.r_c_m,
                    float(np.min(tca.clearance_m / tca.lever_arm_m)))

        k = 392.0 / (beta(784.0)[0] - beta(392.0)[0])
        b = c + 2 * beta(784.0)[1]
        m = measure('hu2020-rv', 'geometric', over, 784.0)
        row(f'Hu RV play {c_am:g}\', b={1000 * bw:g} mm, T_f=0', m, b,
            b + 2 * (beta(0.03 * 784)[0] - beta(784.0)[1]), k)


if __name__ == '__main__':
    main()
