"""The loss channels of a simulated bench: input and output torque, case temperature.

:class:`LossChannels` turns one block of samples (time, input speed, load) into

* the true input torque the drive gives (:meth:`sim.losses.LossModel.input_torque_nm`,
  with the inertia term from the block's speed gradient),
* the loss power and the case temperature it causes (:class:`sim.thermal.ThermalState`;
  the lubricant viscosity is taken at the temperature at the start of the block, which
  moves by micro-kelvins within a block while the thermal time constant is minutes),
* the readings of the input and output torque transducers and of the case temperature
  sensor (:mod:`sim.bench_sensors`), each drawing its noise from its own generator.

It is off unless a session asks for it (``BenchConfig.losses`` /
``ProgramSimulator(losses=...)``): a session without it draws nothing from these
generators and produces exactly the blocks it produced before the loss model existed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from sim._checks import real_number
from sim.bench_sensors import (
    SensorSpec,
    SimulatedSensor,
    nominal_range,
    sensor_preset,
    torque_sensor,
)
from sim.errors import ModelInputError
from sim.losses import LossModel
from sim.thermal import ThermalParams, ThermalState

if TYPE_CHECKING:
    from sim.presets import Preset

__all__ = ['LossBlock', 'LossChannels', 'LossConfig']

#: Auto-chosen ranges: output FS covers this multiple of the reference (rated) torque,
#: input FS the input torque at that load and the reference speed, both rounded up 1-2-5.
_RANGE_MARGIN = 1.5


@dataclass(frozen=True, kw_only=True)
class LossConfig:
    """Settings of the loss channels of one session.

    Attributes:
        torque_in: Input torque transducer: a :data:`sim.bench_sensors.SENSOR_PRESETS`
            name, a spec, or None (a class-``accuracy_class_pct`` transducer whose 1-2-5
            range covers the input torque at 1.5 x the preset's reference torque).
        torque_out: Output torque transducer, likewise (range: 1.5 x reference torque).
        temperature: Case temperature sensor (name or spec).
        accuracy_class_pct: Class of the auto-chosen torque transducers [%], > 0.
        ambient_degc: Ambient temperature [degC]; None: the preset's.
        case_initial_degc: Case temperature at sample 0 [degC]; None: the ambient.
    """

    torque_in: str | SensorSpec | None = None
    torque_out: str | SensorSpec | None = None
    temperature: str | SensorSpec = 'pt100-class-a'
    accuracy_class_pct: float = 0.05
    ambient_degc: float | None = None
    case_initial_degc: float | None = None

    def __post_init__(self) -> None:
        """Validate (ModelInputError / PresetError name the field or sensor)."""
        for name in ('torque_in', 'torque_out', 'temperature'):
            v = getattr(self, name)
            if isinstance(v, str):
                sensor_preset(v)
            elif v is not None and not isinstance(v, SensorSpec):
                msg = f'LossConfig.{name} must be a sensor name or a SensorSpec, got {v!r}'
                raise ModelInputError(msg)
        object.__setattr__(self, 'accuracy_class_pct', real_number(
            'LossConfig.accuracy_class_pct', self.accuracy_class_pct, '>0'))
        for name in ('ambient_degc', 'case_initial_degc'):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, real_number(f'LossConfig.{name}', v))

    def to_plain(self) -> dict[str, Any]:
        """YAML-friendly dict (sensor specs as dicts)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            out[f.name] = v.to_plain() if isinstance(v, SensorSpec) else v
        return out


class LossBlock(NamedTuple):
    """The loss channels of one block (float64 arrays of the block's length).

    Attributes:
        torque_in_true_nm: Input torque the drive gives [N m] (signed like the motion).
        torque_in_meas_nm: Input transducer reading [N m].
        torque_out_meas_nm: Output transducer reading [N m], bench convention.
        temp_case_degc: True case temperature at each sample [degC].
        temp_case_meas_degc: Case temperature sensor reading [degC].
        power_loss_w: Loss power [W] (sum of the loss laws).
    """

    torque_in_true_nm: np.ndarray
    torque_in_meas_nm: np.ndarray
    torque_out_meas_nm: np.ndarray
    temp_case_degc: np.ndarray
    temp_case_meas_degc: np.ndarray
    power_loss_w: np.ndarray


class LossChannels:
    """Loss model + thermal state + sensors of one session (see the module docstring).

    Args:
        preset: The reducer preset (``[losses]``, ``[lubricant]``, ``[thermal]``).
        config: The session's loss settings.
        rng: Generator the sensors' generators are spawned from.
        sample_rate_hz: DAQ rate [Hz] (the thermal step).

    Raises:
        PresetError: The preset has no (valid) loss, lubricant or thermal section.
    """

    def __init__(self, preset: Preset, config: LossConfig, rng: np.random.Generator,
                 sample_rate_hz: float) -> None:
        """Build the model, the thermal state and the three sensors."""
        self.model = LossModel.from_preset(preset)
        thermal = ThermalParams.from_preset(preset)
        if config.ambient_degc is not None:
            thermal = dataclasses.replace(thermal, ambient_degc=config.ambient_degc)
        self.thermal = ThermalState(thermal, config.case_initial_degc)
        self.config = config
        self.dt_s = 1.0 / real_number('sample_rate_hz', sample_rate_hz, '>0')
        self.specs = {'torque_in': self._spec(config.torque_in, 'in'),
                      'torque_out': self._spec(config.torque_out, 'out'),
                      'temperature': (config.temperature if isinstance(
                          config.temperature, SensorSpec) else sensor_preset(
                              config.temperature))}
        self.restart(rng)

    def _spec(self, given: str | SensorSpec | None, which: str) -> SensorSpec:
        if isinstance(given, SensorSpec):
            return given
        if isinstance(given, str):
            return sensor_preset(given)
        p = self.model.params
        load = _RANGE_MARGIN * p.reference_torque_nm
        if which == 'out':
            return torque_sensor(nominal_range(load), self.config.accuracy_class_pct)
        t_in = float(self.model.input_torque_nm(p.reference_speed_rpm * np.pi / 30.0, load,
                                                self.thermal.params.ambient_degc))
        return torque_sensor(nominal_range(t_in), self.config.accuracy_class_pct)

    def restart(self, rng: np.random.Generator) -> None:
        """Back to the initial temperature, with sensor generators spawned from ``rng``."""
        self.thermal.reset()
        r_in, r_out, r_temp = rng.spawn(3)
        self.sensors = {'torque_in': SimulatedSensor(self.specs['torque_in'], r_in),
                        'torque_out': SimulatedSensor(self.specs['torque_out'], r_out),
                        'temperature': SimulatedSensor(self.specs['temperature'], r_temp)}

    def block(self, t_s: np.ndarray, omega_in_rad_s: np.ndarray, load_nm: np.ndarray, *,
              torque_out_reading_nm: np.ndarray | None = None,
              torque_in_true_nm: np.ndarray | None = None) -> LossBlock:
        """The channels of one block; advances the case temperature.

        Args:
            t_s: Sample times [s] (equally spaced by 1 / sample_rate_hz).
            omega_in_rad_s: Input speed [rad/s] at the samples.
            load_nm: True output load [N m], bench convention.
            torque_out_reading_nm: Use this as the output transducer reading (a program's
                locked segments already hold a reading) instead of measuring ``load_nm``.
            torque_in_true_nm: The input torque where the drive does not turn the input at
                a set speed (a torque ramp: the ramp; a free input: 0); the loss power is
                then 0 (quasi-static).
        """
        t = np.asarray(t_s, dtype=np.float64)
        w = np.broadcast_to(np.asarray(omega_in_rad_s, dtype=np.float64), t.shape)
        load = np.broadcast_to(np.asarray(load_nm, dtype=np.float64), t.shape)
        alpha = np.gradient(w, t) if t.size > 1 else np.zeros_like(t)
        temp0 = self.thermal.temp_degc
        if torque_in_true_nm is None:
            t_in, powers = self.model.running(w, load, temp0, alpha_in_rad_s2=alpha)
            p_loss = powers.total_w
        else:
            t_in = np.broadcast_to(np.asarray(torque_in_true_nm, dtype=np.float64), t.shape)
            p_loss = np.zeros(t.shape)
        temps = self.thermal.advance(p_loss, self.dt_s)
        out = (self.sensors['torque_out'].measure(load) if torque_out_reading_nm is None
               else np.array(torque_out_reading_nm, dtype=np.float64))
        return LossBlock(
            torque_in_true_nm=t_in,
            torque_in_meas_nm=self.sensors['torque_in'].measure(t_in),
            torque_out_meas_nm=out,
            temp_case_degc=temps,
            temp_case_meas_degc=self.sensors['temperature'].measure(temps),
            power_loss_w=p_loss)

    def describe(self) -> dict[str, Any]:
        """What a session record states about its loss channels."""
        return {'config': self.config.to_plain(),
                'sensors': {k: v.to_plain() for k, v in self.specs.items()},
                'thermal': dataclasses.asdict(self.thermal.params),
                'case_initial_degc': self.thermal.temp0_degc}
