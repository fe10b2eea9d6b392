"""The parameters of the JointState adapter: one frozen record, declared from its fields.

The node is :mod:`rv_te_bench.nodes.joint_state_adapter`.
No rclpy here: the launcher checks parameter files against :data:`PARAMS` before any node
starts (:mod:`rv_te_bench.launch.node_specs`).
"""

from __future__ import annotations

from dataclasses import dataclass

from rv_te_bench.params import param, param_specs

__all__ = ['PARAMS', 'JointStateAdapterParams']


@dataclass(frozen=True)
class JointStateAdapterParams:
    """The JointState adapter's parameters (bench description, joints, scaling, pairing).

    Declared from these fields (:func:`~rv_te_bench.params.param_specs`), read through the
    record (:func:`~rv_te_bench.params.params_record`); units in the descriptions.
    """

    bench_description: str = param(
        '',
        'Bench description YAML file (rv_te_bench/launch/bench_description_example.yaml)'
        ' published as bench/info; empty = no bench/info (then give the TE node its '
        'gear_ratio) [path]')
    temperature_topic: str = param(
        'case_temperature',
        'sensor_msgs/Temperature topic of the reducer case sensor (degC); read only when '
        'the bench description\'s loss_channels has temperature: its readings (held '
        'between them, none older than 10 s) go on bench/channels with each block [-]')
    input_joint: str = param(
        '',
        'JointState name of the input-shaft encoder; empty = joints.input of the bench '
        "description, else 'input_joint' [-]")
    output_joint: str = param(
        '',
        'JointState name of the output-shaft encoder; empty = joints.output of the '
        "bench description, else 'output_joint' [-]")
    output_head_joints: tuple[str, ...] = param(
        (),
        'JointState names of the output scale\'s read heads, head 0 first (head 0 is '
        'the output joint); empty = joints.output_heads of the bench description, '
        'else one head. The heads must come in the output joint\'s message [-]')
    sample_rate_hz: float = param(
        0.0,
        'Expected sample rate of the header stamps [Hz]; a stamp step above 1.5 periods '
        'is a reported gap; 0 = sample_rate_hz of the bench description',
        min_value=0.0, max_value=1e6)
    block_size: int = param(
        0, 'Samples per EncoderBlock [1]; 0 = block_size of the bench description, else 100',
        min_value=0, max_value=100000)
    position_unit: str = param(
        'rad', 'JointState position unit: rad, or counts (raw counters, see counts_per_rev_*)',
        choices=('rad', 'counts'))
    counts_per_rev_in: float = param(
        0.0,
        'Input encoder counts per revolution [1/rev] with position_unit counts; 0 = '
        'encoders.input.counts_per_rev of the bench description',
        min_value=0.0, max_value=2.0**53)
    counts_per_rev_out: float = param(
        0.0,
        'Output encoder counts per revolution [1/rev] with position_unit counts; 0 = '
        'from the bench description',
        min_value=0.0, max_value=2.0**53)
    wrap: str = param(
        'none',
        'Single-turn absolute encoders whose position wraps at 2 pi (after scaling) and '
        'is unwrapped here; needs < half a turn between two samples [-]',
        choices=('none', 'input', 'output', 'both'))
    effort_scale: float = param(
        0.0,
        'Output torque per unit of the output joint effort [N m / unit]; 0 = the bench '
        "description's torque sensor scale when present, else no torque",
        min_value=-1e9, max_value=1e9)
    pairing_tolerance_s: float = param(
        -1.0,
        'Joints in separate messages: largest stamp difference of one sample\'s input '
        'and output [s], below half a sample period; < 0 = a quarter sample period',
        min_value=-1.0, max_value=1.0)
    max_unpaired: int = param(
        64,
        'Joints in separate messages: samples one joint may run ahead of the other '
        'before its oldest half is a missing joint [1]',
        min_value=1, max_value=100000)
    idle_flush_s: float = param(
        0.5, 'Publish the open (short) block when no sample came for this long [s]', min_value=0.01,
        max_value=60.0)
    wait_for_nodes: tuple[str, ...] = param(
        (),
        'Hold the first blocks until these nodes (same namespace) subscribe '
        'bench/encoders, so a session\'s TE node and recorder get the stream from seq 0 '
        '[-]')
    wait_timeout_s: float = param(
        20.0, 'Publish anyway after this long when subscribers are missing [s]', min_value=0.0,
        max_value=3600.0)
    joints_timeout_s: float = param(
        20.0,
        'End with an error (diagnostics ERROR, exit code 1) when no sample of both joints '
        'came this long after start, naming the joints expected and the names the '
        'messages carry; 0 = wait forever [s]', min_value=0.0, max_value=86400.0)
    diagnostics_period_s: float = param(
        1.0, 'Diagnostics period [s]', min_value=0.05, max_value=60.0)


PARAMS = param_specs(JointStateAdapterParams)
