"""Bags of simulated 2K-V units written by rosbags (not by our BagWriter), and damaging them.

The encoder data comes from :mod:`tests.wang2020_reference` (the paper's equations written
out in the tests), the bag from rosbags' own rosbag2/MCAP writer (1 MiB chunks, no
compression), the messages serialised by the rosbags typestore: nothing of the project's
simulation or writing code is involved.

The messages are of the definitions before issue 36 (no read-head fields,
:mod:`rv_te_bench.io._legacy_msgs`): every test on these bags also checks that older bags
stay readable.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.io._legacy_msgs import legacy_typestore
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK
from tests import wang2020_reference as ref

if TYPE_CHECKING:
    from pathlib import Path

ENCODER_TOPIC = '/bench/encoders'
INFO_TOPIC = '/bench/info'
T0_NS = 1_700_000_000_000_000_000


def write_unit_bag(path: Path, theta_in: np.ndarray, theta_out: np.ndarray, *,
                   rate_hz: float, block: int = 100, info: bool = True,
                   preset: str = 'wang2020-2kv', bench_id: str = 'unit-bench',
                   parameters_yaml: str = '', custom_data: dict[str, str] | None = None,
                   first_seq: int = 0, storage: str = 'mcap') -> Path:
    """A rosbag2/MCAP bag (rosbags writer) with a BenchInfo and the encoder samples in blocks;
    ``custom_data`` goes to metadata.yaml (session metadata, e.g. a unit serial);
    ``first_seq`` > 0 leaves out the blocks before it (a recorder that started late);
    ``storage='sqlite3'`` writes rosbag2's sqlite3 storage instead of MCAP."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = legacy_typestore()        # bags recorded before the head fields existed
    types = store.types

    def header(t_ns: int) -> object:
        return types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=t_ns // 10**9, nanosec=t_ns % 10**9),
            frame_id=bench_id)

    plugin = StoragePlugin.SQLITE3 if storage == 'sqlite3' else StoragePlugin.MCAP
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        for key, value in (custom_data or {}).items():
            writer.set_custom_data(key, value)
        # both channels first, so that they precede every message in the first chunk
        conn = writer.add_connection(INFO_TOPIC, BENCH_INFO, typestore=store) if info else None
        enc = writer.add_connection(ENCODER_TOPIC, ENCODER_BLOCK, typestore=store)
        if conn is not None:
            msg = types[BENCH_INFO](
                header=header(T0_NS), bench_id=bench_id, preset=preset, reducer_type='2kv',
                gear_ratio=ref.RATIO, crank_per_input=ref.CRANK_ORDER / ref.RATIO,
                crank_rel_per_input=(ref.CRANK_ORDER - 1.0) / ref.RATIO,
                mesh_orders=np.array([52.0 * abs(ref.CRANK_ORDER)]),
                mesh_labels=['stage-2 mesh (52 f_w)'],
                encoder_in_model='reference', encoder_out_model='reference',
                encoder_in_resolution_rad=0.0, encoder_out_resolution_rad=0.0,
                sample_rate_hz=rate_hz, block_size=block, parameters_yaml=parameters_yaml)
            writer.write(conn, T0_NS, bytes(store.serialize_cdr(msg, BENCH_INFO)))
        for seq, s in enumerate(range(0, theta_in.size, block)):
            n = min(block, theta_in.size - s)
            t_ns = T0_NS + round(s / rate_hz * 1e9)
            msg = types[ENCODER_BLOCK](
                header=header(t_ns), seq=first_seq + seq, sample_rate_hz=rate_hz,
                time_offset_s=np.arange(n) / rate_hz, theta_in_rad=theta_in[s:s + n],
                theta_out_rad=theta_out[s:s + n], torque_out_nm=np.zeros(0))
            writer.write(enc, t_ns + 1, bytes(store.serialize_cdr(msg, ENCODER_BLOCK)))
    return path


def unit_bag(path: Path, unit: ref.Unit, rng: np.random.Generator, *, rate_hz: float = 10_000.0,
             duration_s: float = 20.5, noise_arcsec: float = 0.2,
             theta_in_start_rad: float | None = None, **kwargs: object) -> Path:
    """A bench run of ``unit`` at 300 rpm (15.8 s per output revolution) as a bag."""
    n = round(duration_s * rate_hz)
    revs = duration_s * 300.0 / 60.0 / ref.RATIO
    start = rng.uniform(0.0, 2 * math.pi * ref.RATIO) if theta_in_start_rad is None \
        else theta_in_start_rad
    th_in, th_out = ref.encoder_record(unit, rng, n_samples=n, revolutions=revs,
                                       noise_arcsec=noise_arcsec, theta_in_start_rad=start,
                                       offset_rad=rng.uniform(-1.0, 1.0))
    return write_unit_bag(path, th_in, th_out, rate_hz=rate_hz, **kwargs)  # type: ignore[arg-type]


def mcap_file(bag: Path) -> Path:
    """The one .mcap file of a bag folder."""
    (file,) = sorted(bag.glob('*.mcap'))
    return file


def damage_bench_info(bag: Path) -> None:
    """Break the first message record of the first MCAP chunk: the BenchInfo.

    rosbags writes the chunk uncompressed and without CRC; the message record gets an
    impossible length, so a reader cannot walk the rest of that chunk (the BenchInfo and the
    first encoder blocks are lost; the channels before it and the later chunks are sound).
    """
    file = mcap_file(bag)
    data = bytearray(file.read_bytes())

    def u64(at: int) -> int:
        return int.from_bytes(data[at:at + 8], 'little')

    pos = 8                                  # after the magic: walk the records to the chunk
    while data[pos] != 0x06:
        pos += 9 + u64(pos + 1)
    at = pos + 9 + 8 + 8 + 8 + 4             # start/end time, uncompressed size, crc
    assert int.from_bytes(data[at:at + 4], 'little') == 0, 'expected an uncompressed chunk'
    at += 4 + 8                              # empty compression string, records length
    while data[at] != 0x05:
        at += 9 + u64(at + 1)
    data[at + 1:at + 9] = b'\xff' * 8
    file.write_bytes(bytes(data))
