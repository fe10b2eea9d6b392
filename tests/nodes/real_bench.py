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

Losses (``losses=StandInLosses(...)``, issue 38), closed form: turning at input speed w
against a load resisting T_out (the applied effort's opposite), the input torque is
T_in = sign(w) (T_out / (i eta) + T0(w)), T0(w) = c0 + c1 |w| (the no-load drag), plus
Gaussian noise; it is the input joint's effort (NaN without losses). The case is one
first-order lag: dT/dt = (T_amb + R P_loss - T) / tau, P_loss = T_in w - T_out w / i, on
``case_temperature`` (``sensor_msgs/Temperature``, 10 Hz, stamped on the same clock).
Measured efficiency at a point: eta_m = T_out / (T_out / eta + i T0(w)).

Faults for the safety tests: ``overshoot`` (the loader's step response overshoots by that
fraction of each setpoint change, decaying in 10 ms: a limit is exceeded at the largest
step), :meth:`go_silent` (joint_states stop: a stale stream).
"""

from __future__ import annotations

import math
import random
import threading
import time
from dataclasses import dataclass
from typing import Any

import rclpy
import yaml
from builtin_interfaces.msg import Time
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rv_te_msgs.action import RunTestPlan
from sensor_msgs.msg import JointState, Temperature
from std_msgs.msg import Float64MultiArray

from rv_te_bench.cli.ack import acknowledge
from rv_te_bench.nodes import qos
from rv_te_bench.nodes.goal_client import TrackedGoal
from tests.nodes.rosutil import spin_until

RATIO = 121.0          # li2023-rv (the bench description names that preset)


@dataclass(frozen=True)
class StandInLosses:
    """The stand-in's loss model (module docstring), SI."""

    eta: float = 0.85              # mesh efficiency
    c0_nm: float = 0.30            # no-load drag at standstill speed [N m]
    c1_nm_s: float = 1.0e-3        # no-load drag per rad/s of input [N m s]
    noise_nm: float = 0.002        # input torque noise (1 sigma) [N m]
    t_amb_degc: float = 23.0
    r_k_per_w: float = 0.08        # steady case rise per watt lost [K/W]
    tau_s: float = 3.0             # case time constant [s]
    temp_rate_hz: float = 10.0     # Temperature readings per second

    def drag_nm(self, w_rad_s: float) -> float:
        """T0(w): the no-load input torque [N m]."""
        return self.c0_nm + self.c1_nm_s * abs(w_rad_s)

    def torque_in_nm(self, w_rad_s: float, t_out_nm: float) -> float:
        """T_in at input speed w against T_out resisting (noise-free)."""
        if w_rad_s == 0.0:
            return 0.0
        return math.copysign(max(t_out_nm, 0.0) / (RATIO * self.eta) + self.drag_nm(w_rad_s),
                             w_rad_s)

    def efficiency(self, w_rad_s: float, t_out_nm: float) -> float:
        """What T_out w_out / (T_in w_in) is at a point (the truth a test reads)."""
        return t_out_nm / (t_out_nm / self.eta + RATIO * self.drag_nm(w_rad_s))


class StandInBench(Node):
    """See the module docstring."""

    def __init__(self, *, context: Any, fs_hz: float = 500.0, te_amp_rad: float = 6e-5,
                 b_rad: float = 1.5e-4, k_nm_per_rad: float = 5.0e5, tf_nm: float = 5.0,
                 overshoot: float = 0.0, losses: StandInLosses | None = None) -> None:
        super().__init__('real_bench_stand_in', context=context)
        self.fs = fs_hz
        self.te_amp, self.b, self.k, self.tf = te_amp_rad, b_rad, k_nm_per_rad, tf_nm
        self.overshoot = overshoot
        self.losses = losses
        self.rng = random.Random(38)
        self.temp = losses.t_amb_degc if losses is not None else math.nan
        self.pub_temp = self.create_publisher(Temperature, 'case_temperature',
                                              qos.ENCODER_QOS) if losses else None
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
            e_in = math.nan
            lo = self.losses
            if lo is not None:
                t_out = -applied * (1.0 if w >= 0 else -1.0)   # the load resisting
                t_in = lo.torque_in_nm(w, t_out)
                p_loss = t_in * w - t_out * abs(w) / RATIO if w != 0.0 else 0.0
                target = lo.t_amb_degc + lo.r_k_per_w * p_loss
                self.temp += (target - self.temp) * (1.0 - math.exp(-1.0 / (self.fs
                                                                            * lo.tau_s)))
                e_in = t_in + self.rng.gauss(0.0, lo.noise_nm)
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
            m.effort = [e_in, applied]
            self.pub.publish(m)
            self.published += 1
            if lo is not None and self.pub_temp is not None and \
                    k % round(self.fs / lo.temp_rate_hz) == 0:
                tm = Temperature(temperature=self.temp, variance=0.0)
                tm.header.stamp = m.header.stamp
                tm.header.frame_id = 'stand-in'
                self.pub_temp.publish(tm)

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

#: The stand-in's description with its loss channels (the transducers' classes: the
#: efficiency budget's inputs).
LOSS_DESCRIPTION = DESCRIPTION + """\
loss_channels:
  torque_in: {model: stand-in input transducer, full_scale: 20, accuracy_class_pct: 0.05,
              scale_nm_per_unit: 1.0}
  torque_out: {model: stand-in output transducer, full_scale: 500, accuracy_class_pct: 0.05}
  temperature: {model: stand-in Pt100}
"""


class Rig:
    """The stand-in bench on a thread of its own; the test's action client here."""

    def __init__(self, ctx: Any, **faults: Any) -> None:
        self.bench = StandInBench(context=ctx, **faults)
        self.bench_ex = SingleThreadedExecutor(context=ctx)
        self.bench_ex.add_node(self.bench)
        self.running = True
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()
        self.node = rclpy.create_node('stand_in_test_client', context=ctx)
        self.ex = SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.node)
        self.client = ActionClient(self.node, RunTestPlan, 'run_test_plan')

    def _spin(self) -> None:
        while self.running:
            self.bench_ex.spin_once(timeout_sec=0.01)

    def run(self, plan: dict, *, serial: str, ack: bool = True,
            during: Any = None, timeout_s: float = 180.0) -> Any:
        assert spin_until(self.ex, self.client.server_is_ready, 30.0), 'no action server'
        feedback: list[Any] = []
        goal = TrackedGoal(self.node, self.client, RunTestPlan, 'run_test_plan',
                           RunTestPlan.Goal(plan_yaml=yaml.safe_dump(plan), serial=serial,
                                            operator_name='pytest'),
                           feedback_callback=lambda f: feedback.append(f.feedback))
        assert spin_until(self.ex, goal.answered, 20.0) and goal.handle.accepted
        acked: set[int] = set()
        end = time.monotonic() + timeout_s
        while not goal.result_done():
            assert time.monotonic() < end, 'the test did not end'
            self.ex.spin_once(timeout_sec=0.05)
            if feedback and feedback[-1].step_kind == 'operator' and ack and \
                    feedback[-1].step_index not in acked:
                acked.add(feedback[-1].step_index)
                ok, msg = acknowledge(self.node, self.ex, wait_s=10.0)
                assert ok, msg
            if during is not None:
                during(feedback)
        return goal.result(), feedback

    def close(self) -> None:
        self.running = False
        self.thread.join(timeout=5)
        self.bench_ex.shutdown()
        self.bench.destroy_node()
        self.ex.shutdown()
        self.node.destroy_node()
