"""Bad input at every entry point of `rv-te`: one clear line naming the bad value, the right
exit code (1 failed, 2 bad usage), and nothing already recorded damaged."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest

from rv_te_bench.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / 'bags' / 'sample'


def digest(folder: Path) -> str:
    h = hashlib.sha256()
    for f in sorted(folder.rglob('*')):
        if f.is_file():
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()


@pytest.fixture
def work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    (tmp_path / 'bad_range.yaml').write_text(
        'bench:\n  ros__parameters:\n    sample_rate_hz: -1.0\n')
    (tmp_path / 'bad_key.yaml').write_text('te_node:\n  ros__parameters:\n    windows: 2\n')
    (tmp_path / 'bad_type.yaml').write_text('bench:\n  ros__parameters:\n    block_size: many\n')
    (tmp_path / 'bad_node.yaml').write_text('viewer:\n  ros__parameters:\n    a: 1\n')
    (tmp_path / 'bad_yaml.yaml').write_text('bench: [unclosed\n')
    (tmp_path / 'python.yaml').write_text(
        'bench: !!python/object/apply:os.system ["touch pwned.txt"]\n')
    (tmp_path / 'notabag.mcap').write_bytes(b'garbage\n' * 10)
    (tmp_path / 'emptydir').mkdir()
    shutil.copytree(SAMPLE, tmp_path / 'sample')
    trunc = tmp_path / 'cut_bag'
    shutil.copytree(SAMPLE, trunc)
    mcap = next(trunc.glob('*.mcap'))
    data = mcap.read_bytes()
    mcap.write_bytes(data[:200])
    return tmp_path


CASES = [
    # (argv, exit code, text in the message)
    (['launch', 'bad_range.yaml'], 1, "'sample_rate_hz' must be >= 1, got -1.0"),
    (['launch', 'bad_key.yaml'], 1, "unknown parameter 'windows'"),
    (['launch', 'bad_type.yaml'], 1, "'block_size' must be an integer"),
    (['launch', 'bad_node.yaml'], 1, "unknown node 'viewer'"),
    (['launch', 'bad_yaml.yaml'], 1, 'not valid YAML'),
    (['launch', 'python.yaml'], 1, 'not valid YAML'),
    (['launch', 'missing.yaml'], 1, 'cannot read'),
    (['launch'], 2, 'give a launch file, a parameter file, --default or --nodes'),
    (['launch', '--default', '--param', 'bench.block_size=0'], 1, "'block_size' must be >= 1"),
    (['launch', '--default', '--param', 'block_size=0'], 1, 'node.key=value'),
    (['launch', '--default', '--namespace', '1x'], 1, 'not a valid ROS namespace'),
    (['launch', '--default', '--remap', 'foo'], 1, 'from:=to'),
    (['launch', '--default', '--nodes', 'bench,viewer'], 1, "unknown node 'viewer'"),
    (['bench', '--param', 'sample_rate_hz=0'], 1, "'sample_rate_hz' must be >= 1"),
    (['bench', '--param', 'time_mode=warp'], 1, "'time_mode' must be one of"),
    (['bench', '--param', 'speed_rpm=fast'], 1, "'speed_rpm' must be a number"),
    (['model', 'no-such'], 1, "unknown preset 'no-such'"),
    (['model', 'wang2020-2kv', '--kind', 'xyz'], 1, "unknown mode 'xyz'"),
    (['model', 'wang2020-2kv', '--revolutions', '-1'], 2, "must be finite and > 0, got '-1'"),
    (['model', 'wang2020-2kv', '--set', 'kinematics.z_ring=49'], 1,
     'must be greater than kinematics.z_gear'),
    (['model', 'wang2020-2kv', '--set', 'kinematics.z_sun=0'], 1,
     'kinematics.z_sun must be a positive tooth count'),
    (['model', 'wang2020-2kv', '--set', 'stage2.r_p_m=nan'], 1, 'must be finite'),
    (['model', 'wang2020-2kv', '--set', 'nokey=1'], 1, "no key 'nokey'"),
    (['model', 'wang2020-2kv', '--phases-deg=1,2,3'], 2, 'expected four finite numbers'),
    (['optimize-phases', 'wang2020-2kv', '--step-deg', '0'], 1, '--step-deg must be'),
    (['optimize-phases', 'wang2020-2kv', '--step-deg', '-5'], 1, 'got -5.0'),
    (['optimize-phases', 'hu2020-rv'], 1, 'need a wang2020-2kv preset'),
    (['compensate', 'hu2020-rv', '--te-arcmin', '0'], 1, '--te-arcmin must be'),
    (['compensate', 'hu2020-rv', '--te-arcmin', 'nan'], 1, 'got nan'),
    (['compensate', 'hu2020-rv', '--te-arcmin', '-1'], 1, 'got -1.0'),
    (['compensate', 'wang2020-2kv', '--te-arcmin', '1'], 1, 'needs a hu2020-rv preset'),
    (['compensate', 'hu2020-rv', '--te-arcmin', '1', '--set', 'stage.z_c=0'], 1, 'z_c'),
    (['identify', 'notabag.mcap'], 1, 'not an MCAP file'),
    (['identify', 'nothere'], 1, 'does not exist'),
    (['identify', 'emptydir'], 1, 'no metadata.yaml'),
    (['analyze', 'nothere'], 1, 'no such bag'),
    (['analyze', 'notabag.mcap'], 1, 'not an MCAP file'),
    (['analyze', 'emptydir'], 1, 'no metadata.yaml'),
    (['analyze', 'sample', '--topic', '/bench/info'], 1, '/bench/info'),
    (['analyze', 'cut_bag'], 1, 'truncated'),
    (['identify', 'cut_bag'], 1, 'truncated'),
    (['optimize-phases', 'wang2020-2kv', '--step-deg', '1'], 1, 'combinations'),
    (['record', '--namespace', '1x'], 1, 'not a valid ROS namespace'),
    (['model', 'wang2020-2kv', '--csv', 'notabag.mcap/x.csv'], 1, 'ERROR'),
    (['demo', '--out-dir', 'notabag.mcap/sub'], 1, 'ERROR'),
    (['replay', 'nothere'], 1, 'does not exist'),
    (['replay', 'emptydir'], 1, 'no metadata.yaml'),
    (['replay', 'sample', '--rate', '0'], 2, 'argument --rate: must be between 0.001 and 1000'),
    (['record', '--compression', 'xz'], 2, "invalid choice: 'xz'"),
    (['demo', '--revolutions', '0'], 2, '--revolutions must be > 0'),
    (['presets', 'nope'], 1, "unknown preset 'nope'"),
    (['presets', 'wang2020-2kv', '--set', 'kinematics.z_sun=abc'], 1, 'expected int'),
    (['no-such-command'], 2, 'invalid choice'),
]


#: Cases whose command builds its ROS node before it reads the input (ReplayNode opens the bag
#: in its constructor): they start the middleware, so they are ``ros`` tests.
ROS_CASES = {('replay', 'nothere'), ('replay', 'emptydir')}


@pytest.mark.parametrize(('argv', 'code', 'needle'), [
    pytest.param(*c, id=' '.join(c[0]),
                 marks=[pytest.mark.ros] if tuple(c[0]) in ROS_CASES else [])
    for c in CASES])
def test_bad_input(work: Path, argv: list[str], code: int, needle: str,
                   capsys: pytest.CaptureFixture[str]) -> None:
    before = digest(work / 'sample')
    try:
        got = main(argv)
    except SystemExit as exc:   # argparse usage errors
        got = exc.code
    err = capsys.readouterr().err
    assert got == code, err
    assert needle in err, err
    if code == 1:
        lines = [ln for ln in err.strip().splitlines() if ln.startswith('ERROR:')]
        assert len(lines) == 1, err
    assert digest(work / 'sample') == before   # nothing recorded is touched
    assert not (work / 'pwned.txt').exists()   # YAML is loaded safely: nothing executed


def test_cases_are_forty_distinct_commands_the_parser_knows() -> None:
    # the table against the real parser: a renamed or removed subcommand would turn its
    # cases into argparse usage errors that no longer test what they name
    assert len({tuple(c[0]) for c in CASES}) >= 40
    assert {c[0][0] for c in CASES} - {'no-such-command'} <= _subcommands()


def _subcommands() -> set[str]:
    """The subcommands of the real ``rv-te`` parser."""
    import argparse

    from rv_te_bench.cli.main import build_parser

    (sub,) = [a for a in build_parser()._actions
              if isinstance(a, argparse._SubParsersAction)]
    return set(sub.choices)


@pytest.mark.ros   # the recorder node is built before it refuses the bag
def test_record_refuses_to_overwrite_an_existing_bag(work: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    before = digest(work / 'sample')
    got = main(['record', '--out', str(work), '--name', 'sample', '--duration', '1'])
    err = capsys.readouterr().err
    assert got == 1
    assert 'exists already' in err
    assert digest(work / 'sample') == before


def test_demo_refuses_an_existing_session_folder(work: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    (work / 'out' / 's1').mkdir(parents=True)
    got = main(['demo', '--out-dir', str(work / 'out'), '--session', 's1'])
    assert got == 1
    assert 'exists already' in capsys.readouterr().err
