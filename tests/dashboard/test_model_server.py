"""The page's model and web server without ROS or a browser: late clients, slow clients,
the token, the port, the JSON (a real uvicorn on a loopback port, a real WebSocket client)."""

from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

import numpy as np
import pytest

from rv_te_bench.dashboard.model import DashboardModel, EncoderSamples
from rv_te_bench.dashboard.server import HttpServer, PortInUseError, bind_socket, create_app

websockets_sync = pytest.importorskip('websockets.sync.client')

RATIO = 79.0
FS = 10_000.0


def _block(seq: int, n: int = 1000) -> EncoderSamples:
    t = (seq * n + np.arange(n)) / FS
    th_out = 2 * math.pi * 0.5 * t
    th_in = RATIO * (th_out - 1e-4 * np.sin(25 * th_out))
    return EncoderSamples(seq=seq, stamp_s=seq * n / FS, time_offset_s=np.arange(n) / FS,
                          theta_in_rad=th_in, theta_out_rad=th_out,
                          torque_out_nm=np.cos(th_out))


class _Page:
    """A client applying updates the way the page does (independent of the model's code)."""

    def __init__(self) -> None:
        self.revs: dict[int, tuple[list, list]] = {}
        self.views: dict[str, dict] = {}
        self.windows: dict[int, dict] = {}

    def apply(self, u: dict) -> None:
        if u['type'] == 'full':
            self.__init__()
        for r in u.get('revs', []):
            lo, hi = self.revs.setdefault(r['rev'], ([None] * 2048, [None] * 2048))
            lo[r['from_bin']:r['from_bin'] + len(r['min'])] = r['min']
            hi[r['from_bin']:r['from_bin'] + len(r['max'])] = r['max']
        for name in ('recent', 'overview'):
            v = u.get(name)
            if v is None:
                continue
            cur = self.views.get(name)
            if v['replace'] or cur is None:
                cur = {'first': v['first_bin'], 'te_min': []}
            off = v['from_bin'] - cur['first']
            col = cur['te_min'][:off] + list(v['cols'].get('te_min', []))
            cur['te_min'] = col[:v['last_bin'] - v['first_bin'] + 1]
            self.views[name] = cur
        for w in u.get('windows', []):
            self.windows[w['index']] = w


def test_open_tab_late_tab_and_stalled_tab_agree():
    m = DashboardModel()
    m.on_bench_info({'gear_ratio': RATIO, 'preset': 'x'})
    live, stalled = _Page(), _Page()
    c_live = c_stalled = None
    u, c_stalled = m.update(None)
    stalled.apply(u)
    for seq in range(40):
        m.on_encoders(_block(seq))
        if seq % 3 == 0:
            m.fold()
            u, c_live = m.update(c_live)
            live.apply(json.loads(json.dumps(u)))
        if seq % 10 == 9:
            m.on_window({'index': seq // 10, 'complete': True, 'pp_rad': 1e-4 * seq,
                         'mean_rad': 0.0, 'std_rad': 1e-5, 'amplitude_rad': 1e-4,
                         'revolutions': 1.0, 'n_samples': 10, 'cumulative_pp_rad': 2e-4})
    m.fold()
    u, c_live = m.update(c_live)
    live.apply(u)
    u, c_stalled = m.update(c_stalled)     # one update after 40 blocks: current state, no backlog
    stalled.apply(u)
    late = _Page()
    late.apply(m.update(None)[0])
    for other in (stalled, late):
        assert other.revs == live.revs
        assert other.views == live.views
        assert other.windows.keys() == live.windows.keys() == {0, 1, 2, 3}
    assert len(live.revs) == 2                          # current and previous revolution
    assert m.samples == 40_000


def test_seq_gap_and_leading_loss_are_events_and_a_new_session_resets():
    m = DashboardModel()
    m.on_encoders(_block(5))
    m.on_encoders(_block(6))
    m.on_encoders(_block(9))
    kinds = [e['kind'] for e in m.events]
    assert kinds == ['leading loss', 'seq gap']
    assert '2 missing' in m.events[1]['text']
    sid = m.session_id
    m.on_encoders(_block(0))                             # a new session (seq back to 0)
    assert m.session_id == sid + 1 and m.events == []


@pytest.fixture
def server():
    m = DashboardModel()
    sock = bind_socket('127.0.0.1', 0)
    app, hub = create_app(m, token='s3cret-token')
    http = HttpServer(app, sock)
    http.start()
    try:
        yield m, hub, sock.getsockname()[1]
    finally:
        http.stop()


def test_token_is_enforced_on_page_api_static_and_websocket(server):
    _, _, port = server
    base = f'http://127.0.0.1:{port}'
    for path in ('/', '/api/state', '/api/stats', '/static/app.js', '/?token=wrong'):
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(base + path, timeout=5)
        assert err.value.code == 403, path
    with urllib.request.urlopen(base + '/?token=s3cret-token', timeout=5) as r:
        assert r.status == 200
        assert 'HttpOnly' in r.headers['set-cookie']
        assert "script-src 'self'" in r.headers['content-security-policy']
        assert b'rv-te live' in r.read()
    req = urllib.request.Request(base + '/static/uPlot.iife.min.js',
                                 headers={'Cookie': 'rv_te_dashboard_token=s3cret-token'})
    with urllib.request.urlopen(req, timeout=5) as r:
        assert r.status == 200
    with pytest.raises(Exception) as err:   # websockets' InvalidStatus: HTTP 403
        websockets_sync.connect(f'ws://127.0.0.1:{port}/ws', open_timeout=5)
    assert '403' in str(err.value)
    with websockets_sync.connect(f'ws://127.0.0.1:{port}/ws?token=s3cret-token',
                                 open_timeout=5) as ws:
        assert json.loads(ws.recv(timeout=5))['type'] == 'full'
        with urllib.request.urlopen(base + '/api/stats?token=s3cret-token', timeout=5) as r:
            stats = json.loads(r.read())
        assert stats['ticks'] > 0 and stats['clients'] and stats['clients'][0]['sent'] >= 1


def test_a_stalled_client_never_holds_more_than_one_update_and_others_keep_going(server):
    m, hub, port = server
    m.on_bench_info({'gear_ratio': RATIO})
    url = f'ws://127.0.0.1:{port}/ws?token=s3cret-token'
    # a client whose socket buffers are tiny and who never reads
    slow = socket.create_connection(('127.0.0.1', port))
    slow.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    slow.sendall(b'GET /ws?token=s3cret-token HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\n'
                 b'Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n'
                 b'Sec-WebSocket-Version: 13\r\n\r\n')
    received = 0

    def stalled_skips() -> int:
        return max((c.skipped for c in hub.clients), default=0)

    with websockets_sync.connect(url, open_timeout=5, max_size=None) as ws:
        # at least 6 s of updates (>= 10 per s on a quiet machine), longer on a busy one:
        # a hub the stalled client blocked would deliver none, however long it ran
        start = time.monotonic()
        seq = 0
        while time.monotonic() - start < 6.0 or (
                (received < 60 or stalled_skips() <= 50) and time.monotonic() - start < 60.0):
            m.on_encoders(_block(seq))
            seq += 1
            try:
                ws.recv(timeout=0.01)
                received += 1
            except TimeoutError:
                pass
        clients = list(hub.clients)
    slow.close()
    assert received >= 6.0 * 10            # the reading tab got its updates
    assert len(clients) == 2
    assert all(c.queue.qsize() <= 1 for c in clients)
    stalled = max(clients, key=lambda c: c.skipped)
    assert stalled.skipped > 50             # skipped while its socket was full, not queued


def test_port_in_use_is_one_line_and_exit_2():
    busy = bind_socket('127.0.0.1', 0)
    port = busy.getsockname()[1]
    try:
        with pytest.raises(PortInUseError, match=f'port {port}'):
            bind_socket('127.0.0.1', port)
        r = subprocess.run([sys.executable, '-m', 'rv_te_bench.cli.main', 'dashboard',
                            '--port', str(port), '--no-foxglove', '--duration', '1'],
                           capture_output=True, text=True, timeout=60, check=False)
    finally:
        busy.close()
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('ERROR: dashboard: port') and 'in use' in \
        lines[0], r.stderr


def test_metrics_decided_while_the_test_runs_are_shown_against_their_limits():
    """A running test/report (the sequencer's metrics decided so far): the table shows each
    against its limit in display units at once, not when a step (or the test) ends."""
    m = DashboardModel()
    m.on_bench_info({'gear_ratio': RATIO, 'preset': ''})
    arcmin = math.pi / 10800
    nan = math.nan
    m.on_report({'serial': 'SN', 'verdict': 'running', 'reason': 'step 1/2 te: 1 of 3',
                 'plan_yaml': '', 'tolerance_yaml': '', 'final': False, 'metrics': [
                     {'name': 'te_pp_ccw_rad', 'step': 'te', 'unit': 'rad',
                      'value': 1.25 * arcmin, 'limit_min': nan, 'limit_max': 1.0 * arcmin,
                      'margin': -0.25 * arcmin, 'verdict': 'fail', 'source': 'catalogue'},
                     {'name': 'lost_motion_arcmin', 'step': '', 'unit': 'rad', 'value': nan,
                      'limit_min': nan, 'limit_max': 1.0 * arcmin, 'margin': nan,
                      'verdict': 'pending', 'source': 'catalogue'}]})
    rows = m.report['rows']
    assert [r['verdict'] for r in rows] == ['fail', 'pending']
    assert rows[0]['label'].endswith('[arcmin]')
    assert float(rows[0]['value']) == pytest.approx(1.25, abs=1e-3)
    assert rows[0]['limit'] == '<= 1' or float(rows[0]['limit'].split()[-1]) == 1.0
    u, _ = m.update(None)
    assert u['report']['rows'] == rows


def test_the_hysteresis_curve_comes_as_branches_of_a_loop():
    """A torque cycle 0 -> +T -> -T -> 0 (ramps, with dwell noise) on a backlash loop: every
    curve point is labelled with the branch it lies on (torque rising / falling), as the
    cycle's own slope says, except within the turn tolerance of the two turning points."""
    from rv_te_bench.dashboard.loop import TURN_FRACTION

    m = DashboardModel()
    m.on_bench_info({'gear_ratio': RATIO, 'preset': ''})
    m.on_step({'serial': 'S', 'step_index': 1, 'step_count': 2, 'step_name': 'hyst',
               'step_kind': 'hysteresis', 'state': 'started', 'first_seq': 0, 'last_seq': 0,
               'result_yaml': ''})
    t_nm, k, b = 400.0, 4e5, 2e-4                           # T_R, N m/rad, backlash rad
    period = 12.0
    n = 1000
    rng = np.random.default_rng(3)
    for seq in range(int(period * FS / n)):
        t = (seq * n + np.arange(n)) / FS
        phase = t / period                                    # 0 .. 1 over the cycle
        applied = t_nm * np.interp(phase, [0, 0.25, 0.75, 1.0], [0, 1, -1, 0])
        rising = (phase < 0.25) | (phase >= 0.75)
        angle = applied / k + np.where(rising, b / 2, -b / 2)
        torque = -applied + rng.normal(0, 0.002 * t_nm, n)    # the reaction, noisy
        m.on_encoders(EncoderSamples(seq=seq, stamp_s=t[0], time_offset_s=t - t[0],
                                     theta_in_rad=np.zeros(n), theta_out_rad=angle,
                                     torque_out_nm=torque))
        m.fold()
    u, cur = m.update(None)
    pts = np.array(u['curve']['points'])
    assert pts.shape[1] == 3 and len(pts) >= 0.99 * period / 0.01
    tq, ang, way = pts.T
    phase = (np.arange(len(pts)) * 0.01 + 0.005) / period   # one point per 10 ms
    true_way = np.where((phase < 0.25) | (phase >= 0.75), 1, -1)
    # the branch turns once the torque is back by TURN_FRACTION of T_R from its extreme
    # (TURN_FRACTION / 4 of the cycle at these ramps); allow twice that, and the start
    turn = 2 * TURN_FRACTION / 4
    near_turn = (np.abs(phase - 0.25) < turn) | (np.abs(phase - 0.75) < turn) | (phase < turn)
    assert np.array_equal(way[~near_turn], true_way[~near_turn])
    # the two branches are the two flanks of the loop: angle - T/k = +-b/2
    for w, sign in ((1, 1), (-1, -1)):
        sel = (way == w) & ~near_turn
        assert np.allclose(ang[sel] - tq[sel] / k, sign * b / 2, atol=3 * 0.002 * t_nm / k)
    # an open tab gets only the new points; a new step starts the curve over
    m.on_step({'serial': 'S', 'step_index': 2, 'step_count': 3, 'step_name': 'hyst2',
               'step_kind': 'hysteresis', 'state': 'started', 'first_seq': 0, 'last_seq': 0,
               'result_yaml': ''})
    m.on_encoders(EncoderSamples(seq=1000, stamp_s=100.0, time_offset_s=np.arange(n) / FS,
                                 theta_in_rad=np.zeros(n), theta_out_rad=np.zeros(n),
                                 torque_out_nm=np.zeros(n)))
    m.fold()
    u2, _ = m.update(cur)
    assert u2['curve']['from'] == 0 and len(u2['curve']['points']) == 10
