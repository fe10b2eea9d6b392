"""A simulated session as DAQ files (CSV, NI TDMS, ASAM MDF4), written with the libraries
themselves (numpy, nptdms, asammdf), and as the original bag written by rosbags: the import
tests compare what ``rv-te import`` makes of the files with the original.
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

RATE_HZ = 2000.0
START = dt.datetime(2026, 11, 24, 9, 30, 0, tzinfo=dt.UTC)
START_NS = int(START.timestamp()) * 1_000_000_000
BENCH = {
    'bench_id': 'daq-bench', 'preset': 'wang2020-2kv', 'sample_rate_hz': RATE_HZ,
    'block_size': 500,
    'encoders': {'input': {'model': 'heidenhain-ron886'},
                 'output': {'model': 'heidenhain-ron886'}},
    'torque_sensor': {'present': True, 'scale_nm_per_unit': 1.0},
    'unit_under_test': {'serial': 'SN-DAQ-1', 'operator': 'pytest', 'temperature_c': 22.0},
    'joints': {'input': 'input_joint', 'output': 'output_joint'},
}


@dataclass(frozen=True)
class Session:
    """A simulated session (SI units)."""

    t_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_nm: np.ndarray


def simulate(duration_s: float = 33.0) -> Session:
    """2K-V of Wang 2020 at 300 rpm (15.8 s per output revolution), RON 886 encoders."""
    from sim.bench import BenchConfig, BenchSimulator
    from sim.drive import ConstantLoad, ConstantSpeed

    n_blocks = math.ceil(duration_s * RATE_HZ / 1000)
    sim = BenchSimulator(BenchConfig(preset='wang2020-2kv', drive=ConstantSpeed(300.0),
                                     load=ConstantLoad(30.0), sample_rate_hz=RATE_HZ,
                                     block_size=1000, seed=19))
    blocks = [sim.next_block() for _ in range(n_blocks)]
    return Session(t_s=np.concatenate([b.t0_s + b.time_offset_s for b in blocks]),
                   theta_in_rad=np.concatenate([b.theta_in_rad for b in blocks]),
                   theta_out_rad=np.concatenate([b.theta_out_rad for b in blocks]),
                   torque_nm=np.concatenate([b.torque_out_nm for b in blocks]))


def original_bag(path: Path, s: Session) -> Path:
    """The session as recorded live would be: a rosbags-written bag (tests.unit_bags)."""
    from tests.unit_bags import write_unit_bag

    return write_unit_bag(path, s.theta_in_rad, s.theta_out_rad, rate_hz=RATE_HZ, block=1000,
                          preset='wang2020-2kv', bench_id='daq-bench')


def bench_yaml(path: Path, **changes: object) -> Path:
    """The bench description of the session."""
    path.write_text(yaml.safe_dump({**BENCH, **changes}), encoding='utf-8')
    return path


def write_csv(path: Path, s: Session, *, unit: str = 'rad', fmt: str = '%.17g',
              single_turn: bool = False, delimiter: str = ',') -> Path:
    """CSV with a header: t_s, theta_in_<unit>, theta_out_<unit>, torque_nm."""
    k = {'rad': 1.0, 'deg': 180.0 / math.pi, 'arcsec': 648000.0 / math.pi}[unit]
    th_in, th_out = s.theta_in_rad, s.theta_out_rad
    if single_turn:
        th_in, th_out = np.mod(th_in, 2 * math.pi), np.mod(th_out, 2 * math.pi)
    names = ['t_s', f'theta_in_{unit}', f'theta_out_{unit}', 'torque_nm']
    np.savetxt(path, np.c_[s.t_s, th_in * k, th_out * k, s.torque_nm], fmt=fmt,
               delimiter=delimiter, header=delimiter.join(names), comments='')
    return path


def write_tdms(path: Path, s: Session, *, unit: str = 'rad') -> Path:
    """TDMS: group 'encoders', waveform channels theta_in / theta_out / torque (float64)."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    props = {'wf_increment': 1.0 / RATE_HZ, 'wf_start_offset': 0.0,
             'wf_start_time': np.datetime64(START.replace(tzinfo=None), 'us')}
    with TdmsWriter(str(path)) as w:
        w.write_segment([
            GroupObject('encoders'),
            ChannelObject('encoders', 'theta_in', s.theta_in_rad,
                          properties={**props, 'unit_string': unit}),
            ChannelObject('encoders', 'theta_out', s.theta_out_rad,
                          properties={**props, 'unit_string': unit}),
            ChannelObject('encoders', 'torque', s.torque_nm,
                          properties={**props, 'unit_string': 'Nm'}),
        ])
    return path


def write_mdf(path: Path, s: Session) -> Path:
    """MDF 4.10: one channel group, master time [s], theta_in / theta_out [rad], torque."""
    from asammdf import MDF, Signal

    mdf = MDF(version='4.10')
    mdf.header.start_time = START
    mdf.append([Signal(s.theta_in_rad, s.t_s, name='theta_in', unit='rad'),
                Signal(s.theta_out_rad, s.t_s, name='theta_out', unit='rad'),
                Signal(s.torque_nm, s.t_s, name='torque', unit='Nm')])
    mdf.save(str(path), overwrite=True)
    mdf.close()
    return path


def write_jointstate_bag(path: Path, s: Session, *, separate: bool = False,
                         storage: str = 'mcap', skip: tuple[int, ...] = (),
                         stamp_ns: dict[int, int] | None = None) -> Path:
    """A ros2_control-style bag of sensor_msgs/JointState on /joint_states, one message per
    sample (``separate``: one per joint and sample), written by rosbags; ``skip`` leaves
    out the output joint's message of those samples (separate only), ``stamp_ns`` replaces
    the stamps of some samples."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    js = store.types['sensor_msgs/msg/JointState']
    header = store.types['std_msgs/msg/Header']
    stamp = store.types['builtin_interfaces/msg/Time']
    plugin = StoragePlugin.SQLITE3 if storage == 'sqlite3' else StoragePlugin.MCAP
    names = (BENCH['joints']['input'], BENCH['joints']['output'])
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection('/joint_states', js.__msgtype__, typestore=store)
        for k in range(s.t_s.size):
            log_ns = START_NS + round(k * 1e9 / RATE_HZ) + 100_000   # arrival: 0.1 ms later
            t_ns = (stamp_ns or {}).get(k, log_ns - 100_000)
            hdr = header(stamp=stamp(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id='')
            pos = (float(s.theta_in_rad[k]), float(s.theta_out_rad[k]))
            eff = (0.0, float(s.torque_nm[k]))
            if separate:
                parts = [(0,)] + ([] if k in skip else [(1,)])
            else:
                parts = [(0, 1)]
            for idx in parts:
                msg = js(header=hdr, name=[names[i] for i in idx],
                         position=np.array([pos[i] for i in idx]), velocity=np.zeros(0),
                         effort=np.array([eff[i] for i in idx]))
                w.write(conn, log_ns, bytes(store.serialize_cdr(msg, js.__msgtype__)))
    return path


def example_inputs(folder: Path) -> None:
    """What ``rv-te import --help`` examples name: bench.yaml, run.csv, run.tdms, run.mf4."""
    s = simulate(duration_s=2.0)
    bench_yaml(folder / 'bench.yaml')
    write_csv(folder / 'run.csv', s)
    np.savetxt(folder / 'run_deg.csv', np.c_[s.t_s, s.theta_in_rad * 180 / math.pi,
                                             s.theta_out_rad * 180 / math.pi], fmt='%.17g',
               delimiter=',')
    write_tdms(folder / 'run.tdms', s)
    write_mdf(folder / 'run.mf4', s)
    write_jointstate_bag(folder / 'joint_states_bag', simulate(duration_s=0.5))
