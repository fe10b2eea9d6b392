"""A real bench described in a YAML file: reducer, encoders, DAQ rate, torque sensor, unit.

The file (``rv_te_bench/launch/bench_description_example.yaml`` is a full example)::

    bench_id: lab-bench-2            # required; EncoderBlock frame_id, BenchInfo.bench_id
    preset: rv-80e-101               # a reducer preset (sim/preset_data) or a .toml path ...
    preset_overrides: []             #   ... with "key=value" overrides as for --set
    reducer:                         # ... or, without a preset, the reducer's kinematics:
      kind: rv                       #   2kv | rv | other
      gear_ratio: 121.0              #   i, input revolutions per output revolution (> 0)
      crank_per_output: 39.0         #   |f_w / f_out|, absolute crank revs per output rev
      crank_rel_per_output: 40.0     #   optional, default crank_per_output + 1
      mesh_orders: [2400.0, 1560.0]  #   optional, orders of the output rotation
      mesh_labels: [stage-1, pin]    #   optional, one per order (default 'mesh k')
    sample_rate_hz: 10000.0          # nominal DAQ rate [Hz]
    block_size: 1000                 # samples per EncoderBlock
    encoders:
      input: {model: heidenhain-ron886}                      # known model: its resolution
      output: {model: RESOLUTE-32, counts_per_rev: 4294967296}   # or counts_per_rev,
                                                             #   or resolution_rad
      # a scale's record and read heads (issue 36), each optional:
      #   serial: RING-42                          the scale's serial (for its calibration)
      #   heads_deg: [0, 90, 180, 270]             read heads around it, head 0 first
      #   scale: {diameter_mm: 100, runout_um: 4, index_deg: 0}   (or eccentricity_um)
      # zero_offset_deg: 123.4   the encoder's reading at the reducer's zero (a zeroing
      #                          step); the TE is then referred to these zeros, else to
      #                          its first sample (rv_te_bench.core.te_zero)
    torque_sensor: {present: true, model: HBM T40B, scale_nm_per_unit: 1.0, unit: N m}
    unit_under_test: {serial: SN-42, operator: A. Tester, temperature_c: 23.5, notes: ''}
    joints: {input: input_joint, output: output_joint}       # JointState names (optional)
      #   output_heads: [h0, h1, h2, h3]           one joint per output head (head 0 first)
    limits: {max_input_speed_rpm: 3000, max_output_torque_nm: 1000}   # the bench's own
                                                             #   (optional; rv-te test checks
                                                             #   every sample read back)
    metadata: {daq: NI PXIe-4492}                            # free strings, into the bag
    loss_channels:                   # optional (issue 38): the whole-reducer steps' channels
      torque_in: {model: HBM T40B, full_scale: 50, accuracy_class_pct: 0.05,
                  scale_nm_per_unit: 1.0}      # --torque-in column x scale = N m
      torque_out: {model: HBM T40B, full_scale: 1000, accuracy_class_pct: 0.05}
      temperature: {model: Pt100 class A}      # --temperature column in degC
    uncertainty:                     # optional: the bench's own error values (the budgets'
      daq_skew_ns: 25                #   inputs; docs/UNCERTAINTY.md); keys in
      encoders:                      #   core.bench_uncertainty.bench_uncertainty_from_plain
        output: {eccentricity_um: 1.5, eccentricity_u_um: 0.5, scale_diameter_mm: 100}
      torque_sensor: {accuracy_class_pct: 0.05, nominal_nm: 1000, gain_tolerance_pct: 0.05}
      temperature: {spread_k: 0.5}

Only ``bench_id``, ``sample_rate_hz`` and either ``preset`` or ``reducer`` are required. With
a preset, ratio, crank orders and mesh orders/labels come from the preset's kinematics
(:func:`sim.kinematics.kinematics_from_preset`), and ``reducer`` is refused (use
``preset_overrides`` to change teeth). Without a preset the cranks are taken to turn
against the input (the sign both shipped reducer kinds have): ``crank_per_input =
-crank_per_output / gear_ratio``. Every bad key or value raises
:class:`~rv_te_bench.errors.BenchDescriptionError` with one line naming the file, the key,
the rule and the value.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, NoReturn

import yaml

from rv_te_bench.core.bench_uncertainty import BenchUncertainty, bench_uncertainty_from_plain
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.errors import BenchDescriptionError, TeConfigError, YamlInputError
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, brief, read_yaml_file
from sim.bench_info import BenchInfoData

if TYPE_CHECKING:
    from collections.abc import Mapping

    from sim.kinematics import ReducerKinematics
    from sim.presets import Preset

__all__ = [
    'REDUCER_KINDS',
    'BenchDescription',
    'EncoderInfo',
    'TorqueSensor',
    'UnitUnderTest',
    'load_bench_description',
    'parse_bench_description',
]

REDUCER_KINDS = ('2kv', 'rv', 'other')
_TWO_PI = 2.0 * math.pi
_MAX_TEXT = 4096        # longest free text (notes, metadata values) [characters]
_MAX_METADATA = 100     # most free metadata keys


def _fail(where: str, key: str, rule: str, value: object = None) -> NoReturn:
    got = '' if value is None else f', got {brief(value)}'
    msg = f'{where}: {key} {rule}{got}'
    raise BenchDescriptionError(msg)


def _number(v: object) -> bool:
    return not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)


@dataclass(frozen=True)
class EncoderInfo:
    """One shaft encoder of the bench.

    Attributes:
        model: Model name (BenchInfo ``encoder_*_model``).
        resolution_rad: Smallest increment [rad] (0.0: unknown / not quantised).
        counts_per_rev: Increments per revolution when known (raw counter columns are
            divided by it), else None.
        serial: The scale's serial number ('' : not stated; a calibration must name it).
        head_angles_rad: Angles of the scale's read heads from head 0 [rad] (empty: one).
        scale_diameter_m: Graduation diameter [m] (0: not stated).
        scale_eccentricity_m: Stated mounting eccentricity, run-out / 2 [m] (0: not stated).
        scale_index_rad: The scale turned on its shaft from its reference mounting [rad].
        scale_tilt_rad: Stated tilt of the scale plane against the axis, axial run-out (TIR)
            / D [rad] (0: not stated); an order-2 error tau^2 / 4 of every head.
        head_joints: JointState names of the heads, head 0 first (empty: one joint).
        zero_offset_rad: The encoder's reading at the reducer's zero position [rad] (from a
            zeroing step), or None when not declared (the TE is then referred to its first
            sample: :mod:`rv_te_bench.core.te_zero`).
    """

    model: str
    resolution_rad: float = 0.0
    counts_per_rev: int | None = None
    serial: str = ''
    head_angles_rad: tuple[float, ...] = ()
    scale_diameter_m: float = 0.0
    scale_eccentricity_m: float = 0.0
    scale_index_rad: float = 0.0
    scale_tilt_rad: float = 0.0
    head_joints: tuple[str, ...] = ()
    zero_offset_rad: float | None = None

    def __post_init__(self) -> None:
        """Validate (model non-empty, resolution finite >= 0, counts >= 1)."""
        if not isinstance(self.model, str) or not self.model.strip():
            _fail('EncoderInfo', 'model', 'must be a non-empty string', self.model)
        if not _number(self.resolution_rad) or self.resolution_rad < 0:
            _fail('EncoderInfo', 'resolution_rad', 'must be a finite number >= 0',
                  self.resolution_rad)
        cpr = self.counts_per_rev
        if cpr is not None and (isinstance(cpr, bool) or not isinstance(cpr, int) or cpr < 1):
            _fail('EncoderInfo', 'counts_per_rev', 'must be an integer >= 1', cpr)
        object.__setattr__(self, 'head_angles_rad', tuple(self.head_angles_rad))
        object.__setattr__(self, 'head_joints', tuple(self.head_joints))
        if not _number(self.scale_tilt_rad) or not 0 <= self.scale_tilt_rad <= 0.1:
            _fail('EncoderInfo', 'scale_tilt_rad', 'must be a finite number in [0, 0.1]',
                  self.scale_tilt_rad)
        if self.head_joints and len(self.head_joints) != max(1, len(self.head_angles_rad)):
            _fail('EncoderInfo', 'head_joints', f'must name one joint per head '
                  f'({len(self.head_angles_rad)})', list(self.head_joints))
        z = self.zero_offset_rad
        if z is not None and not _number(z):
            _fail('EncoderInfo', 'zero_offset_rad', 'must be a finite number or None', z)

    def scale_fields(self, side: str) -> dict[str, Any]:   # BenchInfoData keywords
        """The BenchInfo fields of this scale (``side``: 'in' or 'out')."""
        return {f'encoder_{side}_head_angles_rad': self.head_angles_rad,
                f'encoder_{side}_scale_serial': self.serial,
                f'encoder_{side}_scale_diameter_m': self.scale_diameter_m,
                f'encoder_{side}_scale_eccentricity_m': self.scale_eccentricity_m,
                f'encoder_{side}_scale_index_rad': self.scale_index_rad}


@dataclass(frozen=True)
class TorqueSensor:
    """The output torque sensor.

    Attributes:
        present: Whether the bench measures output torque.
        model: Sensor model ('' when unknown).
        scale_nm_per_unit: Recorded value x scale = torque [N m].
        unit: Unit of the recorded value (for the record, e.g. ``'V'`` or ``'N m'``).
    """

    present: bool = False
    model: str = ''
    scale_nm_per_unit: float = 1.0
    unit: str = 'N m'

    def __post_init__(self) -> None:
        """Validate (finite non-zero scale)."""
        if not _number(self.scale_nm_per_unit) or self.scale_nm_per_unit == 0:
            _fail('TorqueSensor', 'scale_nm_per_unit', 'must be a finite non-zero number',
                  self.scale_nm_per_unit)


@dataclass(frozen=True)
class UnitUnderTest:
    """The reducer being tested (all optional)."""

    serial: str = ''
    operator: str = ''
    temperature_c: float | None = None
    notes: str = ''
    #: Where the serial came from when not from the file ('' = the description itself):
    #: ``rv-te import --serial``, the file name (:mod:`rv_te_bench.io.unit_serial`).
    serial_source: str = field(default='', compare=False)

    def __post_init__(self) -> None:
        """Validate (temperature finite, in -100..300 degC)."""
        t = self.temperature_c
        if t is not None and (not _number(t) or not -100.0 <= t <= 300.0):
            _fail('UnitUnderTest', 'temperature_c', 'must be a number in [-100, 300]', t)


@dataclass(frozen=True)
class BenchDescription:
    """A validated bench description (SI units; see the module docstring for the file).

    Attributes:
        bench_id: Bench identifier (EncoderBlock frame_id).
        preset: Reducer preset name or path, None for a reducer without a preset.
        preset_overrides: ``"key=value"`` overrides applied to the preset.
        reducer_type: ``'2kv'``, ``'rv'`` or ``'other'``.
        gear_ratio: i, input revolutions per output revolution (> 0).
        crank_per_output: |f_w / f_out|, absolute crank revolutions per output revolution.
        crank_rel_per_output: |crank revolutions relative to the carrier| per output rev.
        mesh_orders: Mesh frequencies as orders of the output rotation.
        mesh_labels: One label per mesh order.
        encoder_in: Input-shaft encoder.
        encoder_out: Output-shaft encoder.
        sample_rate_hz: Nominal DAQ rate [Hz].
        block_size: Samples per EncoderBlock.
        torque_sensor: The output torque sensor.
        unit_under_test: Serial, operator, temperature, notes.
        joint_in_name: JointState name of the input joint (None: not given).
        joint_out_name: JointState name of the output joint (None: not given).
        max_input_speed_rpm: The bench's input speed limit [rpm] (NaN: not given).
        max_output_torque_nm: The bench's output torque limit [N m] (NaN: not given).
        metadata: Free string metadata (read-only mapping).
        origin: Where the description came from (file name), for messages.
    """

    bench_id: str
    gear_ratio: float
    crank_per_output: float
    sample_rate_hz: float
    preset: str | None = None
    preset_overrides: tuple[str, ...] = ()
    reducer_type: str = 'other'
    crank_rel_per_output: float = math.nan
    mesh_orders: tuple[float, ...] = ()
    mesh_labels: tuple[str, ...] = ()
    encoder_in: EncoderInfo = field(default_factory=lambda: EncoderInfo('unknown'))
    encoder_out: EncoderInfo = field(default_factory=lambda: EncoderInfo('unknown'))
    block_size: int = 1000
    torque_sensor: TorqueSensor = field(default_factory=TorqueSensor)
    unit_under_test: UnitUnderTest = field(default_factory=UnitUnderTest)
    joint_in_name: str | None = None
    joint_out_name: str | None = None
    max_input_speed_rpm: float = math.nan
    max_output_torque_nm: float = math.nan
    metadata: Mapping[str, str] = field(default_factory=dict, hash=False)
    uncertainty: Mapping[str, Any] | None = field(default=None, hash=False)
    loss_channels: Mapping[str, Mapping[str, str | float]] | None = field(default=None,
                                                                          hash=False)
    origin: str = field(default='<bench description>', compare=False)

    def __post_init__(self) -> None:
        """Validate every field; NaN ``crank_rel_per_output`` becomes crank + 1.

        Raises:
            BenchDescriptionError: A field breaks its rule (names origin, field, value).
        """
        w = self.origin
        if not isinstance(self.bench_id, str) or not self.bench_id.strip():
            _fail(w, 'bench_id', 'must be a non-empty string', self.bench_id)
        if self.preset is not None and (not isinstance(self.preset, str)
                                        or not self.preset.strip()):
            _fail(w, 'preset', 'must be a non-empty string or None', self.preset)
        object.__setattr__(self, 'preset_overrides', tuple(self.preset_overrides))
        if self.reducer_type not in REDUCER_KINDS:
            _fail(w, 'reducer.kind', f'must be one of {list(REDUCER_KINDS)}', self.reducer_type)
        for name in ('gear_ratio', 'crank_per_output', 'sample_rate_hz'):
            v = getattr(self, name)
            if not _number(v) or v <= 0:
                _fail(w, name, 'must be a finite number > 0', v)
            object.__setattr__(self, name, float(v))
        rel = self.crank_rel_per_output
        if isinstance(rel, float) and math.isnan(rel):
            rel = self.crank_per_output + 1.0
        if not _number(rel) or rel <= 0:
            _fail(w, 'crank_rel_per_output', 'must be a finite number > 0', rel)
        object.__setattr__(self, 'crank_rel_per_output', float(rel))
        orders = tuple(self.mesh_orders)
        if any(not _number(o) or o <= 0 for o in orders):
            _fail(w, 'mesh_orders', 'must be finite numbers > 0', list(orders))
        object.__setattr__(self, 'mesh_orders', tuple(float(o) for o in orders))
        labels = tuple(self.mesh_labels) or tuple(f'mesh {k}' for k in range(1, len(orders) + 1))
        if len(labels) != len(orders) or not all(isinstance(s, str) for s in labels):
            _fail(w, 'mesh_labels', f'must be {len(orders)} strings (one per mesh order)',
                  list(labels))
        object.__setattr__(self, 'mesh_labels', labels)
        bs = self.block_size
        if isinstance(bs, bool) or not isinstance(bs, int) or not 1 <= bs <= 1_000_000:
            _fail(w, 'block_size', 'must be an integer in [1, 1000000]', bs)
        for name, cls in (('encoder_in', EncoderInfo), ('encoder_out', EncoderInfo),
                          ('torque_sensor', TorqueSensor), ('unit_under_test', UnitUnderTest)):
            if not isinstance(getattr(self, name), cls):
                _fail(w, name, f'must be a {cls.__name__}', getattr(self, name))
        for name in ('joint_in_name', 'joint_out_name'):
            v = getattr(self, name)
            if v is not None and (not isinstance(v, str) or not v.strip()):
                _fail(w, name, 'must be a non-empty string or None', v)
        for name in ('max_input_speed_rpm', 'max_output_torque_nm'):
            v = getattr(self, name)
            if not (isinstance(v, float) and math.isnan(v)) and (not _number(v) or v <= 0):
                _fail(w, f'limits.{name}', 'must be a finite number > 0', v)
        meta = dict(self.metadata)
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in meta.items()):
            _fail(w, 'metadata', 'must map strings to strings', meta)
        object.__setattr__(self, 'metadata', MappingProxyType(meta))

    @property
    def crank_per_input(self) -> float:
        """Signed absolute crank revolutions per input revolution (BenchInfo field)."""
        if self.preset is not None:
            return float(self._kinematics().crank_per_input)
        return OrderSet(gear_ratio=self.gear_ratio,
                        crank_per_output=self.crank_per_output).crank_per_input()

    @property
    def crank_rel_per_input(self) -> float:
        """Signed crank revolutions relative to the carrier per input revolution."""
        if self.preset is not None:
            return float(self._kinematics().crank_rel_per_input)
        return -self.crank_rel_per_output / self.gear_ratio   # against the input, as above

    @functools.cached_property
    def _kinematics_cached(self) -> ReducerKinematics:
        from sim.kinematics import kinematics_from_preset

        return kinematics_from_preset(self._preset())

    def _kinematics(self) -> ReducerKinematics:
        return self._kinematics_cached

    @functools.cached_property
    def _preset_cached(self) -> Preset:
        """The preset, loaded once per description (BenchInfo needs it three times)."""
        from sim.presets import load_preset

        return load_preset(str(self.preset), list(self.preset_overrides))

    def _preset(self) -> Preset:
        return self._preset_cached

    def to_plain(self) -> dict[str, Any]:
        """The description as validated (SI units), YAML-friendly."""
        return {
            'bench_id': self.bench_id, 'preset': self.preset,
            'overrides': list(self.preset_overrides), 'reducer_type': self.reducer_type,
            'gear_ratio': self.gear_ratio, 'crank_per_output': self.crank_per_output,
            'crank_rel_per_output': self.crank_rel_per_output,
            'mesh_orders': list(self.mesh_orders), 'mesh_labels': list(self.mesh_labels),
            'encoder_in': _encoder_plain(self.encoder_in),
            'encoder_out': _encoder_plain(self.encoder_out),
            'sample_rate_hz': self.sample_rate_hz, 'block_size': self.block_size,
            'torque_sensor': {'present': self.torque_sensor.present,
                              'model': self.torque_sensor.model,
                              'scale_nm_per_unit': self.torque_sensor.scale_nm_per_unit,
                              'unit': self.torque_sensor.unit},
            'unit_under_test': {'serial': self.unit_under_test.serial,
                                'operator': self.unit_under_test.operator,
                                'temperature_c': self.unit_under_test.temperature_c,
                                'notes': self.unit_under_test.notes},
            'joints': {'input': self.joint_in_name, 'output': self.joint_out_name},
            'limits': {k: (None if math.isnan(v) else v) for k, v in (
                ('max_input_speed_rpm', self.max_input_speed_rpm),
                ('max_output_torque_nm', self.max_output_torque_nm))},
            'metadata': dict(self.metadata),
            **({'uncertainty': dict(self.uncertainty)} if self.uncertainty else {}),
            **({'loss_channels': {k: dict(v) for k, v in self.loss_channels.items()}}
               if self.loss_channels else {}),
            'source': 'bench description',
        }

    def bench_info(self) -> BenchInfoData:
        """The ``rv_te_msgs/BenchInfo`` fields of this bench.

        ``parameters_yaml`` holds ``{'bench': to_plain(), 'preset': {name, model, values}}``
        as :attr:`sim.bench.BenchSimulator.info` records it (``bench.overrides`` included,
        so :func:`rv_te_bench.io.bench_record.overrides_from_parameters_yaml` rebuilds the
        exact preset).
        """
        record: dict[str, Any] = {'bench': self.to_plain()}
        zin, zout = self.encoder_in.zero_offset_rad, self.encoder_out.zero_offset_rad
        if zin is not None or zout is not None:
            # declared encoder zeros: the TE is referred to them (core.te_zero)
            record['encoder_zero'] = {'input_rad': zin or 0.0, 'output_rad': zout or 0.0,
                                      'source': f'{self.origin} (encoders.*.zero_offset_deg)'}
        if self.preset is not None:
            preset = self._preset()
            record['preset'] = {'name': preset.name, 'model': preset.model,
                                'values': preset.to_plain()}
        return BenchInfoData(
            bench_id=self.bench_id, preset=self.preset or '', reducer_type=self.reducer_type,
            gear_ratio=self.gear_ratio, crank_per_input=self.crank_per_input,
            crank_rel_per_input=self.crank_rel_per_input, mesh_orders=self.mesh_orders,
            mesh_labels=self.mesh_labels, encoder_in_model=self.encoder_in.model,
            encoder_out_model=self.encoder_out.model,
            encoder_in_resolution_rad=self.encoder_in.resolution_rad,
            encoder_out_resolution_rad=self.encoder_out.resolution_rad,
            sample_rate_hz=self.sample_rate_hz, block_size=self.block_size,
            parameters_yaml=_safe_dump_sorted(record),
            **self.encoder_in.scale_fields('in'), **self.encoder_out.scale_fields('out'))

    def to_metadata(self) -> dict[str, Any]:
        """The bag's metadata ``custom_data`` (keys the report reads: ``unit_serial``).

        Free ``metadata`` keys come first, so the described keys win on a clash.
        """
        uut = self.unit_under_test
        out: dict[str, Any] = dict(self.metadata)
        out.update({
            'bench_id': self.bench_id,
            'preset': self.preset or '',
            'unit_serial': uut.serial,
            'unit_serial_source': uut.serial_source or (
                f'bench description {self.origin} (unit_under_test.serial)' if uut.serial
                else ''),
            'operator': uut.operator,
            'temperature_c': '' if uut.temperature_c is None else f'{uut.temperature_c:g}',
            'unit_notes': uut.notes,
            'bench_description': yaml.safe_dump(self.to_plain(), sort_keys=True),
        })
        return out


def _safe_dump_sorted(data: Any) -> str:
    """``yaml.safe_dump(data, sort_keys=True)``, by libyaml where installed (the same text,
    tested; a quarter of the time)."""
    return yaml.dump(data, Dumper=getattr(yaml, 'CSafeDumper', yaml.SafeDumper), sort_keys=True)


def _encoder_plain(e: EncoderInfo) -> dict[str, Any]:
    out: dict[str, Any] = {'model': e.model, 'resolution_rad': e.resolution_rad,
                           'counts_per_rev': e.counts_per_rev}
    if (e.serial or e.head_angles_rad or e.scale_diameter_m or e.scale_index_rad
            or e.scale_tilt_rad):
        out.update({'serial': e.serial, 'head_angles_rad': list(e.head_angles_rad),
                    'scale_diameter_m': e.scale_diameter_m,
                    'scale_eccentricity_m': e.scale_eccentricity_m,
                    'scale_index_rad': e.scale_index_rad, 'scale_tilt_rad': e.scale_tilt_rad,
                    'head_joints': list(e.head_joints)})
    if e.zero_offset_rad is not None:
        out['zero_offset_rad'] = e.zero_offset_rad
    return out


class _Keys:
    """Pops and checks the keys of one mapping; one line naming where, key, rule, value."""

    def __init__(self, data: Any, where: str, key: str = '') -> None:
        self.where = where
        self.prefix = f'{key}.' if key else ''
        if not isinstance(data, dict):
            _fail(where, key or 'document', 'must be a mapping', data)
        self.data = dict(data)

    def fail(self, key: str, rule: str, value: object = None) -> NoReturn:
        _fail(self.where, f'{self.prefix}{key}', rule, value)

    def num(self, key: str, *, required: bool = False, positive: bool = True,
            default: float | None = None) -> float | None:
        if key not in self.data:
            if required:
                self.fail(key, 'is required')
            return default
        v = self.data.pop(key)
        if not _number(v) or (positive and v <= 0):
            self.fail(key, 'must be a finite number' + (' > 0' if positive else ''), v)
        return float(v)

    def text(self, key: str, default: str | None = None, *, required: bool = False,
             allow_empty: bool = False) -> str | None:
        if key not in self.data:
            if required:
                self.fail(key, 'is required')
            return default
        v = self.data.pop(key)
        if isinstance(v, int | float) and not isinstance(v, bool):
            v = str(v)        # a serial number written as 1234
        if not isinstance(v, str) or (not allow_empty and not v.strip()) or len(v) > _MAX_TEXT:
            self.fail(key, f'must be a {"" if allow_empty else "non-empty "}string of at most '
                      f'{_MAX_TEXT} characters', v)
        return v.strip()

    def sub(self, key: str) -> _Keys:
        return _Keys(self.data.pop(key, {}) or {}, self.where, f'{self.prefix}{key}')

    def done(self) -> None:
        if self.data:
            self.fail(f'unknown key(s) {sorted(map(str, self.data))}',
                      'are not allowed here (misspelt?)')


def _encoder(k: _Keys) -> EncoderInfo:
    from sim.encoders import ENCODER_PRESETS

    model = k.text('model', 'unknown') or 'unknown'
    known = ENCODER_PRESETS.get(model)
    cpr = k.data.pop('counts_per_rev', None)
    if cpr is not None and (isinstance(cpr, bool) or not isinstance(cpr, int) or cpr < 1):
        k.fail('counts_per_rev', 'must be an integer >= 1', cpr)
    res = k.num('resolution_rad', positive=False)
    if res is not None and res < 0:
        k.fail('resolution_rad', 'must be >= 0', res)
    if cpr is not None and res is not None and not math.isclose(res, _TWO_PI / cpr,
                                                                 rel_tol=1e-9):
        k.fail('resolution_rad', f'contradicts counts_per_rev {cpr} (2 pi / counts = '
               f'{_TWO_PI / cpr:.6g} rad); give one of them', res)
    if cpr is None and known is not None:
        cpr = known.counts_per_rev
    if res is None:
        res = _TWO_PI / cpr if cpr else (known.resolution_rad if known is not None else 0.0)
    serial = k.text('serial', '') or ''
    heads = k.data.pop('heads_deg', [])
    if not isinstance(heads, list) or len(heads) > 16 or not all(_number(a) for a in heads):
        k.fail('heads_deg', 'must be a list of at most 16 angles [deg] (head 0 first)', heads)
    if len(heads) == 1 and heads[0] != 0:
        k.fail('heads_deg', 'with one head must be [0] or left out', heads)
    scale = k.sub('scale')
    dia = scale.num('diameter_mm', default=0.0) or 0.0
    ecc = scale.num('eccentricity_um', positive=False)
    runout = scale.num('runout_um', positive=False)
    if ecc is not None and runout is not None:
        scale.fail('runout_um', 'and eccentricity_um both given (run-out = 2 x eccentricity): '
                   'give one', runout)
    e_um = ecc if ecc is not None else (runout / 2.0 if runout is not None else 0.0)
    if e_um < 0:
        scale.fail('eccentricity_um', 'must be >= 0', e_um)
    if e_um > 0 and dia == 0:
        scale.fail('diameter_mm', 'is required with a run-out (angle error = 412 e/D arcsec)')
    index = scale.num('index_deg', default=0.0, positive=False) or 0.0
    tilt = _scale_tilt_rad(scale, dia)
    scale.done()
    zero = k.num('zero_offset_deg', positive=False)
    if zero is not None and abs(zero) > 360.0:
        k.fail('zero_offset_deg', 'must lie within +-360 deg (the reading at the reducer\'s '
               'zero)', zero)
    k.done()
    return EncoderInfo(model=model, resolution_rad=float(res), counts_per_rev=cpr,
                       zero_offset_rad=None if zero is None else math.radians(zero),
                       serial=serial, head_angles_rad=tuple(math.radians(a) for a in heads)
                       if len(heads) > 1 else (),
                       scale_diameter_m=dia * 1e-3, scale_eccentricity_m=e_um * 1e-6,
                       scale_index_rad=math.radians(index), scale_tilt_rad=tilt)


def _scale_tilt_rad(scale: _Keys, dia_mm: float) -> float:
    """The scale's tilt [rad]: ``tilt_mrad``, or ``axial_runout_um`` (TIR of the scale face
    at its graduation diameter) / D; one of them."""
    tilt = scale.num('tilt_mrad', positive=False)
    axial = scale.num('axial_runout_um', positive=False)
    if tilt is not None and axial is not None:
        scale.fail('axial_runout_um', 'and tilt_mrad both given (tilt = axial run-out / D): '
                   'give one', axial)
    if axial is not None:
        if axial < 0:
            scale.fail('axial_runout_um', 'must be >= 0', axial)
        if axial > 0 and dia_mm == 0:
            scale.fail('diameter_mm', 'is required with an axial run-out (tilt = run-out / D)')
        return axial * 1e-6 / (dia_mm * 1e-3) if axial > 0 else 0.0
    if tilt is not None and not 0 <= tilt <= 100:
        scale.fail('tilt_mrad', 'must be between 0 and 100', tilt)
    return (tilt or 0.0) * 1e-3


def _kinematic_fields(top: _Keys, preset: str | None, overrides: tuple[str, ...],
                      ) -> dict[str, Any]:
    if preset is not None:
        if 'reducer' in top.data:
            top.fail('reducer', 'is not allowed with a preset (the preset gives the '
                     'kinematics; change teeth with preset_overrides)')
        from sim.errors import PresetError
        from sim.kinematics import kinematics_from_preset
        from sim.presets import load_preset

        try:
            kin = kinematics_from_preset(load_preset(preset, list(overrides)))
        except (PresetError, OSError) as exc:
            top.fail('preset', f'cannot be used ({" ".join(str(exc).split())})')
        return {'reducer_type': str(kin.kind), 'gear_ratio': float(kin.gear_ratio),
                'crank_per_output': float(kin.crank_per_output),
                'crank_rel_per_output': float(kin.crank_rel_per_output),
                'mesh_orders': tuple(float(o) for o in kin.mesh_orders_out),
                'mesh_labels': tuple(str(s) for s in kin.mesh_labels)}
    if 'reducer' not in top.data:
        top.fail('preset', 'or reducer (gear_ratio, crank_per_output) is required')
    r = top.sub('reducer')
    kind = r.text('kind', 'other')
    if kind not in REDUCER_KINDS:
        r.fail('kind', f'must be one of {list(REDUCER_KINDS)}', kind)
    out: dict[str, Any] = {
        'reducer_type': kind, 'gear_ratio': r.num('gear_ratio', required=True),
        'crank_per_output': r.num('crank_per_output', required=True),
        'crank_rel_per_output': r.num('crank_rel_per_output', default=math.nan)}
    orders = r.data.pop('mesh_orders', [])
    if not isinstance(orders, list) or len(orders) > 20 or any(
            not _number(o) or o <= 0 for o in orders):
        r.fail('mesh_orders', 'must be a list of at most 20 finite numbers > 0', orders)
    labels = r.data.pop('mesh_labels', [f'mesh {j + 1}' for j in range(len(orders))])
    if not isinstance(labels, list) or len(labels) != len(orders) or not all(
            isinstance(s, str) and s.strip() for s in labels):
        r.fail('mesh_labels', f'must be a list of {len(orders)} non-empty strings (one per '
               'mesh order)', labels)
    r.done()
    out['mesh_orders'] = tuple(float(o) for o in orders)
    out['mesh_labels'] = tuple(labels)
    return out


def parse_bench_description(data: Any, origin: str = '<bench description>',
                            ) -> BenchDescription:
    """Validate a bench description mapping (parsed YAML).

    Raises:
        BenchDescriptionError: Anything wrong, in one line (origin, key, rule, value).
    """
    top = _Keys(data, origin)
    bench_id = top.text('bench_id', required=True)
    preset = top.text('preset')
    ov = top.data.pop('preset_overrides', [])
    if not isinstance(ov, list) or not all(isinstance(o, str) and '=' in o for o in ov):
        top.fail('preset_overrides', 'must be a list of "key=value" strings', ov)
    if ov and preset is None:
        top.fail('preset_overrides', 'needs a preset')
    kin = _kinematic_fields(top, preset, tuple(ov))
    rate = top.num('sample_rate_hz', required=True)
    bs = top.data.pop('block_size', 1000)
    if isinstance(bs, bool) or not isinstance(bs, int) or not 1 <= bs <= 1_000_000:
        top.fail('block_size', 'must be an integer in [1, 1000000]', bs)
    enc = top.sub('encoders')
    enc_in = _encoder(enc.sub('input'))
    enc_out = _encoder(enc.sub('output'))
    enc.done()
    ts = top.sub('torque_sensor')
    present = ts.data.pop('present', bool(ts.data))
    if not isinstance(present, bool):
        ts.fail('present', 'must be true or false', present)
    scale = ts.num('scale_nm_per_unit', default=1.0, positive=False)
    if scale == 0:
        ts.fail('scale_nm_per_unit', 'must be non-zero', scale)
    torque = TorqueSensor(present=present, model=ts.text('model', '', allow_empty=True) or '',
                          scale_nm_per_unit=float(scale or 1.0),
                          unit=ts.text('unit', 'N m') or 'N m')
    ts.done()
    u = top.sub('unit_under_test')
    temp = u.num('temperature_c', positive=False)
    if temp is not None and not -100.0 <= temp <= 300.0:
        u.fail('temperature_c', 'must be in [-100, 300] degC', temp)
    uut = UnitUnderTest(serial=u.text('serial', '') or '', operator=u.text('operator', '') or '',
                        temperature_c=temp, notes=u.text('notes', '', allow_empty=True) or '')
    u.done()
    j = top.sub('joints')
    joint_in, joint_out = j.text('input'), j.text('output')
    head_joints = j.data.pop('output_heads', [])
    n_heads = max(1, len(enc_out.head_angles_rad))
    if head_joints and (not isinstance(head_joints, list) or len(head_joints) != n_heads
                        or not all(isinstance(n, str) and n.strip() for n in head_joints)
                        or len(set(head_joints)) != len(head_joints)):
        j.fail('output_heads', f'must list {n_heads} different joint names, one per head of '
               'encoders.output.heads_deg (head 0 first)', head_joints)
    j.done()
    if joint_in is not None and joint_in == joint_out:
        j.fail('output', 'must differ from joints.input', joint_out)
    if joint_in is not None and joint_in in head_joints:
        j.fail('output_heads', 'must not name joints.input', head_joints)
    if head_joints:
        enc_out = replace(enc_out, head_joints=tuple(head_joints))
    lim = top.sub('limits')
    max_speed = lim.num('max_input_speed_rpm')
    max_torque = lim.num('max_output_torque_nm')
    lim.done()
    meta_raw = top.data.pop('metadata', {}) or {}
    if not isinstance(meta_raw, dict) or len(meta_raw) > _MAX_METADATA:
        top.fail('metadata', f'must be a mapping of at most {_MAX_METADATA} keys', meta_raw)
    meta: dict[str, str] = {}
    for key, value in meta_raw.items():
        if not isinstance(key, str) or isinstance(value, dict | list) or value is None \
                or len(str(value)) > _MAX_TEXT:
            top.fail(f'metadata.{key}', f'must be a text or number of at most {_MAX_TEXT} '
                     'characters', value)
        meta[key] = str(value)
    unc = _uncertainty(top, enc_in, enc_out)
    loss = _loss_channels(top.sub('loss_channels')) if 'loss_channels' in top.data else None
    top.done()
    return BenchDescription(
        bench_id=str(bench_id), preset=preset, preset_overrides=tuple(ov),
        sample_rate_hz=float(rate or 0.0), block_size=int(bs), encoder_in=enc_in,
        encoder_out=enc_out, torque_sensor=torque, unit_under_test=uut,
        joint_in_name=joint_in, joint_out_name=joint_out,
        max_input_speed_rpm=math.nan if max_speed is None else float(max_speed),
        max_output_torque_nm=math.nan if max_torque is None else float(max_torque),
        metadata=meta, uncertainty=unc, loss_channels=loss, origin=origin, **kin)


def _loss_channels(k: _Keys) -> dict[str, dict[str, str | float]]:
    """The ``loss_channels:`` section: per channel (``torque_in``, ``torque_out``,
    ``temperature``) its model, range and class (the efficiency budget reads them) and, for
    the input torque, the scale of its column."""
    out: dict[str, dict[str, str | float]] = {}
    for name in ('torque_in', 'torque_out', 'temperature'):
        if name not in k.data:
            continue
        c = k.sub(name)
        spec: dict[str, str | float] = {'model': c.text('model', '', allow_empty=True) or ''}
        for key in ('full_scale', 'accuracy_class_pct'):
            v = c.num(key)
            if v is not None:
                spec[key] = float(v)
        if name == 'torque_in':
            scale = c.num('scale_nm_per_unit', default=1.0, positive=False)
            if scale == 0:
                c.fail('scale_nm_per_unit', 'must be non-zero', scale)
            spec['scale_nm_per_unit'] = float(scale or 1.0)
        c.done()
        out[name] = spec
    k.done()
    return out


def _uncertainty(top: _Keys, enc_in: EncoderInfo, enc_out: EncoderInfo,
                 ) -> dict[str, Any] | None:
    """The ``uncertainty:`` section (the bench's own error values; keys in
    :func:`rv_te_bench.core.bench_uncertainty.bench_uncertainty_from_plain`), checked
    against the described encoders' data-sheet defaults, kept as written."""
    raw = top.data.pop('uncertainty', None)
    if raw is None:
        return None
    base = BenchUncertainty.defaults(enc_in.model, enc_out.model,
                                     resolution_in_rad=enc_in.resolution_rad,
                                     resolution_out_rad=enc_out.resolution_rad)
    try:
        bench_uncertainty_from_plain(raw, base, where=f'{top.where}: uncertainty')
    except TeConfigError as exc:
        raise BenchDescriptionError(str(exc)) from None
    return dict(raw)


def load_bench_description(path: str | Path) -> BenchDescription:
    """Read and validate a bench description YAML file (bounded loader).

    Raises:
        BenchDescriptionError: Unreadable file, bad YAML, or an invalid key or value (one
            line naming the file, the key, the rule and the value).
    """
    p = Path(path)
    try:
        data = read_yaml_file(p, what='bench description', limits=DOCUMENT_LIMITS,
                              scalars='document')
    except YamlInputError as exc:
        raise BenchDescriptionError(str(exc)) from None
    if data is None:
        msg = f'bench description {p}: the file is empty'
        raise BenchDescriptionError(msg)
    return parse_bench_description(data, f'bench description {p}')
