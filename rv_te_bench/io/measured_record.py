"""A whole measured record from a bag of the suite's messages, as arrays: what
``rv-te test PLAN --from BAG`` judges (no rclpy).

The bag is a live session (``rv-te launch``, ``rv-te test``, the JointState adapter's
output recorded) or an import (``rv-te import``): ``bench/info`` and ``bench/encoders``.
Every block's samples are concatenated in recording order with their times (header stamp
+ ``time_offset_s``); a skipped ``seq`` (a lost block, a drop-out of a DAQ file) or a time
that jumps by more than 1.5 sample periods or goes back is a *break*: nothing is read
across it.

The torque comes from the blocks' ``torque_out_nm`` or, with ``torque_topic``, from the
bench's own torque topic (``geometry_msgs/WrenchStamped``: the ``torque_axis`` component;
``std_msgs/Float64``; ``sensor_msgs/JointState``: the effort of ``torque_joint``), its
values linearly interpolated onto the encoder samples by time (header stamps, else log
times); a sample farther than ``max_gap_s`` from a torque reading gets none (NaN), and the
torque is then missing for the whole record (named). The torque is kept in the bench's
convention, ``torque_out_nm`` (positive resists positive rotation), times ``torque_scale``.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rv_te_bench.core.segments import MeasuredRecord
from rv_te_bench.errors import BagError
from rv_te_bench.io.bag_reader import read_encoder_blocks
from rv_te_bench.io.bench_channels import read_bench_channels
from rv_te_bench.io.bench_record import read_bench_info

__all__ = ['MeasuredRecord', 'TorqueTopic', 'read_measured_record']

#: Most samples read into memory (8 bytes x 4 channels each): 50 M = 1.6 GB.
MAX_SAMPLES = 50_000_000


@dataclass(frozen=True)
class TorqueTopic:
    """Where the torque comes from when not in the encoder blocks.

    Attributes:
        topic: The topic name (e.g. ``/bench/torque``).
        axis: ``WrenchStamped`` component: ``x``, ``y`` or ``z`` (the output axis).
        joint: ``JointState``: the joint whose effort is the torque.
        scale: Multiplies the values into ``torque_out_nm`` [N m per unit]; -1 for a
            sensor that reads the torque applied to the output.
        max_gap_s: A sample farther than this from a reading gets no torque [s].
    """

    topic: str
    axis: str = 'z'
    joint: str = ''
    scale: float = 1.0
    max_gap_s: float = 0.05


def read_measured_record(bag: str | Path, *, torque: TorqueTopic | None = None,
                         torque_in: TorqueTopic | None = None,
                         temperature: TorqueTopic | None = None,
                         topics_from: str | Path | None = None) -> MeasuredRecord:
    """Read ``bag`` whole into a :class:`MeasuredRecord`.

    The input torque and case temperature (issue 38) come from ``bench/channels``
    (BenchChannels, sample by sample) or, with ``torque_in`` / ``temperature``, from the
    bench's own topics (WrenchStamped / Float64 / JointState; ``sensor_msgs/Temperature``
    or Float64 in degC), interpolated onto the samples like the torque topic.
    ``topics_from``: the bag holding those topics when it is not ``bag`` (a JointState bag
    imported into ``bag``: the stamps of both are the bench's, so the times line up).

    Raises:
        BagError: Not a readable bag, no ``bench/info``, no encoder blocks, more than
            :data:`MAX_SAMPLES` samples, or the torque topic missing or of another type.
    """
    path = Path(bag)
    info = read_bench_info(path)
    if info is None:
        msg = (f'{path}: no bench/info in the bag (record the session with the bench or '
               'the joint_state_adapter, or import a DAQ file with its bench description)')
        raise BagError(msg)
    stamps, offsets, t_in, t_out, tq, seqs = [], [], [], [], [], []
    total = 0
    has_torque = True
    for b in read_encoder_blocks(path):
        n = len(b.theta_in_rad)
        if n == 0:
            continue
        total += n
        if total > MAX_SAMPLES:
            msg = (f'{path}: more than {MAX_SAMPLES} samples; judge a shorter record (cut '
                   'the bag or import the steps one by one)')
            raise BagError(msg)
        stamps.append(b.stamp_s)
        offsets.append(np.asarray(b.time_offset_s, dtype=np.float64))
        t_in.append(np.asarray(b.theta_in_rad, dtype=np.float64))
        t_out.append(np.asarray(b.theta_out_rad, dtype=np.float64))
        seqs.append(int(b.seq))
        if len(b.torque_out_nm) == n:
            tq.append(np.asarray(b.torque_out_nm, dtype=np.float64))
        else:
            has_torque = False
    if not seqs:
        msg = f'{path}: no encoder samples in the bag'
        raise BagError(msg)
    t0 = float(stamps[0])
    time = np.concatenate([(s - t0) + o for s, o in zip(stamps, offsets, strict=True)])
    sizes = np.array([o.size for o in offsets])
    firsts = np.r_[0, np.cumsum(sizes)[:-1]]
    seq_jump = np.flatnonzero(np.diff(np.asarray(seqs)) != 1) + 1
    period = 1.0 / info.sample_rate_hz
    dt_ = np.diff(time)
    time_jump = np.flatnonzero((dt_ > 1.5 * period) | (dt_ <= 0)) + 1
    breaks = np.unique(np.r_[firsts[seq_jump], time_jump]).astype(np.int64)
    torque_arr = np.concatenate(tq) if has_torque and tq else None
    torque_from = 'encoder blocks (torque_out_nm)' if torque_arr is not None else \
        'none: the encoder blocks carry no torque'
    src = Path(topics_from) if topics_from is not None else path
    if torque is not None:
        torque_arr, torque_from = _torque_from_topic(src, torque, t0 + time)
    if torque_arr is not None and not np.all(np.isfinite(torque_arr)):
        bad = int(np.count_nonzero(~np.isfinite(torque_arr)))
        torque_from += f' ({bad} samples without a torque value)'
    start = dt.datetime.fromtimestamp(t0, dt.UTC).isoformat(timespec='seconds')
    ch = read_bench_channels(path, seqs, [int(n) for n in sizes])
    t_in_nm, temp, what = ch.torque_in_nm, ch.temp_case_degc, [f'bench/channels: {ch.what}']
    if torque_in is not None:
        t_in_nm, line = _torque_from_topic(src, torque_in, t0 + time)
        what.append(f'input torque: {line}')
    if temperature is not None:
        temp, line = _torque_from_topic(src, temperature, t0 + time)
        what.append(f'case temperature: {line}')
    for arr in (time, breaks):
        arr.setflags(write=False)
    return MeasuredRecord(info=info, time_s=time, theta_in_rad=np.concatenate(t_in),
                          theta_out_rad=np.concatenate(t_out), torque_out_nm=torque_arr,
                          breaks=breaks, start_utc=start, source=str(path),
                          torque_from=torque_from, torque_in_nm=t_in_nm, temp_case_degc=temp,
                          channels_from='; '.join(what))


def _value(msg: Any, msgtype: str, spec: TorqueTopic) -> float | None:
    if msgtype == 'geometry_msgs/msg/WrenchStamped':
        return float(getattr(msg.wrench.torque, spec.axis))
    if msgtype in {'std_msgs/msg/Float64', 'std_msgs/msg/Float32'}:
        return float(msg.data)
    if msgtype == 'sensor_msgs/msg/Temperature':   # degC by its definition
        return float(msg.temperature)
    if msgtype == 'sensor_msgs/msg/JointState':
        names = list(msg.name)
        if spec.joint in names:
            k = names.index(spec.joint)
            return float(msg.effort[k]) if k < len(msg.effort) else None
        return None
    msg_ = (f'topic {spec.topic}: type {msgtype} not supported (WrenchStamped, '
            'Float64, JointState, Temperature)')
    raise BagError(msg_)


def _torque_from_topic(path: Path, spec: TorqueTopic,
                       sample_times_s: np.ndarray) -> tuple[np.ndarray, str]:
    """The torque topic's values interpolated onto the samples (absolute times [s])."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if spec.axis not in ('x', 'y', 'z'):
        msg = f'torque axis must be x, y or z, got {spec.axis!r}'
        raise BagError(msg)
    times: list[float] = []
    values: list[float] = []
    msgtype = ''
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            conns = [c for c in reader.connections if c.topic == spec.topic]
            if not conns:
                topics = sorted({c.topic for c in reader.connections})
                msg = f'{path}: no topic {spec.topic!r} (topics: {", ".join(topics)})'
                raise BagError(msg)
            for conn, log_ns, raw in reader.messages(connections=conns):
                msgtype = conn.msgtype
                m = reader.deserialize(raw, conn.msgtype)
                v = _value(m, conn.msgtype, spec)
                if v is None:
                    continue
                header = getattr(m, 'header', None)
                t = (header.stamp.sec + header.stamp.nanosec * 1e-9) if header is not None \
                    else log_ns * 1e-9
                times.append(t)
                values.append(v * spec.scale)
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags raises several types for a bad bag
        msg = f'{path}: cannot read the torque topic {spec.topic} ({type(exc).__name__}: {exc})'
        raise BagError(msg) from None
    short = msgtype.rsplit('/', 1)[-1]
    what = {'WrenchStamped': f'WrenchStamped.torque.{spec.axis}',
            'JointState': f'JointState effort of {spec.joint!r}'}.get(short, short)
    if len(times) < 2:
        msg = f'{path}: the torque topic {spec.topic} has {len(times)} usable reading(s)'
        raise BagError(msg)
    order = np.argsort(times, kind='stable')
    t_s = np.asarray(times, dtype=np.float64)[order]
    val = np.asarray(values, dtype=np.float64)[order]
    out = np.interp(sample_times_s, t_s, val)
    k = np.clip(np.searchsorted(t_s, sample_times_s), 1, t_s.size - 1)
    near = np.minimum(np.abs(sample_times_s - t_s[k - 1]), np.abs(t_s[k] - sample_times_s))
    out[near > spec.max_gap_s] = math.nan
    return out, f'topic {spec.topic} ({what}, x {spec.scale:g}, {t_s.size} readings)'
