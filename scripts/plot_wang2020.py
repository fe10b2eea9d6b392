"""Figures 4-7 of Wang 2020 (2K-V) re-computed with sim.wang2020; PNGs in out/wang2020/.

Run: ``.venv/bin/python scripts/plot_wang2020.py [--out out/wang2020] [--seconds 3]``.
As in the paper, the curves show the first ``--seconds`` (3 s) of the 15.8 s major cycle;
the statistics printed and in the titles are over the whole output revolution.

* fig4_pairs.png: NLTE of gear pairs 1 and 2 (paper: 2.06/1.89/-0.86', 2.89/1.74/-0.29')
* fig5_nlte_ste.png: total NLTE (2.23/1.22/-0.15') and STE at 30/100/300 N m
  (means -0.449/-1.032/-2.195')
* fig6_dte.png: DTE under constant loads and DTE vs STE
* fig7_sin_load.png: DTE under 30 N m sinusoidal load at f_w and at the mesh frequency,
  with NLTE and NLTE + backlash
* fig16_spectrum.png: NLTE amplitude spectrum in orders of f_w
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib as mpl

mpl.use('Agg')
import matplotlib.pyplot as plt
import numpy as np

from sim.presets import load_preset
from sim.units import rad_to_arcmin
from sim.wang2020 import (
    Wang2kvDynamics,
    Wang2kvParams,
    nlte_curves,
    static_te_rad,
)

FS_HZ = 10_000.0


def _stats(te_arcmin: np.ndarray) -> str:
    return (f"p-p {np.ptp(te_arcmin):.3f}', amp {np.max(np.abs(te_arcmin)):.3f}', "
            f"mean {np.mean(te_arcmin):.3f}'")


def main() -> None:
    """Compute and save the figures."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--out', type=Path, default=Path('out/wang2020'))
    ap.add_argument('--seconds', type=float, default=3.0, help='shown span [s]')
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    params = Wang2kvParams.from_preset(load_preset('wang2020-2kv'))
    f_in = params.input_speed_rpm / 60.0
    kin = params.kinematics
    period = kin.output_period_s(f_in)
    n = round(period * FS_HZ)
    t = np.arange(n) / FS_HZ
    omega = 2 * math.pi * f_in
    theta_in = omega * t
    theta_out = theta_in / kin.gear_ratio
    show = t <= args.seconds
    c = nlte_curves(theta_out, params)
    am = {k: rad_to_arcmin(v) for k, v in c._asdict().items()}

    # Fig. 4: per-pair NLTE
    fig, axs = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for ax, key, paper in zip(axs, ('nlte1_rad', 'nlte2_rad'),
                              ("2.06/1.89/-0.86'", "2.89/1.74/-0.29'"), strict=True):
        ax.plot(t[show], am[key][show], lw=0.8)
        ax.set_title(f'{key[:5].upper()} pair {key[4]}: {_stats(am[key])} (paper {paper})',
                     fontsize=9)
        ax.set_ylabel('TE [arcmin]')
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel('time [s]')
    fig.tight_layout()
    fig.savefig(args.out / 'fig4_pairs.png', dpi=120)
    plt.close(fig)
    print('Fig. 4  pair 1:', _stats(am['nlte1_rad']), "| paper 2.06/1.89/-0.86'")
    print('Fig. 4  pair 2:', _stats(am['nlte2_rad']), "| paper 2.89/1.74/-0.29'")

    # Fig. 5: total NLTE and STE
    fig, axs = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    axs[0].plot(t[show], am['nlte_rad'][show], lw=0.8)
    axs[0].set_title(f"NLTE: {_stats(am['nlte_rad'])} (paper 2.23/1.22/-0.15')", fontsize=9)
    print('Fig. 5a NLTE  :', _stats(am['nlte_rad']), "| paper 2.23/1.22/-0.15'")
    for load, paper in ((30.0, -0.44858), (100.0, -1.0321), (300.0, -2.19511)):
        ste = rad_to_arcmin(static_te_rad(theta_out, load, params))
        axs[1].plot(t[show], ste[show], lw=0.8,
                    label=f'{load:.0f} N m: mean {ste.mean():.4f}\' (paper {paper}\')')
        print(f'Fig. 5b STE {load:5.0f} N m:', _stats(ste), f"| paper mean {paper}'")
    axs[1].legend(fontsize=8)
    for ax in axs:
        ax.set_ylabel('TE [arcmin]')
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel('time [s]')
    fig.tight_layout()
    fig.savefig(args.out / 'fig5_nlte_ste.png', dpi=120)
    plt.close(fig)

    # Fig. 6: DTE under constant loads, DTE vs STE
    fig, axs = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for load in (30.0, 100.0, 300.0):
        dte = rad_to_arcmin(Wang2kvDynamics(params).te_rad(
            t, theta_in, np.full(n, omega), np.full(n, load)))
        ste = rad_to_arcmin(static_te_rad(theta_out, load, params))
        axs[0].plot(t[show], dte[show], lw=0.8, label=f'DTE {load:.0f} N m')
        axs[1].plot(t[show], (dte - ste)[show], lw=0.8, label=f'DTE - STE {load:.0f} N m')
        print(f'Fig. 6  DTE {load:5.0f} N m:', _stats(dte))
    for ax in axs:
        ax.legend(fontsize=8)
        ax.set_ylabel('TE [arcmin]')
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel('time [s]')
    fig.tight_layout()
    fig.savefig(args.out / 'fig6_dte.png', dpi=120)
    plt.close(fig)

    # Fig. 7: sinusoidal loads at f_w and at the mesh frequency
    freqs = kin.frequencies(f_in)
    span = t <= min(args.seconds, 1.0)
    fig, axs = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for ax, (label, f_load) in zip(axs, (('f_w', freqs['crank_hz']),
                                         ('mesh', freqs['mesh_stage2_hz'])), strict=True):
        m = int(span.sum())
        load = 30.0 * np.sin(2 * math.pi * f_load * t[:m])
        dte = rad_to_arcmin(Wang2kvDynamics(params).te_rad(
            t[:m], theta_in[:m], np.full(m, omega), load))
        ax.plot(t[:m], dte, lw=0.6, label=f'DTE, 30 N m sin at {label} ({f_load:.2f} Hz)')
        ax.plot(t[:m], am['nlte_rad'][:m], 'k--', lw=0.8, label='NLTE')
        ax.plot(t[:m], (am['nlte_rad'] + am['backlash_rad'])[:m], 'r--', lw=0.8,
                label='NLTE + backlash')
        ax.legend(fontsize=8, loc='upper right')
        ax.set_ylabel('TE [arcmin]')
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel('time [s]')
    fig.tight_layout()
    fig.savefig(args.out / 'fig7_sin_load.png', dpi=120)
    plt.close(fig)

    # Fig. 16a: NLTE spectrum in orders of f_w (whole revolution: lines on bins)
    te = am['nlte_rad']
    amp = np.abs(np.fft.rfft(te - te.mean())) * 2 / n
    orders_fw = np.arange(amp.size) / kin.crank_per_output
    fig, ax = plt.subplots(figsize=(9, 3.5))
    keep = orders_fw <= 6
    ax.stem(orders_fw[keep], amp[keep], markerfmt=' ', basefmt=' ')
    ax.set_xlabel('frequency / f_w')
    ax.set_ylabel('amplitude [arcmin]')
    ax.set_title(f'NLTE spectrum; largest line at {orders_fw[np.argmax(amp)]:.2f} f_w',
                 fontsize=9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out / 'fig16_spectrum.png', dpi=120)
    plt.close(fig)
    print(f'figures written to {args.out}/')


if __name__ == '__main__':
    main()
