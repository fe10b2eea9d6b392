"""A session with the joint_state_adapter: who waits for whom (no ROS needed)."""

from __future__ import annotations

from rv_te_bench.launch.session import build_session, node_parameters


def test_adapter_holds_for_te_node_and_recorder_and_the_bench_waits_for_the_adapter() -> None:
    spec = build_session([], nodes=['bench', 'joint_state_adapter', 'te_node', 'recorder'],
                         overrides=['bench.output=joint_state',
                                    'joint_state_adapter.sample_rate_hz=1000'])
    assert node_parameters(spec, 'joint_state_adapter')['wait_for_nodes'] == ['te_node',
                                                                             'recorder']
    assert node_parameters(spec, 'bench')['wait_for_nodes'] == ['joint_state_adapter']


def test_encoder_block_bench_waits_as_before() -> None:
    spec = build_session([], nodes=['bench', 'te_node', 'recorder'])
    assert node_parameters(spec, 'bench')['wait_for_nodes'] == ['te_node', 'recorder']
    spec = build_session([], nodes=['joint_state_adapter', 'te_node'],
                         overrides=['joint_state_adapter.sample_rate_hz=1000'])
    assert node_parameters(spec, 'joint_state_adapter')['wait_for_nodes'] == ['te_node']
