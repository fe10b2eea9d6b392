"""Issue 34 acceptance, the round trip: one plan run live on the simulated bench through the
ros2_control interfaces (``rv-te test --launch``: setpoints to the bench's forward command
controllers, samples back through joint_states and the JointState adapter), its bag judged
offline (``rv-te test --from BAG``), and its CSV export, written here with pandas from the
bag as rosbags reads it, imported with a bench description and judged (``rv-te test --from
run.csv --bench ...``): the same verdicts, every metric within 0.5 % between the three."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from rv_te_bench.cli.main import main

pytestmark = pytest.mark.ros


def _json(capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    out = capsys.readouterr().out
    return json.loads(out[:out.rindex('}') + 1])


def export_csv(bag: Path, csv: Path) -> None:
    """bench/encoders of the bag as a DAQ's CSV: time [s], angles [rad], torque [N m]."""
    import pandas as pd
    from rosbags.highlevel import AnyReader

    from rv_te_bench.io.msgdefs import rv_te_typestore

    t, th_in, th_out, tq = [], [], [], []
    with AnyReader([bag], default_typestore=rv_te_typestore()) as r:
        conns = [c for c in r.connections if c.topic.endswith('bench/encoders')]
        for conn, _, raw in r.messages(connections=conns):
            m = r.deserialize(raw, conn.msgtype)
            t.append(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
                     + np.asarray(m.time_offset_s))
            th_in.append(np.asarray(m.theta_in_rad))
            th_out.append(np.asarray(m.theta_out_rad))
            tq.append(np.asarray(m.torque_out_nm))
    t_all = np.concatenate(t)
    pd.DataFrame({'t_s': t_all - t_all[0], 'theta_in_rad': np.concatenate(th_in),
                  'theta_out_rad': np.concatenate(th_out),
                  'torque_nm': np.concatenate(tq)}).to_csv(csv, index=False,
                                                           float_format='%.17g')


@pytest.mark.timeout(900)
def test_live_bag_and_csv_give_the_same_verdicts(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    common = ['--serial', 'RT-1', '--operator', 'pytest', '--json']
    # 1. live, through the ros2_control interfaces of the simulated bench
    rc_live = main(['test', 'li2023-rv', *common, '--launch', 'li2023-rv', '--out-dir',
                    str(tmp_path / 'live'), '--speed-factor', '0'])
    live = _json(capsys)
    (run,) = [d for d in (tmp_path / 'live').iterdir() if d.is_dir()]
    bag = run / 'bag'
    steps = {s['name']: s for s in live['steps']}
    assert all(s.get('segments_s') for s in steps.values()), 'not driven by setpoints'
    # 2. its bag, judged offline
    rc_bag = main(['test', 'li2023-rv', *common, '--from', str(bag), '--out-dir',
                   str(tmp_path / 'bag'), '--no-db'])
    from_bag = _json(capsys)
    # 3. its CSV export, imported with a bench description and judged
    export_csv(bag, tmp_path / 'run.csv')
    (tmp_path / 'bench.yaml').write_text(yaml.safe_dump({
        'bench_id': 'csv-bench', 'preset': 'li2023-rv', 'sample_rate_hz': 1000.0,
        'block_size': 100,
        'encoders': {'input': {'model': 'heidenhain-ron886'},
                     'output': {'model': 'heidenhain-ron886'}},
        'torque_sensor': {'present': True, 'scale_nm_per_unit': 1.0}}), encoding='utf-8')
    rc_csv = main(['test', 'li2023-rv', *common, '--from', str(tmp_path / 'run.csv'),
                   '--bench', str(tmp_path / 'bench.yaml'), '--time', 't_s', '--theta-in',
                   'theta_in_rad', '--theta-out', 'theta_out_rad', '--torque', 'torque_nm',
                   '--out-dir', str(tmp_path / 'csv'), '--no-db'])
    from_csv = _json(capsys)

    reports = {'live': live, 'bag': from_bag, 'csv': from_csv}
    assert rc_live == rc_bag == rc_csv == 0, {k: r['reason'] for k, r in reports.items()}
    assert {r['verdict'] for r in reports.values()} == {'pass'}
    names = [m['name'] for m in live['metrics']]
    for r in reports.values():
        assert [m['name'] for m in r['metrics']] == names
    worst = 0.0
    for name in names:
        vals = {k: next(m for m in r['metrics'] if m['name'] == name)
                for k, r in reports.items()}
        assert len({v['verdict'] for v in vals.values()}) == 1, (name, vals)
        for a, b in itertools.combinations(vals, 2):
            x, y = vals[a]['value'], vals[b]['value']
            assert x is not None and y is not None, (name, a, b)
            rel = abs(x - y) / abs(x)
            worst = max(worst, rel)
            assert rel <= 0.005, (name, a, x, b, y)
    # the sweep table too (no limit: info only)
    sweeps = {k: [row['te_pp_rad'] for s in r['steps'] if s['kind'] == 'sweep'
                  for row in s['rows']] for k, r in reports.items()}
    for a, b in itertools.combinations(sweeps, 2):
        for x, y in zip(sweeps[a], sweeps[b], strict=True):
            assert math.isclose(x, y, rel_tol=0.005), (a, x, b, y)
    print(f'largest difference between the three routes: {100 * worst:.3f} %')
