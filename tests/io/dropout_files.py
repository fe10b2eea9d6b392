"""A bench record with drop-outs, written the way real DAQ software writes it: pandas (CSV),
nptdms (NI TDMS, a timestamp channel), asammdf (MDF4, master time) and rosbags (a
ros2_control JointState bag). The truth is closed-form here, not from ``sim``.

The reducer: ratio I = 79, crank order C = 25 per output revolution (the Wang 2020 2K-V's
numbers, stated in the bench description's ``reducer`` block, no preset). The input turns
at 1500 rpm and is read by a multi-turn counter (an arbitrary start angle); the output is
read by a single-turn absolute encoder (radians in [0, 2 pi)). With phi = theta_in / I the
output angle is ``phi + TE(phi)`` with

    TE(phi) = sum_k a_k sin(o_k phi + p_k)

at output orders o_k = 1 (output wheel), C (1 f_w) and 2C (2 f_w). Samples inside the
drop-outs are left out of the file (rows missing, the time column jumps), or written as
NaN (pandas writes an empty cell) where a case says so.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import yaml

if TYPE_CHECKING:
    from pathlib import Path

RATIO = 79.0
CRANK = 25.0
RPM_IN = 1500.0
ARCMIN = math.pi / 10800.0
#: (output order, amplitude [rad], phase of the sine [rad])
LINES = ((1.0, 0.20 * ARCMIN, 0.3), (CRANK, 0.30 * ARCMIN, 0.7), (2 * CRANK, 0.12 * ARCMIN, -1.1))
START = dt.datetime(2026, 11, 24, 9, 30, 0, tzinfo=dt.UTC)
START_NS = int(START.timestamp()) * 1_000_000_000
THETA_IN_0 = 1234.5   # the input counter's reading at t = 0 [rad]
#: (start [s], length [s]) of each drop-out: 25 ms to 10 s, two or more output revolutions
#: (3.16 s each) of good data between them
DROPOUTS = ((4.0, 0.025), (12.0, 0.040), (20.0, 0.3), (28.0, 1.0), (36.0, 10.0))
DURATION_S = 60.0


def te_rad(phi: np.ndarray) -> np.ndarray:
    """The true TE at output reference angles ``phi`` [rad]."""
    return sum(a * np.sin(o * phi + p) for o, a, p in LINES)   # type: ignore[return-value]


def true_pp_rad() -> float:
    """Peak-to-peak of TE over an output revolution, on a dense grid (2^22 points)."""
    phi = np.linspace(0.0, 2 * math.pi, 1 << 22, endpoint=False)
    te = te_rad(phi)
    return float(te.max() - te.min())


def true_lines() -> dict[float, tuple[float, float]]:
    """Output order -> (amplitude [rad], phase [rad] as a cosine: a cos(o phi + phase))."""
    return {o: (a, math.remainder(p - math.pi / 2, 2 * math.pi)) for o, a, p in LINES}


@dataclass(frozen=True)
class Record:
    """The samples a DAQ kept (SI), with the index of each in the full sample grid."""

    k: np.ndarray              # sample numbers on the DAQ clock (int64)
    t_s: np.ndarray
    theta_in_rad: np.ndarray   # multi-turn
    theta_out_rad: np.ndarray  # single-turn, [0, 2 pi)
    rate_hz: float


def record(rate_hz: float = 2000.0, dropouts: tuple[tuple[float, float], ...] = DROPOUTS,
           duration_s: float = DURATION_S, rpm: float = RPM_IN) -> Record:
    """The record with the samples of ``dropouts`` left out."""
    n = round(duration_s * rate_hz)
    keep = np.ones(n, dtype=bool)
    for t0, length in dropouts:
        a = round(t0 * rate_hz)
        keep[a:a + round(length * rate_hz)] = False
    k = np.flatnonzero(keep).astype(np.int64)
    t = k / rate_hz
    th_in = THETA_IN_0 + 2 * math.pi * rpm / 60.0 * t
    phi = th_in / RATIO
    th_out = np.mod(phi + te_rad(phi), 2 * math.pi)
    return Record(k, t, th_in, th_out, rate_hz)


def bench_yaml(path: Path, rate_hz: float = 2000.0) -> Path:
    """A bench description with the reducer's kinematics (no preset)."""
    path.write_text(yaml.safe_dump({
        'bench_id': 'dropout-bench', 'sample_rate_hz': rate_hz, 'block_size': 500,
        'reducer': {'kind': 'other', 'gear_ratio': RATIO, 'crank_per_output': CRANK},
        'encoders': {'input': {'model': 'heidenhain-ron886'},
                     'output': {'model': 'renishaw-resolute'}},
        'joints': {'input': 'input_joint', 'output': 'output_joint'},
        'unit_under_test': {'serial': 'SN-DROP-1', 'operator': 'pytest'},
    }), encoding='utf-8')
    return path


def write_pandas_csv(path: Path, r: Record, *, time: str = 't_s',
                     nan_rows: tuple[tuple[float, float], ...] = ()) -> Path:
    """pandas ``DataFrame.to_csv`` (no index). ``time``: ``t_s`` (seconds), ``t_ms``
    (milliseconds), ``t_ns`` (int64 epoch nanoseconds); ``nan_rows``: (start, length)
    spans written as NaN rows (empty cells) instead of being left out."""
    import pandas as pd

    t, th_in, th_out = r.t_s.copy(), r.theta_in_rad.copy(), r.theta_out_rad.copy()
    for t0, length in nan_rows:
        sel = (t >= t0 - 0.25 / r.rate_hz) & (t < t0 + length - 0.25 / r.rate_hz)
        th_in[sel] = np.nan
        th_out[sel] = np.nan
    if time == 't_s':
        col = t
    elif time == 't_ms':
        col = t * 1e3
    elif time == 't_ns':
        col = START_NS + r.k * round(1e9 / r.rate_hz)
    else:
        raise ValueError(time)
    pd.DataFrame({time: col, 'theta_in_rad': th_in, 'theta_out_rad': th_out}).to_csv(
        path, index=False)
    return path


def write_nptdms(path: Path, r: Record) -> Path:
    """TDMS: group 'daq', a TimeStamp channel 'time' (absolute) beside the angles."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    stamps = np.datetime64(START.replace(tzinfo=None), 'ns') \
        + (r.k * round(1e9 / r.rate_hz)).astype('timedelta64[ns]')
    with TdmsWriter(str(path)) as w:
        w.write_segment([
            GroupObject('daq'),
            ChannelObject('daq', 'time', stamps),
            ChannelObject('daq', 'theta_in', r.theta_in_rad, properties={'unit_string': 'rad'}),
            ChannelObject('daq', 'theta_out', r.theta_out_rad,
                          properties={'unit_string': 'rad'}),
        ])
    return path


def write_asammdf(path: Path, r: Record) -> Path:
    """MDF 4.10: one channel group, master time [s] with the drop-outs in it."""
    from asammdf import MDF, Signal

    mdf = MDF(version='4.10')
    mdf.header.start_time = START
    mdf.append([Signal(r.theta_in_rad, r.t_s, name='theta_in', unit='rad'),
                Signal(r.theta_out_rad, r.t_s, name='theta_out', unit='rad')])
    mdf.save(str(path), overwrite=True)
    mdf.close()
    return path


def write_jointstate_bag(path: Path, r: Record) -> Path:
    """A ros2_control bag (rosbags): one sensor_msgs/JointState per sample on /joint_states,
    header stamps on the DAQ clock, logged 0.1 ms later."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    js = store.types['sensor_msgs/msg/JointState']
    header = store.types['std_msgs/msg/Header']
    stamp = store.types['builtin_interfaces/msg/Time']
    period_ns = round(1e9 / r.rate_hz)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection('/joint_states', js.__msgtype__, typestore=store)
        for k, a, b in zip(r.k.tolist(), r.theta_in_rad.tolist(), r.theta_out_rad.tolist(),
                           strict=True):
            t_ns = START_NS + k * period_ns
            msg = js(header=header(stamp=stamp(sec=t_ns // 10**9, nanosec=t_ns % 10**9),
                                   frame_id=''),
                     name=['input_joint', 'output_joint'], position=np.array([a, b]),
                     velocity=np.zeros(0), effort=np.zeros(0))
            w.write(conn, t_ns + 100_000, bytes(store.serialize_cdr(msg, js.__msgtype__)))
    return path
