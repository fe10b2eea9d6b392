"""Bags of a simulated 2K-V unit read through an eccentric scale by several heads, written
by rosbags' own writer and serialiser (issue 36): the unit's TE from the paper's equations
(:mod:`tests.wang2020_reference`), the heads' readings from the tests' exact-geometry scale
(:mod:`tests.scale_reference`). Used by the analysis tests and the help examples."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.io._legacy_msgs import added_field_defaults
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, rv_te_typestore
from tests import wang2020_reference as ref
from tests.scale_reference import Scale

if TYPE_CHECKING:
    from pathlib import Path

RATE = 2000.0
BLOCK = 500
SERIAL = 'RING-100-7'
UNIT = ref.Unit(e_p1=12e-6, e_p2=9e-6, e_g=6e-6, e_ot=4.1e-6, theta_p1=0.3, theta_p2=2.0,
                theta_g=-1.0, theta_ot=0.8)


def _scale(heads_deg: tuple[float, ...], index_deg: float = 0.0) -> Scale:
    return Scale(radius_m=0.05, eccentricity_m=5e-6, psi_rad=2.5,
                 index_rad=math.radians(index_deg),
                 heads_rad=tuple(math.radians(a) for a in heads_deg))


def write_heads_bag(path: Path, heads_deg: tuple[float, ...], *, revs: float = 2.05,
                    drop_head: tuple[int, int] | None = None, serial: str = SERIAL,
                    index_deg: float = 0.0, heads_record: str | None = None,
                    started_utc: str | None = None) -> Path:
    """A bag of the unit at 300 rpm read through an eccentric scale by ``heads_deg``;
    ``drop_head`` = (head, seq): that block lacks that head; ``index_deg``: the scale turned
    on its shaft (reversal), readings zeroed to the shaft angle; ``heads_record``: the text
    of a ``/te/encoder_heads`` message (what a session's TE node records); ``started_utc``:
    the session start in the bag's metadata (custom_data, as the recorder writes it)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = rv_te_typestore()
    types = store.types
    n = round(revs * ref.RATIO / 5.0 * RATE)          # 300 rpm = 5 input rev/s
    theta_in = np.arange(n) * (2 * math.pi * 5.0 / RATE)
    phi = theta_in / ref.RATIO
    heads = _scale(heads_deg, index_deg).readings(phi + ref.nlte_rad(phi, UNIT))

    def header(t_ns: int) -> object:
        return types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=t_ns // 10**9, nanosec=t_ns % 10**9),
            frame_id='b')

    extra = added_field_defaults(BENCH_INFO)
    extra.update({'encoder_out_head_angles_rad': np.radians(heads_deg) if len(heads_deg) > 1
                  else np.zeros(0), 'encoder_out_scale_serial': serial,
                  'encoder_out_scale_diameter_m': 0.1, 'encoder_out_scale_eccentricity_m': 5e-6,
                  'encoder_out_scale_index_rad': math.radians(index_deg)})
    t0 = 1_700_000_000 * 10**9
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        ci = w.add_connection('/bench/info', BENCH_INFO, typestore=store)
        ce = w.add_connection('/bench/encoders', ENCODER_BLOCK, typestore=store)
        if started_utc is not None:
            w.set_custom_data('started_utc', started_utc)
        if heads_record is not None:
            ch = w.add_connection('/te/encoder_heads', 'std_msgs/msg/String', typestore=store)
            w.write(ch, t0 + 1, bytes(store.serialize_cdr(
                types['std_msgs/msg/String'](data=heads_record), 'std_msgs/msg/String')))
        w.write(ci, t0, bytes(store.serialize_cdr(types[BENCH_INFO](
            header=header(t0), bench_id='b', preset='wang2020-2kv', reducer_type='2kv',
            gear_ratio=ref.RATIO, crank_per_input=ref.CRANK_ORDER / ref.RATIO,
            crank_rel_per_input=(ref.CRANK_ORDER - 1) / ref.RATIO,
            mesh_orders=np.array([1300.0]), mesh_labels=['stage-2 mesh'],
            encoder_in_model='ideal', encoder_out_model='renishaw-resm',
            encoder_in_resolution_rad=0.0, encoder_out_resolution_rad=0.0,
            sample_rate_hz=RATE, block_size=BLOCK, parameters_yaml='', **extra), BENCH_INFO)))
        for seq, s in enumerate(range(0, n, BLOCK)):
            sl = slice(s, min(s + BLOCK, n))
            ids = list(range(len(heads_deg))) if len(heads_deg) > 1 else []
            if drop_head is not None and seq == drop_head[1]:
                ids.remove(drop_head[0])
            t_ns = t0 + round(s / RATE * 1e9)
            w.write(ce, t_ns + 1, bytes(store.serialize_cdr(types[ENCODER_BLOCK](
                header=header(t_ns), seq=seq, sample_rate_hz=RATE,
                time_offset_s=np.arange(sl.stop - s) / RATE, theta_in_rad=theta_in[sl],
                theta_out_rad=heads[ids[0] if ids else 0, sl], torque_out_nm=np.zeros(0),
                in_head_ids=np.zeros(0, dtype=np.uint8), theta_in_heads_rad=np.zeros(0),
                out_head_ids=np.array(ids, dtype=np.uint8),
                theta_out_heads_rad=np.ascontiguousarray(heads[ids, sl]).ravel()),
                ENCODER_BLOCK)))
    return path
