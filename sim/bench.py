"""The simulated TE bench: drive + TE model + two encoders on one clock, block by block.

Sample ``n`` (counted from 0 over the whole session) is taken at
``t_n = start_time_s + n / sample_rate_hz``. For each block the simulator evaluates

* the input angle and speed from the drive profile (closed form, no integration drift),
* the load torque from the load profile,
* the model TE ``te = te_model.te_rad(t, theta_in, omega_in, load)`` (the model carries its
  own state from block to block),
* the true output angle ``theta_out = theta_in / i + te`` (i = kinematics.gear_ratio),
* the encoder readings of both shafts (same sample instants: one DAQ clock),
* with ``BenchConfig.losses`` set, the loss channels (:mod:`sim.loss_bench`): the input
  torque the drive gives, the input and output torque transducer readings and the case
  temperature (true and measured). Without it these fields are None and the session draws
  nothing more from its generators: its blocks are those it gave before losses existed.

Nothing grows with the session length: the block is a function of its index, the drive
and the model state, so memory is flat however long the bench runs. Same config (seed
included) -> identical blocks; the two encoders draw their noise from two child generators
spawned from ``np.random.default_rng(seed)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NotRequired, TypedDict

import numpy as np
import yaml

from sim.bench_info import DEFAULT_SAMPLE_RATE_HZ, BenchInfoData
from sim.drive import ConstantLoad, profile_to_plain
from sim.encoders import EncoderSpec, SimulatedEncoder, encoder_preset
from sim.errors import ModelInputError
from sim.loss_bench import LossBlock, LossChannels, LossConfig
from sim.models import build_te_model
from sim.presets import Preset, load_preset, parse_override_items

if TYPE_CHECKING:
    from collections.abc import Mapping

    from sim.drive import DriveProfile, LoadProfile
    from sim.kinematics import ReducerKinematics
    from sim.models import TeModel

__all__ = ['DEFAULT_SAMPLE_RATE_HZ', 'BenchBlock', 'BenchConfig', 'BenchConfigPlain',
           'BenchInfoData', 'BenchSimulator', 'bench_info_of', 'loss_fields', 'read_heads',
           'scale_fields', 'skewed_reading']


def skewed_reading(theta_out_rad: np.ndarray, omega_ref_rad_s: np.ndarray | float,
                   te_rad: np.ndarray, t_s: np.ndarray, skew_s: float) -> np.ndarray:
    """The output angle a channel latched ``skew_s`` late reads: theta_out(t + skew),
    to first order theta_out + (omega_in / i + dTE/dt) skew (dTE/dt by finite differences
    over the block)."""
    dte = np.gradient(te_rad, t_s) if te_rad.size > 1 else np.zeros_like(te_rad)
    return theta_out_rad + (omega_ref_rad_s + dte) * skew_s


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, kw_only=True)
class BenchConfig:
    """Settings of one simulated bench session (SI units).

    Attributes:
        preset: Reducer preset name (``sim/preset_data/<name>.toml``) or a TOML path.
        drive: Input speed profile (:mod:`sim.drive`).
        overrides: Preset overrides ``"key=value"``.
        te_mode: TE model mode passed to the model factory (``'nlte'``, ``'ste'``, ``'dte'``).
        load: Output load torque profile; no load by default.
        encoder_in: Input-shaft encoder: an :data:`sim.encoders.ENCODER_PRESETS` name or a spec.
        encoder_out: Output-shaft encoder, likewise.
        sample_rate_hz: DAQ sample rate [Hz], > 0.
        block_size: Samples per block, >= 1.
        seed: Seed of the noise generators (int >= 0).
        bench_id: Bench identifier (EncoderBlock frame_id), non-empty.
        start_time_s: Time of sample 0 [s], finite (a large value tests long sessions).
        daq_skew_s: The output channel is latched this much later than the input channel
            [s] (DAQ timing skew; 0: one clock for both). The output reading is then that
            of theta_out(t + skew) ~ theta_out(t) + omega_out(t) skew.
        losses: Simulate the losses, torque transducers and case temperature
            (:class:`sim.loss_bench.LossConfig`); None (default): TE and angles only.
    """

    preset: str
    drive: DriveProfile
    overrides: tuple[str, ...] = ()
    te_mode: str = 'nlte'
    load: LoadProfile = field(default_factory=lambda: ConstantLoad(0.0))
    encoder_in: str | EncoderSpec = 'heidenhain-ron886'
    encoder_out: str | EncoderSpec = 'heidenhain-ron886'
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ
    block_size: int = 1000
    seed: int = 0
    bench_id: str = 'bench'
    start_time_s: float = 0.0
    daq_skew_s: float = 0.0
    losses: LossConfig | None = None

    def __post_init__(self) -> None:
        """Validate every field.

        Raises:
            ModelInputError: A field breaks its rule (the message names field and rule).
            PresetError: Unknown encoder name or malformed override item.
        """
        if not isinstance(self.preset, str) or not self.preset.strip():
            msg = f'BenchConfig.preset must be a non-empty string, got {self.preset!r}'
            raise ModelInputError(msg)
        if isinstance(self.overrides, str):
            msg = (f'BenchConfig.overrides must be a sequence of "key=value" strings, got the '
                   f'string {self.overrides!r}')
            raise ModelInputError(msg)
        object.__setattr__(self, 'overrides', tuple(str(o) for o in self.overrides))
        parse_override_items(list(self.overrides))
        if not isinstance(self.te_mode, str) or not self.te_mode.strip():
            msg = f'BenchConfig.te_mode must be a non-empty string, got {self.te_mode!r}'
            raise ModelInputError(msg)
        for name, attrs in (('drive', ('theta_in_rad', 'omega_in_rad_s', 'nominal_speed_rpm')),
                            ('load', ('torque_out_nm',))):
            obj = getattr(self, name)
            if not all(hasattr(obj, a) for a in attrs):
                msg = (f'BenchConfig.{name} must be a {name} profile from sim.drive '
                       f'(with {", ".join(attrs)}), got {obj!r}')
                raise ModelInputError(msg)
        for name in ('encoder_in', 'encoder_out'):
            enc = getattr(self, name)
            if not isinstance(enc, EncoderSpec):
                encoder_preset(enc)  # raises PresetError naming the known encoders
        rate = self.sample_rate_hz
        if isinstance(rate, bool) or not isinstance(rate, int | float | np.integer | np.floating) \
                or not (math.isfinite(rate) and rate > 0):
            msg = f'BenchConfig.sample_rate_hz must be finite and > 0, got {rate!r}'
            raise ModelInputError(msg)
        object.__setattr__(self, 'sample_rate_hz', float(rate))
        bs = self.block_size
        if isinstance(bs, bool) or not isinstance(bs, int | np.integer) or bs < 1:
            msg = f'BenchConfig.block_size must be an integer >= 1, got {bs!r}'
            raise ModelInputError(msg)
        object.__setattr__(self, 'block_size', int(bs))
        sd = self.seed
        if isinstance(sd, bool) or not isinstance(sd, int | np.integer) or sd < 0:
            msg = f'BenchConfig.seed must be an integer >= 0, got {sd!r}'
            raise ModelInputError(msg)
        object.__setattr__(self, 'seed', int(sd))
        if not isinstance(self.bench_id, str) or not self.bench_id.strip():
            msg = f'BenchConfig.bench_id must be a non-empty string, got {self.bench_id!r}'
            raise ModelInputError(msg)
        st = self.start_time_s
        if isinstance(st, bool) or not isinstance(st, int | float | np.integer | np.floating) \
                or not math.isfinite(st):
            msg = f'BenchConfig.start_time_s must be finite, got {st!r}'
            raise ModelInputError(msg)
        object.__setattr__(self, 'start_time_s', float(st))
        sk = self.daq_skew_s
        if isinstance(sk, bool) or not isinstance(sk, int | float | np.integer | np.floating) \
                or not math.isfinite(sk) or abs(sk) > 1e-3:
            msg = f'BenchConfig.daq_skew_s must be finite and within +-1 ms, got {sk!r}'
            raise ModelInputError(msg)
        object.__setattr__(self, 'daq_skew_s', float(sk))
        if self.losses is not None and not isinstance(self.losses, LossConfig):
            msg = f'BenchConfig.losses must be a LossConfig or None, got {self.losses!r}'
            raise ModelInputError(msg)

    def encoder_spec(self, which: str) -> EncoderSpec:
        """The spec of ``'in'`` or ``'out'`` (a preset looked up by name)."""
        enc = self.encoder_in if which == 'in' else self.encoder_out
        return enc if isinstance(enc, EncoderSpec) else encoder_preset(enc)

    def to_plain(self) -> BenchConfigPlain:
        """YAML-friendly dict of the config (profiles and encoders as dicts; ``losses``
        only when set, so a session without them records what it always did)."""
        out: BenchConfigPlain = {
            'bench_id': self.bench_id,
            'preset': self.preset,
            'overrides': list(self.overrides),
            'te_mode': self.te_mode,
            'drive': profile_to_plain(self.drive),
            'load': profile_to_plain(self.load),
            'encoder_in': self.encoder_spec('in').to_plain(),
            'encoder_out': self.encoder_spec('out').to_plain(),
            'sample_rate_hz': self.sample_rate_hz,
            'block_size': self.block_size,
            'seed': self.seed,
            'start_time_s': self.start_time_s,
            'daq_skew_s': self.daq_skew_s,
        }
        if self.losses is not None:
            out['losses'] = self.losses.to_plain()
        return out


class BenchConfigPlain(TypedDict):
    """:meth:`BenchConfig.to_plain`: the settings a simulated bench records (``bench`` in
    its ``parameters_yaml``); profiles, encoders and losses in their own plain forms."""

    bench_id: str
    preset: str
    overrides: list[str]
    te_mode: str
    drive: dict[str, Any]
    load: dict[str, Any]
    encoder_in: dict[str, Any]
    encoder_out: dict[str, Any]
    sample_rate_hz: float
    block_size: int
    seed: int
    start_time_s: float
    daq_skew_s: float
    losses: NotRequired[dict[str, Any]]


@dataclass(frozen=True)
class BenchBlock:
    """One block of bench samples (read-only arrays, all of length ``block_size``).

    Attributes:
        seq: Block number, contiguous from 0.
        t0_s: Time of the first sample [s].
        time_offset_s: Per-sample time since t0_s [s], first = 0, strictly increasing.
        theta_in_rad: Measured (encoder) unwrapped input angle [rad].
        theta_out_rad: Measured (encoder) unwrapped output angle [rad].
        torque_out_nm: Output (load) torque [N m].
        te_true_rad: Model TE = theta_out_true - theta_in_true / i [rad].
        theta_in_true_rad: True input angle [rad].
        theta_out_true_rad: True output angle [rad].
        torque_in_nm: Input torque transducer reading [N m] (None without losses).
        torque_in_true_nm: Input torque the drive gives [N m] (None without losses).
        torque_out_meas_nm: Output torque transducer reading [N m], bench convention
            (None without losses; ``torque_out_nm`` stays the true load).
        temp_case_degc: Case temperature sensor reading [degC] (None without losses).
        temp_case_true_degc: True case temperature [degC] (None without losses).
        power_loss_w: Loss power [W] (None without losses).
        theta_in_heads_rad: Every read head's reading of the input scale, shape
            (heads, n) [rad] (head 0 = ``theta_in_rad``); None on a one-head scale.
        theta_out_heads_rad: The same for the output scale.
    """

    seq: int
    t0_s: float
    time_offset_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_out_nm: np.ndarray
    te_true_rad: np.ndarray
    theta_in_true_rad: np.ndarray
    theta_out_true_rad: np.ndarray
    torque_in_nm: np.ndarray | None = None
    torque_in_true_nm: np.ndarray | None = None
    torque_out_meas_nm: np.ndarray | None = None
    temp_case_degc: np.ndarray | None = None
    temp_case_true_degc: np.ndarray | None = None
    power_loss_w: np.ndarray | None = None
    theta_in_heads_rad: np.ndarray | None = None
    theta_out_heads_rad: np.ndarray | None = None


def read_heads(encoder: SimulatedEncoder, theta_rad: np.ndarray,
               ) -> tuple[np.ndarray, np.ndarray | None]:
    """(head 0's reading, every head's readings or None) of one encoder: a one-head
    encoder draws exactly as :meth:`SimulatedEncoder.measure` (the same numbers)."""
    if not encoder.spec.heads:
        return _readonly(encoder.measure(theta_rad)), None
    heads = _readonly(encoder.measure_heads(theta_rad))
    return heads[0], heads


def scale_fields(side: str, spec: EncoderSpec) -> dict[str, Any]:
    """The BenchInfo fields of one encoder's scale and heads (``side``: 'in' or 'out')."""
    dia = spec.scale_diameter_m
    return {f'encoder_{side}_head_angles_rad': spec.head_angles_rad if spec.heads else (),
            f'encoder_{side}_scale_serial': spec.serial,
            f'encoder_{side}_scale_diameter_m': dia,
            f'encoder_{side}_scale_eccentricity_m': (spec.eccentricity_amplitude_rad * dia / 2.0
                                                     if dia > 0 else 0.0),
            f'encoder_{side}_scale_index_rad': spec.scale_index_rad}


def loss_fields(lb: LossBlock) -> dict[str, np.ndarray]:
    """The :class:`BenchBlock` loss fields of a :class:`sim.loss_bench.LossBlock`
    (read-only arrays)."""
    return {'torque_in_nm': _readonly(lb.torque_in_meas_nm),
            'torque_in_true_nm': _readonly(lb.torque_in_true_nm),
            'torque_out_meas_nm': _readonly(lb.torque_out_meas_nm),
            'temp_case_degc': _readonly(lb.temp_case_meas_degc),
            'temp_case_true_degc': _readonly(lb.temp_case_degc),
            'power_loss_w': _readonly(lb.power_loss_w)}


def bench_info_of(*, bench_id: str, preset: Preset, kinematics: ReducerKinematics,
                  encoder_in: EncoderSpec, encoder_out: EncoderSpec, sample_rate_hz: float,
                  block_size: int, settings: Mapping[str, object]) -> BenchInfoData:
    """The record of a simulated bench: the preset's kinematics, the encoders, the DAQ.

    ``parameters_yaml`` holds ``{'bench': settings, 'preset': {name, model, values}}``
    (``settings['overrides']`` are the preset overrides, which
    :func:`rv_te_bench.io.bench_record.overrides_from_parameters_yaml` reads back).
    """
    # the simulated encoders read the model's shaft angles: the reducer's zero is theirs
    # (rv_te_bench.core.te_zero reads this to refer the TE to it)
    record = {'bench': settings,
              'preset': {'name': preset.name, 'model': preset.model, 'values': preset.to_plain()},
              'encoder_zero': {'input_rad': 0.0, 'output_rad': 0.0,
                               'source': "the simulated bench (encoders read the model's "
                                         "shaft angles)"}}
    return BenchInfoData(
        bench_id=bench_id,
        preset=preset.name,
        reducer_type=str(kinematics.kind),
        gear_ratio=float(kinematics.gear_ratio),
        crank_per_input=float(kinematics.crank_per_input),
        crank_rel_per_input=float(kinematics.crank_rel_per_input),
        mesh_orders=tuple(float(o) for o in kinematics.mesh_orders_out),
        mesh_labels=tuple(str(s) for s in kinematics.mesh_labels),
        encoder_in_model=encoder_in.name,
        encoder_out_model=encoder_out.name,
        encoder_in_resolution_rad=encoder_in.resolution_rad,
        encoder_out_resolution_rad=encoder_out.resolution_rad,
        sample_rate_hz=float(sample_rate_hz),
        block_size=int(block_size),
        parameters_yaml=yaml.safe_dump(record, sort_keys=True),
        **scale_fields('in', encoder_in), **scale_fields('out', encoder_out),
    )


class BenchSimulator:
    """Produces :class:`BenchBlock` s from a :class:`BenchConfig`.

    Args:
        config: The session settings.
        preset: Use this preset (overrides of ``config`` still applied) instead of loading
            ``config.preset``; for tests and custom reducers.
        model: Use this TE model instead of ``build_te_model(preset, config.te_mode)``.

    Raises:
        PresetError: Unknown preset, bad override, unknown model, bad preset value.
    """

    def __init__(self, config: BenchConfig, *, preset: Preset | None = None,
                 model: TeModel | None = None) -> None:
        """Load the preset, build the model and the encoders (see class docstring)."""
        if not isinstance(config, BenchConfig):
            msg = f'config must be a BenchConfig, got {type(config).__name__}'
            raise ModelInputError(msg)
        self.config = config
        if preset is None:
            preset = load_preset(config.preset, list(config.overrides))
        else:
            preset = preset.with_overrides(list(config.overrides))
        self.preset = preset
        self.model = build_te_model(preset, config.te_mode) if model is None else model
        self.kinematics = self.model.kinematics
        self._gear_ratio = float(self.kinematics.gear_ratio)
        self._spec_in = config.encoder_spec('in')
        self._spec_out = config.encoder_spec('out')
        self._offsets = _readonly(np.arange(config.block_size, dtype=np.float64)
                                  / config.sample_rate_hz)
        self._info: BenchInfoData | None = None
        self._losses: LossChannels | None = None
        self._start_rngs()
        self._seq = 0

    def _start_rngs(self) -> None:
        rng = np.random.default_rng(self.config.seed)
        rng_in, rng_out = rng.spawn(2)
        self._enc_in = SimulatedEncoder(self._spec_in, rng_in)
        self._enc_out = SimulatedEncoder(self._spec_out, rng_out)
        if self.config.losses is not None:   # children 2.. : the encoders' streams unchanged
            (rng_loss,) = rng.spawn(1)
            if self._losses is None:
                self._losses = LossChannels(self.preset, self.config.losses, rng_loss,
                                            self.config.sample_rate_hz)
            else:
                self._losses.restart(rng_loss)

    @property
    def loss_channels(self) -> LossChannels | None:
        """The loss model, thermal state and sensors (None without losses)."""
        return self._losses

    @property
    def seq(self) -> int:
        """Sequence number of the next block."""
        return self._seq

    def reset(self) -> None:
        """Back to block 0: sequence, noise generators, model state, case temperature."""
        self._seq = 0
        self._start_rngs()
        self.model.reset()

    def next_block(self) -> BenchBlock:
        """Simulate the next block of ``block_size`` samples."""
        cfg = self.config
        n = cfg.block_size
        t0 = cfg.start_time_s + (self._seq * n) / cfg.sample_rate_hz
        t = t0 + self._offsets
        drive = cfg.drive
        theta_in = drive.theta_in_rad(t)
        omega_in = drive.omega_in_rad_s(t)
        load = np.asarray(cfg.load.torque_out_nm(t), dtype=np.float64)
        te = np.array(self.model.te_rad(t, theta_in, omega_in, load), dtype=np.float64)
        if te.shape != t.shape:
            msg = f'TE model returned shape {te.shape} for a block of shape {t.shape}'
            raise ModelInputError(msg)
        theta_out = theta_in / self._gear_ratio + te
        theta_out_read = theta_out if not cfg.daq_skew_s else skewed_reading(
            theta_out, omega_in / self._gear_ratio, te, t, cfg.daq_skew_s)
        extra = ({} if self._losses is None
                 else loss_fields(self._losses.block(t, omega_in, load)))
        read_in, heads_in = read_heads(self._enc_in, theta_in)
        read_out, heads_out = read_heads(self._enc_out, theta_out_read)
        block = BenchBlock(
            seq=self._seq,
            t0_s=float(t0),
            time_offset_s=self._offsets,
            theta_in_rad=read_in,
            theta_out_rad=read_out,
            torque_out_nm=_readonly(load),
            te_true_rad=_readonly(te),
            theta_in_true_rad=_readonly(theta_in),
            theta_out_true_rad=_readonly(theta_out),
            theta_in_heads_rad=heads_in,
            theta_out_heads_rad=heads_out,
            **extra,
        )
        self._seq += 1
        return block

    @property
    def info(self) -> BenchInfoData:
        """What ``bench/info`` publishes (computed once)."""
        if self._info is None:
            cfg = self.config
            self._info = bench_info_of(
                bench_id=cfg.bench_id, preset=self.preset, kinematics=self.kinematics,
                encoder_in=self._spec_in, encoder_out=self._spec_out,
                sample_rate_hz=cfg.sample_rate_hz, block_size=cfg.block_size,
                settings=cfg.to_plain())
        return self._info
