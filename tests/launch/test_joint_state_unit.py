"""Issue 33 s.2: the JointState route dropped the unit under test. A session whose bench is a
ros2_control bench (the simulated bench publishing JointState) and whose adapter reads a bench
description with ``unit_under_test`` now records the serial and operator in the bag's metadata
(read back with rosbags, and the MCAP metadata record with the mcap library), and the unit
report of that bag names them.

Real processes over the middleware.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

pytest.importorskip('rclpy')

SERIAL = 'SN-JS-0042'
OPERATOR = 'A. Tester'

DESCRIPTION = f"""\
bench_id: js-bench-7
preset: wang2020-2kv
sample_rate_hz: 1000.0
block_size: 100
encoders:
  input: {{model: heidenhain-ron886, zero_offset_deg: 0.0}}
  output: {{model: heidenhain-ron886, zero_offset_deg: 0.0}}
torque_sensor: {{present: true, scale_nm_per_unit: 1.0}}
unit_under_test: {{serial: {SERIAL}, operator: {OPERATOR}, temperature_c: 22.5, notes: ''}}
joints: {{input: input_joint, output: output_joint}}
"""


@pytest.mark.timeout(300)
def test_unit_under_test_reaches_the_bag_and_the_report(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader

    from rv_te_bench.cli.main import main
    from rv_te_bench.launch.session import build_session, run_session

    desc = tmp_path / 'bench.yaml'
    desc.write_text(DESCRIPTION)
    spec = build_session([], nodes=['bench', 'joint_state_adapter', 'te_node', 'recorder'],
                         overrides=['bench.output=joint_state', 'bench.preset=wang2020-2kv',
                                    'bench.speed_rpm=2950', 'bench.sample_rate_hz=1000',
                                    'bench.block_size=100', 'bench.duration_output_revs=1.3',
                                    'bench.time_mode=fast', 'bench.speed_factor=4.0',
                                    f'joint_state_adapter.bench_description={desc}',
                                    f'recorder.output_dir={tmp_path}',
                                    'recorder.bag_name=bag'])
    lines: list[str] = []
    assert run_session(spec, log=lines.append) == 0, lines
    bag = tmp_path / 'bag'

    with Reader(bag) as reader:                       # rosbags: metadata.yaml's custom_data
        custom = reader.storage.metadata.custom or {}
        blocks = sum(c.msgcount for c in reader.connections if c.topic == '/bench/encoders')
    assert blocks > 0
    assert custom.get('unit_serial') == SERIAL, custom
    assert custom.get('operator') == OPERATOR, custom
    assert custom.get('bench_id') == 'js-bench-7', custom
    assert custom.get('temperature_c') == '22.5', custom

    (mcap_file,) = sorted(bag.glob('*.mcap'))           # the mcap library: the session record
    with mcap_file.open('rb') as f:
        records = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    assert records['rv_te_session']['unit_serial'] == SERIAL, records.keys()
    assert records['rv_te_session']['operator'] == OPERATOR

    report = tmp_path / 'report'
    assert main(['analyze', str(bag), '--report', str(report), '--no-db', '--quiet']) == 0
    html = (report / 'report.html').read_text(encoding='utf-8')
    assert SERIAL in html and OPERATOR in html
    doc = json.loads((report / 'report.json').read_text(encoding='utf-8'))
    text = json.dumps(doc)
    assert f'"unit_serial": "{SERIAL}"' in text and f'"operator": "{OPERATOR}"' in text, \
        text[:2000]
