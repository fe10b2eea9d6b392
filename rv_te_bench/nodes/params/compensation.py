"""The parameters of the compensation node: one frozen record, declared from its fields.

The node is :mod:`rv_te_bench.nodes.compensation_node`.
No rclpy here: the launcher checks parameter files against :data:`PARAMS` before any node
starts (:mod:`rv_te_bench.launch.node_specs`).
"""

from __future__ import annotations

from dataclasses import dataclass

from rv_te_bench.params import param, param_specs

__all__ = ['PARAMS', 'CompensationParams']


@dataclass(frozen=True)
class CompensationParams:
    """The compensation node's parameters (preset, phase search, identification).

    Declared from these fields (:func:`~rv_te_bench.params.param_specs`), read through the
    record (:func:`~rv_te_bench.params.params_record`); units in the descriptions.
    """

    preset: str = param('', 'Reducer preset; empty = the preset named in bench/info [-]')
    overrides: tuple[str, ...] = param((), 'Preset overrides "key=value" [-]')
    optimize_phases: bool = param(
        True, 'Run the Wang 2020 Eq. 21 assembly-phase optimisation for 2K-V presets')
    step_deg: float = param(10.0, 'Phase grid step [deg]', min_value=0.5, max_value=90.0)
    refine: bool = param(True, 'Refine the grid optimum below the grid step')
    identify: bool = param(True, 'Identify eccentricities from each complete window (2K-V presets)')
    te_metric: str = param(
        'pp',
        'Measured statistic given to the tooth-profile '
        'compensation (RV presets) [-]',
        choices=('pp', 'amplitude'))
    diagnostics_period_s: float = param(
        1.0, 'Diagnostics period [s]', min_value=0.05, max_value=60.0)
    search_process: bool = param(
        True,
        'Run the searches in a worker process of the node (off its interpreter lock: in a '
        'one-process session the bench paces without waiting for them); false: on a thread '
        'of the node\'s process')
    search_nice: int = param(
        10,
        'Niceness added to the searches\' process or thread (Linux): the searches yield the '
        'cores to the data path of the benches (0: same priority as the node) [-]',
        min_value=0, max_value=19)


PARAMS = param_specs(CompensationParams)
