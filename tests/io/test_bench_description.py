"""Bench description files (issue #19 s.2): values, defaults from the preset, one-line errors."""

from __future__ import annotations

import math
from importlib import resources
from typing import TYPE_CHECKING

import pytest
import yaml

from rv_te_bench.errors import BenchDescriptionError, TeConfigError
from rv_te_bench.io.bench_description import (
    BenchDescription,
    load_bench_description,
    parse_bench_description,
)
from rv_te_bench.io.bench_record import overrides_from_parameters_yaml

if TYPE_CHECKING:
    from pathlib import Path

NO_PRESET = {
    'bench_id': 'b1', 'sample_rate_hz': 5000,
    'reducer': {'kind': 'rv', 'gear_ratio': 121, 'crank_per_output': 39,
                'mesh_orders': [2400, 1560], 'mesh_labels': ['s1', 'pin']},
}


def write(tmp_path: Path, data: object, name: str = 'bench.yaml') -> Path:
    p = tmp_path / name
    p.write_text(data if isinstance(data, str) else yaml.safe_dump(data), encoding='utf-8')
    return p


def test_shipped_example_loads() -> None:
    text = resources.files('rv_te_bench').joinpath(
        'launch', 'bench_description_example.yaml').read_text('utf-8')
    d = parse_bench_description(yaml.safe_load(text), 'example')
    # rv-80e-101: 18/45 teeth, 39 cycloid teeth, 40 pins -> i = 1 + (45/18)*40 = 101,
    # absolute crank = z_cycloid = 39 per output revolution, relative = z_pin = 40
    assert d.gear_ratio == pytest.approx(101.0, rel=1e-12)
    assert d.crank_per_output == pytest.approx(39.0, rel=1e-12)
    assert d.crank_rel_per_output == pytest.approx(40.0, rel=1e-12)
    assert d.reducer_type == 'rv'
    assert d.mesh_orders == pytest.approx((45 * 40, 40 * 39))
    assert d.encoder_in.resolution_rad == pytest.approx(2 * math.pi / 36e6)
    assert d.encoder_out.resolution_rad == pytest.approx(2 * math.pi / 2**32)
    assert d.unit_under_test.serial == 'SN-2026-0042'
    assert d.unit_under_test.temperature_c == 23.5
    assert d.joint_in_name == 'input_shaft_joint'
    assert d.torque_sensor.present


def test_no_preset_bench_info_and_metadata(tmp_path: Path) -> None:
    d = load_bench_description(write(tmp_path, {**NO_PRESET, 'unit_under_test': {
        'serial': 1234, 'temperature_c': 21}, 'metadata': {'lab': 'L2', 'rig': 7}}))
    info = d.bench_info()
    assert info.gear_ratio == 121.0
    assert info.crank_per_input == pytest.approx(-39 / 121)       # cranks against the input
    assert info.crank_rel_per_input == pytest.approx(-40 / 121)   # default crank + 1
    assert info.mesh_orders == (2400.0, 1560.0)
    assert info.mesh_labels == ('s1', 'pin')
    assert info.preset == ''
    assert info.sample_rate_hz == 5000.0
    assert info.block_size == 1000
    record = yaml.safe_load(info.parameters_yaml)
    assert record['bench']['bench_id'] == 'b1'
    assert 'preset' not in record
    meta = d.to_metadata()
    assert meta['unit_serial'] == '1234'
    assert meta['temperature_c'] == '21'
    assert meta['lab'] == 'L2' and meta['rig'] == '7'
    assert yaml.safe_load(meta['bench_description'])['gear_ratio'] == 121.0


def test_preset_bench_info_matches_simulator() -> None:
    """Same numbers as sim.bench's own BenchInfo for the preset (independent path)."""
    from sim.bench import BenchConfig, BenchSimulator
    from sim.drive import ConstantSpeed

    d = parse_bench_description({'bench_id': 'b', 'preset': 'wang2020-2kv',
                                 'sample_rate_hz': 10000,
                                 'preset_overrides': ['kinematics.z_sun=13']})
    sim = BenchSimulator(BenchConfig(preset='wang2020-2kv', drive=ConstantSpeed(300.0),
                                     overrides=('kinematics.z_sun=13',))).info
    ours = d.bench_info()
    for name in ('gear_ratio', 'crank_per_input', 'crank_rel_per_input', 'mesh_orders',
                 'mesh_labels', 'reducer_type', 'preset'):
        assert getattr(ours, name) == pytest.approx(getattr(sim, name)) \
            if isinstance(getattr(sim, name), float) else getattr(ours, name) == getattr(sim, name)
    assert overrides_from_parameters_yaml(ours.parameters_yaml) == ['kinematics.z_sun=13']
    assert yaml.safe_load(ours.parameters_yaml)['preset']['name'] == 'wang2020-2kv'


def test_wang_preset_values() -> None:
    d = parse_bench_description({'bench_id': 'b', 'preset': 'wang2020-2kv',
                                 'sample_rate_hz': 1000})
    # DESIGN.md s.4: i = 79, |f_w / f_out| = 25, relative 26, stage-2 mesh 52 * 25 = 1300
    assert d.gear_ratio == pytest.approx(79.0)
    assert d.crank_per_output == pytest.approx(25.0)
    assert d.crank_rel_per_output == pytest.approx(26.0)
    assert 1300.0 in [pytest.approx(o) for o in d.mesh_orders]


@pytest.mark.parametrize(('patch', 'words'), [
    ({'bench_id': ''}, ['bench_id', 'non-empty']),
    ({'sample_rate_hz': -1}, ['sample_rate_hz', '> 0', '-1']),
    ({'sample_rate_hz': 'fast'}, ['sample_rate_hz', "'fast'"]),
    ({'block_size': 0}, ['block_size', 'integer']),
    ({'colour': 'red'}, ["unknown key(s) ['colour']"]),
    ({'reducer': {'gear_ratio': 0, 'crank_per_output': 3}}, ['reducer.gear_ratio', '> 0']),
    ({'reducer': {'gear_ratio': 10}}, ['reducer.crank_per_output', 'required']),
    ({'reducer': {'gear_ratio': 10, 'crank_per_output': 3, 'kind': 'harmonic'}},
     ['reducer.kind', "'harmonic'"]),
    ({'reducer': {'gear_ratio': 10, 'crank_per_output': 3, 'mesh_orders': [1, 2],
                  'mesh_labels': ['a']}}, ['reducer.mesh_labels', '2']),
    ({'reducer': {'gear_ratio': 10, 'crank_per_output': 3, 'z': 1}},
     ['reducer.', "unknown key(s) ['z']"]),
    ({'preset': 'no-such-reducer', 'reducer': None}, ['preset', 'no-such-reducer']),
    ({'preset': 'wang2020-2kv'}, ['reducer', 'not allowed with a preset']),
    ({'encoders': {'input': {'counts_per_rev': 0}}}, ['encoders.input.counts_per_rev', '>= 1']),
    ({'encoders': {'input': {'counts_per_rev': 1000, 'resolution_rad': 0.1}}},
     ['encoders.input.resolution_rad', 'contradicts']),
    ({'encoders': {'middle': {}}}, ['encoders.', "['middle']"]),
    ({'torque_sensor': {'present': 'yes'}}, ['torque_sensor.present', 'true or false']),
    ({'torque_sensor': {'scale_nm_per_unit': 0}}, ['torque_sensor.scale_nm_per_unit']),
    ({'unit_under_test': {'temperature_c': 999}}, ['unit_under_test.temperature_c', '999']),
    ({'unit_under_test': {'serail': 'x'}}, ['unit_under_test.', "['serail']"]),
    ({'joints': {'input': 'a', 'output': 'a'}}, ['joints.output', 'differ']),
    ({'metadata': {'k': [1, 2]}}, ['metadata.k']),
    ({'preset_overrides': ['x=1']}, ['preset_overrides', 'needs a preset']),
])
def test_bad_value_one_line(tmp_path: Path, patch: dict, words: list[str]) -> None:
    data = {k: v for k, v in {**NO_PRESET, **patch}.items() if v is not None}
    path = write(tmp_path, data)
    with pytest.raises(BenchDescriptionError) as exc:
        load_bench_description(path)
    text = str(exc.value)
    assert '\n' not in text
    assert str(path) in text
    for w in words:
        assert w in text, (w, text)


@pytest.mark.parametrize(('content', 'words'), [
    ('', ['empty']),
    ('bench_id: [unclosed', ['not valid YAML']),
    ('- 1\n- 2\n', ['must be a mapping']),
    ('bench_id: a\nbench_id: b\n', ['bench_id']),
])
def test_bad_file_one_line(tmp_path: Path, content: str, words: list[str]) -> None:
    path = write(tmp_path, content)
    with pytest.raises(BenchDescriptionError) as exc:
        load_bench_description(path)
    assert '\n' not in str(exc.value)
    assert str(path) in str(exc.value)
    for w in words:
        assert w in str(exc.value)


def test_missing_file_and_error_type(tmp_path: Path) -> None:
    with pytest.raises(TeConfigError, match='cannot read'):
        load_bench_description(tmp_path / 'nope.yaml')


def test_dataclass_is_frozen_and_validated() -> None:
    d = BenchDescription(bench_id='x', gear_ratio=79.0, crank_per_output=25.0,
                         sample_rate_hz=1000.0)
    assert d.crank_rel_per_output == 26.0
    with pytest.raises(AttributeError):
        d.gear_ratio = 3.0  # type: ignore[misc]
    with pytest.raises(BenchDescriptionError, match='gear_ratio'):
        BenchDescription(bench_id='x', gear_ratio=math.nan, crank_per_output=25.0,
                         sample_rate_hz=1000.0)
    with pytest.raises(TypeError):
        d.metadata['k'] = 'v'  # type: ignore[index]


def test_readme_example_is_valid() -> None:
    """The bench description shown in README "Using a real bench" validates."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / 'README.md').read_text('utf-8')
    section = text.split('## Using a real bench', 1)[1]
    (block,) = [b for b in re.findall(r'```yaml\n(.*?)```', section.split('\n## ', 1)[0],
                                      flags=re.DOTALL) if b.startswith('bench_id:')]
    d = parse_bench_description(yaml.safe_load(block), 'README')
    assert d.preset == 'rv-80e-101' and d.unit_under_test.serial == 'SN-2026-0042'
