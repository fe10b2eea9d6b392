"""Records of a plan run on the simulated bench, written the way other tools write them:
a session bag by rosbags' own writer, a CSV by pandas, a JointState bag by rosbags, a
bench description as YAML. Shared by the ``rv-te test --from`` tests."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from rv_te_bench.acceptance import (
    load_tolerance,
    parse_plan,
    parse_tolerance,
    run_plan_offline,
)
from rv_te_bench.io._legacy_msgs import added_field_defaults
from rv_te_bench.io.msgdefs import BENCH_CHANNELS, BENCH_INFO, ENCODER_BLOCK, rv_te_typestore
from sim.program import ProgramSimulator

if TYPE_CHECKING:
    from pathlib import Path

    from sim.bench import BenchBlock
    from sim.bench_info import BenchInfoData

T0_NS = 1_764_000_000_000_000_000
MODES = {'li2023-rv': 'dte', 'rv-80e-101': 'elastic', 'wang2020-2kv': 'nlte'}
#: A short plan of every kind (li2023-rv: ratio 121, rated 450 N m).
QUICK = {'plan': 'quick', 'steps': [
    {'kind': 'te', 'name': 'te', 'speed_rpm': 3000, 'load_nm': 200, 'settle_s': 0.2},
    {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': 450.0, 'dwell_s': 0.1},
    {'kind': 'sweep', 'name': 'sweep', 'speeds_rpm': [3000], 'loads_nm': [0, 450],
     'settle_s': 0.2}]}


@dataclass(frozen=True)
class Run:
    """A plan run on the simulated bench, offline: its live report and every block."""

    report: dict[str, Any]
    info: BenchInfoData
    blocks: list[BenchBlock]

    def arrays(self) -> dict[str, np.ndarray]:
        b = self.blocks
        out = {'t_s': np.concatenate([x.t0_s + x.time_offset_s for x in b]),
               'theta_in_rad': np.concatenate([x.theta_in_rad for x in b]),
               'theta_out_rad': np.concatenate([x.theta_out_rad for x in b]),
               'torque_nm': np.concatenate([x.torque_out_nm for x in b])}
        if b and b[0].torque_in_nm is not None:   # the loss channels (issue 38)
            out['torque_in_nm'] = np.concatenate([x.torque_in_nm for x in b])
            out['temp_case_degc'] = np.concatenate([x.temp_case_degc for x in b])
        return out


def run_plan(plan: dict, preset: str = 'li2023-rv', *, seed: int = 3,
             overrides: tuple[str, ...] = (), limits: dict | None = None,
             losses: bool = False) -> Run:
    from sim.loss_bench import LossConfig

    sim = ProgramSimulator(preset=preset, overrides=overrides, te_mode=MODES[preset],
                           sample_rate_hz=1000.0, block_size=100, seed=seed,
                           losses=LossConfig() if losses else None)
    p = parse_plan(plan)
    profile = parse_tolerance(limits) if limits else load_tolerance(preset)[0]
    blocks: list[BenchBlock] = []
    report = run_plan_offline(p, profile, serial='SN', operator='live',
                              sim=sim, on_block=blocks.append)
    return Run(report=report, info=sim.info, blocks=blocks)


def write_session_bag(path: Path, run: Run, *, torque: bool = True,
                      drop_seqs: tuple[int, ...] = (), channels: bool = False) -> Path:
    """bench/info + bench/encoders as a live session records them, by rosbags' writer;
    with ``channels`` bench/channels too (BenchChannels: input torque, case temperature)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = rv_te_typestore()
    types = store.types
    info = run.info

    def header(t_ns: int) -> object:
        return types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=t_ns // 10**9, nanosec=t_ns % 10**9),
            frame_id=info.bench_id)

    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        ci = w.add_connection('/bench/info', BENCH_INFO, typestore=store)
        ce = w.add_connection('/bench/encoders', ENCODER_BLOCK, typestore=store)
        cc = w.add_connection('/bench/channels', BENCH_CHANNELS, typestore=store) \
            if channels else None
        msg = types[BENCH_INFO](
            header=header(T0_NS), bench_id=info.bench_id, preset=info.preset,
            reducer_type=info.reducer_type, gear_ratio=info.gear_ratio,
            crank_per_input=info.crank_per_input, crank_rel_per_input=info.crank_rel_per_input,
            mesh_orders=np.asarray(info.mesh_orders, dtype=np.float64),
            mesh_labels=list(info.mesh_labels), encoder_in_model=info.encoder_in_model,
            encoder_out_model=info.encoder_out_model,
            encoder_in_resolution_rad=info.encoder_in_resolution_rad,
            encoder_out_resolution_rad=info.encoder_out_resolution_rad,
            sample_rate_hz=info.sample_rate_hz, block_size=info.block_size,
            parameters_yaml=info.parameters_yaml, **added_field_defaults(BENCH_INFO))
        w.write(ci, T0_NS, bytes(store.serialize_cdr(msg, BENCH_INFO)))
        for b in run.blocks:
            if b.seq in drop_seqs:
                continue
            t_ns = T0_NS + round(b.t0_s * 1e9)
            m = types[ENCODER_BLOCK](
                header=header(t_ns), seq=b.seq, sample_rate_hz=info.sample_rate_hz,
                time_offset_s=np.asarray(b.time_offset_s), theta_in_rad=np.asarray(b.theta_in_rad),
                theta_out_rad=np.asarray(b.theta_out_rad),
                torque_out_nm=np.asarray(b.torque_out_nm) if torque else np.zeros(0),
                **added_field_defaults(ENCODER_BLOCK))
            w.write(ce, t_ns + 1000, bytes(store.serialize_cdr(m, ENCODER_BLOCK)))
            if cc is not None:
                c = types[BENCH_CHANNELS](header=header(t_ns), seq=b.seq,
                                          torque_in_nm=np.asarray(b.torque_in_nm),
                                          temp_case_degc=np.asarray(b.temp_case_degc))
                w.write(cc, t_ns + 900, bytes(store.serialize_cdr(c, BENCH_CHANNELS)))
    return path


def write_csv(path: Path, run: Run, *, torque: bool = True, loss: bool = False) -> Path:
    """The record as a DAQ's CSV export, written by pandas (full float precision); with
    ``loss`` the input-torque and case-temperature columns too."""
    import pandas as pd

    a = run.arrays()
    cols = {'t_s': a['t_s'], 'theta_in_rad': a['theta_in_rad'],
            'theta_out_rad': a['theta_out_rad']}
    if torque:
        cols['torque_nm'] = a['torque_nm']
    if loss:
        cols['torque_in_nm'] = a['torque_in_nm']
        cols['case_temp_degc'] = a['temp_case_degc']
    pd.DataFrame(cols).to_csv(path, index=False, float_format='%.17g')
    return path


def bench_yaml(path: Path, run: Run, **extra: Any) -> Path:
    """The bench description of the simulated bench (preset, rate, encoders)."""
    info = run.info
    desc = {'bench_id': 'lab-bench-7', 'preset': info.preset,
            'sample_rate_hz': info.sample_rate_hz, 'block_size': info.block_size,
            'encoders': {'input': {'model': 'heidenhain-ron886'},
                         'output': {'model': 'heidenhain-ron886'}},
            'torque_sensor': {'present': True, 'model': 'HBM T40B', 'scale_nm_per_unit': 1.0},
            'joints': {'input': 'input_joint', 'output': 'output_joint'}, **extra}
    path.write_text(yaml.safe_dump(desc), encoding='utf-8')
    return path


def metric(report: dict, name: str) -> dict:
    return next(m for m in report['metrics'] if m['name'] == name)


def assert_same(live: dict, judged: dict, *, rel: float) -> None:
    """Same verdicts and every metric within ``rel`` of the live run's."""
    assert judged['verdict'] == live['verdict'], (judged['verdict'], judged['reason'])
    names = [m['name'] for m in live['metrics']]
    assert [m['name'] for m in judged['metrics']] == names
    for m in live['metrics']:
        j = metric(judged, m['name'])
        assert j['verdict'] == m['verdict'], (m['name'], j)
        assert math.isclose(j['value'], m['value'], rel_tol=rel), (m['name'], j['value'],
                                                                   m['value'])
    sweep = [r['te_pp_rad'] for s in live['steps'] if s['kind'] == 'sweep' for r in s['rows']]
    sweep_j = [r['te_pp_rad'] for s in judged['steps'] if s['kind'] == 'sweep'
               for r in s['rows']]
    assert len(sweep) == len(sweep_j)
    for a, b in zip(sweep, sweep_j, strict=True):
        assert math.isclose(a, b, rel_tol=rel), (a, b)
