"""``rv-te compensate``: output, JSON keys with units, exit codes and one-line errors.

The parser is built here from the module's ``register`` (the contract with cli/main.py).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import pytest

from rv_te_bench.cli import compensate


def _run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog='rv-te')
    compensate.register(parser.add_subparsers())
    args = parser.parse_args(['compensate', *argv])
    return args.func(args)


def test_text_output_has_table6_rows_and_tca(capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(['hu2020-rv', '--te-arcmin', '1.4559', '--scale', 'table6']) == 0
    out = capsys.readouterr().out
    # Table 6 values at the table6 scale (mm, 4 decimals as printed)
    assert '2.9721' in out
    assert '-0.0266' in out
    assert '-0.0110' in out
    # TCA before: 9 pins in mesh (Hu 2020 s.5.1)
    assert 'TCA before:  9 pins in mesh' in out
    assert 'F_max' in out


def test_json_output(capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(['rv-80e-101', '--te-arcmin', '1.552', '--fraction', '0.5', '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert data['method'] == 'tooth-profile'
    assert data['te_before_arcmin'] == pytest.approx(1.552, rel=1e-12)
    # (1 - 0.5) x the geometric part + the elastic part of the TCA after (issue #18)
    d = data['details']
    to_arcmin = 10800 / math.pi
    want = (0.5 * max(1.552 - d['elastic_pp_before_rad'] * to_arcmin, 0.0)
            + d['elastic_pp_after_rad'] * to_arcmin)
    assert data['te_after_arcmin'] == pytest.approx(want, rel=1e-9)
    assert 0.776 < data['te_after_arcmin'] < 1.552
    assert [m['symbol'] for m in data['modifications']] == ['r_rp', 'delta_r_p',
                                                            'delta_delta_8']
    tb, ta = data['details']['tca_before'], data['details']['tca_after']
    assert {'pins_in_mesh', 'f_max_n', 'delta_max_m'} <= set(tb)
    assert ta['f_max_n'] < tb['f_max_n']


@pytest.mark.parametrize(('argv', 'needle'), [
    (['hu2020-rv', '--te-arcmin', '0'], '--te-arcmin must be a finite value > 0, got 0.0'),
    (['hu2020-rv', '--te-arcmin', 'nan'], '--te-arcmin must be a finite value > 0'),
    (['hu2020-rv', '--te-arcmin', '1', '--set', 'geometry.a_m=0.002'], "K1' = "),
    (['hu2020-rv', '--te-arcmin', '1', '--set', 'nokey=1'], "no key 'nokey'"),
    (['no-such-preset', '--te-arcmin', '1'], "unknown preset 'no-such-preset'"),
    (['hu2020-rv', '--te-arcmin', '1', '--fraction', '2'], 'fraction must be in (0, 1]'),
])
def test_domain_errors_one_line_exit_1(argv: list[str], needle: str,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(argv) == 1
    captured = capsys.readouterr()
    assert captured.out == ''                      # nothing written half-way
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith('ERROR: ')
    assert needle in lines[0]


def test_non_rv_preset_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = tmp_path / 'other.toml'
    path.write_text('name = "other"\nmodel = "wang2020-2kv"\n', encoding='utf-8')
    assert _run([str(path), '--te-arcmin', '1']) == 1
    assert 'needs a hu2020-rv preset' in capsys.readouterr().err
