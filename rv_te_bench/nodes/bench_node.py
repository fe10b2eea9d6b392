"""BenchNode: the simulated TE bench (reducer model + two encoders on one DAQ clock).

Publishes ``bench/encoders`` (EncoderBlock, reliable), ``bench/info`` (BenchInfo,
transient-local, once), ``/diagnostics`` and, in ``fast`` time mode, ``/clock``.

With ``output: joint_state`` it publishes instead what a ros2_control bench would:
``joint_states`` (sensor_msgs/JointState, one message per DAQ sample, or one per joint and
sample with ``joint_state_layout: separate``), positions as the simulated encoders read them,
header stamps on the DAQ clock, effort of the output joint = output torque [N m] (NaN for the
input joint); no EncoderBlock and no BenchInfo (the joint_state_adapter publishes those).
``output: encoder_block`` (the default) is unchanged.

Time modes:
  * ``realtime``: blocks leave at the wall-clock rate of the DAQ; a late timer catches up
    (several blocks in one tick) so the lag stays bounded; the lag is in the diagnostics.
  * ``fast``: faster than real time by ``speed_factor`` (0 = as fast as possible), with the
    simulated time published on ``/clock`` so nodes with ``use_sim_time`` follow it.

All physics is in :class:`sim.bench.BenchSimulator`; this node converts and paces.
"""

from __future__ import annotations

import math
import sys
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from rv_te_msgs.msg import BenchChannels, BenchInfo, EncoderBlock

from rv_te_bench.errors import ParameterFileError, YamlInputError
from rv_te_bench.nodes import convert, qos
from rv_te_bench.nodes.common import (
    OK,
    SESSION_TOPIC_PREFIX,
    WARN,
    declare_from_specs,
    diagnostic_array,
    reject_invalid_changes,
    run_node,
    session_topic,
)
from rv_te_bench.nodes.params.bench import PARAMS, BenchParams
from rv_te_bench.params import params_changed, params_record
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, load_yaml

if TYPE_CHECKING:  # annotations only: the sim and the services load when the node starts
    from rv_te_msgs.srv import RunBenchProgram
    from std_srvs.srv import Trigger

    from sim.bench import BenchBlock, BenchConfig, BenchSimulator
    from sim.bench_info import BenchInfoData


def bench_config_from_params(p: BenchParams) -> BenchConfig:
    """Node parameters -> validated :class:`sim.bench.BenchConfig` (shared with the CLI).

    Raises:
        sim.errors.SimError: An invalid combination, named by the sim validation.
    """
    from sim.bench import BenchConfig
    from sim.drive import drive_from_spec, load_from_spec
    from sim.kinematics import kinematics_from_preset
    from sim.presets import load_preset

    kind = p.drive_profile
    if kind == 'constant':
        drive = drive_from_spec(kind, speed_rpm=p.speed_rpm)
    elif kind == 'sinusoidal':
        drive = drive_from_spec(kind, amplitude_rpm=p.speed_amplitude_rpm,
                                angular_freq_rad_s=p.speed_angular_freq_rad_s,
                                mean_rpm=p.speed_rpm,
                                allow_reversal=p.drive_allow_reversal)
    elif kind == 'ramp':
        drive = drive_from_spec(kind, start_rpm=p.ramp_start_rpm, end_rpm=p.speed_rpm,
                                duration_s=p.ramp_duration_s,
                                allow_reversal=p.drive_allow_reversal)
    else:
        drive = drive_from_spec(kind, speed_rpm=p.speed_rpm, reverse_at_s=p.reverse_at_s,
                                ramp_s=p.reverse_ramp_s)
    if p.load_profile == 'constant':
        load = load_from_spec('constant', torque_nm=p.load_nm)
    else:
        preset = load_preset(p.preset, list(p.overrides))
        kin = kinematics_from_preset(preset)
        extra: dict[str, Any] = (
            {'frequency_hz': p.load_frequency_hz} if p.load_frequency_hz > 0
            else {'tie_to': p.load_tie_to, 'harmonic': p.load_harmonic})
        load = load_from_spec('sinusoidal', kinematics=kin, drive=drive, mean_nm=p.load_nm,
                              amplitude_nm=p.load_amplitude_nm, **extra)
    return BenchConfig(
        preset=p.preset, overrides=tuple(p.overrides), te_mode=p.te_mode,
        drive=drive, load=load, encoder_in=_scale_of(p, 'in'), encoder_out=_scale_of(p, 'out'),
        sample_rate_hz=p.sample_rate_hz, block_size=p.block_size, seed=p.seed,
        bench_id=p.bench_id)


def _scale_of(p: BenchParams, side: str) -> Any:
    """The ``encoder_<side>`` preset name, or the scale as mounted when its heads or scale
    parameters are set (:func:`sim.scales.mounted_scale`; the scale's random phases come
    from a generator of the seed, apart from the encoders' noise streams)."""
    name = getattr(p, f'encoder_{side}')
    keys = ('heads_deg', 'scale_eccentricity_um', 'scale_diameter_mm', 'scale_grade_arcsec',
            'scale_tilt_mrad', 'scale_index_deg', 'scale_serial')
    v = {k: getattr(p, f'encoder_{side}_{k}') for k in keys}
    if not any(v.values()):
        return name
    import numpy as np

    from sim.encoders import encoder_preset
    from sim.scales import mounted_scale

    rng = np.random.default_rng([int(p.seed), 36, 0 if side == 'in' else 1])
    return mounted_scale(
        encoder_preset(name), rng, heads_deg=list(v['heads_deg']),
        eccentricity_m=v['scale_eccentricity_um'] * 1e-6,
        diameter_m=v['scale_diameter_mm'] * 1e-3,
        grade_arcsec=v['scale_grade_arcsec'], tilt_rad=v['scale_tilt_mrad'] * 1e-3,
        index_rad=math.radians(v['scale_index_deg']),
        serial=v['scale_serial'])


#: Longest the bench waits at its end for its readers to acknowledge the info and blocks [s].
FINISH_ACK_S = 3.0
#: Blocks one late timer tick may publish to catch up (fewer for JointStates: their queue).
_MAX_CATCH_UP_BLOCKS = 100

#: Blocks one tick of a ros2_control bench may publish (its setpoints apply between ticks).
_CONTROL_CATCH_UP_BLOCKS = 2

#: The fastest JointState stream (one per sample) a ros2_control session in fast mode
#: publishes: its readers (the adapter, the sequencer) keep up with it on a loaded 2-core PC.
MAX_JOINT_STATE_RATE_HZ = 2000.0

#: Most encoder blocks per second of session time (sample_rate_hz / block_size): rclpy
#: costs ~1-2 ms per message in each node, so faster block streams never keep up.
MAX_BLOCK_RATE_HZ = 1000.0


def with_loss_channels(info: BenchInfoData, program_info: BenchInfoData) -> BenchInfoData:
    """``info`` with the loss channels (``bench.loss_channels``, ``bench.losses``) of the
    program simulator's record in its ``parameters_yaml``."""
    import dataclasses

    import yaml

    rec = yaml.safe_load(info.parameters_yaml or '') or {}
    extra = (yaml.safe_load(program_info.parameters_yaml or '') or {}).get('bench') or {}
    bench = dict(rec.get('bench') or {})
    for key in ('loss_channels', 'losses'):
        if key in extra:
            bench[key] = extra[key]
    rec['bench'] = bench
    return dataclasses.replace(info, parameters_yaml=yaml.safe_dump(rec, sort_keys=False))


def build_simulator(p: BenchParams) -> tuple[BenchSimulator, float]:
    """The bench's start-up: simulator and session length [s] from its parameters.

    Run by the node and by ``rv-te launch --check`` (the same checks).

    Returns:
        (:class:`sim.bench.BenchSimulator`, session length in simulated time [s]; 0 = open).

    Raises:
        ParameterFileError: Blocks faster than :data:`MAX_BLOCK_RATE_HZ`, or a length in
            output revolutions without a speed.
        sim.errors.SimError: An invalid preset, model mode, override, encoder or profile.
    """
    from sim.bench import BenchSimulator

    block_rate_hz = p.sample_rate_hz / p.block_size
    if block_rate_hz > MAX_BLOCK_RATE_HZ:
        least = math.ceil(p.sample_rate_hz / MAX_BLOCK_RATE_HZ)
        msg = (f"sample_rate_hz / block_size = {block_rate_hz:.6g} blocks/s is above the "
               f'{MAX_BLOCK_RATE_HZ:g} blocks/s the nodes can carry (~1 ms per message); '
               f"at {p.sample_rate_hz:g} Hz use block_size >= {least}")
        raise ParameterFileError(msg)
    if p.duration_s > 0 and p.duration_output_revs > 0:
        # both say how long the session runs: one would silently win (issue #32)
        msg = (f'duration_s={p.duration_s:g} and duration_output_revs='
               f'{p.duration_output_revs:g} both set the session length; set the one not '
               'meant to 0 (e.g. --param bench.duration_output_revs=0 to run duration_s)')
        raise ParameterFileError(msg)
    sim = BenchSimulator(bench_config_from_params(p))
    duration_s = p.duration_s
    if p.duration_output_revs > 0:
        nominal_hz = abs(sim.config.drive.nominal_speed_rpm) / 60.0
        if not nominal_hz > 0:
            msg = ('duration_output_revs needs a non-zero nominal input speed (speed_rpm), '
                   'got 0 rpm')
            raise ParameterFileError(msg)
        # + one sample: the sample at exactly N revolutions closes the last window
        duration_s = (p.duration_output_revs * sim.info.gear_ratio / nominal_hz
                      + 1.0 / p.sample_rate_hz)
    return sim, duration_s


def _middleware_priority(p: BenchParams) -> int:
    """The SCHED_FIFO priority of the bench's middleware threads (``middleware_priority``;
    -1: one below ``realtime_priority``; 0: nice -10 instead).

    Raises:
        ParameterFileError: Not below ``realtime_priority`` (where that is in effect: real
            time mode, ``realtime_priority`` > 0).
    """
    want = int(p.realtime_priority)
    below = int(p.middleware_priority)
    below = want - 1 if below < 0 else below
    if want > 0 and p.time_mode != 'fast' and below >= want:
        msg = (f'middleware_priority {below} must be below realtime_priority {want} '
               '(or -1: one below, or 0: nice -10)')
        raise ParameterFileError(msg)
    return below


class BenchNode(Node):
    """Simulated bench publishing encoder blocks from :class:`sim.bench.BenchSimulator`."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare parameters, build the simulator; ``kwargs`` go to ``Node``.

        Raises:
            InvalidParameterValueException, SimError: Bad parameters (named), at start-up.
        """
        super().__init__('bench', **kwargs)
        self.p = params_record(BenchParams, declare_from_specs(self, PARAMS))
        reject_invalid_changes(self, PARAMS)
        # refused before any publisher exists: a bench that does not start leaves no
        # bench/encoders writer behind in its process (where a second bench then saw it)
        self._middleware_priority = _middleware_priority(self.p)
        self.add_post_set_parameters_callback(self._on_params_set)
        self.sim, self.duration_s = build_simulator(self.p)
        info = self.sim.info
        self.program: Any = None
        self.control: Any = None
        if self.p.ros2_control:
            if self.p.commanded:
                msg = ('commanded (bench/run_program) and ros2_control (setpoint topics) '
                       'exclude each other: set one')
                raise ParameterFileError(msg)
            from rv_te_bench.nodes.bench_control import Ros2ControlBench

            self.control = Ros2ControlBench(self, self.p)
            self.sim = self.control       # next_block() and info, driven by the setpoints
            info = self.control.info
        if self.p.commanded:
            self._start_commanded()
        self.block_period_s = self.p.block_size / self.p.sample_rate_hz
        self.finished = False
        self.exit_code = 0
        self.blocks_published = 0
        self.sim_time_s = 0.0
        self.joint_state = self.p.output == 'joint_state' or self.control is not None
        self._max_catch_up_blocks = _MAX_CATCH_UP_BLOCKS
        if self.joint_state:
            from sensor_msgs.msg import JointState

            self._joint_state_type = JointState
            self.pub_data = self.create_publisher(JointState, 'joint_states',
                                                  qos.JOINT_STATE_QOS)
            self.joint_states_published = 0
            # one tick's burst of JointStates fits the readers' queue (a larger one loses)
            per_block = self.p.block_size * (
                2 if self.p.joint_state_layout == 'separate' else 1)
            self._max_catch_up_blocks = max(1, min(
                _MAX_CATCH_UP_BLOCKS, qos.JOINT_STATE_QUEUE_DEPTH // per_block))
            if self.control is not None:
                # a bench that takes setpoints: blocks computed in a burst would all run
                # on the setpoint of before the burst (a real bench applies them as they
                # come), and a burst of JointStates overruns its readers; a bench held up
                # runs slower instead (fast mode: the backlog is forgiven)
                self._max_catch_up_blocks = min(self._max_catch_up_blocks,
                                                _CONTROL_CATCH_UP_BLOCKS)
        else:
            self.pub_blocks = self.create_publisher(EncoderBlock, 'bench/encoders',
                                                    qos.ENCODER_QOS)
            self.pub_info = self.create_publisher(BenchInfo, 'bench/info', qos.LATCHED_QOS)
            self.pub_data = self.pub_blocks
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              qos.DIAGNOSTICS_QOS)
        self.fast = self.p.time_mode == 'fast'
        self.speed_factor = self.p.speed_factor
        if self.control is not None and self.fast and self.speed_factor <= 0:
            # one JointState per sample: "as fast as possible" would flood the readers (the
            # adapter, the sequencer); go as fast as they are known to keep up
            factor = max(1.0, MAX_JOINT_STATE_RATE_HZ / self.p.sample_rate_hz)
            self.get_logger().info(f'ros2_control in fast mode: speed_factor 0 runs at '
                                   f'{factor:g}x ({MAX_JOINT_STATE_RATE_HZ:g} joint states/s)')
            self.speed_factor = factor
        self.pub_clock = self.create_publisher(Clock, '/clock', qos.CLOCK_QOS) if self.fast \
            else None
        self.gate = None   # fast mode: the readers that must not lose hold the bench
        if self.fast and not self.joint_state and self.p.wait_for_nodes:
            from rv_te_bench.nodes.backpressure import AckGate

            self.gate = AckGate(self, self.p.wait_for_nodes, self.p.ack_timeout_s)
        self.wall_start = time.time()
        self.mono_start = time.monotonic()
        self.started = not self.p.wait_for_nodes
        if self.started and self.pub_clock is not None:   # the session clock starts here
            self.pub_clock.publish(Clock(clock=convert.s_to_stamp(self.wall_start)))
        self.pub_channels = None
        if self.program is not None and self.program.losses is not None:
            # the transducers' ranges and classes go in the record (bench.loss_channels)
            info = with_loss_channels(info, self.program.info)
            self.pub_channels = self.create_publisher(BenchChannels, 'bench/channels',
                                                      qos.ENCODER_QOS)
        if not self.joint_state:
            self.pub_info.publish(convert.make_bench_info(info,
                                                          convert.s_to_stamp(self.wall_start)))
        self._diag_last = (time.monotonic(), 0)
        self._lag_s = 0.0
        self._lag_max_s = 0.0
        self._lag_period_max_s = 0.0   # since the previous diagnostics message
        tick = self.block_period_s if not self.fast else max(
            1e-3, self.block_period_s / self.speed_factor if self.speed_factor > 0
            else 1e-3)
        self.timer = self.create_timer(tick, self._on_tick)
        self.create_timer(self.p.diagnostics_period_s, self._publish_diagnostics)
        #: What real-time scheduling took effect (diagnostics 'scheduling').
        self.scheduling = self._realtime_scheduling()
        self.get_logger().info(
            f'bench {info.bench_id}: preset {info.preset} ({info.reducer_type}, '
            f'i={info.gear_ratio:.6g}), {self.p.sample_rate_hz:g} Hz, blocks of '
            f'{self.p.block_size}, {self.p.time_mode} time'
            + (f', {self.duration_s:.3f} s' if self.duration_s > 0 else ''))

    def _realtime_scheduling(self) -> str:
        """``realtime_priority`` > 0: SCHED_FIFO for this thread (the node's, which then
        spins the executor: its timer thread inherits it), SCHED_FIFO ``middleware_priority``
        (by default one below) for the middleware's threads, nice -10 for any other. Only
        in realtime mode: a real-time thread that simulates as fast as it can (fast mode)
        would take a core from every other process."""
        want = int(self.p.realtime_priority)
        if want == 0:
            return 'normal'
        if self.fast:
            self.get_logger().warning(
                f'realtime_priority {want} ignored in fast time mode (a real-time thread '
                'that computes as fast as it can would take a core from everything else)')
            return 'normal (fast time mode)'
        from rv_te_bench.nodes.scheduling import realtime_scheduling

        got = realtime_scheduling(want, middleware_priority=self._middleware_priority)
        if got.startswith('normal') or 'not permitted' in got:
            self.get_logger().warning(f'scheduling: {got}')
        else:
            self.get_logger().info(f'scheduling: {got}')
        return got

    # -- commanded mode (bench programs from the test_sequencer) --------------------------
    def _start_commanded(self) -> None:
        from rv_te_msgs.srv import RunBenchProgram
        from std_srvs.srv import Trigger

        from sim.program import ProgramSimulator

        cfg = self.sim.config
        losses = None
        if self.p.losses:
            from sim.loss_bench import LossConfig

            losses = LossConfig()
        self.program = ProgramSimulator(
            preset=cfg.preset, overrides=cfg.overrides, te_mode=cfg.te_mode,
            encoder_in=cfg.encoder_in, encoder_out=cfg.encoder_out,
            sample_rate_hz=cfg.sample_rate_hz, block_size=cfg.block_size, seed=cfg.seed,
            losses=losses)
        self._prog_blocks = 0
        self.create_service(RunBenchProgram, 'bench/run_program', self._on_run_program)
        self.create_service(Trigger, 'bench/stop', self._on_stop)

    def _on_run_program(self, request: RunBenchProgram.Request,
                        response: RunBenchProgram.Response) -> RunBenchProgram.Response:
        from sim.errors import SimError
        from sim.program import program_from_plain

        if self.program.running:
            response.accepted = False
            response.reason = 'bench busy: a program is running (call bench/stop first)'
            return response
        try:
            segments = program_from_plain(load_yaml(  # bounded: from any peer
                request.program_yaml, origin='program_yaml', limits=DOCUMENT_LIMITS))
            total = self.program.load(segments)
        except (SimError, YamlInputError) as exc:
            response.accepted = False
            response.reason = f'bad program: {exc}'.replace('\n', ' ')
            self.get_logger().warning(response.reason)
            return response
        response.accepted = True
        response.first_seq = self.program.seq
        response.block_count = total
        response.segment_blocks = list(self.program.segment_blocks)
        # pacing restarts with the program; in real time its first block is due now
        self.started = True
        self.mono_start = time.monotonic()
        self._prog_blocks = 0
        if not self.fast:
            self.wall_start = time.time() - self.program.seq * self.block_period_s
        held = ''
        if self.gate is not None:   # fast: the session's readers hold it from this block on
            ns = self.get_namespace()
            have = {i.node_name for i in self.get_subscriptions_info_by_topic(
                self.pub_data.topic_name) if i.node_namespace == ns}
            holding = self.gate.start(have, first_seq=self.program.seq)
            held = f'; waiting for {holding or "no reader"} when more than ' \
                   f'{self.gate.window} blocks behind'
        self.get_logger().info(f'program: {len(segments)} segments, {total} blocks from seq '
                               f'{response.first_seq}{held}')
        return response

    def _on_stop(self, _request: Trigger.Request,
                 response: Trigger.Response) -> Trigger.Response:
        was = self.program.running
        self.program.stop()
        response.success = True
        response.message = 'program stopped' if was else 'no program was running'
        self.get_logger().info(response.message)
        return response

    def _tick_commanded(self) -> None:
        elapsed = time.monotonic() - self.mono_start
        factor = self.speed_factor if self.fast else 1.0
        due = 10 if self.fast and factor <= 0 else int(
            elapsed * factor / self.block_period_s) + 1 - self._prog_blocks
        if self.gate is not None and due > 0:
            due = min(due, self.gate.room(self.program.seq - 1))
        for _ in range(max(0, min(due, 100))):
            if not self.program.running:
                return
            b, _seg = self.program.next_block()
            self._publish_block(b)
            self._prog_blocks += 1

    def _on_params_set(self, params: list[Any]) -> None:
        self.p = params_changed(self.p, {prm.name: prm.value for prm in params})

    def _due_blocks(self) -> int:
        """How many blocks the clock says are due now (bounded catch-up)."""
        elapsed = time.monotonic() - self.mono_start
        if self.fast:
            factor = self.speed_factor
            if factor <= 0:   # as fast as possible: several per tick, still yielding to spin
                return 10 if self.gate is None else min(
                    10, self.gate.room(self.blocks_published - 1))
            elapsed *= factor
        due = int(elapsed / self.block_period_s) + 1 - self.blocks_published
        if self.control is not None and self.fast and due > self._max_catch_up_blocks:
            # held up: forgive the backlog (simulated time runs slower for a moment)
            self.mono_start += (due - self._max_catch_up_blocks) * self.block_period_s \
                / self.speed_factor
        due = max(0, min(due, self._max_catch_up_blocks))
        if self.gate is not None and due:
            due = min(due, self.gate.room(self.blocks_published - 1))
        return due

    def _wait_for_subscribers(self) -> bool:
        """True once the named subscriber nodes are there (or the wait timed out)."""
        ns = self.get_namespace()
        topic = self.pub_data.topic_name
        have = {i.node_name for i in self.get_subscriptions_info_by_topic(topic)
                if i.node_namespace == ns}
        marker = session_topic()
        if marker is not None:   # launched: another session's nodes of these names do not count
            mine = {i.node_name for i in self.get_publishers_info_by_topic(marker)
                    if i.node_namespace == ns}
            have = {n for n in have if n in mine or not self._of_another_session(n, ns, marker)}
        missing = sorted(set(self.p.wait_for_nodes) - have)
        if not missing:
            missing = self._not_matched(ns, have)
        if not missing and self.pub_clock is not None:
            missing = self._clock_not_matched(ns)
        waited = time.monotonic() - self.mono_start
        if missing and waited < self.p.wait_timeout_s:
            return False
        if missing:
            self.get_logger().warning(
                f'starting without {missing} on {topic} after {waited:.1f} s')
        self.started = True
        if self.gate is not None:
            holding = self.gate.start(have)
            self.get_logger().info(f'fast mode: waiting for {holding or "no reader"} when '
                                   f'more than {self.gate.window} blocks behind')
        self.wall_start = time.time()
        self.mono_start = time.monotonic()
        if self.pub_clock is not None:   # the session clock starts at the first block's time
            self.pub_clock.publish(Clock(clock=convert.s_to_stamp(self.wall_start)))
        return True

    def _not_matched(self, ns: str, have: set[str]) -> list[str]:
        """What is still missing once the waited-for nodes are in the graph (issue #15 item
        5): our writers matched to their readers (blocks sent before would be lost), and the
        session's recorder subscribed to bench/info and matched (a short session ended
        before the recorder had its latched BenchInfo, which left with the bench)."""
        readers = len(self.get_subscriptions_info_by_topic(self.pub_data.topic_name))
        if self.pub_data.get_subscription_count() < readers:
            return [f'({self.pub_data.topic_name} matching)']
        # in joint_state output the adapter publishes BenchInfo (and holds its first blocks
        # until the session's recorder subscribes): nothing more to wait for here
        if self.joint_state or 'recorder' not in self.p.wait_for_nodes \
                or 'recorder' not in have:
            return []
        infos = self.get_subscriptions_info_by_topic(self.pub_info.topic_name)
        if not any(i.node_name == 'recorder' and i.node_namespace == ns for i in infos) or \
                self.pub_info.get_subscription_count() < len(infos):
            return ['recorder (bench/info)']
        return []

    def _of_another_session(self, name: str, ns: str, marker: str) -> bool:
        """True when node ``name`` carries another launched session's marker (a stale node
        of an earlier session); a node of no session (a test probe, a tool) counts."""
        try:
            topics = self.get_publisher_names_and_types_by_node(name, ns)
        except Exception:  # noqa: BLE001 - gone between the two graph queries
            return False
        return any(t.startswith(SESSION_TOPIC_PREFIX) and t != marker for t, _ in topics)

    def _clock_not_matched(self, ns: str) -> list[str]:
        """Waited-for nodes on sim time whose /clock subscription has not matched ours yet.

        A recorder with use_sim_time logs each message at the last /clock it received; /clock
        messages sent before its subscription matched are lost, and the first blocks would
        all be logged at one time.
        """
        if self.pub_clock is None:
            return []
        wanted = set(self.p.wait_for_nodes)
        readers = [i.node_name for i in self.get_subscriptions_info_by_topic(
                   self.pub_clock.topic_name)   # (/clock, or the session's own, remapped)
                   if i.node_namespace == ns and i.node_name in wanted]
        if self.pub_clock.get_subscription_count() >= len(readers):
            return []
        on_clock = sorted(set(readers))
        return [f'{n} (/clock)' for n in on_clock]

    def _on_tick(self) -> None:
        if self.program is not None:
            self._tick_commanded()
            return
        if self.finished or (not self.started and not self._wait_for_subscribers()):
            return
        due = self._due_blocks()
        # lag: how long after the end of its samples a block leaves (a DAQ delivers a block
        # once its last sample is taken). The first block of a late tick is the latest one;
        # the last one shows a catch-up burst that took long.
        first_end_s = self.sim_time_s + self.block_period_s
        t_first_s = time.monotonic() - self.mono_start
        for _ in range(due):
            if self.duration_s > 0 and self.sim_time_s >= self.duration_s - 1e-12:
                self._finish()
                return
            self._publish_one()
        if not self.fast and due:
            self._lag_s = max(t_first_s - first_end_s,
                              (time.monotonic() - self.mono_start) - self.sim_time_s)
            self._lag_max_s = max(self._lag_max_s, self._lag_s)
            self._lag_period_max_s = max(self._lag_period_max_s, self._lag_s)

    def _publish_one(self) -> None:
        self._publish_block(self.sim.next_block())

    def _publish_block(self, b: BenchBlock) -> None:
        if self.control is not None:
            self.joint_states_published += self.control.publish(self.pub_data, b,
                                                                self.wall_start)
        elif self.joint_state:
            self._publish_joint_states(b)
        else:
            stamp_s = self.wall_start + b.t0_s
            # serialised here (no message object): publish() sends the bytes as they are
            msg = convert.encoder_block_bytes(
                bench_id=self.sim.info.bench_id, seq=b.seq, stamp_s=stamp_s,
                sample_rate_hz=self.p.sample_rate_hz, time_offset_s=b.time_offset_s,
                theta_in_rad=b.theta_in_rad, theta_out_rad=b.theta_out_rad,
                torque_out_nm=b.torque_out_nm, theta_in_heads_rad=b.theta_in_heads_rad,
                theta_out_heads_rad=b.theta_out_heads_rad)
            if self.pub_channels is not None:   # first: a reader holds the block for it
                self.pub_channels.publish(convert.make_bench_channels(
                    bench_id=self.sim.info.bench_id, seq=b.seq, stamp_s=stamp_s,
                    torque_in_nm=b.torque_in_nm, temp_case_degc=b.temp_case_degc))
            self.pub_blocks.publish(msg)
        self.blocks_published += 1
        self.sim_time_s = b.t0_s + len(b.time_offset_s) / self.p.sample_rate_hz
        if self.pub_clock is not None:
            self.pub_clock.publish(Clock(clock=convert.s_to_stamp(self.wall_start
                                                                  + self.sim_time_s)))

    def _publish_joint_states(self, b: BenchBlock) -> None:
        """One JointState per DAQ sample (per joint and sample when separate)."""
        base_ns = round(self.wall_start * 1e9)
        stamps = (base_ns + np.round((b.t0_s + b.time_offset_s) * 1e9).astype(np.int64)).tolist()
        th_in, th_out = b.theta_in_rad, b.theta_out_rad
        if self.p.joint_state_wrap:
            th_in, th_out = np.mod(th_in, 2.0 * math.pi), np.mod(th_out, 2.0 * math.pi)
        torque = (b.torque_out_nm if len(b.torque_out_nm) else
                  np.full(len(th_in), math.nan)).tolist()
        name_in, name_out = self.p.joint_state_names
        separate = self.p.joint_state_layout == 'separate'
        frame, js, pub = self.sim.info.bench_id, self._joint_state_type, self.pub_data
        nan = math.nan
        # an output scale with several heads: one joint per head, head 0 = the output joint,
        # head j = '<output joint>_head<j>', all in the output joint's message
        extra = b.theta_out_heads_rad[1:] if b.theta_out_heads_rad is not None else None
        head_names = [f'{name_out}_head{j}' for j in range(1, 1 + (
            0 if extra is None else extra.shape[0]))]
        if extra is not None and self.p.joint_state_wrap:
            extra = np.mod(extra, 2.0 * math.pi)
        heads = ([()] * len(stamps) if extra is None else [tuple(r) for r in extra.T.tolist()])
        zeros = [nan] * len(head_names)
        for t_ns, p_in, p_out, tq, hs in zip(stamps, th_in.tolist(), th_out.tolist(), torque,
                                             heads, strict=True):
            stamp = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
            if separate:
                for names, pos, eff in (([name_in], [p_in], [nan]),
                                        ([name_out, *head_names], [p_out, *hs], [tq, *zeros])):
                    m = js()
                    m.header.stamp = stamp
                    m.header.frame_id = frame
                    m.name = names
                    m.position = pos
                    m.effort = eff
                    pub.publish(m)
            else:
                m = js()
                m.header.stamp = stamp
                m.header.frame_id = frame
                m.name = [name_in, name_out, *head_names]
                m.position = [p_in, p_out, *hs]
                m.effort = [nan, tq, *zeros]
                pub.publish(m)
        self.joint_states_published += len(stamps)

    def _finish(self) -> None:
        self.finished = True
        self.timer.cancel()
        # the node process ends next: its info and last blocks must have reached the readers
        from rclpy.duration import Duration

        for pub in ((self.pub_data,) if self.joint_state else (self.pub_info, self.pub_blocks)):
            if not pub.wait_for_all_acked(Duration(seconds=FINISH_ACK_S)):
                self.get_logger().warning(f'{pub.topic_name}: not acknowledged by every '
                                          f'reader within {FINISH_ACK_S:g} s')
        self._publish_diagnostics()
        self.get_logger().info(
            f'session complete: {self.blocks_published} blocks, {self.sim_time_s:.3f} s '
            f'simulated in {time.monotonic() - self.mono_start:.2f} s')

    def _publish_diagnostics(self) -> None:
        now = time.monotonic()
        t_last, n_last = self._diag_last
        rate = (self.blocks_published - n_last) / max(now - t_last, 1e-9)
        self._diag_last = (now, self.blocks_published)
        wall = now - self.mono_start
        values = {
            'blocks_published': self.blocks_published,
            'achieved_block_rate_hz': rate,
            'nominal_block_rate_hz': 1.0 / self.block_period_s,
            'sim_time_s': self.sim_time_s,
            'realtime_factor': self.sim_time_s / wall if wall > 0 else 0.0,
            'lag_s': self._lag_s,
            'lag_max_s': self._lag_max_s,
            # the largest lag since the previous diagnostics message: a monitor (or
            # bench_multibench.py) sees the steady state apart from the start-up
            'lag_period_max_s': self._lag_period_max_s,
            'finished': self.finished,
            'scheduling': self.scheduling,
        }
        self._lag_period_max_s = 0.0
        if self.gate is not None:   # how long the readers held the bench back, and who not
            values['held_by_readers_s'] = self.gate.held_s
            values['readers_let_go'] = ','.join(self.gate.released)
        if self.joint_state:
            values['joint_states_published'] = self.joint_states_published
        late = (not self.fast) and self._lag_s > self.block_period_s
        level = WARN if late else OK
        message = 'lagging behind the clock' if late else (
            'finished' if self.finished else 'running')
        self.pub_diag.publish(diagnostic_array(self, 'bench', level, message, values))


def main(args: list[str] | None = None) -> int:
    """Run the bench node in its own process."""
    return run_node(lambda ctx: BenchNode(context=ctx), list(sys.argv if args is None else args))


if __name__ == '__main__':
    sys.exit(main())
