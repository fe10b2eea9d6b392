"""Every example in ``rv-te --help``, each subcommand's ``--help`` and the README works.

Issue #15 item 9: ``rv-te presets wang2020-2kv --set stiffness.k_n_per_m=9e7`` (a help example)
failed and the README launched a file that did not exist. The examples are run in a folder
holding what they name (``session.yaml`` written by ``rv-te launch --write-default``, the
sample bag under the names the examples use). Commands that compute run whole; commands that
start ROS nodes run everything up to the start: ``launch`` with ``--check``, ``bench``,
``demo`` and ``test`` through their session checks, ``record`` and ``replay`` building their
node in a real context and destroying it. ``results`` / ``spc`` read a store that ``rv-te
analyze`` filled with six units; the examples that name a site's servers (``postgresql://``,
``tcp://`` schedulers) are the only ones not run.
"""

from __future__ import annotations

import argparse
import re
import shlex
import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml

from rv_te_bench.cli.main import build_parser, main

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / 'bags' / 'sample'


def help_texts() -> list[str]:
    parser = build_parser()
    texts = [parser.format_help()]
    sub = next(a for a in parser._actions
               if isinstance(a, argparse._SubParsersAction))
    texts += [p.format_help() for p in dict.fromkeys(sub.choices.values())]
    return texts


def examples(text: str) -> list[str]:
    """Command lines of a help text or a README block: 'rv-te ...' up to its comment."""
    out = []
    text = re.sub(r' *\\\n\s*', ' ', text)   # a command continued on the next line
    for line in text.splitlines():
        body = line.strip()
        if not body.startswith('rv-te '):
            continue
        body = re.split(r'\s{2,}|\s#', body)[0]
        out.append(body)
    return out


def readme_examples() -> list[str]:
    text = (ROOT / 'README.md').read_text(encoding='utf-8')
    blocks = re.findall(r'```sh\n(.*?)```', text, flags=re.DOTALL)
    return [e for b in blocks for e in examples(b)]


HELP_EXAMPLES = list(dict.fromkeys(e for t in help_texts() for e in examples(t)))
README_EXAMPLES = readme_examples()


#: Examples that name a site's servers (a PostgreSQL host, a Dask scheduler): they cannot run
#: here; the same commands run against a local store / cluster in the other examples.
EXTERNAL = re.compile(r'postgresql://|tcp://')


def test_there_are_examples_to_run() -> None:
    assert len(HELP_EXAMPLES) >= 40
    assert len(README_EXAMPLES) >= 10
    assert any('--set mesh.stiffness_n_m=9e7' in e for e in HELP_EXAMPLES)


@pytest.fixture(scope='module')
def example_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """What the examples name: session.yaml, the sample bag under each name used."""
    d = tmp_path_factory.mktemp('examples')
    for name in ('bags/sample', 'out/session_bag', 'before', 'after', 'BAG',
                 'out/bags/rv_te_20260101_120000'):
        shutil.copytree(SAMPLE, d / name)
    mcap = next(SAMPLE.glob('*.mcap'))
    for name in ('real.mcap', 'bag.mcap'):
        shutil.copy(mcap, d / name)
    acceptance = ROOT / 'rv_te_bench' / 'acceptance'
    shutil.copy(acceptance / 'plans' / 'rv-80e.yaml', d / 'my_plan.yaml')
    shutil.copy(acceptance / 'tolerances' / 'rv-80e-101.yaml', d / 'my_limits.yaml')
    launch = ROOT / 'rv_te_bench' / 'launch'
    shutil.copy(launch / 'session.launch.yaml', d / 'session.launch.yaml')
    from tests.io import daq_files

    daq_files.example_inputs(d)   # rv-te import: bench.yaml, run.csv, run.tdms, run.mf4
    # rv-te test li2023-rv --from: the plan run on a simulated Li 2023 unit, as a session
    # bag written by rosbags and as a DAQ's CSV written by pandas, with its bench description
    from tests.acceptance import recorded_data as rec

    run = rec.run_plan(yaml.safe_load((acceptance / 'plans' / 'li2023-rv.yaml').read_text()))
    rec.write_session_bag(d / 'bags' / 'li_session', run)
    rec.write_csv(d / 'li_run.csv', run)
    rec.bench_yaml(d / 'li_bench.yaml', run)
    _heads_inputs(d)
    return d


def _heads_inputs(d: Path) -> None:
    """What the read-head examples name (issue 36): a 4-head bag, a reversal pair, a later
    one-head run of scale RING-42, a cal/ folder, a CSV with one column per head."""
    import numpy as np
    import yaml

    from tests.heads_bags import write_heads_bag

    four = (0.0, 90.0, 180.0, 270.0)
    write_heads_bag(d / 'bags' / 'four_heads', four, serial='RING-42')
    write_heads_bag(d / 'bags' / 'run_0deg', (0.0,), serial='RING-42')
    write_heads_bag(d / 'bags' / 'run_180deg', (0.0,), serial='RING-42', index_deg=180.0)
    write_heads_bag(d / 'bags' / 'later_run', (0.0,), serial='RING-42')
    (d / 'cal').mkdir()
    bench = yaml.safe_load((d / 'bench.yaml').read_text())
    bench['encoders']['output'].update({'heads_deg': list(four), 'serial': 'RING-42'})
    (d / 'bench4.yaml').write_text(yaml.safe_dump(bench))
    k = np.arange(4000)
    t = k / 2000.0
    th_out = 2 * np.pi * 5.0 * t / 79.0
    cols = ['t_s', 'theta_in_rad', *(f'out_h{j}' for j in range(4))]
    rows = np.column_stack([t, 79.0 * th_out, *(th_out + 1e-6 * j for j in range(4))])
    (d / 'heads.csv').write_text(','.join(cols) + '\n' + '\n'.join(
        ','.join(f'{v:.17g}' for v in r) for r in rows) + '\n')


@pytest.fixture(scope='module')
def unit_test_bags(example_dir: Path) -> Path:
    """The session bags the ``rv-te unit-report`` examples name: a short acceptance test of a
    simulated Li 2023 unit run for real by ``rv-te test`` (bench, sequencer and recorder over
    the middleware), under the example's serial, and its bag again under the name a standing
    test session would give it."""
    import yaml

    plan = example_dir / 'quick_plan.yaml'
    plan.write_text(yaml.safe_dump({'plan': 'quick', 'steps': [
        {'kind': 'te', 'name': 'te', 'speed_rpm': 3000, 'settle_s': 0.2},
        {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': 450.0,
         'dwell_s': 0.1}]}))
    out = example_dir / 'out' / 'tests'
    for serial in ('RV80E-0042', 'RV-C1'):
        assert main(['test', str(plan), '--serial', serial, '--operator', 'pytest',
                     '--launch', 'li2023-rv', '--out-dir', str(out),
                     '--speed-factor', '0']) in {0, 3}
    (run,) = out.glob('RV-C1_*')
    shutil.move(run / 'bag', example_dir / 'bags' / 'tests' / 'rv_te_20261124_093122')
    shutil.rmtree(run)
    (run,) = out.glob('RV80E-0042_*')   # under the name unit-report's own example uses
    return run.rename(out / 'RV80E-0042_20261124T092855Z') / 'bag'


@pytest.fixture(scope='module')
def unit_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A results store with what ``rv-te results`` / ``rv-te spc`` examples read: six units
    (rosbags-written bags of random units, two lots, serial SN1042 among them, one bag
    running forward then reverse for per-direction metrics), filled by ``rv-te analyze``."""
    import numpy as np

    from tests import unit_bags
    from tests import wang2020_reference as ref

    d = tmp_path_factory.mktemp('store')
    db = d / 'units.sqlite'
    rng = np.random.default_rng(16)
    for i in range(6):
        bag = unit_bags.unit_bag(d / f'unit{i}', ref.random_unit(rng), rng, rate_hz=500.0,
                                 duration_s=16.5)
        assert main(['analyze', str(bag), '--quiet', '--no-advice', '--db', str(db),
                     '--serial', f'SN104{i}', '--lot', f'L{i // 3}']) == 0
    return db


class _Started(Exception):  # noqa: N818 - control flow: the command got to its start
    """Raised where a session command would start its nodes."""


def _stop_at_start(mp: pytest.MonkeyPatch, command: str) -> None:
    """Let a node-starting command run every check, then stop where the nodes would start."""
    from rv_te_bench.launch import session
    from rv_te_bench.nodes import common

    def started(*_: Any, **__: Any) -> Any:
        raise _Started

    if command == 'bench':
        mp.setattr(session, 'run_single_process', started)
    elif command == 'test':   # after the plan, tolerance and session checks
        from rv_te_bench.cli import test

        mp.setattr(session.Session, 'start', started)
        mp.setattr(test, '_run_goal', started)
    elif command == 'ack':    # it would call a running sequencer's test/acknowledge
        from rv_te_bench.cli import ack

        mp.setattr(ack, 'acknowledge', started)
    elif command == 'demo':   # the demo starts its own session right after building it
        real_build = session.build_session

        def build_then_stop(*args: Any, **kwargs: Any) -> Any:
            real_build(*args, **kwargs)
            raise _Started

        mp.setattr(session, 'build_session', build_then_stop)
    elif command in {'record', 'replay'}:
        def build_node(factory: Any, *_: Any, **__: Any) -> int:
            import rclpy

            ctx = rclpy.context.Context()
            rclpy.init(context=ctx)
            try:
                factory(ctx).destroy_node()
            finally:
                rclpy.try_shutdown(context=ctx)
            raise _Started

        mp.setattr(common, 'run_node', build_node)


def run_example(line: str, mp: pytest.MonkeyPatch, store: Path | None = None) -> int | str:
    """Run one example (see the module doc); its exit code."""
    argv = shlex.split(line)[1:]
    # a shell expands the wildcards of an example (out/tests/RV80E-0042_*/bag)
    argv = [a for arg in argv for a in (sorted(str(p) for p in Path.cwd().glob(arg))
                                         if '*' in arg and list(Path.cwd().glob(arg))
                                         else [arg])]
    if argv[:1] == ['launch'] and '--write-default' not in argv:
        argv.append('--check')
    if argv[:1] == ['dashboard'] and '--duration' not in argv:
        argv += ['--duration', '1']   # serves until Ctrl-C otherwise (the test hung 600 s)
    if argv:
        _stop_at_start(mp, argv[0])
    if argv[:1] in (['results'], ['spc']) and store is not None:
        mp.setenv('RV_TE_DB', str(store))   # a store with units (see unit_store)
    if argv[:1] == ['record']:
        # default bag names have a one-second resolution: each example records in its own
        # folder (two in the same second collide; that case is the disk-full suite's)
        sub = Path.cwd() / f'record_{len(list(Path.cwd().glob("record_*")))}'
        sub.mkdir()
        mp.chdir(sub)
    try:
        return main(argv)
    except _Started:
        return 0
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int | str) else 1


@pytest.mark.ros
@pytest.mark.timeout(600)
def test_every_help_example_works(example_dir: Path, unit_store: Path, unit_test_bags: Path,
                                  monkeypatch: pytest.MonkeyPatch,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(example_dir)
    assert main(['launch', '--write-default', 'session.yaml']) == 0
    failed = {}
    for line in HELP_EXAMPLES:
        if '--write-default' in line or EXTERNAL.search(line):
            continue
        with monkeypatch.context() as mp:
            code = run_example(line, mp, unit_store)
        err = capsys.readouterr().err
        if code != 0:
            failed[line] = (code, err.strip().splitlines()[-1:] if err.strip() else '')
    assert not failed, '\n'.join(f'{line}: exit {code}: {err}'
                                  for line, (code, err) in failed.items())


@pytest.mark.ros
@pytest.mark.timeout(600)
def test_readme_examples_work_in_order(tmp_path: Path, unit_store: Path,
                                       monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    """A newcomer's order: the README's commands one after the other, from a fresh folder."""
    shutil.copytree(SAMPLE, tmp_path / 'bags' / 'sample')
    monkeypatch.chdir(tmp_path)
    failed = {}
    for line in README_EXAMPLES:
        if EXTERNAL.search(line):
            continue
        with monkeypatch.context() as mp:
            code = run_example(line, mp, unit_store)
        err = capsys.readouterr().err
        if code != 0:
            failed[line] = (code, err.strip().splitlines()[-1:] if err.strip() else '')
    assert not failed
