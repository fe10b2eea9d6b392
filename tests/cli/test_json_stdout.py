"""``--json`` means stdout is one JSON document, human lines on stderr (issue #32 s.4):
``rv-te test`` printed 'recorded in the results store ...' and 'VERDICT: ...' after the
JSON; ``unit-report`` the verdict. A real session (li2023-rv, fast)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from rv_te_bench.cli.main import main


@pytest.mark.ros
@pytest.mark.timeout(300)
def test_test_and_unit_report_json_is_the_whole_stdout(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = tmp_path / 'plan.yaml'
    plan.write_text(yaml.safe_dump({'plan': 'quick', 'steps': [
        {'kind': 'te', 'name': 'te', 'speed_rpm': 3000, 'settle_s': 0.2}]}), encoding='utf-8')
    rc = main(['test', str(plan), '--serial', 'LI-J', '--operator', 'pytest', '--launch',
               'li2023-rv', '--out-dir', str(tmp_path / 'out'), '--speed-factor', '0',
               '--json'])
    cap = capsys.readouterr()
    doc = json.loads(cap.out)          # the whole of stdout, nothing after it
    assert doc['unit']['serial'] == 'LI-J' and rc in (0, 3)
    assert 'VERDICT:' in cap.err and 'recorded in the results store' in cap.err
    assert 'VERDICT' not in cap.out and 'recorded in' not in cap.out
    (run,) = [p for p in (tmp_path / 'out').iterdir() if p.is_dir()]
    rc2 = main(['unit-report', str(run / 'bag'), '--report', str(tmp_path / 'again'),
                '--json'])
    cap = capsys.readouterr()
    assert rc2 == rc
    assert json.loads(cap.out)['unit']['serial'] == 'LI-J'
    assert 'VERDICT:' in cap.err


def test_a_parameter_overridden_by_another_is_refused(capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    """``--param bench.duration_s=60`` beside the default file's duration_output_revs: the
    session would have run 2 output revolutions, silently; now --check (and the start)
    names both. Set the other to 0 and it is accepted."""
    rc = main(['launch', '--default', '--param', 'bench.duration_s=60', '--check'])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1
    assert 'duration_s=60 and duration_output_revs=2 both set the session length' in err[0]
    assert main(['launch', '--default', '--param', 'bench.duration_s=60', '--param',
                 'bench.duration_output_revs=0', '--check']) == 0


def test_spc_help_states_the_baseline_and_the_rule_reading(
        capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(['spc', '--help'])
    text = ' '.join(capsys.readouterr().out.split())
    assert 'both of the baseline points only (the first 20 by default)' in text
    assert ('Nelson rules 5 and 6 are read as Minitab and the AIAG SPC manual state them: '
            '2 of 3 (4 of 5) points in a row beyond 2 (1) sigma on the same side') in text
