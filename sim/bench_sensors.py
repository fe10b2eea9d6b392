"""Torque and temperature sensors of the simulated bench: zero offset, gain error, noise.

A reading of a true value ``x`` is

    reading = x (1 + gain_error) + zero_offset + w,    w ~ N(0, noise_rms^2),

one static error pair per sensor (a unit's calibration residual) and white noise per
sample (the amplifier's). Torque transducer makers state an **accuracy class** ``c`` (0.05,
0.1, 0.2 ... as in DIN 51309 / VDI/VDE 2646 usage): a bound, in % of the nominal
(full-scale) torque, of the combined deviations (linearity with hysteresis, temperature
effect on zero and on sensitivity). Data sheets give the bound, not its split; the split
used here is an assumption, stated in each spec, with the rule
``|zero_offset| + |gain_error| FS + 3 noise_rms <= c/100 FS`` (:func:`torque_sensor`:
c/4, c/4 and c/2 of the band). A case temperature sensor is a Pt100 of IEC 60751
tolerance class A, +-(0.15 + 0.002 |t|) degC.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from sim._checks import Rule, real_number
from sim.errors import ModelInputError, PresetError

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = [
    'SENSOR_PRESETS',
    'SensorSpec',
    'SimulatedSensor',
    'nominal_range',
    'sensor_preset',
    'torque_sensor',
]

#: 1-2-5 series of nominal ranges.
_SERIES = (1.0, 2.0, 5.0)


@dataclass(frozen=True)
class SensorSpec:
    """A linear sensor as the simulation sees it (SI units of its quantity).

    Attributes:
        name: Model name (recorded with the session).
        quantity: ``'torque'`` [N m] or ``'temperature'`` [degC].
        full_scale: Nominal range FS (> 0) [N m or K of span].
        accuracy_class_pct: The maker's class [% of FS] (for the record and the budget).
        zero_offset: Static zero error [N m or K].
        gain_error: Relative sensitivity error (|.| < 0.5).
        noise_rms: Standard deviation of the white noise [N m or K], >= 0.
        source: Where the numbers come from.
        assumptions: What the source does not give and this spec assumes.
    """

    name: str
    quantity: str
    full_scale: float
    accuracy_class_pct: float
    zero_offset: float = 0.0
    gain_error: float = 0.0
    noise_rms: float = 0.0
    source: str = ''
    assumptions: str = dataclasses.field(default='', repr=False)

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field and the value)."""
        if not isinstance(self.name, str) or not self.name.strip():
            msg = f'SensorSpec.name must be a non-empty string, got {self.name!r}'
            raise ModelInputError(msg)
        if self.quantity not in ('torque', 'temperature'):
            msg = f"SensorSpec.quantity must be 'torque' or 'temperature', got {self.quantity!r}"
            raise ModelInputError(msg)
        rules: tuple[tuple[str, Rule], ...] = (
            ('full_scale', '>0'), ('accuracy_class_pct', '>=0'), ('zero_offset', ''),
            ('gain_error', ''), ('noise_rms', '>=0'))
        for f, rule in rules:
            object.__setattr__(self, f, real_number(f'SensorSpec.{f}', getattr(self, f), rule))
        if abs(self.gain_error) >= 0.5:
            msg = f'SensorSpec.gain_error must lie within +-0.5, got {self.gain_error!r}'
            raise ModelInputError(msg)

    @property
    def worst_case_error(self) -> float:
        """|zero_offset| + |gain_error| FS + 3 noise_rms (the modelled band)."""
        return abs(self.zero_offset) + abs(self.gain_error) * self.full_scale \
            + 3.0 * self.noise_rms

    def to_plain(self) -> dict[str, Any]:
        """JSON/YAML-friendly dict of the fields."""
        return dataclasses.asdict(self)


def nominal_range(needed: float) -> float:
    """The smallest nominal range of the 1-2-5 series that covers ``needed`` (> 0)."""
    x = real_number('needed', needed, '>0')
    decade = 10.0 ** math.floor(math.log10(x))
    for m in (*_SERIES, 10.0):
        if m * decade >= x * (1.0 - 1e-12):
            return m * decade
    return 10.0 * decade  # pragma: no cover - the loop always returns


def torque_sensor(full_scale_nm: float, accuracy_class_pct: float = 0.05, *,
                  name: str = '') -> SensorSpec:
    """A torque transducer of a nominal range and class, the class split as c/4 zero,
    c/4 sensitivity, c/2 = 3 sigma noise (an assumption; positive signs).

    Examples:
        >>> s = torque_sensor(20.0, 0.1)
        >>> round(s.worst_case_error / s.full_scale * 100, 12)
        0.1
    """
    fs = real_number('full_scale_nm', full_scale_nm, '>0')
    c = real_number('accuracy_class_pct', accuracy_class_pct, '>0') / 100.0
    return SensorSpec(
        name=name or f'torque-{fs:g}nm-class-{c * 100:g}', quantity='torque',
        full_scale=fs, accuracy_class_pct=c * 100.0, zero_offset=c / 4.0 * fs,
        gain_error=c / 4.0, noise_rms=c / 2.0 * fs / 3.0,
        source=f'torque transducer, nominal {fs:g} N m, accuracy class {c * 100:g} '
               '(DIN 51309 / VDI/VDE 2646 usage: % of nominal torque)',
        assumptions='class band split as 1/4 zero offset, 1/4 sensitivity error, 1/2 as '
                    '3 sigma noise, all at the positive limit')


SENSOR_PRESETS: dict[str, SensorSpec] = {
    'pt100-class-a': SensorSpec(
        name='pt100-class-a', quantity='temperature', full_scale=200.0,
        accuracy_class_pct=0.0, zero_offset=0.075, gain_error=0.0, noise_rms=0.01,
        source='Pt100 surface sensor, IEC 60751 tolerance class A: +-(0.15 + 0.002 |t|) degC',
        assumptions='zero offset half the constant tolerance term (0.075 K), noise 0.01 K '
                    'rms (the DAQ), no gain error; contact resistance to the case not '
                    'modelled (the sensor reads the lumped case temperature)'),
    'ideal-torque': SensorSpec(
        name='ideal-torque', quantity='torque', full_scale=1e6, accuracy_class_pct=0.0,
        source='reference: reads the true torque'),
    'ideal-temperature': SensorSpec(
        name='ideal-temperature', quantity='temperature', full_scale=1e3,
        accuracy_class_pct=0.0, source='reference: reads the true temperature'),
}


def sensor_preset(name: str) -> SensorSpec:
    """The sensor registered under ``name``.

    Raises:
        PresetError: Unknown name (the message lists the known ones).
    """
    spec = SENSOR_PRESETS.get(name) if isinstance(name, str) else None
    if spec is None:
        msg = f'unknown sensor {name!r}; known sensors: {", ".join(sorted(SENSOR_PRESETS))}'
        raise PresetError(msg)
    return spec


class SimulatedSensor:
    """One sensor read on the DAQ clock.

    Args:
        spec: The sensor model.
        rng: Generator of its noise (nothing else draws from it).
    """

    def __init__(self, spec: SensorSpec, rng: np.random.Generator) -> None:
        """Store the spec and the generator."""
        if not isinstance(spec, SensorSpec) or not isinstance(rng, np.random.Generator):
            msg = (f'SimulatedSensor needs a SensorSpec and a numpy Generator, got '
                   f'{type(spec).__name__}, {type(rng).__name__}')
            raise ModelInputError(msg)
        self.spec = spec
        self.rng = rng

    def measure(self, true_value: npt.ArrayLike) -> np.ndarray:
        """Readings of the true values (a new float64 array, same shape)."""
        x = np.asarray(true_value, dtype=np.float64)
        s = self.spec
        out = x * (1.0 + s.gain_error) + s.zero_offset
        if s.noise_rms:
            out = out + s.noise_rms * self.rng.standard_normal(x.shape)
        return out
