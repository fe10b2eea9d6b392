"""``rv-te test PLAN --from BAG|FILE`` (issue 34 part 1): a plan judged from data measured
elsewhere gives the live test's verdicts and metrics; data that does not fit a step gives
one line naming what is missing and that step is not judged, never a number.

The records are a plan run on the simulated bench (offline), written by rosbags (a session
bag, a JointState bag with a WrenchStamped torque topic) and by pandas (a DAQ's CSV), with
a bench description as YAML; no step markers reach the judge.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from rv_te_bench.cli.main import main
from tests.acceptance.recorded_data import (
    QUICK,
    T0_NS,
    Run,
    assert_same,
    bench_yaml,
    metric,
    run_plan,
    write_csv,
    write_session_bag,
)


@pytest.fixture(scope='module')
def quick() -> Run:
    return run_plan(QUICK)


#: A hysteresis plan and a profile of its metrics only (a TE limit would fail the unit as
#: not measured, whatever the hysteresis gives).
H_PLAN = {'plan': 'h', 'tolerance': 'h-limits.yaml', 'steps': [
    {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': 450.0, 'dwell_s': 0.1}]}
H_LIMITS = {'profile': 'h-limits', 'limits': {
    'lost_motion_arcmin': {'max': 1.0, 'source': 'test'},
    'backlash_arcmin': {'max': 1.0, 'source': 'test'},
    'torsional_rigidity_nm_per_arcmin': {'min': 108, 'region': 'K', 'source': 'test'}}}


@pytest.fixture
def h_plan(tmp_path: Path) -> dict:
    (tmp_path / 'h-limits.yaml').write_text(yaml.safe_dump(H_LIMITS), encoding='utf-8')
    return H_PLAN


def judge(tmp_path: Path, capsys: pytest.CaptureFixture[str], plan: dict | str, *args: str,
          code: int | None = None) -> tuple[dict[str, Any], str]:
    """Run rv-te test --json; (the report, stderr + the verdict line after the JSON)."""
    if isinstance(plan, dict):
        (tmp_path / 'plan.yaml').write_text(yaml.safe_dump(plan), encoding='utf-8')
        plan = str(tmp_path / 'plan.yaml')
    rc = main(['test', plan, '--serial', 'LI-42', '--operator', 'kim', '--json',
               '--out-dir', str(tmp_path / 'out'), *args])
    cap = capsys.readouterr()
    if code is not None:
        assert rc == code, cap.err
    end = cap.out.rindex('}') + 1
    return json.loads(cap.out[:end]), cap.err + cap.out[end:]


def test_session_bag_gives_the_live_verdicts(tmp_path: Path, quick: Run,
                                            capsys: pytest.CaptureFixture[str],
                                            default_store: Path) -> None:
    bag = write_session_bag(tmp_path / 'session', quick)
    report, err = judge(tmp_path, capsys, QUICK, '--from', str(bag), code=0)
    assert_same(quick.report, report, rel=1e-6)
    assert report['unit'] == {'serial': 'LI-42', 'operator': 'kim',
                              'date_utc': '2025-11-24T16:00:00+00:00'}   # the record's time
    assert report['source']['route'] == 'recorded' and report['source']['breaks'] == 0
    parts = report['source']['steps'][0]['parts']
    assert [p['direction'] for p in parts] == ['ccw', 'cw']
    assert parts[0]['found_speed_rpm'] == pytest.approx(3000, rel=1e-6)
    assert parts[0]['found_load_nm'] == pytest.approx(200, rel=1e-9)
    assert 'judging plan' in err
    # the user's results store: the test, its verdict and metrics
    from rv_te_bench.store import ResultFilter, open_store

    with open_store(default_store) as store:
        (rec,) = store.query(ResultFilter(test='test-plan'))
    assert (rec.serial, rec.plan, rec.verdict, rec.status) == ('LI-42', 'quick', 'pass', 'ok')
    assert rec.metrics[('backlash_rad', 'all')] == pytest.approx(
        metric(report, 'backlash_rad')['value'])
    # the unit report
    (run,) = [d for d in (tmp_path / "out").iterdir() if d.is_dir()]
    assert (run / 'report' / 'report.html').exists()


def test_pandas_csv_with_bench_description(tmp_path: Path, quick: Run,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    csv = write_csv(tmp_path / 'run.csv', quick)
    bench = bench_yaml(tmp_path / 'bench.yaml', quick)
    report, err = judge(tmp_path, capsys, QUICK, '--from', str(csv), '--bench', str(bench),
                        '--time', 't_s', '--theta-in', 'theta_in_rad', '--theta-out',
                        'theta_out_rad', '--torque', 'torque_nm', code=0)
    assert_same(quick.report, report, rel=1e-6)
    assert report['bench']['bench_id'] == 'lab-bench-7'
    assert 'imported' in err
    (run,) = [d for d in (tmp_path / "out").iterdir() if d.is_dir()]
    assert (run / 'bag' / 'metadata.yaml').exists()            # the imported record, kept
    assert report['bench']['bag'] == str(run / 'bag')


def test_no_torque_channel_leaves_the_hysteresis_not_judged(
        tmp_path: Path, quick: Run, capsys: pytest.CaptureFixture[str]) -> None:
    """Without torque the loaded TE runs cannot be told apart either: every step says
    what is missing, none gives a number; the unit is NOT JUDGED (exit 1)."""
    bench = bench_yaml(tmp_path / 'bench.yaml', quick)
    plan = {**QUICK, 'steps': [{**QUICK['steps'][0], 'load_nm': 0}, QUICK['steps'][1]]}
    live = run_plan(plan)
    csv = write_csv(tmp_path / 'run.csv', live, torque=False)
    report, err = judge(tmp_path, capsys, plan, '--from', str(csv), '--bench', str(bench),
                        '--time', 't_s', '--theta-in', 'theta_in_rad', '--theta-out',
                        'theta_out_rad', code=1)
    assert report['verdict'] == 'not_judged'
    for name in ('lost_motion_rad', 'backlash_rad', 'torsional_rigidity_K_nm_per_rad'):
        m = metric(report, name)
        assert m['verdict'] == 'not_judged' and m['value'] is None
        assert m['note'].startswith('no torque channel in the record')
    # TE at no load needs no torque: judged as live
    for name in ('te_pp_ccw_rad', 'te_pp_cw_rad'):
        assert metric(report, name)['value'] == pytest.approx(
            metric(live.report, name)['value'], rel=1e-6)
    lines = [ln for ln in err.splitlines() if ln.startswith("step 'hysteresis' not judged")]
    assert len(lines) == 1 and 'no torque channel' in lines[0]
    assert "VERDICT: NOT JUDGED  unit LI-42: not judged: step 'hysteresis': no torque" in err
    (run,) = [d for d in (tmp_path / 'out').iterdir() if d.is_dir()]
    html = (run / 'report' / 'report.html').read_text()
    assert '<title>Acceptance test of unit LI-42: NOT_JUDGED' in html
    assert 'Steps not judged' in html and 'no torque channel in the record' in html


def test_missing_parts_are_named_per_step(tmp_path: Path, quick: Run,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """A record of the TE step only, judged against a plan at another speed with a
    hysteresis step: one line per step naming what is missing and what the record has."""
    te_only = Run(report=quick.report, info=quick.info,
                  blocks=[b for b in quick.blocks if b.t0_s < 4.0])
    bag = write_session_bag(tmp_path / 'te_only', te_only)
    plan = {'plan': 'other', 'steps': [
        {'kind': 'te', 'name': 'te', 'speed_rpm': 1500, 'load_nm': 200, 'settle_s': 0.2},
        {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': 450.0}]}
    report, err = judge(tmp_path, capsys, plan, '--from', str(bag), code=1)
    te = metric(report, 'te_pp_ccw_rad')
    assert te['verdict'] == 'not_judged' and te['value'] is None
    assert 'no ccw run at 1500 rpm (+-2 %) against 200 N m' in te['note']
    assert 'the record has ccw 3000 rpm / 200 N m' in te['note']
    h = metric(report, 'backlash_rad')
    assert h['verdict'] == 'not_judged'
    assert '1 load cycle(s) to +-450 N m with the input locked' in h['note']
    assert 'the applied torque only reaches' in h['note']
    lines = [ln for ln in err.splitlines() if ln.startswith('step ') and 'not judged:' in ln]
    assert len(lines) == 2, lines
    assert report['reason'].startswith('not judged: ')


def test_a_gap_in_the_hysteresis_is_not_read_across(tmp_path: Path, quick: Run,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Lost blocks in the middle of the hysteresis cycle: the locked run ends at the gap,
    no part holds a whole cycle, and the step says so (the TE and sweep are judged)."""
    locked = [b.seq for b in quick.blocks
              if np.ptp(b.theta_in_true_rad) == 0 and np.ptp(b.torque_out_nm) == 0
              and abs(b.torque_out_nm[0]) > 400]
    bag = write_session_bag(tmp_path / 'gap', quick, drop_seqs=(locked[1],))
    report, _ = judge(tmp_path, capsys, QUICK, '--from', str(bag), code=1)
    assert report['source']['breaks'] == 1
    assert metric(report, 'backlash_rad')['verdict'] == 'not_judged'
    assert metric(report, 'te_pp_ccw_rad')['verdict'] == 'pass'


def test_time_ranges_in_the_plan(tmp_path: Path, quick: Run,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    """The plan says where each part is: the same numbers; a range outside the record is
    named."""
    bag = write_session_bag(tmp_path / 'session', quick)
    found = judge(tmp_path, capsys, QUICK, '--from', str(bag), code=0)[0]['source']['steps']
    te, hy, sw = found
    plan = json.loads(json.dumps(QUICK))
    plan['steps'][0]['time_ranges_s'] = {
        p['direction']: [p['found_t_start_s'], p['found_t_end_s']] for p in te['parts']}
    plan['steps'][1]['time_ranges_s'] = [[hy['parts'][0]['found_t_start_s'],
                                          hy['parts'][0]['found_t_end_s']]]
    plan['steps'][2]['time_ranges_s'] = [[p['found_t_start_s'], p['found_t_end_s']]
                                         for p in sw['parts']]
    report, _ = judge(tmp_path, capsys, plan, '--from', str(bag), code=0)
    assert_same(quick.report, report, rel=1e-6)
    plan['steps'][0]['time_ranges_s']['cw'] = [500.0, 510.0]
    report, _ = judge(tmp_path, capsys, plan, '--from', str(bag), code=1)
    assert 'the time range [500, 510] s holds no data' in metric(report, 'te_pp_cw_rad')['note']


def test_input_not_locked_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   h_plan: dict) -> None:
    """A 'hysteresis' loaded while the input creeps at 0.5 rpm: not a locked input."""
    plan = h_plan
    live = run_plan(plan, limits=H_LIMITS)
    blocks = []
    for b in live.blocks:        # the input turns slowly throughout
        creep = 0.5 * 2 * math.pi / 60 * (b.t0_s + b.time_offset_s)
        blocks.append(type(b)(**{**{f: getattr(b, f) for f in b.__dataclass_fields__},
                                 'theta_in_rad': b.theta_in_rad + creep}))
    bag = write_session_bag(tmp_path / 'creep', Run(live.report, live.info, blocks))
    report, _ = judge(tmp_path, capsys, plan, '--from', str(bag), code=1)
    note = metric(report, 'backlash_rad')['note']
    assert 'the input is not locked while the torque is applied (input speed 0.5 rpm' in note


def test_torque_from_a_wrench_topic(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    h_plan: dict) -> None:
    """Encoder blocks without torque and the bench's torque transducer on its own topic
    (geometry_msgs/WrenchStamped at 500 Hz, torque about z = applied torque): judged as
    live with --torque-topic and --torque-scale -1."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    plan = h_plan
    live = run_plan(plan, limits=H_LIMITS)
    bag = write_session_bag(tmp_path / 'wrench', live, torque=False)
    # add the torque topic to a copy of the bag written by rosbags
    a = live.arrays()
    store = get_typestore(Stores.ROS2_JAZZY)
    ws = store.types['geometry_msgs/msg/WrenchStamped']
    t = store.types
    torque_bag = tmp_path / 'torque'
    with Writer(torque_bag, version=9) as w:
        c = w.add_connection('/bench/torque', ws.__msgtype__, typestore=store)
        for k in range(0, a['t_s'].size, 2):
            ns = T0_NS + round(a['t_s'][k] * 1e9)
            stamp = t['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9)
            msg = ws(header=t['std_msgs/msg/Header'](stamp=stamp, frame_id='flange'),
                     wrench=t['geometry_msgs/msg/Wrench'](
                         force=t['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
                         torque=t['geometry_msgs/msg/Vector3'](
                             x=0.0, y=0.0, z=-float(a['torque_nm'][k]))))
            w.write(c, ns, bytes(store.serialize_cdr(msg, ws.__msgtype__)))
    merged = _merge(bag, torque_bag, tmp_path / 'merged')
    report, _ = judge(tmp_path, capsys, plan, '--from', str(merged), '--torque-topic',
                        '/bench/torque', '--torque-scale', '-1', code=0)
    assert 'topic /bench/torque (WrenchStamped.torque.z' in report['source']['torque_from']
    # half the torque samples interpolated between readings 2 ms apart: held torques are
    # exact, the ramps between them (instant steps here) read one sample differently
    for name in ('backlash_rad', 'lost_motion_rad', 'torsional_rigidity_K_nm_per_rad'):
        assert metric(report, name)['value'] == pytest.approx(
            metric(live.report, name)['value'], rel=2e-3), name
    # without the topic: no torque channel, named
    report, _ = judge(tmp_path, capsys, plan, '--from', str(bag), code=1)
    assert metric(report, 'backlash_rad')['note'].startswith('no torque channel')


def _merge(a: Path, b: Path, out: Path) -> Path:
    """One bag with the connections and messages of two (rosbags reader and writer)."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from rv_te_bench.io.msgdefs import rv_te_typestore

    jazzy = get_typestore(Stores.ROS2_JAZZY)
    with Writer(out, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        for src, store in ((a, rv_te_typestore()), (b, jazzy)):
            with AnyReader([src], default_typestore=store) as r:
                conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                         for c in r.connections}
                for conn, ts, raw in r.messages():
                    w.write(conns[conn.id], ts, raw)
    return out


def test_joint_state_bag_with_effort(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                     h_plan: dict) -> None:
    """What a ros2_control bench records: sensor_msgs/JointState per sample, the output
    joint's effort the torque; imported with the bench description, then judged."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    plan = h_plan
    live = run_plan(plan, limits=H_LIMITS)
    a = live.arrays()
    store = get_typestore(Stores.ROS2_JAZZY)
    js = store.types['sensor_msgs/msg/JointState']
    t = store.types
    bag = tmp_path / 'joint_states'
    with Writer(bag, version=9) as w:
        c = w.add_connection('/joint_states', js.__msgtype__, typestore=store)
        for k in range(a['t_s'].size):
            ns = T0_NS + round(a['t_s'][k] * 1e9)
            msg = js(header=t['std_msgs/msg/Header'](
                stamp=t['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
                frame_id=''), name=['input_joint', 'output_joint'],
                position=np.array([a['theta_in_rad'][k], a['theta_out_rad'][k]]),
                velocity=np.zeros(0), effort=np.array([math.nan, a['torque_nm'][k]]))
            w.write(c, ns + 50_000, bytes(store.serialize_cdr(msg, js.__msgtype__)))
    bench = bench_yaml(tmp_path / 'bench.yaml', live)
    report, err = judge(tmp_path, capsys, plan, '--from', str(bag), '--bench', str(bench),
                        '--torque', 'output_joint', '--no-unwrap', code=0)
    assert_same(live.report, report, rel=1e-5)
    # without --bench: one line saying what is needed
    rc = main(['test', str(tmp_path / 'plan.yaml'), '--serial', 'S', '--operator', 'o',
               '--from', str(bag)])
    assert rc == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f'ERROR: --from {bag} is a JointState bag: give its bench description '
                   'with --bench BENCH.yaml (rv-te import --write-bench-example BENCH.yaml '
                   'writes one to edit)']


def test_from_and_launch_exclude_each_other(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(['test', 'li2023-rv', '--serial', 'S', '--operator', 'o', '--from',
              str(tmp_path), '--launch', 'li2023-rv'])
    assert exc.value.code == 2
    assert '--from judges recorded data and --launch runs' in capsys.readouterr().err
