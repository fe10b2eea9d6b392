"""Tests of the generic preset machinery in sim.presets (loading, overrides, errors)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from sim.errors import PresetError
from sim.presets import (
    Preset,
    available_presets,
    load_preset,
    parse_override_items,
    preset_from_text,
)

TEXT = '''
name = "demo"
model = "wang2020-2kv"
description = "a test preset"
flag = true
label = "plain string"

[gear]
z_sun = { value = 12, unit = "1", source = "Table 1" }
r_p_m = { value = 0.06108, unit = "m", source = "DESIGN.md", note = "assumed" }
harmonics = { value = [0.1, 0.05], unit = "1", source = "assumption" }

[gear.deep]
angle_deg = { value = 35.266, unit = "deg", source = "Table 2" }
'''


@pytest.fixture
def preset() -> Preset:
    return preset_from_text(TEXT, 'test')


def test_flat_keys_units_sources(preset: Preset) -> None:
    assert preset.name == 'demo' and preset.model == 'wang2020-2kv'
    assert preset.description == 'a test preset'
    assert preset.keys() == sorted(['flag', 'label', 'gear.z_sun', 'gear.r_p_m',
                                    'gear.harmonics', 'gear.deep.angle_deg'])
    assert preset['gear.z_sun'] == 12
    assert preset.values['gear.r_p_m'].unit == 'm'
    assert preset.values['gear.r_p_m'].note == 'assumed'
    assert preset.values['flag'].unit == ''          # bare values carry no unit/source
    assert preset.get('missing', 7) == 7
    assert preset.section('gear') == {'z_sun': 12, 'r_p_m': 0.06108,
                                      'harmonics': [0.1, 0.05], 'deep.angle_deg': 35.266}
    rows = {r['key']: r for r in preset.describe_rows()}
    assert rows['gear.deep.angle_deg']['source'] == 'Table 2'
    assert preset.to_plain()['label'] == 'plain string'


def test_missing_key_names_it(preset: Preset) -> None:
    with pytest.raises(PresetError, match=r"no key 'gear\.z_ring'"):
        preset['gear.z_ring']


@pytest.mark.parametrize(('item', 'key', 'expected', 'typ'), [
    ('gear.z_sun=13', 'gear.z_sun', 13, int),
    ('gear.r_p_m=0.05', 'gear.r_p_m', 0.05, float),
    ('gear.r_p_m=1', 'gear.r_p_m', 1.0, float),           # float stays float
    ('gear.harmonics=0.2,0.1,0.3', 'gear.harmonics', [0.2, 0.1, 0.3], list),
    ('gear.harmonics=[0.0]', 'gear.harmonics', [0.0], list),
    ('flag=false', 'flag', False, bool),
    ('label=other', 'label', 'other', str),
])
def test_overrides_keep_types(preset: Preset, item: str, key: str, expected: object,
                              typ: type) -> None:
    new = preset.with_overrides([item])
    assert new[key] == expected
    assert type(new[key]) is typ
    assert new.values[key].source == 'override'
    assert new.values[key].unit == preset.values[key].unit     # unit kept
    assert preset[key] != new[key] or expected == preset[key]  # original untouched


def test_override_mapping_form_and_noop(preset: Preset) -> None:
    assert preset.with_overrides({'gear.z_sun': ' 14 '})['gear.z_sun'] == 14
    assert preset.with_overrides(None) is preset
    assert preset.with_overrides([]) is preset


@pytest.mark.parametrize(('item', 'needle'), [
    ('gear.z_ring=3', r"no key 'gear\.z_ring'"),
    ('z_sun=3', r"did you mean 'gear\.z_sun'"),
    ('gear.z_sun=12.5', r'gear\.z_sun.*expected int'),
    ('gear.r_p_m=abc', r'gear\.r_p_m.*expected float'),
    ('gear.r_p_m=nan', r'gear\.r_p_m.*finite'),
    ('gear.r_p_m=inf', r'gear\.r_p_m.*finite'),
    ('flag=maybe', r'flag.*expected bool'),
    ('gear.harmonics=0.1,x', r'gear\.harmonics.*expected float'),
    ('no_equals_sign', 'not of the form key=value'),
    ('=5', 'not of the form key=value'),
])
def test_override_errors_name_the_key(preset: Preset, item: str, needle: str) -> None:
    with pytest.raises(PresetError, match=needle):
        preset.with_overrides([item])


def test_parse_override_items() -> None:
    assert parse_override_items(['a.b=1', ' c = x=y ']) == {'a.b': '1', 'c': 'x=y'}


@pytest.mark.parametrize(('text', 'needle'), [
    ('name = "x"\nmodel = ', 'not valid TOML'),
    ('model = "m"\n', '"name" and "model"'),
    ('name = "x"\n', '"name" and "model"'),
    ('name = "x"\nmodel = "m"\n[a]\nk = { value = 1, units = "m" }\n',
     r"preset key 'a\.k': unknown fields \['units'\]"),
])
def test_malformed_text(text: str, needle: str) -> None:
    with pytest.raises(PresetError, match=needle):
        preset_from_text(text, 'bad')


def test_shipped_presets_load_and_carry_units() -> None:
    names = available_presets()
    assert 'wang2020-2kv' in names
    for name in names:
        p = load_preset(name)
        assert p.name == name
        for k in ('kind', 'z_sun', 'z_planet', 'z_gear', 'z_ring'):
            assert f'kinematics.{k}' in p.values, f'{name}: kinematics.{k}'
        for key, pv in p.values.items():
            if isinstance(pv.value, int | float) and not isinstance(pv.value, bool):
                assert math.isfinite(pv.value), f'{name}: {key}'
                assert pv.unit, f'{name}: {key} has no unit'
                assert pv.source, f'{name}: {key} has no source'


def test_load_by_path_and_unknown_name(tmp_path: Path) -> None:
    path = tmp_path / 'mine.toml'
    path.write_text(TEXT, encoding='utf-8')
    p = load_preset(path, ['gear.z_sun=11'])
    assert p.name == 'demo' and p['gear.z_sun'] == 11
    with pytest.raises(PresetError, match=r"unknown preset 'nope'.*wang2020-2kv"):
        load_preset('nope')


def test_wang_preset_overrides_reach_the_model() -> None:
    from sim.wang2020 import Wang2kvParams

    p = Wang2kvParams.from_preset(load_preset('wang2020-2kv', ['stage2.r_p_m=0.05307']))
    assert p.r_p_m == 0.05307
    assert p.mesh_stiffness_n_m == 8.43e7


def test_shipped_preset_parsed_once_and_handed_out_as_copies() -> None:
    """load_preset parses a shipped preset once per process (issue 41) but every caller
    gets its own mapping: a change to one does not reach the next caller."""
    from sim.presets import _shipped_preset, load_preset

    _shipped_preset.cache_clear()
    a = load_preset('wang2020-2kv')
    b = load_preset('wang2020-2kv')
    assert _shipped_preset.cache_info().misses == 1
    assert a.values == b.values and a.values is not b.values
    a.values.clear()
    assert load_preset('wang2020-2kv').values == b.values
