"""JointState adapter throughput: the highest one-sample-per-message rate kept lossless.

For each rate, a publisher process sends ``--duration-s`` worth of ``sensor_msgs/JointState``
(both joints in one message, one sample each, stamps 1/rate apart: what
``joint_state_broadcaster`` publishes) to a receiver process, first a **bare rclpy
subscriber** (EventsExecutor, a callback that reads the stamp and both positions: the floor
of any Python JointState consumer), then the **joint_state_adapter** node (EventsExecutor, as
``run_node`` runs it), on the same messages, one after the other in one run. Reported per
receiver: messages received / sent, lossless (adapter: every sample in a published
EncoderBlock and 0 gaps), the receiver's CPU per message [us] and its CPU share.

    .venv/bin/python benchmarks/bench_joint_state.py --rates 1000 2000 5000 10000 --duration-s 5

Prints a markdown table (it replaces the script's table in benchmarks/README.md, with the
machine and date; the old one moves to benchmarks/HISTORY.md).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
NAMES = ['input_joint', 'output_joint']


def cpu_s() -> float:
    """utime + stime of this process [s]."""
    t = os.times()
    return t.user + t.system


def role_pub(rate_hz: float, n: int) -> None:
    import rclpy
    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import JointState

    from rv_te_bench.nodes import qos

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('js_bench_pub', context=ctx)
    pub = node.create_publisher(JointState, 'joint_states', qos.JOINT_STATE_QOS)
    end = time.monotonic() + 20.0
    while pub.get_subscription_count() < 1 and time.monotonic() < end:
        time.sleep(0.05)
    time.sleep(1.0)   # discovery settles (reliable: the reader must be matched both ways)
    t0_ns = time.time_ns()
    period_ns = round(1e9 / rate_hz)
    start = time.perf_counter()
    for i in range(n):
        due = start + i / rate_hz
        delay = due - time.perf_counter()
        if delay > 0.0005:
            time.sleep(delay)
        t = t0_ns + i * period_ns
        m = JointState()
        m.header.stamp = Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)
        m.name = NAMES
        m.position = [0.001 * i, 0.001 * i / 79.0]
        pub.publish(m)
    elapsed = time.perf_counter() - start
    time.sleep(1.0)
    print(json.dumps({'sent': n, 'send_rate_hz': n / elapsed}))
    node.destroy_node()
    rclpy.try_shutdown(context=ctx)


def role_recv(kind: str, rate_hz: float, n: int, timeout_s: float) -> None:
    import rclpy
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    from rv_te_bench.nodes import qos
    from rv_te_bench.nodes.common import make_executor

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    state = {'count': 0, 'first': 0.0, 'last': 0.0}
    if kind == 'bare':
        node = rclpy.create_node('js_bench_bare', context=ctx)

        def on_msg(msg: JointState) -> None:
            st = msg.header.stamp
            _ = (st.sec * 1_000_000_000 + st.nanosec, msg.position[0], msg.position[1])
            state['count'] += 1

        node.create_subscription(JointState, 'joint_states', on_msg, qos.JOINT_STATE_QOS)

        def count() -> int:
            return state['count']
    else:
        from rv_te_bench.nodes.joint_state_adapter import JointStateAdapterNode

        node = JointStateAdapterNode(context=ctx, parameter_overrides=[
            Parameter('sample_rate_hz', value=rate_hz),
            Parameter('block_size', value=max(1, int(rate_hz // 100)))])

        def count() -> int:
            return node.assembler.counters['messages']
    ex = make_executor('events', context=ctx)
    ex.add_node(node)
    c0 = None
    end = time.monotonic() + timeout_s
    last_change, last = time.monotonic(), 0
    while time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
        got = count()
        if got and c0 is None:
            c0 = cpu_s() - 0.0
        if got != last:
            last, last_change = got, time.monotonic()
        if got >= n or (got and time.monotonic() - last_change > 3.0):
            break
    cpu = cpu_s() - (c0 or cpu_s())
    result: dict[str, object] = {'received': count(), 'cpu_s': cpu}
    if kind == 'adapter':
        node.assembler.finish()
        c = node.assembler.counters
        result.update({'gaps': c['gaps'], 'samples_in_blocks': c['samples']
                       + node.assembler.pending_samples, 'blocks': node.blocks_published})
    print(json.dumps(result))
    ex.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=ctx)


def _spawn(args: list[str]) -> subprocess.Popen[str]:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return subprocess.Popen([sys.executable, __file__, *args], stdout=subprocess.PIPE,
                            text=True, env=env)


def run(kind: str, rate_hz: float, duration_s: float) -> dict[str, object]:
    n = int(rate_hz * duration_s)
    recv = _spawn(['--role', kind, '--rate', str(rate_hz), '--n', str(n),
                   '--timeout', str(duration_s + 30)])
    time.sleep(1.5)
    pub = _spawn(['--role', 'pub', '--rate', str(rate_hz), '--n', str(n)])
    p_out, _ = pub.communicate(timeout=duration_s + 60)
    r_out, _ = recv.communicate(timeout=duration_s + 60)
    res = {**json.loads(p_out.strip().splitlines()[-1]),
           **json.loads(r_out.strip().splitlines()[-1])}
    res['lossless'] = res['received'] == n and (
        kind == 'bare' or (res['gaps'] == 0 and res['samples_in_blocks'] == n))
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rates', type=float, nargs='+', default=[1000, 2000, 5000, 10000])
    ap.add_argument('--duration-s', type=float, default=5.0)
    ap.add_argument('--role', choices=['pub', 'bare', 'adapter'], help=argparse.SUPPRESS)
    ap.add_argument('--rate', type=float, help=argparse.SUPPRESS)
    ap.add_argument('--n', type=int, help=argparse.SUPPRESS)
    ap.add_argument('--timeout', type=float, default=60.0, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.role == 'pub':
        role_pub(a.rate, a.n)
        return 0
    if a.role in {'bare', 'adapter'}:
        role_recv(a.role, a.rate, a.n, a.timeout)
        return 0
    print(f'# {platform.node()} {platform.machine()} {os.cpu_count()} cores, '
          f'Python {platform.python_version()}, '
          f'{time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}'
          f', load {os.getloadavg()[0]:.2f}')
    print('| rate [msg/s] | receiver | sent rate [msg/s] | received / sent | lossless | '
          'CPU per message [us] | CPU share |')
    print('|---|---|---|---|---|---|---|')
    for rate in a.rates:
        for kind in ('bare', 'adapter'):
            r = run(kind, rate, a.duration_s)
            n = int(rate * a.duration_s)
            per_msg = 1e6 * float(r['cpu_s']) / max(1, int(r['received']))  # type: ignore[arg-type]
            share = float(r['cpu_s']) / a.duration_s  # type: ignore[arg-type]
            extra = f", {r['gaps']} gaps" if kind == 'adapter' else ''
            print(f"| {rate:g} | {kind} | {float(r['send_rate_hz']):.0f} | "  # type: ignore[arg-type]
                  f"{r['received']} / {n}{extra} | {'yes' if r['lossless'] else 'NO'} | "
                  f'{per_msg:.1f} | {100 * share:.0f} % |', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
