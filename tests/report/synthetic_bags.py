"""Synthetic bags with a known TE for the report tests (shared builders).

The bags are written with the project's own ``BagWriter`` and CDR from the rosbags
typestore (no ROS). The TE is a known sum of cosines of the output angle
phi = theta_in / i, so statistics and spectrum lines have closed-form expectations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.io._legacy_msgs import added_field_defaults
from rv_te_bench.io.bag_writer import BagWriter
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, rv_te_typestore

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable
    from pathlib import Path

ENCODER_TOPIC = '/bench/encoders'
INFO_TOPIC = '/bench/info'

#: Wang 2020 2K-V kinematics (DESIGN.md s.4): i = 79, f_w = 25 f_out, mesh 936 / 1300.
RATIO = 79.0
CRANK_PER_OUTPUT = 25.0
MESH_ORDERS = (936.0, 1300.0)
MESH_LABELS = ('mesh 36 f_w_rel', 'mesh 52 f_w')


@dataclass(frozen=True)
class Harmonic:
    """One TE component a*cos(output_order*phi + phase_rad) [rad]."""

    output_order: float
    amplitude_rad: float
    phase_rad: float


@dataclass(frozen=True)
class Synth:
    """What was written: every sample, for independent expectations."""

    t_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    te_rad: np.ndarray


def te_of(phi_rad: np.ndarray, mean_rad: float, harmonics: Iterable[Harmonic]) -> np.ndarray:
    """Closed-form TE of the synthetic reducer at output angles ``phi_rad``."""
    te = np.full_like(phi_rad, mean_rad, dtype=np.float64)
    for h in harmonics:
        te += h.amplitude_rad * np.cos(h.output_order * phi_rad + h.phase_rad)
    return te


def constant_speed(output_hz: float) -> Callable[[np.ndarray], np.ndarray]:
    """theta_in(t) for a constant output speed ``output_hz`` [rev/s]."""
    return lambda t: 2.0 * math.pi * output_hz * RATIO * t


def varying_speed(output_hz: float, depth: float,
                  mod_hz: float) -> Callable[[np.ndarray], np.ndarray]:
    """theta_in(t) for an input speed C (1 + depth sin(2 pi mod_hz t)) (Hu 2020 style)."""
    w0 = 2.0 * math.pi * output_hz * RATIO
    wm = 2.0 * math.pi * mod_hz
    return lambda t: w0 * (t + depth * (1.0 - np.cos(wm * t)) / wm)


def write_bag(
    path: Path,
    *,
    harmonics: Iterable[Harmonic],
    mean_rad: float = 0.0,
    theta_in_fn: Callable[[np.ndarray], np.ndarray] | None = None,
    duration_s: float = 6.0,
    sample_rate_hz: float = 1000.0,
    block_size: int = 100,
    with_info: bool = True,
    with_blocks: bool = True,
    preset: str = 'synthetic-2kv',
    reducer_type: str = '2kv',
    drop_seqs: Iterable[int] = (),
    encoder_topic: str = ENCODER_TOPIC,
    chunk_size_bytes: int = 16_384,
) -> Synth:
    """Write a rosbag2/MCAP bag with EncoderBlocks of a known TE (and BenchInfo).

    Args:
        path: Bag folder to create.
        harmonics: TE components (orders of the output angle phi = theta_in / i).
        mean_rad: Constant TE offset [rad].
        theta_in_fn: Input angle as a function of time [rad] (default: a constant speed of
            0.5 output revolutions per second).
        duration_s: Length of the recording [s].
        sample_rate_hz: DAQ rate [Hz].
        block_size: Samples per EncoderBlock.
        with_info: Write a BenchInfo message.
        with_blocks: Write the encoder topic at all.
        preset: BenchInfo preset name.
        reducer_type: BenchInfo reducer type.
        drop_seqs: Block sequence numbers to leave out (gaps).
        encoder_topic: Topic of the EncoderBlocks.
        chunk_size_bytes: MCAP chunk size (small: several chunks, so truncation leaves some).

    Returns:
        Every sample written (dropped blocks excluded).
    """
    harmonics = tuple(harmonics)
    store = rv_te_typestore()
    types = store.types
    n = round(duration_s * sample_rate_hz)
    t = np.arange(n, dtype=np.float64) / sample_rate_hz
    theta_in = (theta_in_fn or constant_speed(0.5))(t)
    te = te_of(theta_in / RATIO, mean_rad, harmonics)
    theta_out = theta_in / RATIO + te
    drop = set(drop_seqs)
    keep = np.ones(n, dtype=bool)
    t0_ns = 1_700_000_000_000_000_000
    time_cls = types['builtin_interfaces/msg/Time']
    header_cls = types['std_msgs/msg/Header']

    def header(stamp_ns: int) -> object:
        return header_cls(stamp=time_cls(sec=stamp_ns // 1_000_000_000,
                                         nanosec=stamp_ns % 1_000_000_000),
                          frame_id='synthetic-bench')

    with BagWriter(path, compression='zstd', chunk_size_bytes=chunk_size_bytes) as writer:
        if with_info:
            writer.add_topic(INFO_TOPIC, BENCH_INFO)
            info = types[BENCH_INFO](
                header=header(t0_ns), bench_id='synthetic-bench', preset=preset,
                reducer_type=reducer_type, gear_ratio=RATIO,
                crank_per_input=-CRANK_PER_OUTPUT / RATIO,
                crank_rel_per_input=-(CRANK_PER_OUTPUT + 1.0) / RATIO,
                mesh_orders=np.array(MESH_ORDERS), mesh_labels=list(MESH_LABELS),
                encoder_in_model='ideal', encoder_out_model='ideal',
                encoder_in_resolution_rad=0.0, encoder_out_resolution_rad=0.0,
                sample_rate_hz=sample_rate_hz, block_size=block_size,
                # exact angles: the encoders' zeros are the reducer's (core.te_zero)
                parameters_yaml='synthetic: true\nencoder_zero: {input_rad: 0.0, '
                                'output_rad: 0.0, source: synthetic bench}\n',
                **added_field_defaults(BENCH_INFO))
            writer.write(INFO_TOPIC, t0_ns, store.serialize_cdr(info, BENCH_INFO))
        if not with_blocks:
            return Synth(t_s=t[:0], theta_in_rad=theta_in[:0], theta_out_rad=theta_out[:0],
                         te_rad=te[:0])
        writer.add_topic(encoder_topic, ENCODER_BLOCK)
        for seq, start in enumerate(range(0, n, block_size)):
            sl = slice(start, min(start + block_size, n))
            if seq in drop:
                keep[sl] = False
                continue
            stamp_ns = t0_ns + round(t[start] * 1e9)
            msg = types[ENCODER_BLOCK](
                header=header(stamp_ns), seq=seq, sample_rate_hz=sample_rate_hz,
                time_offset_s=t[sl] - t[start], theta_in_rad=theta_in[sl],
                theta_out_rad=theta_out[sl], torque_out_nm=np.zeros(0),
                **added_field_defaults(ENCODER_BLOCK))
            writer.write(encoder_topic, stamp_ns, store.serialize_cdr(msg, ENCODER_BLOCK))
    return Synth(t_s=t[keep], theta_in_rad=theta_in[keep], theta_out_rad=theta_out[keep],
                 te_rad=te[keep])
