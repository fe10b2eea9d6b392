"""Live page speed at 10 kHz: envelope completeness, screen updates, latency, server CPU,
loss with two tabs open, a late tab's catch-up (issue #37).

Runs a realtime session (``rv-te launch``: bench at --sample-rate-hz in blocks of
--block-size, TE node, compensation, recorder) in namespace /bdash with a separate
``rv-te dashboard`` process (so its CPU is its own: utime+stime from /proc), two headless
Chromium tabs open from the start and a third opened at the end. Afterwards the bag is read
with rosbags and every encoder sample's TE is checked against the drawn whole-session
envelope column it falls in.

    .venv/bin/python benchmarks/bench_dashboard.py --duration-s 600     # the issue's 10 min
    .venv/bin/python benchmarks/bench_dashboard.py --duration-s 60 --json
    taskset -c 0 .venv/bin/python benchmarks/bench_dashboard.py          # one core for all
    # 10 minutes of 10 kHz samples in about a minute (simulated time, 10x): the late tab
    .venv/bin/python benchmarks/bench_dashboard.py --duration-s 600 --speed-factor 10

Besides the targets it reports where the page's time goes: messages received per second
(what the server sent), the page's time per frame (drawing) and per message (parsing and
applying), so a shortfall in screen updates can be placed on the server or on the page.

State the machine's load (uptime) and CPU beside the figures; re-measure on a quiet machine.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.dashboard.chromium import chromium, page_state, wait_for  # noqa: E402
from tests.dashboard.conftest import DashboardProcess, env, free_port  # noqa: E402

ARCMIN = 10800 / math.pi


def cpu_s(pid: int) -> float:
    """utime + stime of a process [s]."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def server_stats(url: str) -> dict:
    """The dashboard server's own timing (GET /api/stats)."""
    import urllib.request

    base = url.split('?')[0].rstrip('/')
    with urllib.request.urlopen(f'{base}/api/stats', timeout=10) as r:
        return json.loads(r.read())


def uptime() -> str:
    """``uptime``'s line (the machine's load as people quote it)."""
    return subprocess.run(['uptime'], capture_output=True, text=True, check=False).stdout.strip()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--duration-s', type=float, default=60.0)
    ap.add_argument('--sample-rate-hz', type=float, default=10_000.0)
    ap.add_argument('--block-size', type=int, default=100)
    ap.add_argument('--measure-s', type=float, default=20.0,
                    help='window (while data flows) for CPU, updates/s and latency [s]')
    ap.add_argument('--speed-factor', type=float, default=0.0,
                    help='0: the bench in real time (the targets); >0: simulated time this '
                         'many times faster (the late tab after a long session, quickly)')
    ap.add_argument('--json', action='store_true')
    a = ap.parse_args()
    out = Path(tempfile.mkdtemp(prefix='bench-dash-'))
    ns = 'bdash'
    dash = DashboardProcess('--namespace', ns, '--port', str(free_port()), '--no-foxglove')
    res: dict = {'duration_s': a.duration_s, 'sample_rate_hz': a.sample_rate_hz,
                 'block_size': a.block_size, 'speed_factor': a.speed_factor,
                 'cpus_allowed': sorted(os.sched_getaffinity(0)),
                 'uptime_before': uptime(), 'load_before': os.getloadavg()}
    try:
        with chromium() as t1, chromium() as t2:
            for t in (t1, t2):
                t.get(dash.url)
                wait_for(lambda t=t: (page_state(t) or {}).get('connected'), 30, 'a tab')
            timing = (['use_sim_time:=false', '--param', 'bench.time_mode=realtime']
                      if a.speed_factor <= 0 else
                      ['use_sim_time:=true', '--param', f'bench.speed_factor={a.speed_factor}'])
            cmd = [sys.executable, '-m', 'rv_te_bench.cli.main', 'launch', '--default',
                   '--namespace', ns, *timing,
                   '--param', f'bench.sample_rate_hz={a.sample_rate_hz}',
                   '--param', f'bench.block_size={a.block_size}',
                   '--param', f'bench.duration_s={a.duration_s}',
                   '--param', 'bench.duration_output_revs=0',
                   '--param', f'recorder.output_dir={out}',
                   '--param', 'bench.wait_for_nodes=[te_node, recorder, dashboard]']
            launch = subprocess.Popen(cmd, env=env(), cwd=REPO, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.PIPE, text=True)
            wait_for(lambda: (page_state(t1)['status'].get('blocks') or 0) > 0, 60, 'data')
            c0, w0 = cpu_s(dash.proc.pid), time.monotonic()
            d0, h0 = page_state(t1)['draws'], server_stats(dash.url)
            time.sleep(a.measure_s)
            c1, w1 = cpu_s(dash.proc.pid), time.monotonic()
            s1, h1 = page_state(t1), server_stats(dash.url)
            res['server_ticks_per_s'] = (h1['ticks'] - h0['ticks']) / (w1 - w0)
            res['server_work_ms_p50'] = h1['work_ms_p50']
            res['server_work_ms_p95'] = h1['work_ms_p95']
            res['server_work_ms_max'] = h1['work_ms_max']
            res['server_tick_gap_ms_max'] = h1['gap_ms_max_last_250']
            res['server_sent_per_s_per_tab'] = [
                (b['sent'] - a_['sent']) / (w1 - w0) for a_, b in zip(
                    sorted(h0['clients'], key=lambda c: c['sent']),
                    sorted(h1['clients'], key=lambda c: c['sent']), strict=False)]
            res['server_skipped_per_s_per_tab'] = [
                (b['skipped'] - a_['skipped']) / (w1 - w0) for a_, b in zip(
                    sorted(h0['clients'], key=lambda c: c['sent']),
                    sorted(h1['clients'], key=lambda c: c['sent']), strict=False)]
            res['server_cpu_pct_of_one_core'] = 100 * (c1 - c0) / (w1 - w0)
            res['screen_updates_per_s'] = (s1['draws'] - d0) / (w1 - w0)
            perf = t1.execute_script('const d = window.rvte; return {draw: d.drawMs.slice(-3000),'
                                     ' apply: d.applyMs.slice(-3000),'
                                     ' msg: d.msgWall.slice(-3000)};')
            since = time.time() - (w1 - w0)
            res['messages_per_s'] = sum(t >= since for t in perf['msg']) / (w1 - w0)
            res['page_draw_ms_p50'] = float(np.percentile(perf['draw'], 50))
            res['page_draw_ms_p95'] = float(np.percentile(perf['draw'], 95))
            res['page_apply_ms_p50'] = float(np.percentile(perf['apply'], 50))
            res['page_apply_ms_p95'] = float(np.percentile(perf['apply'], 95))
            if a.speed_factor <= 0:   # stamps are wall time only in real time
                lat = np.array(s1['latency'][-2000:])
                res['sample_to_screen_p50_ms'] = float(np.percentile(lat, 50) * 1e3)
                res['sample_to_screen_p95_ms'] = float(np.percentile(lat, 95) * 1e3)
            _, err = launch.communicate(timeout=a.duration_s + 120)
            res['launch_rc'] = launch.returncode
            res['launch_lines'] = [ln for ln in err.splitlines() if '[launch]' in ln]
            time.sleep(2.0)
            final = page_state(t1)
            with chromium() as late:
                start = time.monotonic()
                late.get(dash.url)
                wait_for(lambda: (page_state(late) or {}).get('windows') == final['windows']
                         and (page_state(late)['drawn'].get('overview') or {}).get('max')
                         == final['drawn']['overview']['max'], 30, 'the late tab')
                res['late_tab_drawn_s'] = time.monotonic() - start
            res['two_tabs_agree'] = page_state(t2)['drawn'] == page_state(t1)['drawn']
    finally:
        dash.stop()
    res['load_after'] = os.getloadavg()
    res['uptime_after'] = uptime()
    from rosbags.highlevel import AnyReader

    bag = next(p for p in out.iterdir() if (p / 'metadata.yaml').exists())
    with AnyReader([bag]) as r:
        conns = {c.topic: c for c in r.connections}
        info = next(r.deserialize(raw, c.msgtype) for c, _, raw in
                    r.messages([conns[f'/{ns}/bench/info']]))
        blocks = [r.deserialize(raw, c.msgtype) for c, _, raw in
                  r.messages([conns[f'/{ns}/bench/encoders']])]
        stats = [r.deserialize(raw, c.msgtype) for c, _, raw in
                 r.messages([conns[f'/{ns}/te/statistics']])]
    seqs = [b.seq for b in blocks]
    res['bag_blocks'] = len(blocks)
    res['bag_seq_contiguous_from_0'] = seqs == list(range(len(seqs)))
    res['te_node_gaps'] = int(stats[-1].gaps) if stats else None
    res['page_first_seq'] = final['status']['first_seq']
    res['page_blocks'] = final['status']['blocks']
    th_in = np.concatenate([b.theta_in_rad for b in blocks])
    th_out = np.concatenate([b.theta_out_rad for b in blocks])
    te = (th_out - th_in / info.gear_ratio) * ARCMIN
    ov = final['drawn']['overview']
    lo = np.array([np.nan if x is None else x for x in ov['min']])
    hi = np.array([np.nan if x is None else x for x in ov['max']])
    col = ((np.arange(len(te)) // ov['samples_per_bin'] - ov['first_bin']) * ov['ncols']
           ) // ov['nbins']
    inside = (lo[col] <= te + 1e-9) & (te <= hi[col] + 1e-9)
    res['samples_checked'] = len(te)
    res['samples_outside_envelope'] = int((~inside).sum())
    res['cpu'] = next((ln.split(':', 1)[1].strip() for ln in
                       Path('/proc/cpuinfo').read_text().splitlines()
                       if ln.startswith('model name')), '?')
    if a.json:
        print(json.dumps(res, indent=1))
    else:
        for k, v in res.items():
            print(f'{k}: {v}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
