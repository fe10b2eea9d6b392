"""Calibrate the loss model of each preset to a published part-load efficiency curve.

The reference (docs/DESIGN_NOTES.md, "Losses, efficiency and case temperature"): Harmonic
Drive AG, HFUS-2A / CSD-2A Component Sets Engineering Data (documents 1019658 / 1019659,
11/2014), s.4.3.1 / 4.4.1 "Efficiency calculations", worked example of an HFUC-20-80-2A-GR
(i = 80, grease, input 1000 rpm, 20 degC): efficiency at rated torque 78 % (read by the maker
off its efficiency chart), part-load factor K = 0.93 at V = T / T_N = 0.57, so
eta(0.57 T_N) = 78 % x 0.93 = 72.54 % (the document rounds to 73 %).

With the loss laws of sim.losses at the reference speed and temperature, the efficiency at
a load V T_N is

    1 / eta(V) = 1 + f_ref V^0.2 + g + d / V,    g = i r_b f1 k_P dm,   d = i T_drag / T_N

where g (load-dependent bearing friction) follows from the assumed bearing geometry and
Palmgren's f1, and the two published points fix f_ref and d (two linear equations). The
drag T_drag = d T_N / i is then split into bearings (Palmgren M0, via f0), churning and
seals by assumed shares. Everything but the two catalogue numbers is an assumption and is
marked so in the presets.

Usage::

    .venv/bin/python scripts/calibrate_losses.py            # TOML [losses] values per preset
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sim.kinematics import kinematics_from_preset
from sim.losses import palmgren_m0_nm
from sim.lubricant import Lubricant
from sim.presets import load_preset
from sim.units import RAD_S_PER_RPM

#: The published points: (V = T / T_N, efficiency) at 1000 rpm input, 20 degC.
REFERENCE = ((1.0, 0.78), (0.57, 0.78 * 0.93))
REFERENCE_SPEED_RPM = 1000.0
REFERENCE_TEMP_DEGC = 20.0
MESH_LOAD_EXP = 0.2
SHARES = {'bearing': 0.45, 'churn': 0.35, 'seal': 0.20}
F1 = 0.0005
STATIC_MESH_RATIO = 2.0

#: preset -> (bearing dm [m], bearing count, bearing load per output torque k_P [N/(N m)])
GEOMETRY = {
    'hu2020-rv': (0.035, 8, 30.0),
    'hu2020-rv-modified': (0.035, 8, 30.0),
    'rv-80e-101': (0.035, 8, 30.0),
    'li2023-rv': (0.030, 8, 35.0),
    'wang2020-2kv': (0.028, 8, 35.0),
}


def calibrate(name: str) -> dict[str, float]:
    """Loss parameters of preset ``name`` reproducing REFERENCE."""
    preset = load_preset(name)
    kin = kinematics_from_preset(preset)
    i = float(kin.gear_ratio)
    r_b = abs(float(kin.crank_rel_per_input))
    t_n = float(preset['torsion.rated_torque_nm'])
    dm, count, k_p = GEOMETRY[name]
    g = i * r_b * F1 * k_p * dm
    (v1, e1), (v2, e2) = REFERENCE
    a = np.array([[v1 ** MESH_LOAD_EXP, 1.0 / v1], [v2 ** MESH_LOAD_EXP, 1.0 / v2]])
    rhs = np.array([1.0 / e1 - 1.0 - g, 1.0 / e2 - 1.0 - g])
    f_ref, d = np.linalg.solve(a, rhs)
    t_drag = d * t_n / i
    lub = Lubricant(preset['lubricant.nu40_mm2_s'], preset['lubricant.nu100_mm2_s'])
    nu = float(lub.viscosity_mm2_s(REFERENCE_TEMP_DEGC))
    n_b = REFERENCE_SPEED_RPM * r_b
    m0_per_f0 = float(palmgren_m0_nm(nu, n_b, 1.0, dm)) * r_b * count
    return {'gear_ratio': i, 'g': g, 'd': d, 'no_load_torque_ref_nm': t_drag,
            'mesh_loss_ref': f_ref, 'mesh_loss_static': STATIC_MESH_RATIO * f_ref,
            'bearing_f0': SHARES['bearing'] * t_drag / m0_per_f0,
            'churn_torque_ref_nm': SHARES['churn'] * t_drag,
            'seal_torque_nm': SHARES['seal'] * t_drag,
            'bearing_dm_m': dm, 'bearing_count': count, 'bearing_load_n_per_nm': k_p,
            'reference_torque_nm': t_n,
            'omega_ref_rad_s': REFERENCE_SPEED_RPM * RAD_S_PER_RPM}


def main() -> int:
    """Print each preset's calibrated values."""
    for name in GEOMETRY:
        c = calibrate(name)
        print(f'# {name}: i = {c["gear_ratio"]:.4g}, g = {c["g"]:.5f}, d = {c["d"]:.5f}, '
              f'no-load torque at the reference {c["no_load_torque_ref_nm"]:.4f} N m')
        for key in ('mesh_loss_ref', 'mesh_loss_static', 'bearing_f0', 'churn_torque_ref_nm',
                    'seal_torque_nm'):
            print(f'{key} = {c[key]:.6g}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
