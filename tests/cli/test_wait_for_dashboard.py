"""Which node of a session waits for the live page's bridge (``--dashboard``).

The bridge subscribes to ``bench/encoders``, never to ``joint_states``. A ros2_control bench
publishes joint states, so it must not wait for the bridge: it did, for its whole 20 s
wait, and the JointState adapter gave up on its joints meanwhile (the live test then
aborted with "no joint state read back"). The node that publishes the encoder blocks waits.
"""
from types import SimpleNamespace

from rv_te_bench.cli.dashboard import wait_for_dashboard


def _spec(bench: dict, nodes: tuple[str, ...]) -> SimpleNamespace:
    return SimpleNamespace(nodes=nodes, parameters={'bench': dict(bench)}, use_sim_time=False)


def test_a_bench_publishing_encoder_blocks_waits_for_the_page() -> None:
    spec = _spec({}, ('bench', 'te_node', 'recorder'))
    wait_for_dashboard(spec)
    assert spec.parameters['bench']['wait_for_nodes'] == ['te_node', 'recorder', 'dashboard']


def test_a_ros2_control_bench_leaves_the_waiting_to_the_adapter() -> None:
    spec = _spec({'ros2_control': True},
                 ('bench', 'joint_state_adapter', 'te_node', 'recorder', 'test_sequencer'))
    wait_for_dashboard(spec)
    assert 'wait_for_nodes' not in spec.parameters['bench']
    assert spec.parameters['joint_state_adapter']['wait_for_nodes'] == [
        'te_node', 'recorder', 'dashboard']


def test_a_joint_state_bench_without_an_adapter_waits_for_nobody() -> None:
    spec = _spec({'output': 'joint_state'}, ('bench',))
    wait_for_dashboard(spec)
    assert spec.parameters == {'bench': {'output': 'joint_state'}}
