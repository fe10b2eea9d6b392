"""The node types a session can start: their modules, parameter records, command lines.

The lowest floor of :mod:`rv_te_bench.launch`: the parameter files and ``--param`` items
are checked against :func:`node_specs` (:mod:`.session`, :mod:`.launch_file`), the
start-up checks build :func:`node_record` (:mod:`.checks`), and every node process, the
single-process session and rcl's own argument check take their ``--ros-args`` from
:func:`ros_arguments`, built in this one place. The parameter records come from
:mod:`rv_te_bench.nodes.params`, which import no rclpy: reading them costs nothing of ROS.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from rv_te_bench.nodes.params import (
    bench,
    compensation,
    joint_state_adapter,
    recorder,
    te,
    test_sequencer,
)
from rv_te_bench.params import param_specs, params_record

if TYPE_CHECKING:
    from collections.abc import Mapping, Sequence
    from pathlib import Path

    from rv_te_bench.params import ParamSpec

__all__ = ['NODE_PARAMS', 'NODE_TYPES', 'node_record', 'node_specs', 'ros_arguments']

#: node name -> (module, class name); the order is the start order; shutdown runs reversed
#: except that the recorder always stops last.
NODE_TYPES: dict[str, tuple[str, str]] = {
    'recorder': ('rv_te_bench.nodes.recorder', 'RecorderNode'),
    'compensation': ('rv_te_bench.nodes.compensation_node', 'CompensationNode'),
    'te_node': ('rv_te_bench.nodes.te_node', 'TeNode'),
    'bench': ('rv_te_bench.nodes.bench_node', 'BenchNode'),
    'joint_state_adapter': ('rv_te_bench.nodes.joint_state_adapter', 'JointStateAdapterNode'),
    'test_sequencer': ('rv_te_bench.nodes.test_sequencer', 'TestSequencerNode'),
}

#: node name -> its parameter record (the fields are its declared parameters).
NODE_PARAMS: dict[str, type] = {
    'recorder': recorder.RecorderParams,
    'compensation': compensation.CompensationParams,
    'te_node': te.TeParams,
    'bench': bench.BenchParams,
    'joint_state_adapter': joint_state_adapter.JointStateAdapterParams,
    'test_sequencer': test_sequencer.TestSequencerParams,
}


def node_specs(name: str) -> tuple[ParamSpec, ...]:
    """The parameter specs of a node type (``KeyError`` for an unknown one)."""
    return param_specs(NODE_PARAMS[name])


def node_record(name: str, values: Mapping[str, Any]) -> Any:
    """A node's parameter record from the session's values (defaults for the rest)."""
    return params_record(NODE_PARAMS[name], values)


def ros_arguments(*, node: str | None, namespace: str = '',
                  remappings: Sequence[tuple[str, str]] = (),
                  params_file: Path | None = None) -> list[str]:
    """The ``--ros-args`` of a node process (or of a process of several nodes: ``node``
    None, no ``__node`` rule): its name, the namespace, the remappings in order, the
    parameter file."""
    args = ['--ros-args']
    if node is not None:
        args += ['-r', f'__node:={node}']
    if namespace:
        args += ['-r', f'__ns:={namespace}']
    for a, b in remappings:
        args += ['-r', f'{a}:={b}']
    if params_file is not None:
        args += ['--params-file', str(params_file)]
    return args
