"""Lumped thermal model of a reducer case: one heat capacity, one conductance to ambient.

    C dT/dt = P_loss(t) - G (T - T_amb),     C = m c,   G = h A + G_mount,   tau = C / G

``P_loss`` is the sum of the losses of :mod:`sim.losses`; ``h A`` is convection and
radiation from the case surface, ``G_mount`` conduction into the bench through the flanges.
For a constant loss the step response is

    T(t) = T_inf + (T_0 - T_inf) exp(-t / tau),     T_inf = T_amb + P_loss / G,

(:func:`step_response_degc`), and the time at which the rate |dT/dt| has fallen to ``r``
is ``tau ln(|T_inf - T_0| / (tau r))`` (:meth:`ThermalParams.settle_time_s`).

:class:`ThermalState` integrates a sampled loss exactly for a loss held constant over each
sample interval (zero-order hold): ``T[k+1] = a T[k] + (1 - a)(T_amb + P[k] / G)``,
``a = exp(-dt / tau)``, as one linear recursion per block (``scipy.signal.lfilter``), so a
block of samples costs no Python loop and a long session no drift: the recursion is the
exact solution of the ODE between samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np

from sim._checks import Rule, real_number
from sim.errors import ModelInputError, PresetError

if TYPE_CHECKING:
    from sim.presets import Preset

__all__ = ['ThermalParams', 'ThermalState', 'step_response_degc']

_RULES: dict[str, Rule] = {
    'case_mass_kg': '>0', 'specific_heat_j_kgk': '>0', 'surface_area_m2': '>=0',
    'h_conv_w_m2k': '>=0', 'mount_conductance_w_k': '>=0', 'ambient_degc': ''}


@dataclass(frozen=True)
class ThermalParams:
    """The ``[thermal]`` section of a preset (SI units, temperatures in degC).

    Attributes:
        case_mass_kg: Mass that heats up with the case m [kg], > 0.
        specific_heat_j_kgk: Its specific heat c [J/(kg K)], > 0.
        surface_area_m2: Case surface exchanging heat with the air A [m^2], >= 0.
        h_conv_w_m2k: Convection + radiation coefficient h [W/(m^2 K)], >= 0.
        mount_conductance_w_k: Conduction into the bench G_mount [W/K], >= 0.
        ambient_degc: Ambient (and default initial) temperature [degC].
    """

    case_mass_kg: float
    specific_heat_j_kgk: float
    surface_area_m2: float
    h_conv_w_m2k: float
    mount_conductance_w_k: float
    ambient_degc: float

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field); G must be > 0."""
        for f in fields(self):
            object.__setattr__(self, f.name, real_number(f'thermal.{f.name}',
                                                         getattr(self, f.name), _RULES[f.name]))
        if not self.conductance_w_k > 0.0:
            msg = ('thermal: h_conv_w_m2k * surface_area_m2 + mount_conductance_w_k must be > 0 '
                   '(the case must lose heat somewhere)')
            raise ModelInputError(msg)

    @property
    def capacity_j_k(self) -> float:
        """C = m c [J/K]."""
        return self.case_mass_kg * self.specific_heat_j_kgk

    @property
    def conductance_w_k(self) -> float:
        """G = h A + G_mount [W/K]."""
        return self.h_conv_w_m2k * self.surface_area_m2 + self.mount_conductance_w_k

    @property
    def time_constant_s(self) -> float:
        """tau = C / G [s]."""
        return self.capacity_j_k / self.conductance_w_k

    def steady_temp_degc(self, power_w: float) -> float:
        """T_inf = T_amb + P / G [degC]."""
        return self.ambient_degc + real_number('power_w', power_w) / self.conductance_w_k

    def settle_time_s(self, power_w: float, temp0_degc: float, rate_k_per_s: float) -> float:
        """Time after a loss step at which |dT/dt| has fallen to ``rate_k_per_s`` [s]
        (0 if it is already below)."""
        r = real_number('rate_k_per_s', rate_k_per_s, '>0')
        gap = abs(self.steady_temp_degc(power_w) - real_number('temp0_degc', temp0_degc))
        tau = self.time_constant_s
        return max(0.0, tau * math.log(gap / (tau * r))) if gap > 0 else 0.0

    @classmethod
    def from_preset(cls, preset: Preset) -> ThermalParams:
        """Read ``thermal.*`` of a :class:`sim.presets.Preset`.

        Raises:
            PresetError: Missing, unknown or invalid keys (the message names the key).
        """
        sec = preset.section('thermal')
        name = preset.name
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(sec) - set(names))
        missing = [n for n in names if n not in sec]
        if unknown or missing:
            what = f'unknown key thermal.{unknown[0]}' if unknown else f'no thermal.{missing[0]}'
            msg = f'preset {name!r} has {what}; expected {", ".join(names)}'
            raise PresetError(msg)
        try:
            return cls(**{k: sec[k] for k in names})
        except ModelInputError as exc:
            msg = f'preset {name!r}: {exc}'
            raise PresetError(msg) from None


def step_response_degc(t_s: np.ndarray | float, power_w: float, temp0_degc: float,
                       params: ThermalParams) -> np.ndarray:
    """Case temperature after a constant loss ``power_w`` is switched on at t = 0 [degC].

    Examples:
        >>> p = ThermalParams(10.0, 460.0, 0.1, 10.0, 4.0, 20.0)  # G = 5 W/K, tau = 920 s
        >>> float(step_response_degc(920.0, 100.0, 20.0, p))  # 63.2 % of the 20 K rise
        32.64...
    """
    t = np.asarray(t_s, dtype=np.float64)
    t_inf = params.steady_temp_degc(power_w)
    return t_inf + (temp0_degc - t_inf) * np.exp(-t / params.time_constant_s)


class ThermalState:
    """The case temperature carried from block to block.

    Args:
        params: The thermal parameters.
        temp0_degc: Initial case temperature [degC]; the ambient by default.
    """

    def __init__(self, params: ThermalParams, temp0_degc: float | None = None) -> None:
        """Start at ``temp0_degc`` (see class docstring)."""
        self.params = params
        self.temp0_degc = params.ambient_degc if temp0_degc is None else real_number(
            'temp0_degc', temp0_degc)
        self.temp_degc = self.temp0_degc

    def reset(self) -> None:
        """Back to the initial temperature."""
        self.temp_degc = self.temp0_degc

    def advance(self, power_w: np.ndarray, dt_s: float) -> np.ndarray:
        """Temperatures at the start of each sample interval while ``power_w`` is dissipated
        (held over each interval of ``dt_s``); the state moves to the end of the last one.

        Raises:
            ModelInputError: ``dt_s`` not > 0, or a power that is not finite.
        """
        dt = real_number('dt_s', dt_s, '>0')
        p = np.asarray(power_w, dtype=np.float64)
        if p.ndim != 1 or not np.isfinite(p).all():
            msg = f'power_w must be a finite 1-D array, got shape {p.shape}'
            raise ModelInputError(msg)
        if p.size == 0:
            return np.empty(0)
        pr = self.params
        # imported here: scipy.signal costs ~0.9 CPU s in every process that imports sim.bench
        from scipy.signal import lfilter

        a = math.exp(-dt / pr.time_constant_s)
        u = pr.ambient_degc + p / pr.conductance_w_k
        nxt, _ = lfilter([1.0 - a], [1.0, -a], u, zi=[a * self.temp_degc])
        temps = np.concatenate(([self.temp_degc], nxt[:-1]))
        self.temp_degc = float(nxt[-1])
        return temps
