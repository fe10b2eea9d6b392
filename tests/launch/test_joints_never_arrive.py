"""Issue 33 s.2: a JointState adapter whose joint names never arrive ended with exit 0 and an
empty bag ("no /clock received" the only clue). After ``joints_timeout_s`` without a sample
of both joints it now names the joints it expected and those the messages carry, in
/diagnostics (ERROR) and in the session's exit code and failure line.

Real processes (the session's adapter) and a real publisher over the middleware.
"""

from __future__ import annotations

import threading
import time

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

EXPECTED = ['input_shaft_joint', 'output_flange_joint']   # the bench description's names
SENT = ['joint_1', 'joint_2']                              # what the broadcaster publishes
TIMEOUT_S = 3.0


class Broadcaster:
    """A joint_state_broadcaster with other joint names, and a /diagnostics listener, spinning
    in a thread of the test process (the session's launcher needs the main thread)."""

    def __init__(self, domain_id: int, names: list[str] | None) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import JointState

        from rv_te_bench.nodes import qos

        self.ctx = rclpy.context.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = rclpy.create_node('broadcaster', context=self.ctx)
        self.statuses: list[tuple[int, str, dict[str, str]]] = []
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                                      qos.DIAGNOSTICS_QOS)
        if names is not None:
            pub = self.node.create_publisher(JointState, 'joint_states', qos.JOINT_STATE_QOS)
            self.k = 0

            def send() -> None:
                m = JointState()
                t_ns = 1_700_000_000_000_000_000 + self.k * 10_000_000
                m.header.stamp.sec, m.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
                m.name = list(names)
                m.position = [0.01 * self.k, 0.01 * self.k / 79.0]
                self.k += 1
                pub.publish(m)

            self.node.create_timer(0.01, send)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on_diag(self, arr) -> None:
        for st in arr.status:
            if 'joint_state_adapter' in st.name:
                level = st.level[0] if isinstance(st.level, bytes) else int(st.level)
                self.statuses.append((level, st.message, {v.key: v.value for v in st.values}))

    def _spin(self) -> None:
        while not self.stop.is_set() and self.ctx.ok():
            self.ex.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(10.0)
        self.ex.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


def _session(single_process: bool):
    from rv_te_bench.launch.session import build_session

    return build_session([], nodes=['joint_state_adapter'], single_process=single_process,
                         overrides=['joint_state_adapter.sample_rate_hz=100',
                                    f'joint_state_adapter.input_joint={EXPECTED[0]}',
                                    f'joint_state_adapter.output_joint={EXPECTED[1]}',
                                    f'joint_state_adapter.joints_timeout_s={TIMEOUT_S}'])


@pytest.mark.timeout(120)
def test_wrong_joint_names_end_the_session_non_zero_naming_both(ros_domain_id, capsys) -> None:
    from rv_te_bench.launch.session import run_session

    caster = Broadcaster(ros_domain_id, SENT)
    lines: list[str] = []
    try:
        t0 = time.monotonic()
        code = run_session(_session(False), log=lines.append)
        took = time.monotonic() - t0
        time.sleep(0.5)
    finally:
        caster.close()
    assert code == 1, lines
    assert took < TIMEOUT_S + 30.0, took           # it ends by itself, not on a Ctrl-C
    assert caster.k > 50, caster.k                 # the messages were sent all along
    failures = [ln for ln in lines if str(EXPECTED) in ln]
    assert failures == lines[-1:], lines           # one clear line, the session's last
    line = failures[0]
    assert 'exited with code 1' in line, line
    assert str(EXPECTED) in line and str(SENT) in line, line
    assert 'never in a message' in line, line
    # /diagnostics: ERROR, the same names as values
    errors = [s for s in caster.statuses if s[0] == 2]
    assert errors, caster.statuses
    _level, message, values = errors[-1]
    assert str(EXPECTED) in message and str(SENT) in message, message
    assert values['expected_joints'] == ', '.join(EXPECTED), values
    assert values['seen_joints'] == ', '.join(SENT), values
    assert values['samples'] == '0', values


@pytest.mark.timeout(120)
def test_no_joint_states_at_all_single_process(ros_domain_id, capsys) -> None:
    from rv_te_bench.launch.session import run_single_process

    caster = Broadcaster(ros_domain_id, None)      # listens to /diagnostics, sends nothing
    try:
        code = run_single_process(_session(True))
        time.sleep(0.3)
    finally:
        caster.close()
    err = capsys.readouterr().err
    assert code == 1, err
    failed = [ln for ln in err.splitlines() if ln.startswith("[launch] node 'joint_state")]
    assert len(failed) == 1, err
    assert 'no JointState message on /joint_states' in failed[0], failed
    assert str(EXPECTED) in failed[0], failed
    assert any(s[0] == 2 and values_seen_empty(s[2]) for s in caster.statuses), \
        caster.statuses


def values_seen_empty(values: dict[str, str]) -> bool:
    return values.get('seen_joints') == '' and values.get('expected_joints') == \
        ', '.join(EXPECTED)


@pytest.mark.timeout(120)
def test_the_right_names_run_on(ros_domain_id) -> None:
    """The same session with the names the broadcaster sends: no failure by the time-out."""
    from rv_te_bench.launch.session import run_session

    caster = Broadcaster(ros_domain_id, EXPECTED)
    lines: list[str] = []
    end = time.monotonic() + TIMEOUT_S + 4.0

    def tick(_session) -> None:   # a Ctrl-C once well past the time-out
        if time.monotonic() > end:
            raise KeyboardInterrupt

    try:
        code = run_session(_session(False), log=lines.append, on_tick=tick)
    finally:
        caster.close()
    assert code == 0, lines
    assert not any('exited' in ln for ln in lines), lines
    oks = [s for s in caster.statuses if s[0] == 0]
    assert oks and 'seen_joints' not in oks[-1][2], caster.statuses
