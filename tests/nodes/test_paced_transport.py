"""A paced bench's process talks over UDP on the loopback only (issue 41 item 4).

Over shared memory, a writer pushes each sample into the reader's port under that port's
interprocess mutex, which ordinary time-shared threads of other processes hold too (every
writer to that reader, the reader's receive thread). Traced with eight sessions
(benchmarks/trace_multibench.py): the bench's SCHED_FIFO thread slept in publish() on that
mutex (``SharedMemManager::Port::try_push``) for 10-650 ms. The launcher therefore gives a
paced bench's process (realtime_priority > 0, real time) the UDP-only profile, and only
that process: the other nodes keep shared memory (cheaper for them, nothing paced waits).
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import pytest

from rv_te_bench.launch import session as session_mod
from rv_te_bench.launch.session import Session, bench_is_paced, build_session, child_env
from rv_te_bench.nodes.middleware import (
    PACED_PROFILE,
    PROFILE,
    PROFILE_ENV,
    use_paced_transport,
    use_quick_acknowledgements,
)

RANGE = 'ROS_AUTOMATIC_DISCOVERY_RANGE'


def _spec(*overrides: str) -> Any:
    return build_session([], namespace='paced_t', overrides=list(overrides))


def test_which_sessions_have_a_paced_bench() -> None:
    assert bench_is_paced(_spec('bench.realtime_priority=50'))
    assert bench_is_paced(_spec('bench.realtime_priority=1', 'bench.time_mode=realtime'))
    assert not bench_is_paced(_spec())                                  # default 0
    assert not bench_is_paced(_spec('bench.realtime_priority=0'))
    # fast mode: the bench ignores realtime_priority (it does not pace to the wall clock)
    assert not bench_is_paced(_spec('bench.realtime_priority=50', 'bench.time_mode=fast'))


class _FakeProc:
    def __init__(self, cmd: list[str], env: dict[str, str], **_: Any) -> None:
        self.cmd, self.env, self.pid, self.returncode = cmd, env, 0, None

    def poll(self) -> None:
        return None


@pytest.mark.parametrize('priority', [50, 0])
def test_the_launcher_gives_only_a_paced_bench_the_udp_profile(
        monkeypatch: pytest.MonkeyPatch, priority: int) -> None:
    for var in (*PROFILE_ENV, RANGE, 'RMW_IMPLEMENTATION', 'RMW_FASTRTPS_USE_QOS_FROM_XML'):
        monkeypatch.delenv(var, raising=False)
    started: dict[str, _FakeProc] = {}

    def popen(cmd: list[str], **kw: Any) -> _FakeProc:
        p = _FakeProc(cmd, **kw)
        started[cmd[3].rsplit('.', 1)[-1]] = p   # python -m rv_te_bench.nodes._entry MODULE
        return p

    monkeypatch.setattr(session_mod.subprocess, 'Popen', popen)
    monkeypatch.setattr(session_mod.time, 'sleep', lambda _s: None)
    s = Session(_spec(f'bench.realtime_priority={priority}'))
    try:
        s._start_nodes([])
    finally:
        s._tmp.cleanup()
    assert set(started) == {'bench_node', 'te_node', 'compensation_node', 'recorder'}
    for name, p in started.items():
        paced = priority > 0 and name == 'bench_node'
        assert p.env.get(PROFILE_ENV[0]) == (str(PACED_PROFILE) if paced else None), name
        assert p.env[RANGE] == ('SYSTEM_DEFAULT' if paced else 'LOCALHOST'), name


def test_a_users_profile_range_or_middleware_is_left_alone() -> None:
    env = {RANGE: 'LOCALHOST'}
    assert use_paced_transport(env)
    assert env == {RANGE: 'SYSTEM_DEFAULT', PROFILE_ENV[0]: str(PACED_PROFILE)}
    for mine in ({RANGE: 'SUBNET'}, {RANGE: 'OFF'}, {},
                 {RANGE: 'LOCALHOST', PROFILE_ENV[1]: '/etc/my.xml'},
                 {RANGE: 'LOCALHOST', 'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'},
                 {RANGE: 'LOCALHOST', 'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'}):
        env = dict(mine)
        assert not use_paced_transport(env) and env == mine
    # run_node's own call then leaves the paced profile in place
    env = {RANGE: 'LOCALHOST'}
    use_paced_transport(env)
    assert not use_quick_acknowledgements(env) and env[PROFILE_ENV[0]] == str(PACED_PROFILE)


def test_the_paced_profile_keeps_the_default_profiles_settings() -> None:
    """Same heartbeat and lease as the default profile; UDPv4 on 127.0.0.1, built-ins off."""
    import xml.etree.ElementTree as ET

    ns = {'d': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
    base, paced = ET.parse(PROFILE).getroot(), ET.parse(PACED_PROFILE).getroot()
    for path in ('.//d:heartbeatPeriod/d:nanosec', './/d:leaseDuration/d:sec',
                 './/d:leaseAnnouncement/d:sec'):
        assert paced.findtext(path, namespaces=ns) == base.findtext(path, namespaces=ns)
    assert paced.findtext('.//d:transport_descriptor/d:type', namespaces=ns) == 'UDPv4'
    assert paced.findtext('.//d:interfaceWhiteList/d:address', namespaces=ns) == '127.0.0.1'
    assert paced.findtext('.//d:useBuiltinTransports', namespaces=ns) == 'false'


_SCRIPT = textwrap.dedent("""
    import os, sys, time
    import rclpy
    from std_msgs.msg import Float64MultiArray
    from rv_te_bench.nodes import qos
    rclpy.init()
    node = rclpy.create_node('paced_t_' + sys.argv[1])
    if sys.argv[1] == 'sub':
        got = []
        node.create_subscription(Float64MultiArray, 'paced_t/blocks',
                                 lambda m: got.append(m.data[0]), qos.ENCODER_QOS)
        end = time.monotonic() + 60.0
        while len(got) < 20 and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
        print('got', len(got), flush=True)
    else:
        pub = node.create_publisher(Float64MultiArray, 'paced_t/blocks', qos.ENCODER_QOS)
        end = time.monotonic() + 60.0
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.05)
        names = sorted({open(f'/proc/self/task/{t}/comm').read().strip()
                        for t in os.listdir('/proc/self/task')})
        print('threads', ' '.join(names), flush=True)
        for k in range(40):
            pub.publish(Float64MultiArray(data=[float(k)]))
            time.sleep(0.02)
        time.sleep(1.0)
""")


@pytest.mark.ros
@pytest.mark.timeout(150)
@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='/proc/self/task')
def test_a_paced_process_reaches_a_localhost_reader_without_shared_memory(
        tmp_path: Path) -> None:
    """The environment the launcher gives a paced bench: its participant has no
    shared-memory transport (no dds.shm.* threads, as the default's has), and a reader
    with the sessions' default settings (LOCALHOST, shared memory and UDP) finds it and
    gets its messages."""
    script = tmp_path / 'paced.py'
    script.write_text(_SCRIPT, encoding='utf-8')
    base = {k: v for k, v in child_env().items() if k not in PROFILE_ENV}
    base[RANGE] = 'LOCALHOST'
    base['PYTHONPATH'] = str(Path(__file__).resolve().parents[2])
    reader_env = dict(base)
    use_quick_acknowledgements(reader_env)
    paced_env = dict(base)
    assert use_paced_transport(paced_env)
    default_env = dict(reader_env)   # a writer as every other node: shared memory on
    for writer_env, shm in ((paced_env, False), (default_env, True)):
        reader = subprocess.Popen([sys.executable, str(script), 'sub'], env=reader_env,
                                  stdout=subprocess.PIPE, text=True)
        try:
            time.sleep(0.5)
            out = subprocess.run([sys.executable, str(script), 'pub'], env=writer_env,
                                 capture_output=True, text=True, timeout=100, check=False)
            got, _ = reader.communicate(timeout=90)
        finally:
            if reader.poll() is None:
                reader.kill()
                reader.wait(timeout=30)
        threads = next((ln.split()[1:] for ln in out.stdout.splitlines()
                        if ln.startswith('threads')), None)
        assert threads is not None, (out.stdout, out.stderr)
        assert any(t.startswith('dds.shm') for t in threads) is shm, threads
        assert any(t.startswith('dds.udp') for t in threads), threads
        assert got.split()[:1] == ['got'] and int(got.split()[1]) >= 20, (got, out.stderr)
