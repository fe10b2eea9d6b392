"""The parameters of the test sequencer: one frozen record, declared from its fields.

The node is :mod:`rv_te_bench.nodes.test_sequencer`.
No rclpy here: the launcher checks parameter files against :data:`PARAMS` before any node
starts (:mod:`rv_te_bench.launch.node_specs`).
"""

from __future__ import annotations

from dataclasses import dataclass

from rv_te_bench.params import param, param_specs

__all__ = ['PARAMS', 'TestSequencerParams']


@dataclass(frozen=True)
class TestSequencerParams:
    """The test sequencer's parameters (timeouts, feedback, who must record, the
    ros2_control bench's command topics, the bench description's limits).

    Declared from these fields (:func:`~rv_te_bench.params.param_specs`), read through the
    record (:func:`~rv_te_bench.params.params_record`); units in the descriptions.
    """

    bench_timeout_s: float = param(
        20.0, 'Give up when the bench gives no bench/info, no joint state or no controller on '
        'a command topic for this long at the start [s]', min_value=0.5, max_value=3600.0)
    feedback_period_s: float = param(0.25, 'Feedback period [s]', min_value=0.02, max_value=10.0)
    wait_for_nodes: tuple[str, ...] = param(
        ('recorder',),
        'Start a plan once these nodes (same namespace) subscribe bench/encoders, so '
        'that every step is recorded [-]')
    wait_timeout_s: float = param(
        10.0, 'Start anyway after this long when they are missing (logged) [s]', min_value=0.0,
        max_value=3600.0)


    drive_command_topic: str = param(
        'drive_velocity_controller/commands',
        "The drive (input) joint's velocity forward command controller topic "
        '(std_msgs/Float64MultiArray, [rad/s]) [-]')
    load_effort_command_topic: str = param(
        'load_effort_controller/commands',
        "The load (output) joint's effort controller topic ([N m] applied to the output) [-]")
    load_position_command_topic: str = param(
        'load_position_controller/commands',
        "The load joint's position controller topic ([rad]; constant-speed loading) [-]")
    bench_description: str = param(
        '', 'Bench description YAML whose limits (max_input_speed_rpm, max_output_torque_nm) '
        "bound every step besides the plan's safety [path]")
    setpoint_period_s: float = param(
        0.2, 'The last setpoint is sent again this often [s]', min_value=0.01, max_value=10.0)
    loss_route: str = param(
        'setpoints',
        'How whole-reducer steps (efficiency, no_load, temperature_rise, life) run: '
        "'setpoints' through the controllers like every step (input torque from "
        "bench/channels: the drive joint's effort and the case temperature topic, through "
        "the JointState adapter); 'programs' as the simulated bench's own programs "
        "(bench/run_program; also starting_torque and back_driving) [-]",
        choices=('setpoints', 'programs'))


PARAMS = param_specs(TestSequencerParams)
