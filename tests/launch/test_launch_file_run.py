"""The shipped ROS 2 launch file runs with ``rv-te launch``: the four nodes over the real
middleware, one output revolution, a bag that holds what the file asked for."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.ros

pytest.importorskip('rclpy')


def test_rv_te_launch_runs_the_shipped_launch_file(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    from rv_te_bench.cli.launch import default_launch_file
    from rv_te_bench.cli.main import main
    from tests.launch.conftest import read_decoded

    code = main(['launch', default_launch_file(), 'namespace:=rig',
                 '--param', 'bench.duration_output_revs=1.0',
                 '--param', f'recorder.output_dir={tmp_path}',
                 '--param', 'recorder.bag_name=bag'])
    err = capsys.readouterr().err
    assert code == 0, err[-3000:]
    bag = tmp_path / 'bag'
    rows = read_decoded(bag, ['/rig/bench/encoders', '/rig/te/statistics', '/rig/te/plot'])
    topics = [t for t, _, _ in rows]
    assert topics.count('/rig/bench/encoders') == 159           # 15.8 s of 1 kHz in 100s, +1
    assert any(t == '/rig/te/statistics' and m.window_complete for t, _, m in rows)
    assert '/rig/te/plot' in topics
    custom = yaml.safe_load((bag / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']['custom_data']
    assert custom['log_time'].startswith('sim:')               # use_sim_time from the file
    assert custom['launch_file'].endswith('session.launch.yaml')   # the session says where from
    assert yaml.safe_load(custom['launch_arguments'])['namespace'] == 'rig'
