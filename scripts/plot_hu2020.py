"""Plots of the Hu 2020 RV model into ``out/hu2020/`` (or the folder given as argument).

* ``tca_forces.png``: contact force, normal deformation and initial clearance per pin for
  the initial (Table 3) and modified (Table 6) prototypes (cf. Figs 7 and 10).
* ``geometric_te.png``: geometric TE of hu2020-rv with its default ``[errors]`` over one
  output revolution, and its order spectrum (one line per error factor).

Usage: ``.venv/bin/python scripts/plot_hu2020.py [OUT_DIR]``
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib as mpl

mpl.use('Agg')
import matplotlib.pyplot as plt
import numpy as np

from sim.hu2020 import (
    FACTOR_KEYS,
    HuRvParams,
    build_te_model,
    tooth_contact_analysis,
)
from sim.presets import load_preset
from sim.units import rad_to_arcmin, rad_to_deg


def plot_tca(out: Path) -> Path:
    """Force / deformation / clearance per pin, before and after the modification."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=False)
    for ax, name in zip(axes, ('hu2020-rv', 'hu2020-rv-modified'), strict=True):
        res = tooth_contact_analysis(HuRvParams.from_preset(load_preset(name)))
        deg = rad_to_deg(res.pin_angle_rad)
        ax.bar(deg, res.force_n, width=6, color='tab:blue', label='contact force F_i [N]')
        ax.set_xlabel('pin angle phi_i [deg]')
        ax.set_ylabel('F_i [N]')
        ax.set_title(f'{name}: {res.pins_in_mesh} pins, F_max {res.f_max_n:.0f} N')
        ax2 = ax.twinx()
        ax2.plot(deg, res.deformation_m * 1e6, 'k.-', label='deformation delta_i [um]')
        ax2.plot(deg, res.clearance_m * 1e6, 'r.--', label='clearance Delta_i [um]')
        ax2.set_ylabel('[um]')
        ax2.set_ylim(0, 25)
        ax2.legend(loc='upper right', fontsize=8)
        ax.legend(loc='upper left', fontsize=8)
    fig.tight_layout()
    path = out / 'tca_forces.png'
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_geometric_te(out: Path, n: int = 16384) -> Path:
    """Geometric TE over one output revolution and its order spectrum (peak amplitude)."""
    model = build_te_model(load_preset('hu2020-rv'), 'geometric')
    i = model.kinematics.gear_ratio
    theta_in = np.arange(n) / n * 2 * np.pi * i
    z = np.zeros(n)
    te = model.te_rad(z, theta_in, z, z)
    amp = np.abs(np.fft.rfft(te)) * 2 / n
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7))
    a1.plot(rad_to_deg(theta_in / i), rad_to_arcmin(te), lw=0.6)
    a1.set_xlabel('output angle [deg]')
    a1.set_ylabel('TE [arcmin]')
    a1.set_title(f'hu2020-rv geometric TE, p-p {rad_to_arcmin(np.ptp(te)):.3f} arcmin')
    lines = np.flatnonzero(amp > 1e-6 * amp.max())
    a2.vlines(lines, 1e-4, rad_to_arcmin(amp[lines]), lw=2)
    a2.set_xscale('log')
    for o in lines:
        names = [k for k in FACTOR_KEYS if round(model.orders[k]) == o
                 and model.line_amplitude_rad[k] != 0]
        a2.annotate(f'order {o}:\n' + '\n'.join(names), (o, rad_to_arcmin(amp[o])),
                    xytext=(4 if o != 39 else -90, -10), textcoords='offset points',
                    fontsize=7, va='top')
    a2.set_xlim(10, 5000)
    a2.set_ylim(1e-3, 2)
    a2.set_yscale('log')
    a2.set_xlabel('order (per output revolution); crank 39, crank rel. 40, pin mesh 1560')
    a2.set_ylabel('amplitude [arcmin, peak]')
    fig.tight_layout()
    path = out / 'geometric_te.png'
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv: list[str]) -> int:
    """Write both figures; print their paths."""
    out = Path(argv[0]) if argv else Path('out/hu2020')
    out.mkdir(parents=True, exist_ok=True)
    for path in (plot_tca(out), plot_geometric_te(out)):
        print(path)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
