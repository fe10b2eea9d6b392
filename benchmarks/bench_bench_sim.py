"""Throughput of sim.bench.BenchSimulator.next_block: samples/s and real-time factor.

Run: ``.venv/bin/python benchmarks/bench_bench_sim.py [--seconds 2]``. Prints a markdown table.
Cases: 10 kHz sampling, blocks of 100 and 1000, RON 886 on both shafts, 300 rpm; models:
the real ``wang2020-2kv`` in its modes (when sim/wang2020.py is present) and a closed-form
sinusoidal fake (bench overhead alone). Real-time factor = simulated seconds / wall seconds.
"""

from __future__ import annotations

import argparse
import importlib.util
import platform
import time
from dataclasses import dataclass

import numpy as np

from sim.bench import BenchConfig, BenchSimulator
from sim.drive import ConstantLoad, ConstantSpeed
from sim.kinematics import ReducerKinematics, kinematics_2kv
from sim.presets import preset_from_text

FAKE_TOML = """
name = "fake-2kv"
model = "fake"
[kinematics]
kind = "2kv"
z_sun = 12
z_planet = 36
z_gear = 50
z_ring = 52
"""


@dataclass
class _SineTe:
    """TE = 1 arcmin sin(25 theta_out): the cheapest model, to time the bench alone."""

    kinematics: ReducerKinematics

    def te_rad(self, t_s, theta_in_rad, omega_in_rad_s, load_nm):
        return 2.9e-4 * np.sin(25.0 * theta_in_rad / self.kinematics.gear_ratio)

    def reset(self) -> None:
        """Stateless."""


def _time_case(sim: BenchSimulator, seconds: float) -> tuple[float, float]:
    """Samples per second and real-time factor of next_block over ~``seconds`` wall time."""
    cfg = sim.config
    sim.next_block()  # warm-up (imports, caches)
    n = 0
    t0 = time.perf_counter()
    while True:
        sim.next_block()
        n += 1
        wall = time.perf_counter() - t0
        if wall >= seconds:
            break
    samples = n * cfg.block_size
    return samples / wall, samples / cfg.sample_rate_hz / wall


def main(argv: list[str] | None = None) -> int:
    """Run the cases and print the table."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--seconds', type=float, default=2.0, help='wall time per case [s]')
    ap.add_argument('--modes', default='nlte,ste,dte', help='wang2020 modes to time')
    args = ap.parse_args(argv)

    cases: list[tuple[str, int]] = []
    have_wang = importlib.util.find_spec('sim.wang2020') is not None
    if have_wang:
        cases += [(f'wang2020-2kv {m}', bs) for m in args.modes.split(',') for bs in (100, 1000)]
    cases += [('fake sine (bench overhead)', bs) for bs in (100, 1000)]

    print(f'BenchSimulator.next_block, 10 kHz, RON 886 both shafts, 300 rpm, 30 N m; '
          f'{platform.python_version()}, numpy {np.__version__}, {args.seconds:g} s per case\n')
    print('| model | block size | samples/s | real-time factor | ms/block |')
    print('|---|---:|---:|---:|---:|')
    for label, bs in cases:
        common = {'drive': ConstantSpeed(300.0), 'load': ConstantLoad(30.0),
                  'encoder_in': 'heidenhain-ron886', 'encoder_out': 'heidenhain-ron886',
                  'sample_rate_hz': 10_000.0, 'block_size': bs, 'seed': 0}
        if label.startswith('wang2020'):
            mode = label.split()[-1]
            try:
                sim = BenchSimulator(BenchConfig(preset='wang2020-2kv', te_mode=mode, **common))
            except Exception as exc:  # noqa: BLE001 - report and go on
                print(f'| {label} | {bs} | n/a ({type(exc).__name__}: {exc}) | | |')
                continue
        else:
            preset = preset_from_text(FAKE_TOML)
            sim = BenchSimulator(BenchConfig(preset='fake-2kv', **common), preset=preset,
                                 model=_SineTe(kinematics_2kv(12, 36, 50, 52)))
        rate, rtf = _time_case(sim, args.seconds)
        print(f'| {label} | {bs} | {rate:,.0f} | {rtf:,.1f} | {1e3 * bs / rate:.3f} |')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
