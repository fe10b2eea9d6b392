"""Message types outside ROS 2 Jazzy and rv_te_msgs (a vendor's message on the bench) are
learnt from their installed .msg files and recorded with their full definition; a bag with
them reads back in independent readers (rosbags builds its types from the stored text)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from rv_te_bench.errors import BagError
from rv_te_bench.io.bag_writer import BagWriter
from rv_te_bench.io.msgdefs import SEPARATOR, full_msgdef, learn_type, rv_te_typestore
from tests.io.bag_fixtures import T0_NS

PROBE = 'vendor_probe_msgs/msg/Probe'
INNER_TEXT = '# one reading\nfloat64 value_rad\nuint8 channel\n'
PROBE_TEXT = 'std_msgs/Header header\nInner[] readings\nfloat64[3] gains\n'


@pytest.fixture
def vendor_install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A ROS install prefix with a vendor package's .msg files, on AMENT_PREFIX_PATH."""
    msg_dir = tmp_path / 'prefix' / 'share' / 'vendor_probe_msgs' / 'msg'
    msg_dir.mkdir(parents=True)
    (msg_dir / 'Probe.msg').write_text(PROBE_TEXT)
    (msg_dir / 'Inner.msg').write_text(INNER_TEXT)
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'prefix'))
    return tmp_path


def test_vendor_type_is_learnt_and_recorded(vendor_install: Path) -> None:
    text = full_msgdef(PROBE)
    own, *deps = text.split(SEPARATOR + '\n')
    assert own == PROBE_TEXT
    assert {d.split('\n', 1)[0] for d in deps} == {
        'MSG: vendor_probe_msgs/Inner', 'MSG: std_msgs/Header', 'MSG: builtin_interfaces/Time'}
    assert f'MSG: vendor_probe_msgs/Inner\n{INNER_TEXT}' in text
    store = rv_te_typestore()
    cls = store.types[PROBE]
    inner = store.types['vendor_probe_msgs/msg/Inner']
    header = store.types['std_msgs/msg/Header']
    stamp = store.types['builtin_interfaces/msg/Time']
    msg = cls(header=header(stamp=stamp(sec=3, nanosec=4), frame_id='probe'),
              readings=[inner(value_rad=0.25, channel=2), inner(value_rad=-1.5, channel=7)],
              gains=np.array([1.0, 2.0, 3.0]))
    bag = vendor_install / 'bag'
    with BagWriter(bag) as writer:
        writer.add_topic('/probe', PROBE)
        writer.write('/probe', T0_NS, bytes(store.serialize_cdr(msg, PROBE)))
    with AnyReader([bag]) as reader:   # no default typestore: types from the bag's text
        (conn,) = reader.connections
        (got,) = [reader.deserialize(raw, conn.msgtype) for _, _, raw in reader.messages()]
    assert [(r.value_rad, r.channel) for r in got.readings] == [(0.25, 2), (-1.5, 7)]
    assert got.gains.tolist() == [1.0, 2.0, 3.0]
    assert got.header.frame_id == 'probe'


def test_unknown_type_names_what_is_missing(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    msg_dir = tmp_path / 'share' / 'half_msgs' / 'msg'
    msg_dir.mkdir(parents=True)
    (msg_dir / 'Outer.msg').write_text('half_msgs/Missing part\n')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    with pytest.raises(BagError, match=r"'half_msgs/msg/Missing' \(used by "
                                       r"'half_msgs/msg/Outer'\).*no \.msg file"):
        learn_type('half_msgs/msg/Outer')
    with pytest.raises(BagError, match=r"Unknown message type 'nope_msgs/msg/X'"):
        full_msgdef('nope_msgs/msg/X')


# --- the small store of our own types (issue 41: no Jazzy store per import) -----------------

def test_own_store_defines_our_types_as_the_jazzy_store_does() -> None:
    """Definitions, type hashes and serialised bytes from ``own_typestore`` equal those of
    the full Jazzy store (rosbags' own definitions of Header and Time), for every type."""
    from rosbags.typesys import Stores, get_typestore

    from rv_te_bench.io.msgdefs import (
        BASE_MSG_TEXTS,
        full_msgdef_from,
        load_msg_texts,
        own_typestore,
    )

    jazzy = get_typestore(Stores.ROS2_JAZZY)
    full = rv_te_typestore()
    for name in BASE_MSG_TEXTS:
        assert own_typestore(name).fielddefs[name] == jazzy.fielddefs[name]
    ours = sorted(load_msg_texts())
    assert len(ours) >= 13
    own = own_typestore(*ours)
    for name in ours:
        assert full_msgdef_from(own, name) == full_msgdef_from(full, name), name
        assert own.hash_rihs01(name) == full.hash_rihs01(name), name


def test_bench_info_bytes_unchanged_by_the_small_store() -> None:
    """BenchInfo serialised by the import (small store) == by the full store, byte for byte;
    the preset loaded once per description gives the same record as a fresh load."""
    import dataclasses

    import yaml

    from rv_te_bench.io.bench_description import parse_bench_description
    from rv_te_bench.io.bench_record import bench_info_cdr
    from rv_te_bench.io.msgdefs import BENCH_INFO
    from sim.bench_info import BenchInfoData

    desc = parse_bench_description({'bench_id': 'b7', 'preset': 'rv-80e-101',
                                    'sample_rate_hz': 5000.0, 'block_size': 250})
    info = desc.bench_info()
    assert info == parse_bench_description({'bench_id': 'b7', 'preset': 'rv-80e-101',
                                            'sample_rate_hz': 5000.0,
                                            'block_size': 250}).bench_info()
    record = yaml.safe_load(info.parameters_yaml)
    assert info.parameters_yaml == yaml.safe_dump(record, sort_keys=True)
    store = rv_te_typestore()
    ty = store.types
    values = BenchInfoData.from_message(info).message_values()
    values = {k: (np.asarray(v, dtype=np.float64) if isinstance(v, (list, tuple))
                  and k not in ('mesh_labels',) else v) for k, v in values.items()}
    header = ty['std_msgs/msg/Header'](stamp=ty['builtin_interfaces/msg/Time'](
        sec=1_700_000_000, nanosec=123), frame_id='b7')
    msg = ty[BENCH_INFO](header=header, **values)
    expected = bytes(store.serialize_cdr(msg, BENCH_INFO))
    assert bench_info_cdr(info, 1_700_000_000 * 10**9 + 123) == expected
    assert dataclasses.asdict(info)   # a plain record
