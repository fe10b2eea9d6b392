"""Measured-looking hysteresis records written from a closed-form curve (issue 34).

The unit: free play ``b``, Coulomb friction ``tf`` in parallel with an elastic flank of
stiffness ``k1`` up to the elastic torque ``tk`` and ``k2`` beyond (symmetric). The output
angle follows the true applied torque quasi-statically through the play operator

    phi_n = min(max(phi_{n-1}, phi_up(T_n - tf)), phi_down(T_n + tf))

(phi_up(x): the smallest angle whose elastic torque reaches x; phi_down(x): the largest
whose elastic torque does not exceed x). Nothing here comes from the suite's code: the
truth of each metric is worked out below from these closed forms.

The bench: a loader that ramps between held torques in ``ramp_s`` and ripples about them
(a slow sine), a torque transducer with white noise ``noise_nm``, and the RON 886 on the
output (36,000 lines: its 0.1" position error within each 36" signal period, 0.01" noise,
quantised to 36e6 counts per revolution).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

ARCMIN = math.pi / 10800
ARCSEC = ARCMIN / 60


@dataclass(frozen=True)
class Unit:
    """The closed-form unit (SI)."""

    rated_nm: float = 167.0              # RV-20E class
    b_rad: float = 0.6 * ARCMIN          # free play
    tf_nm: float = 2.5                   # friction, 1.5 % of rated
    k1: float = 35.0 / ARCMIN            # N m/rad up to tk
    k2: float = 49.0 / ARCMIN            # beyond
    tk_nm: float = 0.4 * 167.0           # elastic torque of the knee

    def phi_up(self, x: np.ndarray) -> np.ndarray:
        """Smallest angle with elastic torque >= x."""
        x = np.asarray(x, dtype=float)
        return np.sign(x) * self._inv(np.abs(x)) + np.where(x > 0, self.b_rad / 2,
                                                            -self.b_rad / 2)

    def phi_down(self, x: np.ndarray) -> np.ndarray:
        """Largest angle with elastic torque <= x."""
        x = np.asarray(x, dtype=float)
        return np.sign(x) * self._inv(np.abs(x)) + np.where(x >= 0, self.b_rad / 2,
                                                            -self.b_rad / 2)

    def _inv(self, y: np.ndarray) -> np.ndarray:
        return np.where(y <= self.tk_nm, y / self.k1,
                        self.tk_nm / self.k1 + (y - self.tk_nm) / self.k2)

    # -- the truth of each metric (catalogue definitions on the noise-free curve) -------
    def truth(self, *, lost_motion_fraction: float = 0.03,
              regions: dict[str, tuple[float, float]] | None = None) -> dict[str, float]:
        """Backlash, lost motion and rigidities of the closed form."""
        tf, tr = self.tf_nm, self.rated_nm
        t = lost_motion_fraction * tr
        out = {
            'backlash_rad': float(self.phi_down(tf) - self.phi_up(-tf)),
            'lost_motion_rad': float(0.5 * (self.phi_up(t - tf) + self.phi_down(t + tf))
                                     - 0.5 * (self.phi_up(-t - tf) + self.phi_down(-t + tf))),
        }
        for name, (lo, hi) in (regions or {'K': (0.5, 1.0)}).items():
            t1, t2 = lo * tr, hi * tr
            pos = (t2 - t1) / float(self.phi_up(t2 - tf) - self.phi_up(t1 - tf))
            neg = (t2 - t1) / float(self.phi_down(-t1 + tf) - self.phi_down(-t2 + tf))
            out[f'torsional_rigidity_{name}_nm_per_rad'] = min(pos, neg)
        return out

    def loop_area_j(self) -> float:
        """Area of the quasi-static loop between -T_R and +T_R [J], by quadrature."""
        tr, tf = self.rated_nm, self.tf_nm
        t = np.linspace(-tr, tr, 400_001)
        top = self.phi_up(tr - tf)
        bottom = self.phi_down(-tr + tf)
        desc = np.minimum(top, self.phi_down(t + tf))
        asc = np.maximum(bottom, self.phi_up(t - tf))
        return float(np.trapezoid(desc - asc, t))

    def respond(self, torque_nm: np.ndarray, phi0: float = 0.0) -> np.ndarray:
        """Output angle under the true applied torque (play operator, sample by sample)."""
        up = self.phi_up(torque_nm - self.tf_nm)
        down = self.phi_down(torque_nm + self.tf_nm)
        out = np.empty_like(torque_nm)
        phi = phi0
        for i in range(torque_nm.size):
            phi = min(max(phi, up[i]), down[i])
            out[i] = phi
        return out

    def torque_at(self, phi: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """Torque to turn the output at angle phi in ``direction`` (+1/-1): elastic torque
        plus friction (constant-speed loading)."""
        x = np.asarray(phi, dtype=float)
        y = np.maximum(np.abs(x) - self.b_rad / 2, 0.0)
        g = np.sign(x) * np.where(y <= self.tk_nm / self.k1, self.k1 * y,
                                  self.tk_nm + (y - self.tk_nm / self.k1) * self.k2)
        return g + direction * self.tf_nm


def step_torques(unit: Unit, *, step_fraction: float = 0.1, lost_motion_fraction: float = 0.03,
                 regions: tuple[float, ...] = (0.5, 1.0), preload: bool = True,
                 cycles: int = 1) -> list[float]:
    """The held torques of an equal-torque-step test (the plan's sequence)."""
    tr = unit.rated_nm
    n = round(1 / step_fraction)
    fr = sorted({round(k / n, 12) for k in range(n + 1)} | {lost_motion_fraction}
                | set(regions))
    up = [f * tr for f in fr]
    one = up + up[-2::-1] + [-t for t in up[1:]] + [-t for t in up[-2::-1]]
    seq = ([-0.5 * tr, -tr, -0.5 * tr, 0.0] if preload else []) + one
    for _ in range(cycles - 1):
        seq += one[1:]
    return seq


def ron886(theta_rad: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """What a RON 886 reads (see the module docstring)."""
    x = theta_rad + 0.1 * ARCSEC * np.sin(36_000 * theta_rad) \
        + rng.normal(0.0, 0.01 * ARCSEC, theta_rad.size)
    q = 2 * math.pi / 36e6
    return np.round(x / q) * q


@dataclass(frozen=True)
class Record:
    """A measured record: time, measured torque, measured angle (SI)."""

    time_s: np.ndarray
    torque_nm: np.ndarray
    angle_rad: np.ndarray
    true_torque_nm: np.ndarray
    true_angle_rad: np.ndarray


def torque_step_record(unit: Unit, torques: list[float], rng: np.random.Generator, *,
                       fs_hz: float = 1000.0, dwell_s: float = 0.5, ramp_s: float = 0.03,
                       noise_nm: float = 0.4, ripple_nm: float = 0.15,
                       offset_rad: float = 1.234) -> Record:
    """Held torques with linear ramps between them, ripple, transducer noise."""
    n_dwell, n_ramp = round(dwell_s * fs_hz), round(ramp_s * fs_hz)
    parts = [np.full(n_dwell, torques[0])]
    for a, b in itertools.pairwise(torques):
        parts.append(np.linspace(a, b, n_ramp + 2)[1:-1])
        parts.append(np.full(n_dwell, b))
    command = np.concatenate(parts)
    t = np.arange(command.size) / fs_hz
    true = command + ripple_nm * np.sin(2 * math.pi * 1.3 * t)
    phi = unit.respond(true)
    return Record(time_s=t, torque_nm=true + rng.normal(0.0, noise_nm, t.size),
                  angle_rad=ron886(phi + offset_rad, rng), true_torque_nm=true,
                  true_angle_rad=phi)


def constant_speed_record(unit: Unit, rng: np.random.Generator, *, cycles: int = 2,
                          speed_rad_s: float = 2e-4, fs_hz: float = 1000.0,
                          noise_nm: float = 0.4, preload: bool = True,
                          offset_rad: float = 0.5) -> Record:
    """The output turned at a constant speed between the torques +-T_R (position control):
    the torque is the elastic torque plus friction in the direction of motion."""
    tr = unit.rated_nm
    top = float(unit.phi_up(tr - unit.tf_nm))        # where turning up reaches +T_R
    bottom = float(unit.phi_down(-tr + unit.tf_nm))  # turning down reaches -T_R
    dstep = speed_rad_s / fs_hz
    moves = ([(-1, bottom), (1, 0.0)] if preload else []) + \
        [(1, top), (-1, bottom), (1, 0.0)] * 1
    for _ in range(cycles - 1):
        moves[-1] = (1, top)
        moves += [(-1, bottom), (1, 0.0)]
    phis, dirs = [], []
    phi = 0.0
    for direction, target in moves:
        n = max(1, math.ceil(abs(target - phi) / dstep))
        seg = np.linspace(phi, target, n + 1)[1:]
        phis.append(seg)
        dirs.append(np.full(seg.size, float(direction)))
        phi = target
    p = np.concatenate(phis)
    d = np.concatenate(dirs)
    true = unit.torque_at(p, d)
    t = np.arange(p.size) / fs_hz
    return Record(time_s=t, torque_nm=true + rng.normal(0.0, noise_nm, t.size),
                  angle_rad=ron886(p + offset_rad, rng), true_torque_nm=true,
                  true_angle_rad=p)
