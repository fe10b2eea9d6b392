"""Wang 2020: the scans behind docs/DESIGN_NOTES.md's NLTE rows (record windows, angle laws).

Run: ``.venv/bin/python scripts/wang2020_readings.py [--grid] [--json]`` (about 1 min; with
``--grid`` the full 36^4 Eq. 21 grid of the four named angle laws, a few minutes more).

What it computes, all from Wang 2020 Eqs 1-5 and 8 written out here (r_p, alpha and the
Table 2 eccentricities of the preset; nothing of sim's NLTE code is used):

* **Windows.** The std of the NLTE before optimisation over every record [0, T] with T from
  3 s to 31.6 s (two output revolutions) in 0.1 s steps, and the p-p / amplitude over the
  same windows: can a shorter or longer record give Table 4's 0.637' std?
* **Angle laws.** Which rate (turns per output turn) each eccentricity phase turns at is the
  open reading of Eqs 1-4. Every integer rate of the planet phases (-27..27), the revolution
  phase (-27..27) and the output-wheel phase (-3..3) is scored on the paper's NLTE numbers
  (Fig. 5a p-p / amplitude / mean, Table 3's nine values, Table 4's six NLTE cells): the
  score of a reading is its largest relative error (means: error over max(|paper|, 0.1')).
* **Optimum of other readings** (``--grid``): the Eq. 21 optimum on the paper's 10 deg grid
  for the readings 'planet -26', 'revolution -26' and 'planet spin +1' and how far each
  moves Fig. 5a.

``tests/sim/test_wang2020_readings.py`` runs the window scan and the scores of the named
readings (fast); the full rate scan and the grid are this script's.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

import numpy as np

ALPHA = math.radians(35.266)
R_P = 0.065 * math.cos(math.radians(20.0))
E_M = (1e-5, 2e-5, 1e-5, 1e-5)                      # e_p1, e_p2, e_g, e_ot (Table 2)
ARCMIN = 10800.0 / math.pi
PERIOD_S = 15.8
TABLE2 = (90.0, 180.0, -135.0, 90.0)                # theta_p1, theta_p2, theta_g, theta_ot
OPTIMUM = (-70.0, 120.0, 110.0, 40.0)               # Eq. 21 (s.2.4.2)
TABLE3 = ((0.0, -50.0, 130.0, 120.0), (-60.0, 130.0, 100.0, 50.0), (90.0, 90.0, 180.0, 130.0))
#: paper values: Fig. 5a (p-p, amp, mean), Table 3 (amp, mean, std) x 3, Table 4 NLTE
PAPER_FIG5A = (2.23, 1.22, -0.15)
PAPER_TABLE3 = ((4.49, 2.24, 1.26), (0.79, 0.16, 0.32), (1.78, 0.05, 0.88))
PAPER_TABLE4 = ((2.245, 1.231, 0.637), (1.072, 0.604, 0.263))
SUITE = (-25, -25, 1)
NAMED = {'suite (-25, -25, +1)': (-25, -25, 1), 'planet -26': (-26, -25, 1),
         'revolution -26': (-25, -26, 1), 'planet spin +1': (1, -25, 1)}


def increments(phi: np.ndarray, phases_deg: Any, rates: tuple[Any, Any, Any],
               ) -> tuple[np.ndarray, np.ndarray]:
    """Wang 2020 Eqs 1-2 [m]; phases (..., 4) broadcast against phi (n,), and so do the rates
    (numbers, or (B, 1) arrays: B readings at once)."""
    ph = np.radians(np.asarray(phases_deg, dtype=float))[..., None]
    rp, rg, ro = rates

    def term(e: float, th0: np.ndarray, rate: Any, off: float) -> np.ndarray:
        if np.ndim(rate) == 2 and np.shape(rate)[0] > 1 and np.size(th0) == 1:
            # a batch of readings at one set of phases: each term depends on one of the
            # three rates, which take few values (55 in the full scan); the rows of each
            # value are computed once and gathered (the same operations on the same
            # numbers: the same array)
            vals, rows = np.unique(rate, return_inverse=True)
            one = e * (np.sin(th0 + vals[:, None] * phi + off) - np.sin(th0 + off))
            return one[rows.reshape(-1)]
        return e * (np.sin(th0 + rate * phi + off) - np.sin(th0 + off))

    e1, e2, eg, eo = E_M
    d1 = (term(e1, ph[..., 0, :], rp, -ALPHA) + term(eg, ph[..., 2, :], rg, -ALPHA)
          + term(eo, ph[..., 3, :], ro, -ALPHA))
    d2 = (term(e2, ph[..., 1, :], rp, -ALPHA) + term(eg, ph[..., 2, :], rg, math.pi - ALPHA)
          + term(eo, ph[..., 3, :], ro, math.pi - ALPHA))
    return d1, d2


def nlte_arcmin(phi: np.ndarray, phases_deg: Any, rates: tuple[Any, Any, Any]
                ) -> np.ndarray:
    """Eqs 5 and 8: max(Delta_1, Delta_2) / r_p in arcmin."""
    d1, d2 = increments(phi, phases_deg, rates)
    return np.maximum(d1, d2) / R_P * ARCMIN


def stats(te: np.ndarray) -> tuple[float, float, float, float]:
    """(p-p, amplitude, mean, std) along the last axis."""
    return (np.ptp(te, axis=-1), np.max(np.abs(te), axis=-1), np.mean(te, axis=-1),
            np.std(te, axis=-1))


# ------------------------------------------------------------------------------ windows


def window_scan(fs_hz: float = 1000.0) -> dict[str, float]:
    """Std / p-p / amplitude of the NLTE before optimisation over [0, T], T = 3..31.6 s."""
    t = np.arange(round(2 * PERIOD_S * fs_hz) + 1) / fs_hz
    te = nlte_arcmin(2 * math.pi * t / PERIOD_S, TABLE2, SUITE)
    n = np.arange(1, te.size + 1)
    mean = np.cumsum(te) / n
    std = np.sqrt(np.maximum(np.cumsum(te * te) / n - mean * mean, 0.0))
    hi, lo = np.maximum.accumulate(te), np.minimum.accumulate(te)
    amp = np.maximum.accumulate(np.abs(te))
    ends = np.round(np.arange(3.0, 2 * PERIOD_S + 1e-9, 0.1) * fs_hz).astype(int)
    return {'std_min_arcmin': float(std[ends].min()), 'std_max_arcmin': float(std[ends].max()),
            'pp_at_3s_arcmin': float(hi[ends[0]] - lo[ends[0]]),
            'pp_max_arcmin': float((hi - lo)[ends].max()),
            'amp_at_3s_arcmin': float(amp[ends[0]]), 'amp_max_arcmin': float(amp[ends].max())}


# ------------------------------------------------------------------------------ readings


def _errors(got: np.ndarray, want: tuple[float, ...], kinds: str) -> np.ndarray:
    """|relative error| per value (kind 'm' = mean: over max(|paper|, 0.1'))."""
    out = []
    for g, w, k in zip(got, want, kinds, strict=True):
        den = max(abs(w), 0.1) if k == 'm' else abs(w)
        out.append(np.abs(g - w) / den)
    return np.stack(out)


def reading_errors(rates_batch: np.ndarray, n: int = 3000,
                   batch: int = 256) -> dict[str, np.ndarray]:
    """Relative errors of each reading (rows of rates_batch) per group of paper values;
    'table3_fit': whether all nine Table 3 values are within the paper's rounding
    (+-0.005') plus 1 % (the tolerance of tests/sim/test_fidelity_wang2020.py).

    Readings are evaluated ``batch`` at a time as rows of one array (the same elementwise
    operations and per-row reductions as one reading at a time, 7x less CPU in the scan)."""
    phi = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    out: dict[str, list[Any]] = {'fig5a': [], 'table3': [], 'table4': [], 'table3_fit': []}
    every = np.asarray(rates_batch, dtype=float).reshape(-1, 3)
    for start in range(0, every.shape[0], batch):
        rows = every[start:start + batch]
        r = (rows[:, 0:1], rows[:, 1:2], rows[:, 2:3])       # (B, 1) against phi (n,)
        pp, amp, mean, _ = stats(nlte_arcmin(phi, TABLE2, r))
        out['fig5a'].append(_errors(np.array([pp, amp, mean]), PAPER_FIG5A, 'pam').T)
        t3 = [np.array(stats(nlte_arcmin(phi, g, r))[1:]) for g in TABLE3]   # (3, B) each
        out['table3'].append(np.concatenate([
            _errors(s, w, 'ams') for s, w in zip(t3, PAPER_TABLE3, strict=True)]).T)
        out['table3_fit'].append(np.all([
            np.all(np.abs(s - np.array(w)[:, None]) <= 0.005 + 0.01 * np.abs(w)[:, None],
                   axis=0)
            for s, w in zip(t3, PAPER_TABLE3, strict=True)], axis=0))
        t4 = [stats(nlte_arcmin(phi, g, r)) for g in (TABLE2, OPTIMUM)]
        out['table4'].append(np.concatenate([
            _errors(np.array([s[0], s[1], s[3]]), w, 'pas')
            for s, w in zip(t4, PAPER_TABLE4, strict=True)]).T)
    return {k: np.concatenate(v) for k, v in out.items()}


def score(errors: dict[str, np.ndarray]) -> np.ndarray:
    """Largest relative error over all paper values, per reading."""
    return np.max(np.concatenate([errors[k] for k in ('fig5a', 'table3', 'table4')], axis=1),
                  axis=1)


def rate_scan() -> dict[str, Any]:
    """Every integer reading: planet -27..27, revolution -27..27, output wheel -3..3."""
    rp, rg, ro = np.meshgrid(np.arange(-27, 28), np.arange(-27, 28), np.arange(-3, 4),
                             indexing='ij')
    rates = np.stack([rp.ravel(), rg.ravel(), ro.ravel()], axis=1)
    rates = rates[(rates[:, 0] != 0) | (rates[:, 1] != 0)]
    err = reading_errors(rates, n=1500)
    sc = score(err)
    order = np.argsort(sc)
    t3_ok = err['table3_fit']
    return {'readings': int(rates.shape[0]), 'best': [
        {'rates': [int(v) for v in rates[i]], 'score': float(sc[i])} for i in order[:5]],
        'table3_fit': [[int(v) for v in rates[i]] for i in np.nonzero(t3_ok)[0]]}


def grid_optimum(rates: tuple[float, float, float], n: int = 720) -> dict[str, Any]:
    """Eq. 21 on the 10 deg grid (36^4 sets) for one reading; refined on 40 candidates."""
    ax = np.arange(-180.0, 180.0, 10.0)
    phi = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    rp, rg, ro = rates
    e1, e2, eg, eo = E_M
    r = np.radians(ax)[:, None]

    def tab(e: float, rate: float, off: float) -> np.ndarray:
        return e * (np.sin(r + rate * phi + off) - np.sin(r + off))

    tp1, tp2 = tab(e1, rp, -ALPHA), tab(e2, rp, -ALPHA)
    tg, to = tab(eg, rg, -ALPHA), tab(eo, ro, -ALPHA)
    best = np.empty((36, 36, 36, 36))
    for i3 in range(36):
        for i4 in range(36):
            c = tg[i3] + to[i4]                 # pair 1 adds these terms, pair 2 subtracts
            env = np.maximum((tp1 + c)[:, None, :], (tp2 - c)[None, :, :])
            best[:, :, i3, i4] = np.max(np.abs(env), axis=-1)
    flat = np.argsort(best, axis=None)[:40]
    fine = np.linspace(0.0, 2 * math.pi, 40_000, endpoint=False)
    cands = np.stack(np.unravel_index(flat, best.shape), axis=1)
    s = [float(np.max(np.abs(nlte_arcmin(fine, ax[c], rates)))) for c in cands]
    k = int(np.argmin(s))
    return {'rates': list(rates), 'optimum_deg': [float(v) for v in ax[cands[k]]],
            'S_arcmin': s[k]}


def fig5a_change(rates: tuple[float, float, float]) -> list[float]:
    """Relative errors of Fig. 5a's p-p, amplitude, mean under a reading (signed)."""
    phi = np.linspace(0.0, 2 * math.pi, 40_000, endpoint=False)
    pp, amp, mean, _ = stats(nlte_arcmin(phi, TABLE2, rates))
    return [float(pp / 2.23 - 1), float(amp / 1.22 - 1), float(mean / -0.15 - 1)]


def main(argv: list[str] | None = None) -> int:
    """Print (or --json) the scans."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--grid', action='store_true', help='also the 36^4 grid of three readings')
    ap.add_argument('--json', action='store_true', help='one JSON document on stdout')
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    out: dict[str, Any] = {'windows': window_scan()}
    named = np.array(list(NAMED.values()), dtype=float)
    err = reading_errors(named)
    out['named'] = {name: {'score': float(sc), 'table3_fit': bool(fit),
                           'fig5a': fig5a_change(rates)}
                    for name, rates, sc, fit in zip(NAMED, NAMED.values(), score(err),
                                                    err['table3_fit'], strict=True)}
    print('rate scan ...', file=sys.stderr)
    out['rate_scan'] = rate_scan()
    if args.grid:
        out['grid'] = {}
        for name, rates in NAMED.items():
            print(f'grid {name} ...', file=sys.stderr)
            out['grid'][name] = grid_optimum(rates)
    out['compute_s'] = time.perf_counter() - t0
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for key, value in out.items():
            print(f'{key}: {json.dumps(value)}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
