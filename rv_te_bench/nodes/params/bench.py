"""The parameters of the bench node: one frozen record, declared from its fields.

The node is :mod:`rv_te_bench.nodes.bench_node`.
No rclpy here: the launcher checks parameter files against :data:`PARAMS` before any node
starts (:mod:`rv_te_bench.launch.node_specs`).
"""

from __future__ import annotations

from dataclasses import dataclass

from rv_te_bench.params import param, param_specs
from sim.bench_info import DEFAULT_SAMPLE_RATE_HZ

__all__ = ['PARAMS', 'BenchParams']


@dataclass(frozen=True)
class BenchParams:
    """The bench node's parameters (a simulated bench: preset, drive, load, encoders, DAQ,
    session length, output).

    Declared from these fields (:func:`~rv_te_bench.params.param_specs`), read through the
    record (:func:`~rv_te_bench.params.params_record`); units in the descriptions.
    """

    bench_id: str = param('bench0', 'Bench id (frame_id of every message) [-]')
    preset: str = param('wang2020-2kv', 'Reducer preset name or TOML path [-]')
    overrides: tuple[str, ...] = param(
        (), 'Preset overrides "key=value" (same keys as rv-te --set) [-]')
    te_mode: str = param(
        'nlte',
        'Reducer model mode: nlte | ste | dte (2K-V), geometric | elastic (hu2020-rv), dte '
        '(li2023)')
    drive_profile: str = param(
        'constant', 'Input speed profile [-]',
        choices=('constant', 'sinusoidal', 'ramp', 'forward_reverse'))
    speed_rpm: float = param(
        300.0, 'Input speed [rpm]: constant / forward speed, sinusoidal mean C, ramp end speed',
        min_value=-100000.0, max_value=100000.0)
    speed_amplitude_rpm: float = param(
        0.0, 'Sinusoidal speed amplitude A [rpm] (V = A sin(B t) + C, Hu 2020)', min_value=0.0,
        max_value=100000.0)
    speed_angular_freq_rad_s: float = param(
        1.0, 'Sinusoidal speed angular frequency B [rad/s]', min_value=1e-6, max_value=1e4)
    drive_allow_reversal: bool = param(
        False, 'Allow sinusoidal/ramp profiles whose speed changes sign (Hu 2020: A > C)')
    ramp_start_rpm: float = param(
        0.0, 'Ramp start speed [rpm]', min_value=-100000.0, max_value=100000.0)
    ramp_duration_s: float = param(5.0, 'Ramp duration [s]', min_value=1e-3, max_value=1e6)
    reverse_at_s: float = param(
        10.0, 'Forward-reverse: start of reversal [s]', min_value=0.0, max_value=1e6)
    reverse_ramp_s: float = param(
        1.0, 'Forward-reverse: reversal duration [s]', min_value=1e-3, max_value=1e6)
    load_profile: str = param(
        'constant', 'Load torque profile [-]', choices=('constant', 'sinusoidal'))
    load_nm: float = param(
        0.0, 'Constant load / sinusoidal mean load [N m]', min_value=-1e6, max_value=1e6)
    load_amplitude_nm: float = param(
        0.0, 'Sinusoidal load amplitude [N m]', min_value=0.0, max_value=1e6)
    load_frequency_hz: float = param(
        0.0, 'Sinusoidal load frequency [Hz]; 0 = tie it to load_tie_to', min_value=0.0,
        max_value=1e5)
    load_tie_to: str = param(
        'crank', 'Rate the sinusoidal load follows when load_frequency_hz = 0 [-]',
        choices=('input', 'output', 'crank', 'crank_rel', 'mesh'))
    load_harmonic: float = param(
        1.0, 'Multiple of the tied rate [1]', min_value=1e-6, max_value=1e4)
    encoder_in: str = param('heidenhain-ron886', 'Input-shaft encoder preset [-]')
    encoder_out: str = param('heidenhain-ron886', 'Output-shaft encoder preset [-]')
    encoder_in_heads_deg: tuple[float, ...] = param(
        (), 'input scale: angles of its read heads from head 0 [deg]; empty: the '
        'preset\'s one head (2 heads: 0, 180; 4: 0, 90, 180, 270)',
        rule=lambda v: None if len(v) <= 16 else 'must list at most 16 heads')
    encoder_in_scale_eccentricity_um: float = param(
        0.0, 'input scale: mounting eccentricity (run-out / 2) [um]; +-412 e/D arcsec '
        '(needs the diameter)', min_value=0.0, max_value=1000.0)
    encoder_in_scale_diameter_mm: float = param(
        0.0, 'input scale: graduation diameter [mm] (0: not stated)', min_value=0.0,
        max_value=10000.0)
    encoder_in_scale_grade_arcsec: float = param(
        0.0, 'input scale: the maker\'s accuracy of graduation +- [arcsec]; > 0 draws a '
        'graduation error of that grade (phases from the seed); 0: the preset\'s',
        min_value=0.0, max_value=3600.0)
    encoder_in_scale_tilt_mrad: float = param(
        0.0, 'input scale: tilt of the scale plane against the shaft axis (axial run-out / '
        'D) [mrad]; an order-2 error tau^2 / 4 (1 mrad: 0.05 arcsec)', min_value=0.0,
        max_value=100.0)
    encoder_in_scale_index_deg: float = param(
        0.0, 'input scale: turned on its shaft by this from its reference mounting [deg] '
        '(reversal: 180 or 120)', min_value=-360.0, max_value=360.0)
    encoder_in_scale_serial: str = param(
        '', 'input scale: serial number (a calibration must name it) [-]')
    encoder_out_heads_deg: tuple[float, ...] = param(
        (), 'output scale: angles of its read heads from head 0 [deg]; empty: the '
        'preset\'s one head (2 heads: 0, 180; 4: 0, 90, 180, 270)',
        rule=lambda v: None if len(v) <= 16 else 'must list at most 16 heads')
    encoder_out_scale_eccentricity_um: float = param(
        0.0, 'output scale: mounting eccentricity (run-out / 2) [um]; +-412 e/D arcsec '
        '(needs the diameter)', min_value=0.0, max_value=1000.0)
    encoder_out_scale_diameter_mm: float = param(
        0.0, 'output scale: graduation diameter [mm] (0: not stated)', min_value=0.0,
        max_value=10000.0)
    encoder_out_scale_grade_arcsec: float = param(
        0.0, 'output scale: the maker\'s accuracy of graduation +- [arcsec]; > 0 draws a '
        'graduation error of that grade (phases from the seed); 0: the preset\'s',
        min_value=0.0, max_value=3600.0)
    encoder_out_scale_tilt_mrad: float = param(
        0.0, 'output scale: tilt of the scale plane against the shaft axis (axial run-out / '
        'D) [mrad]; an order-2 error tau^2 / 4 (1 mrad: 0.05 arcsec)', min_value=0.0,
        max_value=100.0)
    encoder_out_scale_index_deg: float = param(
        0.0, 'output scale: turned on its shaft by this from its reference mounting [deg] '
        '(reversal: 180 or 120)', min_value=-360.0, max_value=360.0)
    encoder_out_scale_serial: str = param(
        '', 'output scale: serial number (a calibration must name it) [-]')
    sample_rate_hz: float = param(
        DEFAULT_SAMPLE_RATE_HZ, 'DAQ sample rate [Hz]', min_value=1.0, max_value=1e6)
    block_size: int = param(
        100, 'Samples per EncoderBlock [1]; sample_rate_hz / block_size <= 1000 blocks/s',
        min_value=1, max_value=100000)
    seed: int = param(0, 'Random seed of the encoder noise [-]', min_value=0, max_value=2**31 - 1)
    duration_s: float = param(
        0.0, 'Session length in simulated time [s]; 0 = until stopped', min_value=0.0,
        max_value=1e7)
    duration_output_revs: float = param(
        0.0, 'Session length [output revolutions] (0 = duration_s decides; both > 0 is '
        'refused)', min_value=0.0,
        max_value=1e6)
    time_mode: str = param(
        'realtime', 'realtime (wall clock) or fast (sim time)', choices=('realtime', 'fast'))
    speed_factor: float = param(
        20.0, 'fast mode: times faster than real time; 0 = as fast as possible [1]', min_value=0.0,
        max_value=1e4)
    wait_for_nodes: tuple[str, ...] = param(
        (), 'Start the clock once these nodes (same namespace) subscribe bench/encoders [-]')
    wait_timeout_s: float = param(
        20.0, 'Start anyway after this long when subscribers are missing [s]', min_value=0.0,
        max_value=3600.0)
    ack_timeout_s: float = param(
        5.0, 'fast mode: how long a waited-for reader (recorder, te_node) that takes no '
        'block may hold the bench before it goes on without it [s]', min_value=0.1,
        max_value=3600.0)
    diagnostics_period_s: float = param(
        1.0, 'Diagnostics period [s]', min_value=0.05, max_value=60.0)
    output: str = param(
        'encoder_block',
        'What the bench publishes: encoder_block (bench/encoders + bench/info) or '
        'joint_state (joint_states, one sensor_msgs/JointState per DAQ sample, as a '
        'ros2_control bench; ~0.1 ms of Python per message: keep sample_rate_hz to a '
        'few kHz) [-]',
        choices=('encoder_block', 'joint_state'))
    joint_state_layout: str = param(
        'one_message',
        'output joint_state: both joints in one message per sample (one_message, as '
        'joint_state_broadcaster) or one message per joint and sample (separate) [-]',
        choices=('one_message', 'separate'))
    joint_state_names: tuple[str, ...] = param(
        ('input_joint', 'output_joint'),
        'output joint_state: names of the input and output joints; an output scale '
        "with several heads adds '<output>_head1', ... in the output's message [-]",
        rule=lambda v: None if len(v) == 2 and v[0] and v[1] and v[0] != v[1]
        else 'must be two different non-empty joint names')
    joint_state_wrap: bool = param(
        False,
        'output joint_state: publish positions wrapped to [0, 2 pi), as single-turn '
        'absolute encoders read them')
    commanded: bool = param(
        False,
        'Idle until a program arrives on bench/run_program (test_sequencer), instead '
        'of running the drive profile from the start')
    losses: bool = param(
        False,
        'commanded or ros2_control: simulate the reducer\'s losses, the input/output torque '
        'transducers and the case temperature sensor (issue 38); commanded: publish the '
        'input torque and case temperature on bench/channels (BenchChannels, one per '
        'EncoderBlock); ros2_control: the input joint\'s effort is the input torque and the '
        'case temperature goes on temperature_topic, as a real bench serves them [-]')
    temperature_topic: str = param(
        'case_temperature',
        'ros2_control with losses: sensor_msgs/Temperature topic of the case sensor [-]')
    ros2_control: bool = param(
        False, "Serve a ros2_control bench's interfaces: setpoints on the forward command "
        "controllers' topics (drive velocity, load effort or position), joint_states out "
        '(with velocities and efforts); runs until stopped (docs/ACCEPTANCE.md)')
    drive_command_topic: str = param(
        'drive_velocity_controller/commands',
        "ros2_control: the drive (input) joint's velocity setpoint topic "
        '(std_msgs/Float64MultiArray, [rad/s]) [-]')
    load_effort_command_topic: str = param(
        'load_effort_controller/commands',
        "ros2_control: the load (output) joint's effort setpoint topic ([N m], the torque "
        'applied to the output) [-]')
    load_position_command_topic: str = param(
        'load_position_controller/commands',
        "ros2_control: the load (output) joint's position setpoint topic ([rad]) [-]")
    max_input_speed_rpm: float = param(
        10000.0, "ros2_control: the drive's own speed limit (faster setpoints are clipped) "
        '[rpm]', min_value=1.0, max_value=1e5)
    realtime_priority: int = param(
        0,
        'realtime time mode: SCHED_FIFO priority of the thread that paces and '
        'publishes the blocks, its middleware threads below it (middleware_priority; Linux; needs '
        'CAP_SYS_NICE or an rtprio limit, as ros2_control\'s thread_priority); 0 = '
        'normal scheduling. Keeps a bench on time beside other benches on a shared PC '
        '[-]',
        min_value=0, max_value=99)
    middleware_priority: int = param(
        -1,
        'with realtime_priority: SCHED_FIFO priority of the middleware (Fast DDS) threads of '
        'the bench process, below the pacing thread, so that one holding the writer\'s lock '
        'is not preempted by time-shared work; -1 = realtime_priority - 1; 0 = nice -10 '
        'instead (as before issue 41) [-]',
        min_value=-1, max_value=98)


PARAMS = param_specs(BenchParams)
