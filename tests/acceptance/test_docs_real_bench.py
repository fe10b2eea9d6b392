"""The commands of the real-bench sections (README's "Acceptance tests on a real bench",
docs/ACCEPTANCE.md's "A real bench"), run as written, in order, in a folder holding what
they name:

* judged from a record: a DAQ's CSV written here with pandas from a closed-form unit
  (tests/core/hysteresis_records.py), its bench description and plan; ``<time>`` stands
  for the folder ``rv-te test --from`` made;
* driven live: the session command starts the adapter, the sequencer and the recorder in
  processes, a plain rclpy stand-in bench written in the tests
  (tests/nodes/real_bench.py) serves the ros2_control topics, ``rv-te test`` runs the plan
  and ``rv-te ack`` answers its operator step from another process.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from rv_te_bench.cli.main import main
from tests.acceptance.test_measured_hysteresis_cli import TRUTH, UNIT, write_daq
from tests.core.hysteresis_records import step_torques, torque_step_record

ROOT = Path(__file__).resolve().parents[2]
MARK = '<!-- the commands of this block are run by tests/acceptance/test_docs_real_bench.py -->'


def blocks(path: Path) -> list[list[str]]:
    """The marked blocks of a page: their command lines (continuations joined)."""
    text = path.read_text(encoding='utf-8')
    out = []
    for body in re.findall(re.escape(MARK) + r'\n```console\n(.*?)```', text, flags=re.S):
        body = re.sub(r' *\\\n\s*', ' ', body)
        out.append([ln.strip() for ln in body.splitlines() if ln.strip().startswith('rv-te ')])
    return out


def test_both_pages_show_both_routes() -> None:
    readme, acceptance = blocks(ROOT / 'README.md'), blocks(ROOT / 'docs' / 'ACCEPTANCE.md')
    assert len(readme) == len(acceptance) == 2
    assert readme == acceptance     # one set of commands, shown on both pages
    live, offline = readme
    assert any(c.startswith('rv-te launch ') for c in live) and 'rv-te ack' in live
    assert any('--from' in c for c in offline)
    assert any(c.startswith('rv-te unit-report ') for c in offline)
    assert any(c.startswith('rv-te analyze ') for c in offline)


def test_judged_from_its_record(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                capsys: pytest.CaptureFixture[str]) -> None:
    _, offline = blocks(ROOT / 'README.md')
    write_daq(tmp_path, torque_step_record(UNIT, step_torques(UNIT, cycles=3),
                                           np.random.default_rng(7)))
    (tmp_path / 'bench.yaml').rename(tmp_path / 'other_bench.yaml')
    (tmp_path / 'plan.yaml').rename(tmp_path / 'daq_plan.yaml')
    monkeypatch.chdir(tmp_path)
    when = ''
    for cmd in offline:
        argv = shlex.split(cmd.replace('<time>', when))
        assert main(argv[1:]) == 0, cmd
        if not when:
            (made,) = [p for p in Path('out/tests').iterdir() if p.is_dir()]
            when = made.name.split('_', 1)[1]
    text = capsys.readouterr().out
    assert text.count('VERDICT: PASS  unit RV20-7') == 2     # the test, the unit report
    lm = float(re.search(r'lost motion \(\+-5\.01 N m\)\s+([0-9.]+) arcmin', text).group(1))
    assert lm == pytest.approx(TRUTH['lost_motion_rad'] * 10800 / np.pi, rel=0.02)


def _env(domain: int) -> dict[str, str]:
    env = {**os.environ, 'ROS_DOMAIN_ID': str(domain), 'PYTHONPATH': str(ROOT)}
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    return env


@pytest.mark.ros
@pytest.mark.timeout(400)
def test_driven_live_through_ros2_control(tmp_path: Path, ros_context: object,
                                          ros_domain_id: int) -> None:
    from rclpy.executors import SingleThreadedExecutor

    from tests.nodes.real_bench import DESCRIPTION, StandInBench

    live, _ = blocks(ROOT / 'README.md')
    (tmp_path / 'my_bench.yaml').write_text(DESCRIPTION, encoding='utf-8')
    plan = {'plan': 'stand-in', 'safety': {'max_output_torque_nm': 500}, 'steps': [
        {'kind': 'te', 'name': 'te', 'speed_rpm': 3000, 'settle_s': 0.2},
        {'kind': 'operator', 'name': 'lock', 'instruction': 'lock the input shaft',
         'timeout_s': 120},
        {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': 450.0,
         'dwell_s': 0.1, 'step_fraction': 0.25}]}
    (tmp_path / 'my_plan.yaml').write_text(yaml.safe_dump(plan), encoding='utf-8')
    bench = StandInBench(context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(bench)
    running = True

    def spin() -> None:
        while running:
            ex.spin_once(timeout_sec=0.01)

    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()
    env = _env(ros_domain_id)
    rv = [sys.executable, '-m', 'rv_te_bench.cli.main']
    procs: list[subprocess.Popen] = []
    log = (tmp_path / 'session.log').open('wb')
    try:
        setup, session_cmd, test_cmd, ack_cmd = live
        assert subprocess.run(rv + shlex.split(setup)[1:], cwd=tmp_path, env=env,
                              capture_output=True, check=False).returncode == 0
        session = subprocess.Popen(rv + shlex.split(session_cmd)[1:], cwd=tmp_path, env=env,
                                   stdout=log, stderr=subprocess.STDOUT,
                                   start_new_session=True)
        procs.append(session)
        # files, not pipes: the report JSON is larger than a pipe holds
        t_out = (tmp_path / 'test.out').open('w+')
        t_err = (tmp_path / 'test.err').open('w+')
        test = subprocess.Popen(rv + shlex.split(test_cmd)[1:] + ['--json'], cwd=tmp_path,
                                env=env, stdout=t_out, stderr=t_err,
                                stdin=subprocess.DEVNULL, text=True)
        procs.append(test)
        acks = 0
        end = time.monotonic() + 300
        while test.poll() is None:
            assert time.monotonic() < end, 'the test did not end'
            time.sleep(1.0)
            r = subprocess.run(rv + shlex.split(ack_cmd)[1:], cwd=tmp_path, env=env,
                               capture_output=True, text=True, check=False, timeout=60)
            acks += r.returncode == 0
        test.wait()
        t_out.close()
        t_err.close()
        out = (tmp_path / 'test.out').read_text(encoding='utf-8')
        err = (tmp_path / 'test.err').read_text(encoding='utf-8')
        assert test.returncode == 0, err[-2000:]
        assert acks == 1        # one operator step, acknowledged once from another process
        report = json.loads(out)
        assert report['verdict'] == 'pass'
        got = {m['name']: m['value'] for m in report['metrics']}
        for name, value in bench.truth(450.0).items():
            assert got[name] == pytest.approx(value, rel=0.01 if 'te_pp' in name else 0.02)
        assert bench.velocity == 0.0 and bench.effort == 0.0    # left at zero
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGINT) if p is procs[0] else p.terminate()
                try:
                    p.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        log.close()
        running = False
        spinner.join(timeout=5)
        ex.shutdown()
        bench.destroy_node()
    # the recorder's bag of the session: the test's records, readable offline
    (bag,) = [p.parent for p in (tmp_path / 'bags' / 'tests').rglob('metadata.yaml')]
    assert main(['unit-report', str(bag), '--report', str(tmp_path / 'again')]) == 0
