"""The rv-te entry point: subcommands, exit codes 0/1/2, one-line errors, presets."""

from __future__ import annotations

import json

import pytest

from rv_te_bench.cli.main import SUBCOMMAND_MODULES, build_parser, main


def test_help_lists_every_subcommand(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(['--help'])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for name in SUBCOMMAND_MODULES:
        assert name.rstrip('_').replace('_', '-') in out
    assert 'examples:' in out


@pytest.mark.parametrize('name', [n.rstrip('_').replace('_', '-') for n in SUBCOMMAND_MODULES])
def test_every_subcommand_has_help_with_examples(name: str,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main([name, '--help'])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert 'usage: rv-te' in out
    assert 'example' in out.lower()


def test_no_command_and_bad_usage_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    with pytest.raises(SystemExit) as info:
        main(['no-such-command'])
    assert info.value.code == 2
    capsys.readouterr()


def test_presets_list_and_show(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['presets', '--json']) == 0
    names = {p['name'] for p in json.loads(capsys.readouterr().out)['presets']}
    assert {'wang2020-2kv', 'hu2020-rv', 'li2023-rv', 'rv-80e-101'} <= names
    assert main(['presets', 'wang2020-2kv', '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert data['model'] == 'wang2020-2kv'
    rows = {r['key']: r for r in data['values']}
    assert rows['kinematics.z_ring']['value'] == 52  # Wang 2020 Table 2
    assert all(r['unit'] or isinstance(r['value'], str | bool) for r in rows.values())


@pytest.mark.parametrize(('argv', 'needle'), [
    (['presets', 'no-such'], "unknown preset 'no-such'"),
    (['presets', 'wang2020-2kv', '--set', 'kinematics.z_sun=abc'], 'kinematics.z_sun'),
    (['presets', 'wang2020-2kv', '--set', 'nokey=1'], "no key 'nokey'"),
    (['presets', 'wang2020-2kv', '--set', 'novalue'], 'key=value'),
])
def test_presets_bad_input_one_line_exit_1(argv: list[str], needle: str,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith('ERROR: ')
    assert needle in err
    assert '\n' not in err


def test_parser_builds() -> None:
    assert build_parser().prog == 'rv-te'
