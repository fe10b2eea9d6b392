"""Input speed profiles and load torque profiles of the simulated bench.

Every speed profile gives the input angle and speed in closed form, vectorised over time::

    omega_in_rad_s(t_s) -> np.ndarray      input shaft speed [rad/s]
    theta_in_rad(t_s)   -> np.ndarray      its exact integral from t = 0 (theta_in(0) = 0)

so that a bench can evaluate any block of samples without integrating step by step (no
drift over long sessions). Speeds are given in rpm (how benches and the papers state them)
and converted to rad/s inside.

Profiles:

* :class:`ConstantSpeed` - n [rpm].
* :class:`SinusoidalSpeed` - Hu 2020 s.5.2: V = A sin(B t) + C; theta(t) = C t +
  (A / B)(1 - cos B t). With Hu's A = 4615, B = 30, C = 2005 (V in deg/s, B in rad/s) the
  input turns 826.0 deg in 0.4 s (the paper's Adams run reports 826.3 deg). A > |C| reverses
  the input; that must be asked for with ``allow_reversal=True``.
* :class:`Ramp` - linear from start_rpm to end_rpm over duration_s, then hold.
* :class:`ForwardReverse` - +n until reverse_at_s, a cosine reversal to -n over ramp_s
  (zero acceleration at both ends), then -n.

Load profiles give the output (load) torque ``torque_out_nm(t_s)`` [N m]:
:class:`ConstantLoad` and :class:`SinusoidalLoad`; the latter's frequency can be tied to a
reducer frequency (crank, mesh ...) at the drive's nominal speed by :func:`load_from_spec`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, TypeAlias, TypeVar

import numpy as np

from sim._checks import Rule, real_number
from sim.errors import ModelInputError
from sim.units import RAD_S_PER_RPM

if TYPE_CHECKING:
    import numpy.typing as npt
    from _typeshed import DataclassInstance

    from sim.kinematics import ReducerKinematics

__all__ = [
    'DRIVE_KINDS',
    'LOAD_KINDS',
    'AnyDrive',
    'AnyLoad',
    'ConstantLoad',
    'ConstantSpeed',
    'DriveProfile',
    'ForwardReverse',
    'LoadProfile',
    'Ramp',
    'SinusoidalLoad',
    'SinusoidalSpeed',
    'drive_from_spec',
    'load_from_spec',
    'profile_to_plain',
]


def _num(cls: str, name: str, value: object, *, rule: Rule = '') -> float:
    """``value`` as a finite float keeping ``rule``; the message names ``cls.name``."""
    return real_number(f'{cls}.{name}', value, rule)


def _set_nums(obj: object, rules: dict[str, Rule]) -> None:
    """Validate and store the numeric fields of a frozen dataclass as float."""
    cls = type(obj).__name__
    for name, rule in rules.items():
        object.__setattr__(obj, name, _num(cls, name, getattr(obj, name), rule=rule))


def _check_bool(obj: object, name: str) -> None:
    value = getattr(obj, name)
    if not isinstance(value, bool | np.bool_):
        msg = f'{type(obj).__name__}.{name} must be a bool, got {value!r}'
        raise ModelInputError(msg)
    object.__setattr__(obj, name, bool(value))


def _t(t_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
    return np.asarray(t_s, dtype=np.float64)


class DriveProfile(Protocol):
    """An input speed profile with a closed-form angle."""

    kind: ClassVar[str]

    def omega_in_rad_s(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Input speed [rad/s] at times ``t_s`` [s]."""
        ...

    def theta_in_rad(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Input angle [rad] at ``t_s`` [s], the integral of the speed from 0."""
        ...

    @property
    def nominal_speed_rpm(self) -> float:
        """Characteristic |speed| [rpm] used to tie load frequencies to the reducer."""
        ...


class LoadProfile(Protocol):
    """An output (load) torque profile."""

    kind: ClassVar[str]

    def torque_out_nm(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Load (output) torque [N m] at ``t_s`` [s]."""
        ...


@dataclass(frozen=True)
class ConstantSpeed:
    """Constant input speed.

    Attributes:
        speed_rpm: Input speed [rpm], finite and non-zero (negative: reverse).
    """

    kind: ClassVar[str] = 'constant'
    speed_rpm: float

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field and the rule)."""
        _set_nums(self, {'speed_rpm': ''})
        if self.speed_rpm == 0:
            msg = 'ConstantSpeed.speed_rpm must be non-zero (zero speed everywhere)'
            raise ModelInputError(msg)

    @property
    def nominal_speed_rpm(self) -> float:
        """|speed_rpm| [rpm]."""
        return abs(self.speed_rpm)

    def omega_in_rad_s(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Input speed [rad/s]."""
        return np.full_like(_t(t_s), self.speed_rpm * RAD_S_PER_RPM)

    def theta_in_rad(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Input angle [rad] = omega t."""
        return (self.speed_rpm * RAD_S_PER_RPM) * _t(t_s)


@dataclass(frozen=True)
class SinusoidalSpeed:
    """Hu 2020 input speed V(t) = A sin(B t) + C.

    Attributes:
        amplitude_rpm: A [rpm], >= 0.
        angular_freq_rad_s: B [rad/s], > 0.
        mean_rpm: C [rpm]; A and C not both zero.
        allow_reversal: Whether A > |C| (the speed changes sign) is allowed.
    """

    kind: ClassVar[str] = 'sinusoidal'
    amplitude_rpm: float
    angular_freq_rad_s: float
    mean_rpm: float
    allow_reversal: bool = False

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field and the rule)."""
        _set_nums(self, {'amplitude_rpm': '>=0', 'angular_freq_rad_s': '>0', 'mean_rpm': ''})
        _check_bool(self, 'allow_reversal')
        if self.amplitude_rpm == 0 and self.mean_rpm == 0:
            msg = ('SinusoidalSpeed: amplitude_rpm and mean_rpm are both 0 '
                   '(zero speed everywhere)')
            raise ModelInputError(msg)
        if self.amplitude_rpm > abs(self.mean_rpm) and not self.allow_reversal:
            msg = (f'SinusoidalSpeed.amplitude_rpm ({self.amplitude_rpm}) must be <= '
                   f'|mean_rpm| ({abs(self.mean_rpm)}) unless allow_reversal=True '
                   '(the input would reverse)')
            raise ModelInputError(msg)

    @property
    def nominal_speed_rpm(self) -> float:
        """|mean_rpm| [rpm] (the amplitude if the mean is zero)."""
        return abs(self.mean_rpm) or self.amplitude_rpm

    def omega_in_rad_s(self, t_s: npt.ArrayLike) -> np.ndarray:
        """V(t) [rad/s]."""
        t = _t(t_s)
        return RAD_S_PER_RPM * (self.amplitude_rpm * np.sin(self.angular_freq_rad_s * t)
                                + self.mean_rpm)

    def theta_in_rad(self, t_s: npt.ArrayLike) -> np.ndarray:
        """C t + (A / B)(1 - cos B t) [rad], with 1 - cos x = 2 sin^2(x / 2) (no cancellation)."""
        t = _t(t_s)
        b = self.angular_freq_rad_s
        osc = (2.0 * self.amplitude_rpm / b) * np.sin(0.5 * b * t) ** 2
        return RAD_S_PER_RPM * (self.mean_rpm * t + osc)


@dataclass(frozen=True)
class Ramp:
    """Linear speed ramp from start_rpm to end_rpm over duration_s, then hold end_rpm.

    Before t = 0 the speed is start_rpm.

    Attributes:
        start_rpm: Speed at t = 0 [rpm].
        end_rpm: Speed from t = duration_s on [rpm]; start and end not both zero.
        duration_s: Ramp duration [s], > 0.
        allow_reversal: Whether start and end may have opposite signs.
    """

    kind: ClassVar[str] = 'ramp'
    start_rpm: float
    end_rpm: float
    duration_s: float
    allow_reversal: bool = False

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field and the rule)."""
        _set_nums(self, {'start_rpm': '', 'end_rpm': '', 'duration_s': '>0'})
        _check_bool(self, 'allow_reversal')
        if self.start_rpm == 0 and self.end_rpm == 0:
            msg = 'Ramp: start_rpm and end_rpm are both 0 (zero speed everywhere)'
            raise ModelInputError(msg)
        if self.start_rpm * self.end_rpm < 0 and not self.allow_reversal:
            msg = (f'Ramp: start_rpm ({self.start_rpm}) and end_rpm ({self.end_rpm}) have '
                   'opposite signs; set allow_reversal=True to reverse the input')
            raise ModelInputError(msg)

    @property
    def nominal_speed_rpm(self) -> float:
        """|end_rpm| [rpm] (the held speed), |start_rpm| if the ramp stops."""
        return abs(self.end_rpm) or abs(self.start_rpm)

    def omega_in_rad_s(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Speed [rad/s]."""
        t = _t(t_s)
        frac = np.clip(t / self.duration_s, 0.0, 1.0)
        return RAD_S_PER_RPM * (self.start_rpm + (self.end_rpm - self.start_rpm) * frac)

    def theta_in_rad(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Angle [rad]: w0 t + (w1 - w0) t^2 / (2 D) on the ramp, then w1 (t - D) added."""
        t = _t(t_s)
        w0 = self.start_rpm * RAD_S_PER_RPM
        w1 = self.end_rpm * RAD_S_PER_RPM
        d = self.duration_s
        tr = np.clip(t, 0.0, d)
        ramp = w0 * tr + (w1 - w0) * tr * tr / (2.0 * d)
        return ramp + w0 * np.minimum(t, 0.0) + w1 * np.maximum(t - d, 0.0)


@dataclass(frozen=True)
class ForwardReverse:
    """Forward at speed_rpm, a smooth reversal at reverse_at_s, then backwards.

    omega(t) = w for t < t_r; w cos(pi (t - t_r) / ramp_s) during the reversal; -w after.
    The cosine law has zero acceleration at both ends; the angle gained during the
    reversal is zero, so theta = w t_r - w (t - t_r - ramp_s) afterwards.

    Attributes:
        speed_rpm: Forward speed [rpm], finite and non-zero.
        reverse_at_s: Start of the reversal [s], >= 0.
        ramp_s: Duration of the reversal [s], > 0.
    """

    kind: ClassVar[str] = 'forward_reverse'
    speed_rpm: float
    reverse_at_s: float
    ramp_s: float

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field and the rule)."""
        _set_nums(self, {'speed_rpm': '', 'reverse_at_s': '>=0', 'ramp_s': '>0'})
        if self.speed_rpm == 0:
            msg = 'ForwardReverse.speed_rpm must be non-zero (zero speed everywhere)'
            raise ModelInputError(msg)

    @property
    def nominal_speed_rpm(self) -> float:
        """|speed_rpm| [rpm]."""
        return abs(self.speed_rpm)

    def omega_in_rad_s(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Speed [rad/s]."""
        t = _t(t_s)
        w = self.speed_rpm * RAD_S_PER_RPM
        u = np.clip((t - self.reverse_at_s) / self.ramp_s, 0.0, 1.0)
        return w * np.cos(math.pi * u)

    def theta_in_rad(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Angle [rad]."""
        t = _t(t_s)
        w = self.speed_rpm * RAD_S_PER_RPM
        tr = self.reverse_at_s
        u = np.clip((t - tr) / self.ramp_s, 0.0, 1.0)
        fwd = w * np.minimum(t, tr)
        rev = w * self.ramp_s / math.pi * np.sin(math.pi * u)
        back = -w * np.maximum(t - tr - self.ramp_s, 0.0)
        return fwd + rev + back


@dataclass(frozen=True)
class ConstantLoad:
    """Constant output torque.

    Attributes:
        torque_nm: Load torque [N m], finite (0 = no load).
    """

    kind: ClassVar[str] = 'constant'
    torque_nm: float

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field and the rule)."""
        _set_nums(self, {'torque_nm': ''})

    def torque_out_nm(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Load torque [N m] at ``t_s``."""
        return np.full_like(_t(t_s), self.torque_nm)


@dataclass(frozen=True)
class SinusoidalLoad:
    """Load torque T(t) = mean + amplitude sin(2 pi f t + phase).

    Attributes:
        mean_nm: Mean torque [N m].
        amplitude_nm: Peak amplitude [N m], >= 0.
        frequency_hz: f [Hz], > 0.
        phase_rad: Phase at t = 0 [rad].
    """

    kind: ClassVar[str] = 'sinusoidal'
    mean_nm: float
    amplitude_nm: float
    frequency_hz: float
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        """Validate (ModelInputError names the field and the rule)."""
        _set_nums(self, {'mean_nm': '', 'amplitude_nm': '>=0', 'frequency_hz': '>0',
                         'phase_rad': ''})

    def torque_out_nm(self, t_s: npt.ArrayLike) -> np.ndarray:
        """Load torque [N m] at ``t_s``."""
        t = _t(t_s)
        return self.mean_nm + self.amplitude_nm * np.sin(
            2.0 * math.pi * self.frequency_hz * t + self.phase_rad)


AnyDrive: TypeAlias = ConstantSpeed | SinusoidalSpeed | Ramp | ForwardReverse
AnyLoad: TypeAlias = ConstantLoad | SinusoidalLoad

DRIVE_KINDS: dict[str, type] = {
    'constant': ConstantSpeed,
    'sinusoidal': SinusoidalSpeed,
    'ramp': Ramp,
    'forward_reverse': ForwardReverse,
}
LOAD_KINDS: tuple[str, ...] = ('constant', 'sinusoidal')
_TIE_TARGETS = ('input', 'output', 'crank', 'crank_rel', 'mesh')
_P = TypeVar('_P', bound='DataclassInstance')


def _construct(kind_label: str, cls: type[_P], params: dict[str, Any]) -> _P:
    """``cls(**params)`` with unknown/missing parameters reported by name."""
    fields = [f.name for f in dataclasses.fields(cls)]
    required = [f.name for f in dataclasses.fields(cls)
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    unknown = sorted(set(params) - set(fields))
    if unknown:
        msg = f'{kind_label}: unknown parameter(s) {unknown}; allowed: {fields}'
        raise ModelInputError(msg)
    missing = [f for f in required if f not in params]
    if missing:
        msg = f'{kind_label}: missing parameter(s) {missing}'
        raise ModelInputError(msg)
    return cls(**params)


def drive_from_spec(kind: str, **params: Any) -> AnyDrive:
    """Build a speed profile from a kind name and its parameters (e.g. node parameters).

    Args:
        kind: ``'constant'``, ``'sinusoidal'``, ``'ramp'`` or ``'forward_reverse'``
            (``'-'`` accepted for ``'_'``).
        **params: The fields of the profile class, e.g. ``speed_rpm=300.0``.

    Raises:
        ModelInputError: Unknown kind, unknown or missing parameter, or a value that breaks
            a rule (the message names the parameter and the rule).

    Examples:
        >>> drive_from_spec('constant', speed_rpm=300).nominal_speed_rpm
        300.0
    """
    key = str(kind).strip().lower().replace('-', '_')
    cls = DRIVE_KINDS.get(key)
    if cls is None:
        msg = f'drive kind {kind!r} unknown; known kinds: {", ".join(DRIVE_KINDS)}'
        raise ModelInputError(msg)
    return _construct(f'drive {key!r}', cls, params)


def _tied_frequency_hz(tie_to: str, harmonic: float, mesh_index: int,
                       kinematics: ReducerKinematics | None, drive: AnyDrive | None) -> float:
    """Frequency [Hz] of ``harmonic`` x the named reducer rate at the drive's nominal speed."""
    if tie_to not in _TIE_TARGETS:
        msg = f'load tie_to must be one of {_TIE_TARGETS}, got {tie_to!r}'
        raise ModelInputError(msg)
    if kinematics is None or drive is None:
        msg = f'load tie_to={tie_to!r} needs the reducer kinematics and the drive profile'
        raise ModelInputError(msg)
    f_in = drive.nominal_speed_rpm / 60.0
    i = kinematics.gear_ratio
    if tie_to == 'mesh':
        n = len(kinematics.mesh_orders_out)
        if isinstance(mesh_index, bool) or not isinstance(mesh_index, int) \
                or not 0 <= mesh_index < n:
            msg = f'load mesh_index must be an integer in [0, {n - 1}], got {mesh_index!r}'
            raise ModelInputError(msg)
        rate = kinematics.mesh_orders_out[mesh_index] / i
    else:
        rate = {'input': 1.0, 'output': 1.0 / i, 'crank': abs(kinematics.crank_per_input),
                'crank_rel': abs(kinematics.crank_rel_per_input)}[tie_to]
    harmonic = _num('load', 'harmonic', harmonic, rule='>0')
    return harmonic * rate * f_in


def load_from_spec(kind: str, *, kinematics: ReducerKinematics | None = None,
                   drive: AnyDrive | None = None,
                   **params: Any) -> AnyLoad:
    """Build a load profile from a kind name and its parameters.

    ``'constant'``: ``torque_nm``. ``'sinusoidal'``: ``mean_nm``, ``amplitude_nm``,
    ``phase_rad`` (optional) and either ``frequency_hz`` or ``tie_to`` (``'input'``,
    ``'output'``, ``'crank'`` (absolute crank rate f_w), ``'crank_rel'``, ``'mesh'``) with
    optional ``harmonic`` (multiple, default 1) and ``mesh_index`` (default 0). A tied
    frequency is computed once, at ``drive.nominal_speed_rpm``.

    Args:
        kind: ``'constant'`` or ``'sinusoidal'``.
        kinematics: Reducer kinematics (``gear_ratio``, ``crank_per_input``,
            ``crank_rel_per_input``, ``mesh_orders_out``); needed with ``tie_to``.
        drive: The speed profile; needed with ``tie_to``.
        **params: The profile parameters.

    Raises:
        ModelInputError: Unknown kind or parameter, both or neither of frequency_hz and
            tie_to, or a value that breaks a rule.
    """
    key = str(kind).strip().lower()
    if key == 'constant':
        p = dict(params)
        unknown = sorted(set(p) - {'torque_nm'})
        if unknown or 'torque_nm' not in p:
            msg = f"load 'constant': parameters must be exactly ['torque_nm'], got {sorted(p)}"
            raise ModelInputError(msg)
        return ConstantLoad(p['torque_nm'])
    if key == 'sinusoidal':
        p = dict(params)
        tie_to = p.pop('tie_to', None)
        harmonic = p.pop('harmonic', 1.0)
        mesh_index = p.pop('mesh_index', 0)
        if tie_to in ('', None):
            if 'frequency_hz' not in p:
                msg = "load 'sinusoidal': give frequency_hz or tie_to"
                raise ModelInputError(msg)
        else:
            if 'frequency_hz' in p:
                msg = "load 'sinusoidal': give frequency_hz or tie_to, not both"
                raise ModelInputError(msg)
            p['frequency_hz'] = _tied_frequency_hz(str(tie_to), harmonic, mesh_index,
                                                   kinematics, drive)
        return _construct("load 'sinusoidal'", SinusoidalLoad, p)
    msg = f'load kind {kind!r} unknown; known kinds: {", ".join(LOAD_KINDS)}'
    raise ModelInputError(msg)


def profile_to_plain(profile: object) -> dict[str, Any]:
    """``{'kind': ..., field: value, ...}`` of a drive or load profile (for YAML records)."""
    out: dict[str, Any] = {'kind': getattr(profile, 'kind', type(profile).__name__)}
    for f in dataclasses.fields(profile):  # type: ignore[arg-type]
        out[f.name] = getattr(profile, f.name)
    return out
