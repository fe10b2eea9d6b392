"""Hostile input at every entry point of ``rv-te`` (issue #16): bounded, one clear line.

The second half of the bad-input suite (:mod:`tests.test_bad_input_cli` is the first):
YAML bombs wherever YAML is read (bag metadata.yaml, a BenchInfo's parameters_yaml,
parameter files, ``--param`` and ``--metadata`` values), text that is not UTF-8, names ROS
refuses, checks that ``launch --check`` must run because the nodes run them at start, and
work without a bound. Each case ends within its time limit with the exit code and one
``ERROR:`` line naming the bad value (cut short), and leaves nothing behind.
"""

from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

import pytest

from rv_te_bench.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / 'bags' / 'sample'


def alias_bomb(levels: int = 9) -> list[str]:
    """Billion laughs: 9**9 'lol' once expanded, ~1 KB of text (lines of a mapping)."""
    lines = ['a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]']
    lines += [f'a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']' for i in range(1, levels)]
    return lines


BOMB = '\n'.join(alias_bomb()) + '\n'
#: ~380 bytes, as in the issue: a --param value that hung ``launch --check``
PARAM_BOMB = '{' + ', '.join(alias_bomb(7)) + '}'


def bomb_bag(folder: Path) -> Path:
    """The sample bag with an alias bomb in front of its metadata.yaml."""
    shutil.copytree(SAMPLE, folder)
    meta = folder / 'metadata.yaml'
    meta.write_text(BOMB + meta.read_text(encoding='utf-8'), encoding='utf-8')
    return folder


@pytest.fixture(scope='module')
def hostile_files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The hostile files, made once (an 8 MB parameter file, a 5 MB metadata.yaml...)."""
    tmp_path = tmp_path_factory.mktemp('hostile')
    ros = 'bench:\n  ros__parameters:\n'
    bomb_bag(tmp_path / 'bomb_bag')
    big = tmp_path / 'big_meta'
    shutil.copytree(SAMPLE, big)
    (big / 'metadata.yaml').write_text(
        (big / 'metadata.yaml').read_text(encoding='utf-8') + '#' * (5 << 20) + '\n',
        encoding='utf-8')
    (tmp_path / 'bomb.yaml').write_text(BOMB + ros + '    speed_rpm: 300.0\n')
    (tmp_path / 'alias.yaml').write_text(ros + '    bench_id: &b x\n    preset: *b\n')
    (tmp_path / 'deep.yaml').write_text(ros + '    speed_rpm: ' + '[' * 5000 + ']' * 5000)
    with (tmp_path / 'huge.yaml').open('w', encoding='utf-8') as f:   # 8 MB (98 s before)
        f.write(ros)
        for i in range(250_000):
            f.write(f'    p{i}: {i}.0\n')
    (tmp_path / 'latin1.yaml').write_bytes((ros + '    bench_id: caf\xe9\n').encode('latin-1'))
    (tmp_path / 'utf16.yaml').write_text(ros + '    bench_id: caf\xe9\n    speed_rpm: 1.0e2\n',
                                         encoding='utf-16')   # with a BOM, as YAML allows
    (tmp_path / 'dup_key.yaml').write_text(ros + '    speed_rpm: 300.0\n    speed_rpm: 600.0\n')
    (tmp_path / 'dup_node.yaml').write_text(ros + '    seed: 1\n' + ros + '    seed: 2\n')
    (tmp_path / 'never_ns.yaml').write_text('/1x/bench:\n  ros__parameters:\n    seed: 1\n')
    (tmp_path / 'never_ns2.yaml').write_text('/a//b/bench:\n  ros__parameters:\n    seed: 1\n')
    (tmp_path / 'ros_numbers.yaml').write_text(
        ros + '    speed_rpm: 3e2\n    duration_s: 1.0e1\n    seed: 0x10\n')
    (tmp_path / 'bomb_plan.yaml').write_text(BOMB + 'name: bomb\nsteps: *a8\n')
    (tmp_path / 'a_file').write_text('not a folder\n')
    (tmp_path / 'bags' / 'taken').mkdir(parents=True)
    shutil.copytree(SAMPLE, tmp_path / 'sample')
    bad_name = tmp_path / 'bag\udcff'   # a folder name that is not UTF-8
    shutil.copytree(SAMPLE, bad_name)
    (tmp_path / 'zero.toml').symlink_to('/dev/zero')
    return tmp_path


@pytest.fixture
def work(hostile_files: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(hostile_files)
    return hostile_files


def ns(n: int) -> str:
    return 'a' * n


CASES = [
    # (argv, exit code, text in the message); YAML bounds
    (['analyze', 'bomb_bag', '--no-advice'], 1, 'YAML nodes (aliases expanded)'),
    (['identify', 'bomb_bag', '--no-recommend'], 1, 'YAML nodes (aliases expanded)'),
    (['analyze', 'big_meta', '--no-advice'], 1, 'larger than 4 MiB'),
    (['launch', 'bomb.yaml', '--check'], 1, 'aliases (*name) are not allowed'),
    (['launch', 'alias.yaml', '--check'], 1, 'aliases (*name) are not allowed'),
    (['launch', 'deep.yaml', '--check'], 1, 'nested deeper than 32 levels'),
    (['launch', 'huge.yaml', '--check'], 1, 'larger than 1 MiB'),
    (['launch', '--default', '--check', '--param', f'bench.bench_id={PARAM_BOMB}'], 1,
     'aliases (*name) are not allowed'),
    (['bench', 'deep.yaml'], 1, 'nested deeper than 32 levels'),
    (['test', 'bomb_plan.yaml', '--serial', 'SN1', '--operator', 'kim'], 1,
     'YAML nodes (aliases expanded)'),
    (['test', 'rv-80e', '--serial', 'SN1', '--operator', 'kim', '--condition',
      f'x={PARAM_BOMB}'], 1, 'aliases (*name) are not allowed'),
    # tracebacks before
    (['launch', '--default', '--check', '--namespace', '//'], 1,
     "namespace '//' is not a valid ROS namespace"),
    (['launch', '--default', '--check', '--namespace', 'a/1b'], 1,
     'token that starts with a number'),
    (['launch', '--default', '--check', '--namespace', ns(300)], 1,
     'should not exceed'),
    (['launch', '--default', '--check', '--namespace', ns(209)], 1,
     'needs a namespace of at most 208 characters (got 210)'),
    (['launch', 'latin1.yaml', '--check'], 1, 'is not UTF-8 text (byte 0xe9 at offset 43)'),
    (['launch', '--default', '--check', '--param', 'bench.bench_id=b\udcff'], 1,
     "'bench_id' must be UTF-8 text"),
    (['bench', '--param', 'bench_id=b\udcff'], 1, "'bench_id' must be UTF-8 text"),
    (['identify', 'sample', '--seed', '-5'], 2, "argument --seed: must be >= 0, got '-5'"),
    (['model', 'wang2020-2kv', '--plot', 'out.txt'], 1,
     '.txt is not an image format matplotlib writes'),
    (['presets', 'zero.toml'], 1, 'not a regular file'),
    # launch --check runs what the nodes run at start
    (['launch', '--default', '--check', '--param', 'bench.preset=nope'], 1,
     "node 'bench': unknown preset 'nope'"),
    (['launch', '--default', '--check', '--param', 'bench.te_mode=xyz'], 1,
     "node 'bench': wang2020-2kv: unknown mode 'xyz'"),
    (['launch', '--default', '--check', '--param', 'bench.encoder_in=ron9000'], 1,
     "node 'bench': unknown encoder 'ron9000'"),
    (['launch', '--default', '--check', '--param', 'bench.overrides=[nokey=1]'], 1,
     "node 'bench': preset 'wang2020-2kv' has no key 'nokey'"),
    (['launch', '--default', '--check', '--param', 'compensation.preset=nope'], 1,
     "node 'compensation': unknown preset 'nope'"),
    (['launch', '--default', '--check', '--param', 'te_node.gear_ratio=79'], 1,
     "node 'te_node': crank_per_output must be finite and > 0"),
    (['launch', '--default', '--check', '--param', 'recorder.session_metadata_yaml=[x'], 1,
     "node 'recorder': parameter 'session_metadata_yaml': not valid YAML"),
    (['launch', '--default', '--check', '--param', 'recorder.topic_types=[a=no_pkg/msg/T]'],
     1, "type 'no_pkg/msg/T' not importable"),
    (['launch', '--default', '--check', '--param', "recorder.topics=['bad topic']"], 1,
     "topic 'bad topic' is not a valid ROS topic name"),
    (['launch', '--default', '--check', '--remap', 'bench/encoders:=enc oders'], 1,
     "ROS refuses its arguments: Couldn't parse remap rule"),
    (['launch', '--default', '--check', '--remap', '/a//b:=c'], 1, 'remap rule'),
    (['launch', '--default', '--check', '--param', 'recorder.bag_name=taken',
      '--param', 'recorder.output_dir=bags'], 1, 'exists already'),
    (['launch', '--default', '--check', '--param', 'recorder.output_dir=a_file/bags'], 1,
     'a_file is not a folder'),
    (['launch', 'dup_key.yaml', '--check'], 1, "line 4: key 'speed_rpm' appears twice"),
    (['launch', 'dup_node.yaml', '--check'], 1, "key 'bench' appears twice"),
    (['launch', 'never_ns.yaml', '--check'], 1, "node '/1x/bench' can never match a node"),
    (['launch', 'never_ns2.yaml', '--check'], 1, "repeated '/'"),
    # limits
    (['analyze', 'sample', '--harmonics', '100000'], 2,
     "argument --harmonics: must be <= 200, got '100000'"),
    (['analyze', 'sample', '--window-revolutions', '5000'], 2,
     'argument --window-revolutions: must be <= 1000'),
    (['launch', '--default', '--check', '--param', 'bench.sample_rate_hz=1e6',
      '--param', 'bench.block_size=1'], 1,
     'above the 1000 blocks/s the nodes can carry (~1 ms per message); at 1e+06 Hz use '
     'block_size >= 1000'),
    (['replay', 'sample', '--rate', '5000'], 2,
     "argument --rate: must be between 0.001 and 1000, got '5000'"),
    (['replay', 'sample', '--start-offset', '-1'], 2, 'argument --start-offset'),
    (['record', '--flush-interval', '0'], 2,
     "argument --flush-interval: must be between 0.01 and 60, got '0'"),
    (['record', '--duration', 'nan'], 2, 'argument --duration'),
    (['model', 'wang2020-2kv', '--revolutions', '1e4'], 1,
     '--revolutions 10000 at --sample-rate-hz 10000 give 1580000000 samples'),
    # a value of any size is cut in the message
    (['presets', 'wang2020-2kv', '--set', 'k' * 100_000 + '=1'], 1, 'characters cut'),
    (['launch', '--default', '--check', '--param', 'bench.' + 'k' * 100_000 + '=1'], 1,
     'unknown parameter'),
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize(('argv', 'code', 'needle'), CASES,
                         ids=[' '.join(c[0])[:60] for c in CASES])
def test_hostile_input(work: Path, argv: list[str], code: int, needle: str,
                       capsys: pytest.CaptureFixture[str]) -> None:
    t0 = time.monotonic()
    try:
        got = main(argv)
    except SystemExit as exc:   # argparse usage errors
        got = exc.code
    err = capsys.readouterr().err
    assert got == code, err
    assert needle in err, err
    assert 'Traceback' not in err
    if code == 1:
        lines = [ln for ln in err.strip().splitlines() if ln.startswith('ERROR:')]
        assert len(lines) == 1, err
        assert len(lines[0]) < 700, lines[0]   # no value echoed unbounded
    assert time.monotonic() - t0 < 30.0
    assert not (work / 'bags' / 'session').exists()   # --check left no bag folder


@pytest.mark.ros
@pytest.mark.timeout(60)
@pytest.mark.parametrize('argv', [
    ['record', '--topics', 'bad topic', '--duration', '1'],
    ['record', '--topics', '/a//b', '--duration', '1'],
    ['record', '--metadata', BOMB, '--duration', '1'],
    ['replay', 'bomb_bag'],
], ids=['record bad topic', 'record /a//b', 'record --metadata bomb', 'replay bomb_bag'])
def test_hostile_input_to_ros_commands(work: Path, argv: list[str],
                                       capsys: pytest.CaptureFixture[str]) -> None:
    t0 = time.monotonic()
    got = main(argv)
    err = capsys.readouterr().err
    assert got == 1, err
    assert 'Traceback' not in err
    lines = [ln for ln in err.strip().splitlines() if ln.startswith('ERROR:')]
    assert len(lines) == 1, err
    assert len(lines[0]) < 700, lines[0]
    assert time.monotonic() - t0 < 30.0
    assert not (work / 'out').exists()   # no empty bag folder


def test_numbers_as_ros_reads_them(work: Path) -> None:
    """1.0e1 and 3e2 are doubles for rcl (strings in YAML 1.1), 0x10 an integer."""
    from rv_te_bench.launch.session import build_session

    spec = build_session(['ros_numbers.yaml'], nodes=['bench'],
                         overrides=['bench.load_nm=1e1'])
    bench = spec.parameters['bench']
    assert bench['speed_rpm'] == 300.0
    assert bench['duration_s'] == 10.0
    assert bench['seed'] == 16
    assert bench['load_nm'] == 10.0


def test_utf16_parameter_file_is_read(work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """YAML allows UTF-16 with a byte-order mark (libyaml and so rcl read it): accepted."""
    from rv_te_bench.launch.session import build_session

    assert main(['launch', 'utf16.yaml', '--check']) == 0, capsys.readouterr().err
    spec = build_session(['utf16.yaml'], nodes=['bench'])
    assert spec.parameters['bench']['bench_id'] == 'caf\xe9'
    assert spec.parameters['bench']['speed_rpm'] == 100.0


@pytest.mark.timeout(120)
def test_report_of_a_bag_with_a_non_utf8_name(work: Path, capsys: pytest.CaptureFixture[str],
                                              default_store: Path) -> None:
    """Undecodable bytes in the bag's and the report's path: the report is written."""
    out = work / 'rep\udcff'
    got = main(['analyze', 'bag\udcff', '--no-advice', '--quiet', '--report', str(out)])
    err = capsys.readouterr().err
    assert got == 0, err
    assert {p.name for p in out.iterdir()} >= {'te.png', 'spectrum.png', 'report.html',
                                               'report.json'}
    assert 'bag\ufffd' in (out / 'report.html').read_text(encoding='utf-8')
    assert json.loads((out / 'report.json').read_text(encoding='utf-8'))
    # the results store (UTF-8 only) keeps the bytes as \xNN, so two such bags stay apart
    assert main(['results', '--db', str(default_store), '--json']) == 0
    assert '/bag\\\\xff' in capsys.readouterr().out


def test_launch_nodes_without_a_file(work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--nodes alone runs those nodes with the packaged session's parameters."""
    assert main(['launch', '--nodes', 'bench,te_node', '--check']) == 0
    out = capsys.readouterr().out
    assert re.search(r'^ok: (bench, te_node|te_node, bench) in namespace /$', out, re.M), out


def test_write_default_gives_a_file_to_start_from(work: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The README's ``rv-te launch my_session.yaml`` needs a file: --write-default makes it."""
    assert main(['launch', '--write-default', 'my_session.yaml']) == 0
    assert main(['launch', 'my_session.yaml', '--namespace', 'bench1', '--check']) == 0
    assert 'namespace /bench1' in capsys.readouterr().out
    assert main(['launch', '--write-default', 'my_session.yaml']) == 1   # never overwrites
    assert 'exists already' in capsys.readouterr().err


def test_namespace_at_the_length_limit_passes(work: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['launch', '--default', '--check', '--namespace', ns(207)]) == 0, \
        capsys.readouterr().err


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_name_length_limit_is_what_rcl_enforces(ros_context) -> None:
    """The compensation node (the longest name) starts with a 208-character namespace and
    not with 209: the limit --check states is rcl's."""
    import rclpy

    from rv_te_bench.errors import ParameterFileError
    from rv_te_bench.launch.checks import check_ros_names

    for length, ok in ((208, True), (209, False)):
        namespace = '/' + 'a' * (length - 1)
        try:
            node = rclpy.create_node('compensation', namespace=namespace, context=ros_context)
            node.destroy_node()
            started = True
        except Exception:  # noqa: BLE001 - rclpy's InvalidServiceNameException
            started = False
        try:
            check_ros_names('compensation', namespace, ())
            checked = True
        except ParameterFileError:
            checked = False
        assert started is ok
        assert checked is ok


def test_hostile_cases_are_forty_distinct_commands_the_parser_knows() -> None:
    # the table against the real parser (see test_bad_input_cli); the bomb stays small
    assert len({tuple(c[0]) for c in CASES}) >= 40
    assert {c[0][0] for c in CASES} <= _subcommands()
    assert len(PARAM_BOMB) < 400


def _subcommands() -> set[str]:
    """The subcommands of the real ``rv-te`` parser."""
    import argparse

    from rv_te_bench.cli.main import build_parser

    (sub,) = [a for a in build_parser()._actions
              if isinstance(a, argparse._SubParsersAction)]
    return set(sub.choices)


def test_param_bomb_is_a_bomb() -> None:
    """The --param case is a real bomb: PyYAML builds it (shared lists), 9**7 leaves."""
    import yaml

    doc = yaml.safe_load(PARAM_BOMB)
    leaves, node = 1, doc['a6']
    while isinstance(node, list):
        leaves, node = leaves * len(node), node[0]
    assert leaves == 9 ** 7


@pytest.mark.timeout(120)
def test_bench_info_with_a_yaml_bomb_is_analysed(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """A BenchInfo whose parameters_yaml is an alias bomb (from a bag or the network): the
    record is ignored (base preset) instead of being expanded while looking for overrides."""
    import numpy as np

    from tests import unit_bags
    from tests import wang2020_reference as ref

    record = BOMB + 'bench:\n  overrides: [*a8, *a8]\n'
    bag = unit_bags.unit_bag(tmp_path / 'bag', ref.table2_unit(), np.random.default_rng(3),
                             rate_hz=500.0, duration_s=16.5, parameters_yaml=record)
    t0 = time.monotonic()
    got = main(['analyze', str(bag), '--quiet', '--json'])
    captured = capsys.readouterr()
    assert got == 0, captured.err
    assert time.monotonic() - t0 < 60.0
    doc = json.loads(captured.out)
    assert doc['bags'][0]['recommendation']['advice'] is not None


@pytest.mark.parametrize(('flag', 'limit'), [('--stall-buffer', 1 << 40),
                                             ('--split-size', 1 << 62)])
def test_record_byte_flags_name_the_flag_and_state_the_limit(
        flag: str, limit: int, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue #16: ``rv-te record --stall-buffer 2000000000000`` printed the node's
    'Parameter stall_buffer_bytes out of range' after starting it; now argparse refuses it
    naming the flag, exit 2, and --help states both maxima (fails before: the stall buffer
    was any non-negative integer, neither help gave a maximum)."""
    with pytest.raises(SystemExit) as exc:
        main(['record', flag, str(limit + 1), '--duration', '1'])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.endswith(f"argument {flag}: must be <= {limit}, got '{limit + 1}'"), err
    assert 'stall_buffer_bytes' not in err and 'split_size_bytes' not in err
    with pytest.raises(SystemExit):
        main(['record', '--help'])
    help_text = ' '.join(capsys.readouterr().out.split())
    assert f'(0..{limit})' in help_text


@pytest.mark.ros
def test_cli_ranges_are_the_node_parameter_ranges() -> None:
    """The flags of rv-te record / replay check (and --help states) the nodes' own ranges,
    so a range error names the flag the user typed, not a node parameter."""
    from rv_te_bench.cli import analyze, record, replay
    from rv_te_bench.nodes import recorder as rec_node
    from rv_te_bench.nodes import te_node
    from rv_te_bench.nodes.params import replay as replay_params

    spec = {s.name: s for s in rec_node.PARAMS}
    assert spec['duration_s'].max_value == record.MAX_DURATION_S
    assert spec['split_duration_s'].max_value == record.MAX_DURATION_S
    assert (spec['flush_interval_s'].min_value,
                                    spec['flush_interval_s'].max_value) == record.FLUSH_RANGE_S
    assert spec['split_size_bytes'].max_value == record.MAX_SPLIT_BYTES
    assert spec['stall_buffer_bytes'].max_value == record.MAX_STALL_BUFFER_BYTES
    rp = {s.name: s for s in replay_params.PARAMS}   # what the replay node declares
    rate, offset, wait = (rp[n] for n in ('rate', 'start_offset_s', 'wait_for_subscribers_s'))
    assert (rate.min_value, rate.max_value) == replay.RATE_RANGE
    assert (offset.min_value, offset.max_value) == replay.START_OFFSET_RANGE_S
    assert (wait.min_value, wait.max_value) == replay.WAIT_RANGE_S
    te = {s.name: s for s in te_node.PARAMS}
    assert te['n_crank_harmonics'].max_value == analyze.MAX_HARMONICS
    assert te['window_revolutions'].max_value == analyze.MAX_WINDOW_REVOLUTIONS
