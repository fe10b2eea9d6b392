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
