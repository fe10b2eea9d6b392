"""Live pipeline benchmark: bench -> TE node -> recorder, one process per node, real time.

For each sample rate it runs a real-time session for ``--duration-s`` and reports:
messages lost (bench blocks published vs recorded vs processed by the TE node), CPU per node
(utime + stime from /proc over the wall time), the bench's lag behind the clock, and the latency
from a block's arrival to the TE samples computed from it (both measured at one probe node).

    .venv/bin/python benchmarks/bench_pipeline.py --rates 1000 10000 --duration-s 600

Prints a markdown table (it replaces the script's table in benchmarks/README.md, with the
machine and date; the old one moves to benchmarks/HISTORY.md).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

CLK_TCK = os.sysconf('SC_CLK_TCK')


def cpu_s(pid: int) -> float:
    """utime + stime of a process [s] (0 when it is gone)."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def run_one(rate_hz: float, block: int, duration_s: float, out_dir: Path) -> dict[str, object]:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rv_te_msgs.msg import EncoderBlock, TransmissionError

    from rv_te_bench.io.bag_reader import bag_summary
    from rv_te_bench.launch.session import Session, build_session
    from rv_te_bench.nodes import qos
    from rv_te_bench.nodes.common import make_executor

    bag = out_dir / f'pipeline_{int(rate_hz)}hz'
    spec = build_session([], nodes=['bench', 'te_node', 'recorder'], overrides=[
        'bench.te_mode=nlte', f'bench.sample_rate_hz={rate_hz}', f'bench.block_size={block}',
        f'bench.duration_s={duration_s}', 'bench.time_mode=realtime',
        f'recorder.output_dir={out_dir}', f'recorder.bag_name={bag.name}',
        'bench.wait_for_nodes=[te_node, recorder, pipeline_probe]'])
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    probe = rclpy.create_node('pipeline_probe', context=ctx)
    block_arrival: list[tuple[float, float, float]] = []   # (stamp_s, dur_s, arrival)
    te_arrival: list[tuple[float, float]] = []             # (stamp_s, arrival)
    diags: dict[str, dict[str, str]] = {}

    def on_block(m: EncoderBlock) -> None:
        block_arrival.append((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9,
                              len(m.time_offset_s) / rate_hz, time.monotonic()))

    def on_te(m: TransmissionError) -> None:
        te_arrival.append((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9,
                           time.monotonic()))

    def on_diag(m: DiagnosticArray) -> None:
        for st in m.status:
            diags[st.name] = {kv.key: kv.value for kv in st.values}

    probe.create_subscription(EncoderBlock, 'bench/encoders', on_block, qos.ENCODER_QOS)
    probe.create_subscription(TransmissionError, 'te/samples', on_te, qos.ENCODER_QOS)
    probe.create_subscription(DiagnosticArray, '/diagnostics', on_diag, qos.DIAGNOSTICS_QOS)
    ex = make_executor('events', context=ctx)
    ex.add_node(probe)
    session = Session(spec, log=lambda s: print(s, file=sys.stderr))
    session.start()
    t0 = time.monotonic()
    cpu0: dict[str, tuple[float, float]] = {}
    cpu_end: dict[str, tuple[float, float]] = {}
    last_sample = 0.0
    crashed = False
    try:
        while True:
            ex.spin_once(timeout_sec=0.1)
            if not cpu0 and time.monotonic() - t0 > 3.0:
                cpu0 = {n: (cpu_s(p.proc.pid), time.monotonic())
                        for n, p in session.procs.items()}
            if cpu0 and time.monotonic() - last_sample > 1.0:
                # keep the last reading of each live process (the bench exits at its end)
                last_sample = time.monotonic()
                for n, p in session.procs.items():
                    c = cpu_s(p.proc.pid)
                    if c > 0 and p.proc.poll() is None:
                        cpu_end[n] = (c, last_sample)
            session.poll()
            if session.failures:
                crashed = True
                break
            if session.procs['bench'].proc.poll() is not None:
                break
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
    finally:
        codes = session.stop()
        ex.shutdown()
        probe.destroy_node()
        rclpy.try_shutdown(context=ctx)
    cpu_pct = {}
    for n, (c1, w1) in cpu_end.items():
        c0, w0 = cpu0.get(n, (0.0, t0))
        cpu_pct[n] = 100.0 * (c1 - c0) / max(w1 - w0, 1e-9)
    expected = round(duration_s * rate_hz / block)
    summary = bag_summary(bag)
    topics = summary.get('topics', {})
    enc_count = next((t.get('count', t.get('message_count')) for name, t in topics.items()
                      if name.endswith('bench/encoders')), None) if isinstance(topics, dict) \
        else None
    # latency: TE samples stamp falls inside a block; arrival(te) - arrival(block)
    lat = []
    if block_arrival and te_arrival:
        b = np.asarray(block_arrival)
        for stamp, arr in te_arrival:
            k = np.searchsorted(b[:, 0], stamp, side='right') - 1
            if 0 <= k < len(b) and stamp < b[k, 0] + b[k, 1] + 1e-9:
                lat.append(arr - b[k, 2])
    lat_ms = np.asarray(lat) * 1e3 if lat else np.asarray([np.nan])
    te_diag = next((v for k, v in diags.items() if 'te analysis' in k), {})
    bench_diag = next((v for k, v in diags.items() if k.endswith(': bench')), {})
    return {
        'rate_hz': rate_hz, 'block': block, 'duration_s': duration_s,
        'expected_blocks': expected, 'probe_blocks': len(block_arrival),
        'recorded_blocks': enc_count, 'te_blocks': te_diag.get('blocks'),
        'te_gaps': te_diag.get('gaps_reported'),
        'bench_lag_max_s': bench_diag.get('lag_max_s'),
        'crashed': crashed or any(c not in (0, None) for c in codes.values()),
        'cpu_pct': cpu_pct, 'latency_median_ms': float(np.nanmedian(lat_ms)),
        'latency_p99_ms': float(np.nanpercentile(lat_ms, 99)),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--rates', type=float, nargs='+', default=[1000.0, 10000.0])
    ap.add_argument('--block', type=int, default=100)
    ap.add_argument('--duration-s', type=float, default=60.0)
    ap.add_argument('--out-dir', type=Path, default=None)
    args = ap.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
    out = args.out_dir or Path(tempfile.mkdtemp(prefix='rv-te-pipeline-'))
    rows = []
    for rate in args.rates:
        print(f'running {rate:g} Hz for {args.duration_s:g} s ...', file=sys.stderr)
        rows.append(run_one(rate, args.block, args.duration_s, out))
    print(f'\nmachine: {platform.node()} {platform.machine()}, {os.cpu_count()} cores, '
          f'python {platform.python_version()}, date {time.strftime("%Y-%m-%d")}\n')
    print('| rate | block | duration | blocks expected / seen by probe / recorded / TE | '
          'TE gaps | crashed | CPU bench / TE / recorder | latency block->TE median / p99 | '
          'bench lag, max over the run |')
    print('|---|---|---|---|---|---|---|---|---|')
    for r in rows:
        cpu = r['cpu_pct']
        print(f"| {r['rate_hz']:g} Hz | {r['block']} | {r['duration_s']:g} s | "
              f"{r['expected_blocks']} / {r['probe_blocks']} / {r['recorded_blocks']} / "
              f"{r['te_blocks']} | {r['te_gaps']} | {r['crashed']} | "
              f"{cpu.get('bench', float('nan')):.0f} % / {cpu.get('te_node', float('nan')):.0f} %"
              f" / {cpu.get('recorder', float('nan')):.0f} % | "
              f"{r['latency_median_ms']:.2f} / {r['latency_p99_ms']:.2f} ms | "
              f"{r['bench_lag_max_s']} s |")
    return 0


if __name__ == '__main__':
    sys.exit(main())
