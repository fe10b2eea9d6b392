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
    """The test sequencer's parameters (timeouts, feedback, who must record).

    Declared from these fields (:func:`~rv_te_bench.params.param_specs`), read through the
    record (:func:`~rv_te_bench.params.params_record`); units in the descriptions.
    """

    bench_timeout_s: float = param(
        20.0, 'Give up when the bench sends no block (or no bench/info) for this long [s]',
        min_value=0.5, max_value=3600.0)
    feedback_period_s: float = param(0.25, 'Feedback period [s]', min_value=0.02, max_value=10.0)
    wait_for_nodes: tuple[str, ...] = param(
        ('recorder',),
        'Start a plan once these nodes (same namespace) subscribe bench/encoders, so '
        'that every step is recorded [-]')
    wait_timeout_s: float = param(
        10.0, 'Start anyway after this long when they are missing (logged) [s]', min_value=0.0,
        max_value=3600.0)


PARAMS = param_specs(TestSequencerParams)
