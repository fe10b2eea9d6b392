"""N benches live (issue #23 item 1, issue #41 item 4): N sessions side by side, each in its own
namespace.

Each session is a full one (bench -> TE node -> compensation node, recorder), one process per
node, real time, in namespace ``/benchK`` (the launcher's namespace support: ``rv-te launch
--namespace benchK``). For each bench it reports what bench_pipeline.py reports for one:
blocks published / recorded / processed by the TE node, TE gaps, CPU per node (utime +
stime from /proc over the wall time after the warm-up), and the bench's largest lag behind
its clock (its own diagnostics). The first ``--probes`` benches (default 1) also get a probe
node in the driver: blocks seen, a block's arrival after the end of its samples, and the
latency from a block's arrival to the TE samples computed from it (the probes read raw CDR
and decode the stamp only; each still costs the driver ~2 % of a core at 10 kHz, which is
why not every bench is probed by default).

The target (#41): 0 lost, 0 gaps, and each bench's lag after the warm-up within 1 ms of the
machine's floor measured beside it (a bare paced thread with the benches' scheduling, no
middleware: ``--no-rt-probe`` leaves it out, and the lag is then judged against one block
period). The output ends with the row for benchmarks/README.md's index.

    .venv/bin/python benchmarks/bench_multibench.py --benches 8 --duration-s 600   # 10 kHz, 100
    .venv/bin/python benchmarks/bench_multibench.py --benches 1 --duration-s 60 --no-rt-probe
    .venv/bin/python benchmarks/bench_multibench.py --floor             # the middleware floor
    .venv/bin/python benchmarks/bench_multibench.py --realtime-priority 0   # no SCHED_FIFO

The benches run with ``realtime_priority: 50`` by default (their pacing thread on SCHED_FIFO,
as a test PC runs its DAQ node; root or an rtprio limit needed, else they say 'normal' in the
scheduling line and run without it).

``--floor`` runs N bare rclpy publisher / subscriber pairs (a process each) of the same
EncoderBlock messages (same size, same rate, ENCODER_QOS, EventsExecutor, a timer that
publishes what the clock says is due, like the bench): the cost of rclpy + Fast DDS alone,
the least any node that sends or receives these blocks can cost.

Everything goes to a temporary folder that is removed at the end (``--keep`` keeps the bags).
Prints a markdown table per bench and a total CPU line.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import platform
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

sys.path.insert(0, str(Path(__file__).resolve().parent))


NODES = ('bench', 'te_node', 'compensation', 'recorder')
#: The driver's own CPU (this process; the node processes are its children).
DRIVER = 'driver (probes)'
PROBE = 'multibench_probe'
#: The process layouts of a session: one process per node (``rv-te launch``), or all four
#: nodes in one process on one executor (``rv-te launch --single-process``).
LAYOUTS = ('per-node', 'single')


def cdr_stamp_s(data: bytes) -> float:
    """header.stamp of a serialised message whose first field is a std_msgs/Header [s]."""
    fmt = '<iI' if data[1] == 1 else '>iI'   # encapsulation: CDR_LE (0x0001) or CDR_BE
    sec, nsec = struct.unpack_from(fmt, data, 4)
    return sec + nsec * 1e-9


def cpu_tree_s(pid: int, *, children: bool = True) -> float:
    """utime + stime of a process and of its children, those still running and those it
    has waited for [s] (0 when it is gone): a node's compensation searches run in a worker
    process of its own (issue 41 item 4), which is the node's cost too."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0
    if not children:
        return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
    total = sum(int(f) for f in fields[11:15]) / os.sysconf('SC_CLK_TCK')
    try:
        kids = [int(k) for t in Path(f'/proc/{pid}/task').iterdir()
                for k in (t / 'children').read_text().split()]
    except OSError:
        kids = []
    return total + sum(cpu_tree_s(k) for k in kids)


class CpuMeter:
    """CPU of named processes (with their children: :func:`cpu_tree_s`) from a start (after
    warm-up) to their last reading alive."""

    def __init__(self) -> None:
        """Nothing measured yet."""
        self.start: dict[str, tuple[float, float]] = {}
        self.end: dict[str, tuple[float, float]] = {}

    def begin(self, pids: dict[str, int]) -> None:
        """Take the first reading of every process."""
        now = time.monotonic()
        self.start = {n: (cpu_tree_s(p, children=not n.startswith(DRIVER)), now)
                      for n, p in pids.items()}

    def sample(self, pids: dict[str, int], alive: dict[str, bool]) -> None:
        """Keep the last reading of each live process (a bench exits at its end)."""
        now = time.monotonic()
        for n, p in pids.items():
            c = cpu_tree_s(p, children=not n.startswith(DRIVER))   # (its children: nodes)
            if c > 0 and alive.get(n, True):
                self.end[n] = (c, now)

    def pct(self) -> dict[str, float]:
        """Percent of one core per process over its measured interval."""
        out = {}
        for n, (c1, w1) in self.end.items():
            if n in self.start:
                c0, w0 = self.start[n]
                out[n] = 100.0 * (c1 - c0) / max(w1 - w0, 1e-9)
        return out

    def seconds(self) -> dict[str, float]:
        """CPU seconds per process over its measured interval."""
        return {n: c1 - self.start[n][0] for n, (c1, _) in self.end.items() if n in self.start}


def _stop_on_sigterm() -> dict[str, Any]:
    """SIGTERM / SIGINT raise KeyboardInterrupt once (the finally blocks stop every node)."""
    def handler(*_: object) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        raise KeyboardInterrupt

    return {s: signal.signal(s, handler) for s in (signal.SIGTERM,)}


# -- the pipeline: N full sessions ---------------------------------------------------------

class OneProcessSession:
    """A session with its four nodes in one process (a child of this script that runs
    :func:`rv_te_bench.launch.session.run_single_process`, as ``rv-te launch
    --single-process`` does), with the parts of :class:`~rv_te_bench.launch.session.Session`
    the driver uses: ``procs`` (one, named 'session'), ``failures``, ``poll``, ``stop``."""

    def __init__(self, ns: str, overrides: list[str]) -> None:
        """Prepare; nothing starts until :meth:`start`."""
        self.ns, self.overrides = ns, overrides
        self.procs: dict[str, Any] = {}
        self.failures: list[str] = []

    def start(self) -> None:
        """Start the session's process."""
        from rv_te_bench.launch.session import NodeProcess, child_env

        cmd = [sys.executable, str(Path(__file__).resolve()), '--_session', self.ns,
               '--_overrides', json.dumps(self.overrides)]
        self.procs['session'] = NodeProcess('session', subprocess.Popen(
            cmd, env=child_env(), start_new_session=True))

    def poll(self) -> dict[str, int | None]:
        """Exit code so far; a non-zero one is a failure."""
        np_ = self.procs['session']
        code = np_.proc.poll()
        if code is not None and not np_.expected_exit:
            np_.expected_exit = True
            if code != 0:
                self.failures.append(f'session {self.ns} exited with code {code}')
        return {'session': code}

    def stop(self) -> dict[str, int | None]:
        """SIGTERM (the session stops its nodes in data-flow order), then SIGKILL."""
        proc = self.procs['session'].proc
        self.procs['session'].expected_exit = True
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        return {'session': proc.returncode}


def one_process_session(ns: str, overrides: list[str]) -> int:
    """The child of :class:`OneProcessSession`: the session's nodes in this process."""
    from rv_te_bench.launch.session import build_session, run_single_process

    spec = build_session([], namespace=ns, nodes=list(NODES), overrides=overrides,
                         single_process=True)
    return run_single_process(spec)


def run_benches(n_benches: int, rate_hz: float, block: int, duration_s: float,
                out_dir: Path, warmup_s: float = 2.0, profile_s: float = 0.0,
                start_timeout_s: float = 90.0, extra_params: tuple[str, ...] = (),
                rt_probe_priority: int = -1, probes: int | None = None,
                first: int = 1, layout: str = 'per-node') -> dict[str, Any]:
    """Run N sessions side by side; return per-bench results and per-process CPU.

    ``probes``: how many benches (the first ones) get a probe node (block arrival,
    latency); None: every bench. A probe reads two topics of its bench, 150 messages/s at
    10 kHz: eight of them cost the driver a fifth of a core, which the benches would feel.
    ``first``: the number of the first namespace (``/bench<first>``), so that two runs
    (two versions of the code) can go side by side in one ROS domain.
    ``layout``: 'per-node' (a process per node) or 'single' (a session's four nodes in one
    process on one executor); the CPU is then per session, not per node.
    """
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rv_te_msgs.msg import EncoderBlock, TransmissionError

    from rv_te_bench.io.bag_reader import bag_summary
    from rv_te_bench.launch.session import Session, build_session
    from rv_te_bench.nodes import qos
    from rv_te_bench.nodes.common import make_executor

    names = [f'bench{k + first}' for k in range(n_benches)]
    probed = names if probes is None else names[:max(0, probes)]
    specs, overrides = {}, {}
    for ns in names:
        waits = f'te_node, recorder, {PROBE}' if ns in probed else 'te_node, recorder'
        overrides[ns] = [
            'bench.te_mode=nlte', f'bench.bench_id={ns}', f'bench.sample_rate_hz={rate_hz}',
            f'bench.block_size={block}', f'bench.duration_s={duration_s}',
            'bench.time_mode=realtime',
            f'recorder.output_dir={out_dir}', f'recorder.bag_name={ns}',
            f'bench.wait_for_nodes=[{waits}]',
            f'bench.wait_timeout_s={start_timeout_s + 30.0}', *extra_params]
        specs[ns] = build_session([], namespace=ns, nodes=list(NODES), overrides=overrides[ns])
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    ex = make_executor('events', context=ctx)
    probes = []
    block_arrival: dict[str, list[tuple[float, float]]] = {ns: [] for ns in names}
    te_arrival: dict[str, list[tuple[float, float]]] = {ns: [] for ns in names}
    diags: dict[str, dict[str, str]] = {}
    # the benches' own lag after the warm-up: the largest 'lag_period_max_s' (the bench's
    # largest lag since its previous diagnostics message) of the messages sent after it
    steady_lag: dict[str, float] = {}
    in_steady = [False]

    def on_diag(m: DiagnosticArray) -> None:
        for st in m.status:
            values = {kv.key: kv.value for kv in st.values}
            diags[st.name] = values
            if in_steady[0] and 'lag_period_max_s' in values:
                steady_lag[st.name] = max(steady_lag.get(st.name, 0.0),
                                          float(values['lag_period_max_s']))

    watch = rclpy.create_node('multibench_watch', context=ctx)
    watch.create_subscription(DiagnosticArray, '/diagnostics', on_diag, qos.DIAGNOSTICS_QOS)
    ex.add_node(watch)

    def add_probes() -> None:
        """The probes the benches wait for: made once every node of every session is up,
        so that the benches start their clocks together, after the start-up of all."""
        for ns in probed:
            p = rclpy.create_node(PROBE, namespace=ns, context=ctx)
            blocks, tes = block_arrival[ns], te_arrival[ns]
            p.create_subscription(EncoderBlock, 'bench/encoders',
                                  lambda d, b=blocks: b.append((cdr_stamp_s(d), time.time())),
                                  qos.ENCODER_QOS, raw=True)
            p.create_subscription(TransmissionError, 'te/samples',
                                  lambda d, t=tes: t.append((cdr_stamp_s(d), time.time())),
                                  qos.ENCODER_QOS, raw=True)
            ex.add_node(p)
            probes.append(p)

    def all_up() -> bool:
        have = set(watch.get_node_names_and_namespaces())
        return all((n, f'/{ns}') in have for ns in names for n in NODES)

    sessions: dict[str, Any] = {
        ns: OneProcessSession(ns, overrides[ns]) if layout == 'single'
        # (each node's output in its own file: a crash report shows the node's last lines)
        else Session(specs[ns], log=lambda s: print(s, file=sys.stderr),
                     log_dir=out_dir / 'logs' / ns) for ns in names}
    kinds = ('session',) if layout == 'single' else NODES
    ends = 'session' if layout == 'single' else 'bench'
    meter = CpuMeter()
    crashed: list[str] = []
    interrupted = False
    old = _stop_on_sigterm()
    try:
        for s in sessions.values():
            s.start()
        up_by = time.monotonic() + start_timeout_s
        while not all_up():
            ex.spin_once(timeout_sec=0.1)
            for s in sessions.values():
                s.poll()
            if time.monotonic() > up_by or any(s.failures for s in sessions.values()):
                print('not every node came up: starting the benches anyway', file=sys.stderr)
                break
        add_probes()

        def pids() -> dict[str, int]:
            d = {f'{ns}/{n}': p.proc.pid for ns, s in sessions.items()
                 for n, p in s.procs.items()}
            d[DRIVER] = os.getpid()
            return d

        def alive() -> dict[str, bool]:
            return {f'{ns}/{n}': p.proc.poll() is None for ns, s in sessions.items()
                    for n, p in s.procs.items()}

        last, streaming = 0.0, 0.0
        spies: list[subprocess.Popen[bytes]] = []
        rt_probe: subprocess.Popen[str] | None = None
        while True:
            ex.spin_once(timeout_sec=0.1)
            now = time.monotonic()
            if not streaming and all(block_arrival[ns] for ns in probed) and (
                    probed or all(f'/{ns}/bench: bench' in diags for ns in names)):
                streaming = now   # every bench publishes: measure from warm-up on
            if not meter.start and streaming and now - streaming > warmup_s:
                meter.begin(pids())
                in_steady[0] = True
                if profile_s > 0:
                    spies = start_profiles(sessions[names[0]], profile_s, out_dir / 'profile')
                if rt_probe_priority >= 0:   # the machine's wake-up floor, beside the benches
                    rt_probe = start_rt_probe(duration_s - warmup_s - 1.0,
                                              block / rate_hz, rt_probe_priority)
            if meter.start and now - last > 1.0:
                last = now
                meter.sample(pids(), alive())
            for ns, s in sessions.items():
                s.poll()
                if s.failures and ns not in crashed:
                    crashed.append(ns)
            if crashed or all(s.procs[ends].proc.poll() is not None
                              for s in sessions.values()):
                break
        end = time.monotonic() + 3.0   # the TE nodes and the recorders take the last blocks
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
    except KeyboardInterrupt:
        interrupted = True
        print('interrupted: stopping every session', file=sys.stderr)
    finally:
        floor = finish_rt_probe(rt_probe)
        for spy in spies:
            try:
                spy.wait(timeout=profile_s + 30)
            except subprocess.TimeoutExpired:
                spy.kill()
                spy.wait()
        codes, stop_wall = {}, {}
        for ns, s in sessions.items():
            t_stop = time.monotonic()
            codes[ns] = s.stop()
            stop_wall[ns] = time.monotonic() - t_stop
        ex.shutdown()
        for p in [*probes, watch]:
            p.destroy_node()
        rclpy.try_shutdown(context=ctx)
        for sig, h in old.items():
            signal.signal(sig, h)
    if interrupted:
        raise KeyboardInterrupt
    cpu = meter.pct()
    expected = round(duration_s * rate_hz / block)
    benches = []
    for ns in names:
        topics = bag_summary(out_dir / ns).get('topics', {})
        recorded = next((t.get('count', t.get('message_count')) for name, t in topics.items()
                         if name.endswith('bench/encoders')), None) \
            if isinstance(topics, dict) else None
        lat = []
        b = np.asarray(block_arrival[ns]) if block_arrival[ns] else np.zeros((0, 2))
        if len(b):
            order = np.argsort(b[:, 0])
            b = b[order]
            for stamp, arr in te_arrival[ns]:
                k = np.searchsorted(b[:, 0], stamp, side='right') - 1
                if 0 <= k < len(b) and stamp < b[k, 0] + block / rate_hz + 1e-9:
                    lat.append(arr - b[k, 1])
        lat_ms = np.asarray(lat) * 1e3 if lat else np.asarray([np.nan])
        # lag seen at the probe: a block's arrival after the end of its samples (bench lag +
        # delivery), after the warm-up; and when the worst one came (s after the first block)
        probe_lag = (b[:, 1] - b[:, 0] - block / rate_hz) if len(b) else np.asarray([np.nan])
        skip = int(warmup_s * rate_hz / block)
        steady = probe_lag[skip:] if len(probe_lag) > skip else probe_lag
        worst = int(np.nanargmax(steady)) + (skip if len(probe_lag) > skip else 0) \
            if np.isfinite(steady).any() else 0
        te_diag = diags.get(f'/{ns}/te_node: te analysis', {})
        bench_diag = diags.get(f'/{ns}/bench: bench', {})
        published = bench_diag.get('blocks_published')
        if bench_diag.get('finished') != 'True' and published is not None:
            published = f'>={published}'   # the bench's last diagnostics did not arrive
        benches.append({
            'ns': ns, 'expected': expected,
            'published': published,
            'probe': len(block_arrival[ns]) if ns in probed else None, 'recorded': recorded,
            'te': te_diag.get('blocks'), 'te_gaps': te_diag.get('gaps_reported'),
            'lag_max_s': bench_diag.get('lag_max_s'),
            'steady_lag_max_s': steady_lag.get(f'/{ns}/bench: bench'),
            'scheduling': bench_diag.get('scheduling', '?'),
            # (a node that did not stop on SIGTERM failed its stop even if it exited 0)
            'crashed': ns in crashed or bool(sessions[ns].failures)
            or any(c not in (0, None) for c in codes[ns].values()),
            'crash_report': crash_report(sessions[ns], codes[ns], out_dir / 'logs' / ns),
            'stop_s': stop_wall[ns], 'node_stop_s': dict(getattr(sessions[ns], 'stop_s', {})),
            'cpu': {n: cpu.get(f'{ns}/{n}', float('nan')) for n in kinds},
            'probe_lag_max_ms': float(np.nanmax(steady)) * 1e3,
            'probe_lag_p99_ms': float(np.nanpercentile(steady, 99)) * 1e3,
            'probe_late': int(np.count_nonzero(steady > block / rate_hz)),
            'probe_n': int(steady.size),
            'probe_lag_worst_at_s': worst * block / rate_hz,
            'lat_median_ms': float(np.nanmedian(lat_ms)),
            'lat_p99_ms': float(np.nanpercentile(lat_ms, 99)),
        })
    return {'benches': benches, 'cpu': cpu, 'rt_floor': floor, 'cpu_s': meter.seconds(),
            'kinds': kinds, 'layout': layout,
            'measured_s': max((w for _, w in meter.end.values()), default=0.0)
            - min((w for _, w in meter.start.values()), default=0.0),
            'profiles': sorted((out_dir / 'profile').glob('*.txt')) if profile_s else []}


def crash_report(session: Any, codes: dict[str, int | None], log_dir: Path,
                 tail: int = 40) -> list[str]:
    """What went wrong in one session: its failures (a node that ended on its own, or did
    not stop on SIGTERM: where it was in its stop), each node that ended with an error (exit
    code or signal, how long its stop took) with the last lines of its output; [] if none."""
    from rv_te_bench.launch.session import exit_text

    lines = list(session.failures)
    stop_s = getattr(session, 'stop_s', {})
    for node, code in codes.items():
        if code in (0, None):
            continue
        took = stop_s.get(node)
        lines.append(f'node {node!r} ended {exit_text(code)}'
                     + (f', {took:.1f} s after its SIGTERM' if took is not None else
                        ' before the stop'))
        log = log_dir / f'{node}.log'
        with contextlib.suppress(OSError):
            last = log.read_text(encoding='utf-8', errors='replace').splitlines()[-tail:]
            lines += [f'  {node}: {x[:300]}' for x in last]
    return lines


def rt_probe(seconds: float, period_s: float, priority: int) -> int:
    """The machine's floor for a paced thread (a child process): a bare thread that sleeps
    to every period boundary, scheduled as the benches' pacing threads (``realtime_priority``
    ``priority``; 0: normal), with no middleware, messages or other work; prints how late it
    woke (JSON, ms)."""
    import gc

    from rv_te_bench.nodes.scheduling import realtime_scheduling

    sched = realtime_scheduling(priority)   # what the benches' pacing threads get
    gc.disable()
    late = np.empty(int(seconds / period_s) + 1)
    t0 = time.monotonic()
    for k in range(late.size):
        target = t0 + (k + 1) * period_s
        wait = target - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        late[k] = time.monotonic() - target
    ms = late * 1e3
    print(json.dumps({'scheduling': sched, 'n': int(ms.size), 'max_ms': float(ms.max()),
                      'p99_ms': float(np.percentile(ms, 99)),
                      'over_period': int(np.count_nonzero(ms > period_s * 1e3))}), flush=True)
    return 0


def start_rt_probe(seconds: float, period_s: float, priority: int) -> subprocess.Popen[str]:
    """Start :func:`rt_probe` in a child process for ``seconds``."""
    return subprocess.Popen(
        [sys.executable, __file__, '--_rt-probe', str(max(1.0, seconds)),
         '--_period', str(period_s), '--_priority', str(priority)],
        stdout=subprocess.PIPE, text=True)


def finish_rt_probe(proc: subprocess.Popen[str] | None) -> dict[str, Any] | None:
    """The probe's result (it ends on its own; stopped if the run was cut short)."""
    if proc is None:
        return None
    try:
        out, _ = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        return None
    with contextlib.suppress(ValueError):
        return json.loads(out.strip().splitlines()[-1]) if out.strip() else None
    return None


def start_profiles(session: Any, seconds: float, folder: Path,
                   ) -> list[subprocess.Popen[bytes]]:
    """py-spy record (collapsed stacks, all threads, GIL-idle excluded) of each node of one
    session for ``seconds``; [] when py-spy is not installed."""
    spy = shutil.which('py-spy') or str(Path(sys.executable).parent / 'py-spy')
    if not Path(spy).exists():
        print('--profile-s: py-spy not found (pip install py-spy)', file=sys.stderr)
        return []
    folder.mkdir(parents=True, exist_ok=True)
    procs = []
    for name, np_ in session.procs.items():
        procs.append(subprocess.Popen(
            [spy, 'record', '--pid', str(np_.proc.pid), '--duration', str(int(seconds)),
             '--rate', '250', '--nonblocking', '--format', 'raw',
             '--output', str(folder / f'{name}.txt')],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    return procs


def print_profiles(paths: list[Path], top: int = 12) -> None:
    """Per node: where the sampled (non-idle) time goes, by innermost frame of our code or
    of rclpy, and by the top-level callback."""
    for path in paths:
        leaf: dict[str, int] = {}
        total = 0
        for line in path.read_text().splitlines():
            stack, _, count = line.rpartition(' ')
            if not count.isdigit():
                continue
            n = int(count)
            total += n
            frames = stack.split(';')
            key = frames[-1]
            leaf[key] = leaf.get(key, 0) + n
        print(f'\nprofile {path.stem}: {total} samples (self time by function)\n')
        print('| function | share |')
        print('|---|---|')
        for k, v in sorted(leaf.items(), key=lambda kv: -kv[1])[:top]:
            print(f'| `{k[:110]}` | {100.0 * v / max(total, 1):.1f} % |')


def _f(v: Any, fmt: str = '{:.1f}') -> str:
    try:
        return fmt.format(float(v))
    except (TypeError, ValueError):
        return str(v)


def lag_limit_ms(res: dict[str, Any], period_ms: float) -> tuple[float, str]:
    """The lag a bench may show after the warm-up: within 1 ms of the machine's floor
    measured beside it (a bare paced thread; issue #41 item 4), or one block period when
    the floor was not measured; and how it was set."""
    fl = res.get('rt_floor')
    if fl and math.isfinite(float(fl.get('max_ms', math.nan))):
        return float(fl['max_ms']) + 1.0, f"floor {float(fl['max_ms']):.1f} ms + 1 ms"
    return period_ms, f'one block period ({period_ms:g} ms; floor not measured)'


def print_benches(res: dict[str, Any], args: argparse.Namespace) -> bool:
    """The per-bench table, the CPU lines and the README row; True when every bench met
    the target (0 lost, 0 gaps, no crash, lag within the limit of :func:`lag_limit_ms`)."""
    period_ms = 1e3 * args.block_size / args.rate_hz
    limit_ms, limit_why = lag_limit_ms(res, period_ms)
    kinds = res.get('kinds', NODES)
    one = tuple(kinds) == ('session',)
    print(f'\n{args.benches} benches x {args.rate_hz:g} Hz, blocks of {args.block_size} '
          f'(block period {period_ms:g} ms), {args.duration_s:g} s real time; '
          + ('each session in one process (its four nodes on one executor)' if one
             else 'one process per node') + '\n')
    print('| bench | blocks expected / published / probe / recorded / TE | TE gaps | crashed | '
          + ('CPU of the session\'s process | ' if one else
             'CPU bench / TE / compensation / recorder (sum) | ') +
          'bench lag max after the warm-up (whole run) | '
          'block arrival after its end, max / p99 (worst at) | '
          'blocks arriving > 1 period after their end | '
          'latency block->TE median / p99 |')
    print('|---|---|---|---|---|---|---|---|---|')
    ok = True
    lags, lost_gaps = [], 0
    probe_short: list[str] = []
    for b in res['benches']:
        c = b['cpu']
        lag_ms = float(b['lag_max_s']) * 1e3 if b['lag_max_s'] is not None else float('nan')
        steady_ms = (float(b['steady_lag_max_s']) * 1e3 if b['steady_lag_max_s'] is not None
                     else float('nan'))
        lags.append(steady_ms)
        counts = [b['published'], '-' if b['probe'] is None else b['probe'], b['recorded'],
                  b['te']]
        # the session's own readers; the probe is the driver's reader (a normal-priority
        # Python process of this script): what it misses is said apart, not counted as lost
        complete = (all(str(x) == str(b['expected']) for x in (b['recorded'], b['te']))
                    and str(b['te_gaps']) == '0' and not b['crashed'])
        if b['probe'] is not None and str(b['probe']) != str(b['expected']):
            probe_short.append(f"{b['ns']} {int(b['expected']) - int(b['probe'])}")
        lost_gaps += not complete
        ok &= complete and steady_ms <= limit_ms
        print(f"| {b['ns']} | {b['expected']} / {' / '.join(str(x) for x in counts)} | "
              f"{b['te_gaps']} | {b['crashed']} | "
              + (f"{_f(c['session'])} % | " if one else
                 f"{' / '.join(_f(c[n]) for n in NODES)} % ({_f(sum(c[n] for n in NODES))} %) | ")
              + f"{_f(steady_ms)} ms ({_f(lag_ms)} ms) | "
              + ('- | - | - |' if b['probe'] is None else   # no probe on this bench
                 f"{_f(b['probe_lag_max_ms'])} / {_f(b['probe_lag_p99_ms'])} "
                 f"ms ({b['probe_lag_worst_at_s']:.0f} s) | "
                 f"{b['probe_late']} of {b['probe_n']} | "
                 f"{_f(b['lat_median_ms'], '{:.2f}')} / "
                 f"{_f(b['lat_p99_ms'], '{:.2f}')} ms |"))
    for b in res['benches']:
        if b['crash_report']:
            print(f"\n{b['ns']} crashed:")
            for line in b['crash_report']:
                print(f'  {line}')
    stops = [(b['stop_s'], b['ns']) for b in res['benches']]
    node_stops = [(t, f"{b['ns']}/{n}") for b in res['benches']
                  for n, t in b['node_stop_s'].items() if t is not None]
    if stops:
        print(f'\nsession stops (one after another): {min(stops)[0]:.1f}-{max(stops)[0]:.1f} s'
              f' each (slowest {max(stops)[1]})'
              + (f'; slowest node {max(node_stops)[1]} {max(node_stops)[0]:.1f} s after its '
                 'SIGTERM' if node_stops else ''))
    scheds = sorted({str(b['scheduling']) for b in res['benches']})
    print(f"\nbench scheduling (diagnostics): {'; '.join(scheds)}")
    fl = res.get('rt_floor')
    if fl:
        print(f"machine floor over the same time (a bare paced thread scheduled as the "
              f"benches: {fl['scheduling']}; no messages): woke up to {fl['max_ms']:.1f} ms "
              f"late (p99 "
              f"{fl['p99_ms']:.2f} ms), {fl['over_period']} of {fl['n']} periods more than "
              f"one block period late; kernel {platform.release()} {platform.version()}")
    cpu, cpu_s_ = res['cpu'], res.get('cpu_s', {})
    per_kind = {n: sum(v for k, v in cpu.items() if k.endswith('/' + n)) for n in kinds}
    total = sum(cpu.values())
    n_b = max(1, len(res['benches']))
    per_bench = sum(per_kind.values()) / n_b
    print(f"\ntotal CPU {total:.0f} % of one core (of {os.cpu_count() * 100} %): "
          + ', '.join(f'{n} {v:.1f} %' for n, v in per_kind.items())
          + f", driver (probes) {cpu.get('driver (probes)', float('nan')):.1f} %")
    print(f"per bench (its {'process' if one else 'four processes'}, mean of {n_b}): "
          f'{per_bench:.1f} % of one core'
          + ('' if one else ' = ' + ' / '.join(f'{per_kind[n] / n_b:.1f}' for n in NODES)
             + ' % (bench / TE / compensation / recorder)')
          + f"; CPU time (user + sys) "
          f"{sum(v for k, v in cpu_s_.items() if '/' in k):.1f} s over "
          f"{res.get('measured_s', float('nan')):.1f} s of wall time (after the warm-up)")
    print(f"result: {'PASS' if ok else 'FAIL'} (0 lost, 0 gaps, no crash, lag after the "
          f'warm-up <= {limit_ms:.1f} ms on every bench: {limit_why})')
    if probe_short:
        print('the driver\'s probe (not a node of the sessions) missed blocks: '
              + ', '.join(probe_short) + '; its arrival figures cover what it got')
    load = os.getloadavg()
    cpu_model = _cpu_model()
    worst = max(lags) if lags else float('nan')
    got = (f"{'0 lost, 0 gaps' if not lost_gaps else f'{lost_gaps} benches lost blocks'}; "
           f'lag {min(lags):.1f}-{worst:.1f} ms vs floor '
           + (f"{fl['max_ms']:.1f} ms" if fl else 'not measured')
           + f'; {total:.0f} % of the {os.cpu_count() * 100} %, {per_bench:.1f} % per bench'
           + ('' if ok else ' (**not met**)'))
    print('\nREADME row:\n'
          f"| [{args.benches} bench{'es' if args.benches > 1 else ''}]"
          '(#eight-benches-bench_multibenchpy) live, '
          f'{args.benches} x {args.rate_hz / 1e3:g} kHz, {args.duration_s / 60:g} min | '
          f'`bench_multibench.py` | 0 lost, 0 gaps, lag within 1 ms of the floor; per-bench '
          f'cost halved (#41) | {got} | {time.strftime("%Y-%m-%d")}, {cpu_model}, '
          f'load {load[0]:.1f} after |')
    return ok


def _cpu_model() -> str:
    """``Model name`` of lscpu (the CPU the figures ran on)."""
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        out = subprocess.run(['lscpu'], capture_output=True, text=True, timeout=10,
                             check=False).stdout
        for line in out.splitlines():
            if line.startswith('Model name'):
                return line.split(':', 1)[1].strip()
    return platform.processor() or '?'


# -- the floor: N bare rclpy publisher / subscriber pairs ---------------------------------

def _report_and_close(result: dict[str, Any], ex: Any, node: Any, ctx: Any) -> None:
    """End of a floor process: its result as one JSON line, then rclpy shut down."""
    import rclpy

    print(json.dumps(result), flush=True)
    ex.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=ctx)


def floor_publisher(ns: str, rate_hz: float, block: int, duration_s: float) -> int:
    """A bare publisher of EncoderBlocks at the bench's rate (a child process)."""
    import rclpy
    from rv_te_msgs.msg import EncoderBlock

    from rv_te_bench.nodes import qos
    from rv_te_bench.nodes.common import make_executor

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('floor_pub', namespace=ns, context=ctx)
    pub = node.create_publisher(EncoderBlock, 'bench/encoders', qos.ENCODER_QOS)
    period = block / rate_hz
    total = round(duration_s / period)
    t = np.arange(block) / rate_hz
    state = {'sent': 0, 'start': None, 'lag_max': 0.0}
    give_up = time.monotonic() + 60.0   # no subscriber by then: publish anyway (gaps show)

    def tick() -> None:
        if state['start'] is None:
            if pub.get_subscription_count() < 1 and time.monotonic() < give_up:
                return
            state['start'] = time.monotonic()
        due = min(total, int((time.monotonic() - state['start']) / period) + 1)
        while state['sent'] < due:
            k = state['sent']
            m = EncoderBlock()
            ns_ = round((time.time()) * 1e9)
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns_, 1_000_000_000)
            m.header.frame_id = ns
            m.seq = k
            m.sample_rate_hz = rate_hz
            m.time_offset_s = t
            m.theta_in_rad = t * 31.4 + k
            m.theta_out_rad = t * 0.4 + k
            m.torque_out_nm = np.full(block, 30.0)
            pub.publish(m)
            state['sent'] += 1
        lag = time.monotonic() - state['start'] - state['sent'] * period
        state['lag_max'] = max(state['lag_max'], lag)

    node.create_timer(period, tick)
    ex = make_executor('events', context=ctx)
    ex.add_node(node)
    try:
        while state['sent'] < total:
            ex.spin_once(timeout_sec=0.1)
        from rclpy.duration import Duration

        pub.wait_for_all_acked(Duration(seconds=5.0))
    except KeyboardInterrupt:
        pass
    finally:
        _report_and_close({'sent': state['sent'], 'lag_max_s': state['lag_max']}, ex, node,
                          ctx)
    return 0


def floor_subscriber(ns: str, expected: int, timeout_s: float) -> int:
    """A bare subscriber (deserialising, as the TE node does) counting blocks and gaps."""
    import rclpy
    from rv_te_msgs.msg import EncoderBlock

    from rv_te_bench.nodes import qos
    from rv_te_bench.nodes.common import make_executor

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('floor_sub', namespace=ns, context=ctx)
    state = {'n': 0, 'gaps': 0, 'next': 0}

    def on_block(m: EncoderBlock) -> None:
        if m.seq != state['next']:
            state['gaps'] += 1
        state['next'] = m.seq + 1
        state['n'] += 1

    node.create_subscription(EncoderBlock, 'bench/encoders', on_block, qos.ENCODER_QOS)
    ex = make_executor('events', context=ctx)
    ex.add_node(node)
    end = time.monotonic() + timeout_s
    try:
        while state['n'] < expected and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        _report_and_close({'received': state['n'], 'gaps': state['gaps']}, ex, node, ctx)
    return 0


def run_floor(n: int, rate_hz: float, block: int, duration_s: float,
              warmup_s: float = 3.0) -> dict[str, Any]:
    """N publisher / subscriber process pairs; counts, gaps and CPU per message."""
    from rv_te_bench.launch.session import child_env

    expected = round(duration_s * rate_hz / block)
    me = [sys.executable, str(Path(__file__).resolve())]
    common = ['--rate-hz', str(rate_hz), '--block-size', str(block),
              '--duration-s', str(duration_s)]
    procs: dict[str, subprocess.Popen[str]] = {}
    meter = CpuMeter()
    old = _stop_on_sigterm()
    interrupted = False
    t0 = time.monotonic()
    try:
        for k in range(n):
            ns = f'floor{k + 1}'
            procs[f'{ns}/sub'] = subprocess.Popen(
                [*me, '--_floor-sub', ns, *common, '--_expected', str(expected)],
                env=child_env(), stdout=subprocess.PIPE, text=True)
            procs[f'{ns}/pub'] = subprocess.Popen(
                [*me, '--_floor-pub', ns, *common], env=child_env(), stdout=subprocess.PIPE,
                text=True)
        last = 0.0
        deadline = t0 + duration_s + 150.0
        while any(p.poll() is None for p in procs.values()):
            if time.monotonic() > deadline:
                print('floor: a process did not end in time: stopping it', file=sys.stderr)
                break
            time.sleep(0.1)
            now = time.monotonic()
            pids = {k: p.pid for k, p in procs.items()}
            if not meter.start and now - t0 > warmup_s:
                meter.begin(pids)
            if meter.start and now - last > 1.0:
                last = now
                meter.sample(pids, {k: p.poll() is None for k, p in procs.items()})
    except KeyboardInterrupt:
        interrupted = True
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs.values():
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for sig, h in old.items():
            signal.signal(sig, h)
    if interrupted:
        raise KeyboardInterrupt
    out = {}
    for k, p in procs.items():
        text = p.stdout.read() if p.stdout else ''
        lines = [ln for ln in text.splitlines() if ln.startswith('{')]
        out[k] = json.loads(lines[-1]) if lines else {}
    return {'expected': expected, 'results': out, 'cpu': meter.pct(),
            'cpu_s': meter.seconds(), 'measured_s': duration_s - warmup_s}


def print_floor(res: dict[str, Any], args: argparse.Namespace) -> None:
    """One row per pair: counts, gaps, CPU and CPU per message."""
    msgs_per_s = args.rate_hz / args.block_size
    print(f'\nfloor: {args.benches} bare rclpy publisher / subscriber pairs of EncoderBlock '
          f'({args.block_size} samples), {msgs_per_s:g} msg/s each, {args.duration_s:g} s\n')
    print('| pair | blocks expected / sent / received | gaps | publisher lag max | '
          'CPU publisher / subscriber | CPU per message publisher / subscriber |')
    print('|---|---|---|---|---|---|')
    cpu = res['cpu']
    for k in range(args.benches):
        ns = f'floor{k + 1}'
        pub, sub = res['results'].get(f'{ns}/pub', {}), res['results'].get(f'{ns}/sub', {})
        cp, cs = cpu.get(f'{ns}/pub', float('nan')), cpu.get(f'{ns}/sub', float('nan'))
        # percent of a core at msgs_per_s messages per second -> us per message
        print(f"| {ns} | {res['expected']} / {pub.get('sent')} / {sub.get('received')} | "
              f"{sub.get('gaps')} | {_f(1e3 * float(pub.get('lag_max_s', 'nan')))} ms | "
              f'{cp:.1f} % / {cs:.1f} % | {cp * 1e4 / msgs_per_s:.0f} / '
              f'{cs * 1e4 / msgs_per_s:.0f} us |')
    print(f'\ntotal CPU {sum(cpu.values()):.0f} % of one core (of {os.cpu_count() * 100} %)')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--benches', type=int, default=4)
    ap.add_argument('--rate-hz', type=float, default=10000.0)
    ap.add_argument('--block-size', type=int, default=100)
    ap.add_argument('--duration-s', type=float, default=600.0)
    ap.add_argument('--floor', action='store_true',
                    help='bare rclpy publisher/subscriber pairs instead of the sessions')
    ap.add_argument('--profile-s', type=float, default=0.0,
                    help='py-spy record bench1\'s nodes for this long after the warm-up '
                         '(collapsed stacks in the temporary folder; see --keep)')
    ap.add_argument('--param', action='append', default=[], metavar='NODE.KEY=VALUE',
                    help='a parameter for every session, as rv-te launch --param '
                         '(e.g. compensation.identify=false to see what the searches cost)')
    ap.add_argument('--realtime-priority', type=int, default=50,
                    help='the benches\' realtime_priority (SCHED_FIFO of the pacing thread, '
                         'as a test PC runs its DAQ node; needs root or an rtprio limit); '
                         '0 = normal scheduling')
    ap.add_argument('--no-rt-probe', action='store_true',
                    help='do not measure the machine floor (a bare paced thread beside the '
                         'benches, same scheduling)')
    ap.add_argument('--probes', type=int, default=1,
                    help='benches (the first ones) with a probe node in the driver (block '
                         'arrival, latency block->TE; default 1); the counts, gaps and lag of '
                         'every bench come from its own nodes. -1: every bench')
    ap.add_argument('--first', type=int, default=1,
                    help='number of the first namespace, /bench<FIRST> (two runs side by '
                         'side in one ROS domain: e.g. the code before and after a change)')
    ap.add_argument('--layout', choices=LAYOUTS, default='per-node',
                    help="per-node: a process per node (rv-te launch); single: a session's "
                         'four nodes in one process on one executor (rv-te launch '
                         '--single-process)')
    ap.add_argument('--keep', action='store_true', help='keep the temporary folder (bags)')
    ap.add_argument('--_session', dest='session', help=argparse.SUPPRESS)
    ap.add_argument('--_overrides', dest='overrides', help=argparse.SUPPRESS)
    ap.add_argument('--_rt-probe', dest='rt_probe', type=float, help=argparse.SUPPRESS)
    ap.add_argument('--_period', dest='period', type=float, help=argparse.SUPPRESS)
    ap.add_argument('--_priority', dest='priority', type=int, help=argparse.SUPPRESS)
    ap.add_argument('--_floor-pub', dest='floor_pub', help=argparse.SUPPRESS)
    ap.add_argument('--_floor-sub', dest='floor_sub', help=argparse.SUPPRESS)
    ap.add_argument('--_expected', dest='expected', type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.rt_probe:
        return rt_probe(args.rt_probe, args.period, args.priority)
    if args.session:
        return one_process_session(args.session, json.loads(args.overrides))
    if args.floor_pub:
        return floor_publisher(args.floor_pub, args.rate_hz, args.block_size, args.duration_s)
    if args.floor_sub:
        return floor_subscriber(args.floor_sub, args.expected, args.duration_s + 60.0)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
    with contextlib.suppress(OSError):
        load = os.getloadavg()
    print(f'machine: {platform.node()} {platform.machine()}, {os.cpu_count()} cores, '
          f'python {platform.python_version()}, date {time.strftime("%Y-%m-%d %H:%M")}, '
          f'load average before {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}', file=sys.stderr)
    out = Path(tempfile.mkdtemp(prefix='rv-te-multibench-'))
    try:
        if args.floor:
            res = run_floor(args.benches, args.rate_hz, args.block_size, args.duration_s)
            print_floor(res, args)
            ok = True
        else:
            res = run_benches(args.benches, args.rate_hz, args.block_size, args.duration_s,
                              out, profile_s=args.profile_s,
                              extra_params=(f'bench.realtime_priority={args.realtime_priority}',
                                            *args.param),
                              rt_probe_priority=-1 if args.no_rt_probe
                              else args.realtime_priority,
                              probes=None if args.probes < 0 else args.probes,
                              first=args.first, layout=args.layout)
            ok = print_benches(res, args)
            print_profiles(res['profiles'])
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        ok = False
    finally:
        if args.keep:
            print(f'kept: {out}', file=sys.stderr)
        else:
            shutil.rmtree(out, ignore_errors=True)
    load = os.getloadavg()
    print(f'load average after: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}')
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
