"""rv-te import with one column per read head (issue 36): CSV by pandas, TDMS by nptdms,
MDF by asammdf.

The unit's TE comes from the paper's equations in tests/wang2020_reference, the heads'
readings from the tests' exact-geometry scale; the files are written by pandas / nptdms as
a DAQ would. Truth: the test's own FFT of its own TE.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pytest
import yaml

from rv_te_bench.cli.main import main
from rv_te_bench.io.bag_reader import read_encoder_blocks
from rv_te_bench.report.analysis import analyze_bag
from tests import wang2020_reference as ref
from tests.scale_reference import ARCSEC_RAD, Scale, whole_revolutions_fft

if TYPE_CHECKING:
    from pathlib import Path

RATE = 2000.0
UNIT = ref.Unit(e_p1=12e-6, e_p2=9e-6, e_g=6e-6, e_ot=4.1e-6, theta_p1=0.3, theta_p2=2.0,
                theta_g=-1.0, theta_ot=0.8)
HEADS_DEG = (0.0, 90.0, 180.0, 270.0)


def _bench(tmp_path: Path, heads_deg: tuple[float, ...] = HEADS_DEG) -> Path:
    p = tmp_path / 'bench.yaml'
    p.write_text(yaml.safe_dump({
        'bench_id': 'csv-heads', 'preset': 'wang2020-2kv', 'sample_rate_hz': RATE,
        'block_size': 500,
        'encoders': {'input': {'model': 'ideal'},
                     'output': {'model': 'renishaw-resm', 'serial': 'R-1',
                                'heads_deg': list(heads_deg),
                                'scale': {'diameter_mm': 100.0, 'eccentricity_um': 5.0}}}}))
    return p


def _record(revs: float = 2.05) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = round(revs * ref.RATIO / 5.0 * RATE)
    theta_in = np.arange(n) * (2 * math.pi * 5.0 / RATE)
    phi = theta_in / ref.RATIO
    scale = Scale(radius_m=0.05, eccentricity_m=5e-6, psi_rad=2.5,
                  heads_rad=tuple(np.radians(HEADS_DEG)))
    return np.arange(n) / RATE, theta_in, scale.readings(phi + ref.nlte_rad(phi, UNIT))


def _truth_arcsec() -> float:
    phi = np.linspace(0.0, 2 * math.pi * 3, 3 * 65_536, endpoint=False)
    te = ref.nlte_rad(phi, UNIT)
    return abs(whole_revolutions_fft(phi + te, te, 1)[0]) / ARCSEC_RAD


def _line1(bag: Path, **kw) -> float:
    res = analyze_bag(bag, with_advice=False, **kw)
    return next(ln.amplitude_rad for ln in res.spectrum.lines
                if abs(ln.output_order - 1) < 1e-9) / ARCSEC_RAD


def test_csv_one_column_per_head(tmp_path: Path) -> None:
    """pandas CSV: t_s, theta_in_rad, out_h0..3 with head 2 empty in three rows of one
    block. The bag holds 4 heads (3 in that block); averaged, the line is the reducer's."""
    pd = pytest.importorskip('pandas')
    t, th_in, heads = _record()
    frame = pd.DataFrame({'t_s': t, 'theta_in_rad': th_in,
                          **{f'out_h{j}': heads[j] for j in range(4)}})
    frame.loc[10_010:10_012, 'out_h2'] = np.nan            # block 20 lacks head 2
    csv = tmp_path / 'run.csv'
    frame.to_csv(csv, index=False, float_format='%.17g')
    out = tmp_path / 'bag'
    assert main(['import', str(csv), '--bench', str(_bench(tmp_path)), '--out', str(out),
                 '--time', 't_s', '--theta-in', 'theta_in_rad',
                 '--theta-out-heads', 'out_h0,out_h1,out_h2,out_h3']) == 0
    blocks = list(read_encoder_blocks(out))
    assert sum(b.theta_in_rad.size for b in blocks) == t.size         # nothing lost
    assert blocks[0].out_head_ids == (0, 1, 2, 3)
    np.testing.assert_allclose(blocks[0].theta_out_heads_rad, heads[:, :500], rtol=0,
                               atol=1e-12)
    assert blocks[20].out_head_ids == (0, 1, 3)
    assert abs(_line1(out) - _truth_arcsec()) < 0.2
    assert abs(_line1(out, heads_mode='head0') - _truth_arcsec()) > 5.0


def test_tdms_one_channel_per_head(tmp_path: Path) -> None:
    nptdms = pytest.importorskip('nptdms')
    _t, th_in, heads = _record()
    props = {'wf_increment': 1.0 / RATE, 'wf_start_offset': 0.0, 'unit_string': 'rad'}
    chans = [nptdms.ChannelObject('enc', 'theta_in', th_in, properties=props)]
    chans += [nptdms.ChannelObject('enc', f'head{j}', heads[j], properties=props)
              for j in range(4)]
    path = tmp_path / 'run.tdms'
    with nptdms.TdmsWriter(str(path)) as w:
        w.write_segment(chans)
    out = tmp_path / 'bag'
    assert main(['import', str(path), '--bench', str(_bench(tmp_path)), '--out', str(out),
                 '--theta-in', 'enc/theta_in',
                 '--theta-out-heads', 'enc/head0,enc/head1,enc/head2,enc/head3']) == 0
    assert next(iter(read_encoder_blocks(out))).out_head_ids == (0, 1, 2, 3)
    assert abs(_line1(out) - _truth_arcsec()) < 0.2


def test_mdf_one_channel_per_head(tmp_path: Path) -> None:
    """MDF 4.10 written by asammdf as a DAQ does: one channel group, master time, the
    input and four head channels; the heads reach the bag and their mean gives the
    reducer's line."""
    asammdf = pytest.importorskip('asammdf')
    t, th_in, heads = _record()
    mdf = asammdf.MDF(version='4.10')
    mdf.append([asammdf.Signal(th_in, t, name='theta_in', unit='rad'),
                *(asammdf.Signal(heads[j], t, name=f'out_h{j}', unit='rad')
                  for j in range(4))])
    path = tmp_path / 'run.mf4'
    mdf.save(str(path), overwrite=True)
    mdf.close()
    out = tmp_path / 'bag'
    assert main(['import', str(path), '--bench', str(_bench(tmp_path)), '--out', str(out),
                 '--theta-in', 'theta_in',
                 '--theta-out-heads', 'out_h0,out_h1,out_h2,out_h3']) == 0
    blocks = list(read_encoder_blocks(out))
    assert sum(b.theta_in_rad.size for b in blocks) == t.size
    assert blocks[0].out_head_ids == (0, 1, 2, 3)
    np.testing.assert_allclose(blocks[0].theta_out_heads_rad, heads[:, :500], rtol=0,
                               atol=1e-12)
    assert abs(_line1(out) - _truth_arcsec()) < 0.2
    assert abs(_line1(out, heads_mode='head0') - _truth_arcsec()) > 5.0


@pytest.mark.parametrize(('args', 'bench_heads', 'message'), [
    (['--theta-out-heads', 'out_h0,out_h1'], HEADS_DEG,
     '2 output head columns given, but bench description'),
    (['--theta-out', 'out_h1', '--theta-out-heads', 'out_h0,out_h1,out_h2,out_h3'], HEADS_DEG,
     "--theta-out 'out_h1' must be the first of --theta-out-heads"),
    (['--theta-out-heads', 'out_h0,out_h0'], HEADS_DEG, 'must name 2 to 16 different'),
])
def test_bad_head_columns_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                       args: list[str], bench_heads, message: str) -> None:
    csv = tmp_path / 'run.csv'
    csv.write_text('t_s,theta_in_rad,out_h0,out_h1,out_h2,out_h3\n'
                   + ''.join(f'{k / RATE},{k * 0.01},{k * 1e-4},{k * 1e-4},{k * 1e-4},'
                             f'{k * 1e-4}\n' for k in range(100)))
    out = tmp_path / 'bag'
    code = main(['import', str(csv), '--bench', str(_bench(tmp_path, bench_heads)),
                 '--out', str(out), '--time', 't_s', '--theta-in', 'theta_in_rad', *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert len(err) == 1 and err[0].startswith('ERROR:') and message in err[0], err
    assert not out.exists()


def test_jointstate_bag_one_joint_per_head(tmp_path: Path) -> None:
    """A ros2_control bag (rosbags writer) with one joint per head; the bench description
    names them (joints.output_heads). Head 3 has no reading in some messages: those blocks
    lack head 3, nothing is dropped."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    t, th_in, heads = _record(revs=1.1)
    store = get_typestore(Stores.ROS2_JAZZY)
    js = store.types['sensor_msgs/msg/JointState']
    hdr_t, stamp_t = store.types['std_msgs/msg/Header'], store.types['builtin_interfaces/msg/Time']
    names = ['in', 'h0', 'h1', 'h2', 'h3']
    bag = tmp_path / 'js'
    t0 = 1_700_000_000 * 10**9
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection('/joint_states', js.__msgtype__, typestore=store)
        for k in range(t.size):
            t_ns = t0 + round(k * 1e9 / RATE)
            n = 4 if 1000 <= k < 1003 else 5          # head 3 missing in three messages
            pos = np.array([th_in[k], *heads[:, k]])[:n]
            msg = js(header=hdr_t(stamp=stamp_t(sec=t_ns // 10**9, nanosec=t_ns % 10**9),
                                  frame_id=''), name=names[:n], position=pos,
                     velocity=np.zeros(0), effort=np.zeros(0))
            w.write(conn, t_ns, bytes(store.serialize_cdr(msg, js.__msgtype__)))
    bench = _bench(tmp_path)
    data = yaml.safe_load(bench.read_text())
    data['joints'] = {'input': 'in', 'output': 'h0', 'output_heads': ['h0', 'h1', 'h2', 'h3']}
    bench.write_text(yaml.safe_dump(data))
    out = tmp_path / 'bag'
    assert main(['import', str(bag), '--bench', str(bench), '--out', str(out)]) == 0
    blocks = list(read_encoder_blocks(out))
    assert sum(b.theta_in_rad.size for b in blocks) == t.size
    assert blocks[0].out_head_ids == (0, 1, 2, 3)
    assert blocks[2].out_head_ids == (0, 1, 2)                  # samples 1000..1002
    np.testing.assert_allclose(blocks[0].theta_out_heads_rad, heads[:, :500], atol=1e-12)
