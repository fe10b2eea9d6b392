"""bench_info_cdr: a bench's record written as BenchInfo without ROS, every field of it.

The bytes are read back by rosbags' own deserialiser on the package's ``.msg`` file (not
through :mod:`rv_te_bench.io.msgdefs`), so a field the writer left out or mangled shows.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rv_te_bench.io.bench_record import bench_info_cdr, read_bench_info
from sim.bench_info import BenchInfoData

BENCH_INFO = 'rv_te_msgs/msg/BenchInfo'
MSG_FILE = Path(__file__).resolve().parents[2] / 'rv_te_msgs_py' / 'msg' / 'BenchInfo.msg'

#: Every field away from its default (0, '', empty), so a field not written reads differently.
VALUES = {
    'bench_id': 'bench-7', 'preset': 'wang2020-2kv', 'reducer_type': '2kv',
    'gear_ratio': 79.0, 'crank_per_input': -0.31645569620253167, 'crank_rel_per_input': 0.25,
    'mesh_orders': (25.0, 50.0, 75.0), 'mesh_labels': ('stage-2 mesh', '2x', '3x'),
    'encoder_in_model': 'heidenhain-ron886', 'encoder_out_model': 'heidenhain-rcn8580',
    'encoder_in_resolution_rad': 1.2e-7, 'encoder_out_resolution_rad': 2.9e-8,
    'sample_rate_hz': 10000.0, 'block_size': 250, 'parameters_yaml': 'bench:\n  seed: 3\n',
    'encoder_in_head_angles_rad': (0.0, 3.141592653589793),
    'encoder_out_head_angles_rad': (0.0, 2.0943951023931953, 4.1887902047863905),
    'encoder_in_scale_serial': 'S-1001', 'encoder_out_scale_serial': 'S-2002',
    'encoder_in_scale_diameter_m': 0.18, 'encoder_out_scale_diameter_m': 0.25,
    'encoder_in_scale_eccentricity_m': 1.5e-6, 'encoder_out_scale_eccentricity_m': 2.5e-6,
    'encoder_in_scale_index_rad': 0.5, 'encoder_out_scale_index_rad': -1.25,
}


def _plain(v: object) -> object:
    if isinstance(v, np.ndarray):
        return tuple(v.tolist())
    return tuple(v) if isinstance(v, list) else v


def test_every_field_of_the_record_is_written() -> None:
    assert set(VALUES) == set(BenchInfoData.field_names()), 'a new field: give it a value here'
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(MSG_FILE.read_text(encoding='utf-8'), BENCH_INFO))
    data = bench_info_cdr(BenchInfoData(**VALUES), 1_700_000_000_123_456_789)
    msg = store.deserialize_cdr(data, BENCH_INFO)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
    assert msg.header.frame_id == 'bench-7'
    got = {name: _plain(getattr(msg, name)) for name in VALUES}
    assert got == VALUES


def test_values_are_written_as_the_message_types_them(tmp_path: Path) -> None:
    # an int ratio and a float block size (as a YAML file may give them) go out as the
    # message's float64 and uint32, and a bag holding them reads back as the same record
    from rv_te_bench.io.bag_writer import BagWriter

    info = BenchInfoData(gear_ratio=81, block_size=100.0, bench_id='b')
    with BagWriter(tmp_path / 'bag') as writer:
        writer.add_topic('/bench/info', BENCH_INFO)
        writer.write('/bench/info', 5, bench_info_cdr(info, 5))
    back = read_bench_info(tmp_path / 'bag')
    assert back == BenchInfoData(gear_ratio=81.0, block_size=100, bench_id='b')
    assert type(back.gear_ratio) is float and type(back.block_size) is int
