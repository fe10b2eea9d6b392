"""The simulated bench as a ros2_control bench: forward command controllers in, joint_states
out (the bench node's ``ros2_control: true``).

What a ros2_control test bench offers a test sequencer, served by the simulator: the drive
(input) joint's velocity setpoint on ``drive_command_topic``, the load (output) joint's
effort setpoint on ``load_effort_command_topic`` and its position setpoint on
``load_position_command_topic``, each ``std_msgs/Float64MultiArray`` with one value, as
``forward_command_controller`` takes them (the last setpoint received on either load topic
selects that interface, as a controller switch does). Published: ``joint_states``
(``sensor_msgs/JointState``, one message per DAQ sample, header stamps on the DAQ clock):
positions as the encoders read them, velocities (input: the drive's; output: the input's
over the ratio while turning, else the output's own), efforts (input: NaN or the input
torque transducer; output: the torque applied to the output, in the joint's sense, as its
effort command). With ``losses: true`` the simulator has the reducer's losses, its torque
transducers and case sensor (issue 38): the input joint's effort is the input torque
transducer's reading and the case temperature goes on ``temperature_topic``
(``sensor_msgs/Temperature``, one reading per block, stamped at its last sample), as a real
bench serves them. Physics: :class:`sim.commanded.CommandedBench`.

A malformed setpoint (empty, not finite) is counted, logged (throttled) and ignored.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState, Temperature
from std_msgs.msg import Float64MultiArray

from rv_te_bench.nodes import qos
from rv_te_bench.nodes.common import DropCounter
from sim.commanded import BenchCommand, CommandedBench
from sim.program import ProgramSimulator
from sim.units import RAD_S_PER_RPM

if TYPE_CHECKING:
    from rclpy.node import Node

    from sim.bench import BenchBlock
    from sim.bench_info import BenchInfoData

__all__ = ['Ros2ControlBench']


class Ros2ControlBench:
    """Setpoint subscriptions and the simulator they drive, for the bench node.

    Args:
        node: The bench node (its parameters ``p``, publishers created by it).
        p: The bench's parameters (preset, overrides, te_mode, encoders, rate, block, seed,
            the command topics, ``joint_state_names``, ``max_input_speed_rpm``).
    """

    def __init__(self, node: Node, p: Any) -> None:
        """Build the simulator and subscribe to the command topics."""
        get = (lambda k: p[k]) if isinstance(p, dict) else (lambda k: getattr(p, k))
        self.node = node
        sim = ProgramSimulator(
            preset=get('preset'), overrides=tuple(get('overrides')), te_mode=get('te_mode'),
            encoder_in=get('encoder_in'), encoder_out=get('encoder_out'),
            sample_rate_hz=get('sample_rate_hz'), block_size=get('block_size'),
            seed=get('seed'), bench_id=get('bench_id'), losses=_losses(get('losses')))
        self.bench = CommandedBench(
            sim, max_input_speed_rad_s=get('max_input_speed_rpm') * RAD_S_PER_RPM)
        self.names = tuple(get('joint_state_names'))
        self.drops = DropCounter(node)
        self.setpoints_received = 0
        node.create_subscription(Float64MultiArray, get('drive_command_topic'),
                                 lambda m: self._on(m, 'drive'), qos.COMMAND_QOS)
        node.create_subscription(Float64MultiArray, get('load_effort_command_topic'),
                                 lambda m: self._on(m, 'effort'), qos.COMMAND_QOS)
        node.create_subscription(Float64MultiArray, get('load_position_command_topic'),
                                 lambda m: self._on(m, 'position'), qos.COMMAND_QOS)
        self._last_out = math.nan
        self.pub_temp = (node.create_publisher(Temperature, get('temperature_topic'),
                                               qos.ENCODER_QOS)
                         if sim.losses is not None else None)

    @property
    def info(self) -> BenchInfoData:
        """The simulated bench's record."""
        return self.bench.sim.info

    def _on(self, msg: Float64MultiArray, which: str) -> None:
        data = list(msg.data)
        if len(data) != 1 or not math.isfinite(data[0]):
            self.drops.drop('bad_setpoint', f'{which} setpoint must be one finite value, got '
                                            f'{data[:4]!r}')
            return
        c = self.bench.command
        v = float(data[0])
        if which == 'drive':
            c = BenchCommand(v, c.load_mode, c.load_value)
        else:
            c = BenchCommand(c.drive_velocity_rad_s, which, v)
        self.bench.set(c)
        self.setpoints_received += 1

    def next_block(self) -> BenchBlock:
        """The next block with the latest setpoints."""
        return self.bench.next_block()

    def publish(self, pub: Any, b: BenchBlock, wall_start_s: float) -> int:
        """One JointState per sample of block ``b``; returns the number published."""
        base_ns = round(wall_start_s * 1e9)
        stamps = (base_ns + np.round((b.t0_s + b.time_offset_s) * 1e9).astype(np.int64)).tolist()
        n = len(stamps)
        ratio = self.bench.gear_ratio
        w_in = self.bench.command.drive_velocity_rad_s if np.ptp(b.theta_in_true_rad) > 0 \
            else 0.0
        out = np.asarray(b.theta_out_true_rad)
        if w_in != 0.0:
            w_out = np.full(n, w_in / ratio)
        else:
            prev = out[0] if not math.isfinite(self._last_out) else self._last_out
            w_out = np.diff(np.r_[prev, out]) * self.info.sample_rate_hz
        self._last_out = float(out[-1])
        applied = (-np.asarray(b.torque_out_nm)).tolist() if len(b.torque_out_nm) \
            else [math.nan] * n
        t_in = (np.asarray(b.torque_in_nm).tolist() if b.torque_in_nm is not None
                else [math.nan] * n)
        name_in, name_out = self.names
        frame = self.info.bench_id
        if self.pub_temp is not None and b.temp_case_degc is not None and len(
                b.temp_case_degc):
            tm = Temperature(temperature=float(b.temp_case_degc[-1]), variance=0.0)
            tm.header.stamp = Time(sec=stamps[-1] // 1_000_000_000,
                                   nanosec=stamps[-1] % 1_000_000_000)
            tm.header.frame_id = frame
            self.pub_temp.publish(tm)
        for t_ns, p_in, p_out, wo, e_in, e_out in zip(
                stamps, b.theta_in_rad.tolist(), b.theta_out_rad.tolist(), w_out.tolist(),
                t_in, applied, strict=True):
            m = JointState()
            m.header.stamp = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
            m.header.frame_id = frame
            m.name = [name_in, name_out]
            m.position = [p_in, p_out]
            m.velocity = [w_in, wo]
            m.effort = [e_in, e_out]
            pub.publish(m)
        return n


def _losses(on: bool) -> Any:
    """The simulator's loss model (issue 38) when ``losses`` is set, else None."""
    if not on:
        return None
    from sim.loss_bench import LossConfig

    return LossConfig()
