"""A "real bench" stand-in: a plain rclpy node written here, with the interfaces a
ros2_control reducer test bench has and closed-form physics of its own (nothing of sim/).

Interfaces: ``drive_velocity_controller/commands`` (the input joint's velocity [rad/s]),
``load_effort_controller/commands`` (the torque the load motor applies to the output [N m]),
both ``std_msgs/Float64MultiArray`` as ``forward_command_controller`` takes them;
``joint_states`` (one ``sensor_msgs/JointState`` per sample, in real time, header stamps
from the wall clock; efforts: input NaN, output the applied torque as its sensor reads it).

Physics (ideal encoders, SI):

* turning (velocity != 0): theta_in advances at the setpoint; the output follows the
  ratio with a transmission error ``te_amp_rad * sin(theta_in / ratio)`` (p-p 2 x amp over
  every output revolution);
* input stopped: the output's torsion angle under the applied torque T follows a linear
  flank of stiffness ``k_nm_per_rad`` beyond a free play ``b_rad`` with Coulomb friction
  ``tf_nm``: phi = min(max(phi, up(T - tf)), down(T + tf)), up/down the flank positions.
  Truth: backlash b + 2 tf / k, lost motion b + 2 t / k (t > tf), rigidity k.

Faults for the safety tests: ``overshoot`` (the loader's step response overshoots by that
fraction of each setpoint change, decaying in 10 ms: a limit is exceeded at the largest
step), :meth:`go_silent` (joint_states stop: a stale stream).
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

from builtin_interfaces.msg import Time
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from rv_te_bench.nodes import qos

RATIO = 121.0          # li2023-rv (the bench description names that preset)


class StandInBench(Node):
    """See the module docstring."""

    def __init__(self, *, context: Any, fs_hz: float = 500.0, te_amp_rad: float = 6e-5,
                 b_rad: float = 1.5e-4, k_nm_per_rad: float = 5.0e5, tf_nm: float = 5.0,
                 overshoot: float = 0.0) -> None:
        super().__init__('real_bench_stand_in', context=context)
        self.fs = fs_hz
        self.te_amp, self.b, self.k, self.tf = te_amp_rad, b_rad, k_nm_per_rad, tf_nm
        self.overshoot = overshoot
        self.step_from = 0.0      # the effort before the last change, and when it changed
        self.step_at = -1.0
        self.lock = threading.Lock()
        self.velocity = 0.0
        self.effort = 0.0
        self.theta_in = 0.0
        self.phi = 0.0
        self.silent = False
        self.setpoints = 0
        self.published = 0
        self.pub = self.create_publisher(JointState, 'joint_states', qos.JOINT_STATE_QOS)
        self.create_subscription(Float64MultiArray, 'drive_velocity_controller/commands',
                                 lambda m: self._set('velocity', m), qos.COMMAND_QOS)
        self.create_subscription(Float64MultiArray, 'load_effort_controller/commands',
                                 lambda m: self._set('effort', m), qos.COMMAND_QOS)
        self.t0 = time.time()
        self.k_next = 0
        self.create_timer(0.02, self._tick)

    def _set(self, what: str, msg: Float64MultiArray) -> None:
        with self.lock:
            value = float(msg.data[0])
            if what == 'effort' and value != self.effort:
                self.step_from, self.step_at = self.effort, self.k_next / self.fs
            setattr(self, what, value)
            self.setpoints += 1

    def go_silent(self) -> None:
        """Stop publishing joint_states (a dead hardware interface)."""
        self.silent = True

    # flank positions of the locked output
    def _up(self, x: float) -> float:
        return (self.b / 2 if x > 0 else -self.b / 2) + x / self.k

    def _down(self, x: float) -> float:
        return (self.b / 2 if x >= 0 else -self.b / 2) + x / self.k

    def _tick(self) -> None:
        due = int((time.time() - self.t0) * self.fs)
        while self.k_next < due:
            k = self.k_next
            self.k_next += 1
            with self.lock:
                w, eff = self.velocity, self.effort
                since = k / self.fs - self.step_at
            applied = eff + self.overshoot * (eff - self.step_from) * math.exp(-since / 0.01) \
                if self.step_at >= 0 and since >= 0 else eff
            if w != 0.0:
                self.theta_in += w / self.fs
                out = self.theta_in / RATIO + self.te_amp * math.sin(self.theta_in / RATIO)
                w_out = w / RATIO
            else:
                self.phi = min(max(self.phi, self._up(applied - self.tf)),
                               self._down(applied + self.tf))
                out = self.theta_in / RATIO + self.phi
                w_out = 0.0
            if self.silent:
                continue
            t_ns = round((self.t0 + k / self.fs) * 1e9)
            m = JointState()
            m.header.stamp = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
            m.header.frame_id = 'stand-in'
            m.name = ['input_joint', 'output_joint']
            m.position = [self.theta_in, out]
            m.velocity = [w, w_out]
            m.effort = [math.nan, applied]
            self.pub.publish(m)
            self.published += 1

    # the truth of the closed form
    def truth(self, rated_nm: float) -> dict[str, float]:
        t = 0.03 * rated_nm
        return {'te_pp_ccw_rad': 2 * self.te_amp, 'te_pp_cw_rad': 2 * self.te_amp,
                'backlash_rad': self.b + 2 * self.tf / self.k,
                'lost_motion_rad': self.b + 2 * t / self.k,
                'torsional_rigidity_K_nm_per_rad': self.k}


DESCRIPTION = """\
bench_id: stand-in
preset: li2023-rv
sample_rate_hz: 500.0
block_size: 10
encoders:
  input: {model: ideal}
  output: {model: ideal}
torque_sensor: {present: true, model: stand-in, scale_nm_per_unit: -1.0}
joints: {input: input_joint, output: output_joint}
limits: {max_input_speed_rpm: 4000, max_output_torque_nm: 520}
"""
