"""The live page in a real browser (Debian's chromium via Selenium) beside a real session.

One fast session (``rv-te launch``, real nodes over the middleware) runs once for the
module with a ``rv-te dashboard`` process, a tab open from the start and a Foxglove
WebSocket client; afterwards its bag is read back with rosbags (an independent reader) and
compared with what the page shows and what the Foxglove client decoded.
"""

from __future__ import annotations

import json
import math
import os
import struct
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from tests.dashboard.chromium import chromium, page_state, text, wait_for
from tests.dashboard.conftest import REPO, DashboardProcess, env, free_port

pytestmark = [pytest.mark.ros, pytest.mark.usefixtures('need_chromium')]
ARCMIN = 10800 / math.pi


class FoxgloveClient(threading.Thread):
    """A Foxglove WebSocket protocol client: advertisements, then subscribed messages."""

    def __init__(self, url: str, topics: tuple[str, ...]) -> None:
        super().__init__(daemon=True)
        self.url, self.topics = url, topics
        self.channels: dict[int, dict] = {}
        self.messages: dict[str, list[bytes]] = {t: [] for t in topics}
        self.stop = threading.Event()
        self.error: Exception | None = None

    def run(self) -> None:
        from websockets.sync.client import connect

        try:
            with connect(self.url, subprotocols=['foxglove.sdk.v1', 'foxglove.websocket.v1'],
                         open_timeout=10, max_size=None) as ws:
                subs: dict[int, str] = {}
                while not self.stop.is_set():
                    try:
                        msg = ws.recv(timeout=0.2)
                    except TimeoutError:
                        continue
                    if isinstance(msg, str):
                        doc = json.loads(msg)
                        if doc.get('op') == 'advertise':
                            for ch in doc['channels']:
                                self.channels[ch['id']] = ch
                                if ch['topic'] in self.topics:
                                    sid = len(subs) + 1
                                    subs[sid] = ch['topic']
                                    ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                                        {'id': sid, 'channelId': ch['id']}]}))
                    elif msg[0] == 1:
                        sid, _ = struct.unpack_from('<IQ', msg, 1)
                        self.messages[subs[sid]].append(bytes(msg[13:]))
        except Exception as exc:  # noqa: BLE001 - reported by the test
            self.error = exc


@pytest.fixture(scope='module')
def session(tmp_path_factory, need_chromium):
    ns = f'dash{os.getpid() % 10000}'
    out = tmp_path_factory.mktemp('dash_session')
    port, fox = free_port(), free_port()
    dash = DashboardProcess('--namespace', ns, '--port', str(port), '--foxglove-port', str(fox))
    client = FoxgloveClient(f'ws://127.0.0.1:{fox}', (f'/{ns}/bench/encoders',
                                                       f'/{ns}/te/statistics'))
    client.start()
    result: dict = {'ns': ns, 'out': out, 'dash': dash}
    try:
        with chromium() as tab:
            tab.get(dash.url)
            wait_for(lambda: (page_state(tab) or {}).get('connected'), 20, 'the tab to connect')
            launch = subprocess.Popen(
                [sys.executable, '-m', 'rv_te_bench.cli.main', 'launch', '--default',
                 '--namespace', ns, '--param', 'bench.speed_factor=5',
                 '--param', f'recorder.output_dir={out}',
                 '--param', 'bench.wait_for_nodes=[te_node, recorder, dashboard]'],
                env=env(), cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                text=True)
            seen = []
            while launch.poll() is None:
                s = page_state(tab)
                seen.append((time.monotonic(), s['draws'], s['status'].get('blocks', 0)))
                time.sleep(0.5)
            result['launch_rc'] = launch.returncode
            result['launch_err'] = launch.stderr.read()
            result['seen'] = seen
            time.sleep(2.0)
            result['tab1'] = page_state(tab)
            result['tab1_text'] = {k: text(tab, k) for k in ('last-pp', 'cum-pp', 'dominant',
                                                             'windows')}
            with chromium() as late:
                t0 = time.monotonic()
                late.get(dash.url)
                wait_for(lambda: (page_state(late) or {}).get('windows') == result['tab1'][
                    'windows'], 10, 'the late tab to catch up')
                result['late_s'] = time.monotonic() - t0
                time.sleep(1.0)
                result['tab2'] = page_state(late)
                result['tab2_text'] = {k: text(late, k) for k in result['tab1_text']}
                result['tab1_again'] = page_state(tab)
    finally:
        client.stop.set()
        client.join(5)
        dash.stop()
    result['fox'] = client
    bags = [p for p in out.iterdir() if (p / 'metadata.yaml').exists()]
    assert len(bags) == 1, (list(out.iterdir()), result.get('launch_err'))
    result['bag'] = bags[0]
    return result


def _bag_messages(bag: Path, topic: str) -> list:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]


def test_the_page_updates_while_the_session_runs(session):
    assert session['launch_rc'] == 0, session['launch_err']
    seen = session['seen']
    running = [(d, b) for _, d, b in seen if b > 0]
    assert len({b for _, b in running}) >= 3, seen    # blocks grew on screen, several times
    assert running[-1][0] - running[0][0] >= 3        # and the page redrew meanwhile
    assert session['tab1']['status']['first_seq'] == 0
    for tab in ('tab1', 'tab2'):
        assert session[tab]['errors'] == [], session[tab]['errors']   # no panel failed


def test_values_on_screen_equal_the_te_nodes_messages(session):
    ns = session['ns']
    windows = [m for m in _bag_messages(session['bag'], f'/{ns}/te/statistics')
               if m.window_complete]
    last = max(windows, key=lambda m: m.window_index)
    assert session['tab1_text']['last-pp'] == f'{last.window.pp_rad * ARCMIN:.4f}'
    assert {w['index'] for w in session['tab1']['windows']} == {
        int(m.window_index) for m in windows}
    spectra = _bag_messages(session['bag'], f'/{ns}/te/spectrum')
    top = max(spectra[-1].lines, key=lambda ln: ln.amplitude_rad)
    assert session['tab1_text']['dominant'].startswith(f'{top.label}: ')
    assert session['tab1']['dominant']['amplitude_rad'] == top.amplitude_rad


def test_every_sample_is_inside_the_drawn_envelope(session):
    ns = session['ns']
    info = _bag_messages(session['bag'], f'/{ns}/bench/info')[0]
    blocks = _bag_messages(session['bag'], f'/{ns}/bench/encoders')
    assert [b.seq for b in blocks] == list(range(len(blocks)))
    th_in = np.concatenate([b.theta_in_rad for b in blocks])
    th_out = np.concatenate([b.theta_out_rad for b in blocks])
    te = (th_out - th_in / info.gear_ratio) * ARCMIN
    drawn = session['tab1']['drawn']['angle']
    ncols, nbins = drawn['ncols'], drawn['nbins']
    rel = (th_out - th_out[0]) / (2 * math.pi)
    rev = np.floor(rel)
    col = (np.minimum(((rel - rev) * nbins).astype(int), nbins - 1) * ncols) // nbins
    checked = 0
    for role in ('current', 'previous'):
        d = drawn[role]
        lo = np.array([np.nan if x is None else x for x in d['min']])
        hi = np.array([np.nan if x is None else x for x in d['max']])
        mine = rev == d['rev']
        c = col[mine]
        assert np.all(lo[c] <= te[mine] + 1e-9) and np.all(te[mine] <= hi[c] + 1e-9)
        checked += int(mine.sum())
    assert checked >= 15_000                          # a whole revolution at least
    # the whole-session plot: every sample of the session inside its time column
    ov = session['tab1']['drawn']['overview']
    lo = np.array([np.nan if x is None else x for x in ov['min']])
    hi = np.array([np.nan if x is None else x for x in ov['max']])
    b = np.arange(len(te)) // ov['samples_per_bin'] - ov['first_bin']
    c = (b * ov['ncols']) // ov['nbins']
    assert ov['first_bin'] == 0 and c[-1] < ov['ncols']
    assert np.all(lo[c] <= te + 1e-9) and np.all(te <= hi[c] + 1e-9)


def test_a_late_tab_catches_up_and_two_tabs_agree(session):
    assert session['late_s'] < 10
    a, b = session['tab1_again'], session['tab2']
    assert a['windows'] == b['windows']
    assert a['drawn']['angle'] == b['drawn']['angle']
    assert a['drawn']['overview']['max'] == b['drawn']['overview']['max']
    assert session['tab1_text'] == session['tab2_text']


def test_foxglove_clients_get_the_topics_as_the_bag_has_them(session):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    fox, ns = session['fox'], session['ns']
    assert fox.error is None, fox.error
    by_topic = {ch['topic']: ch for ch in fox.channels.values()}
    enc = by_topic[f'/{ns}/bench/encoders']
    assert (enc['encoding'], enc['schemaName'], enc['schemaEncoding']) == (
        'cdr', 'rv_te_msgs/msg/EncoderBlock', 'ros2msg')
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(enc['schema'].split('=' * 80)[0],
                                      'rv_te_msgs/msg/EncoderBlock'))
    got = [store.deserialize_cdr(m, 'rv_te_msgs/msg/EncoderBlock')
           for m in fox.messages[f'/{ns}/bench/encoders']]
    bag = {b.seq: b for b in _bag_messages(session['bag'], f'/{ns}/bench/encoders')}
    assert len(got) >= 0.9 * len(bag)
    for m in got:
        ref = bag[m.seq]
        np.testing.assert_array_equal(m.theta_in_rad, ref.theta_in_rad)
        np.testing.assert_array_equal(m.theta_out_rad, ref.theta_out_rad)
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == (ref.header.stamp.sec,
                                                                ref.header.stamp.nanosec)
    assert fox.messages[f'/{ns}/te/statistics']


def test_the_token_is_enforced_and_hostile_text_stays_text(need_chromium, ros_context):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rv_te_msgs.msg import TestReport

    ns = f'tok{os.getpid() % 10000}'
    dash = DashboardProcess('--namespace', ns, '--host', '0.0.0.0', '--port', str(free_port()),
                            '--no-foxglove')
    node = None
    try:
        token = dash.token()
        assert token and len(token) >= 20
        base = dash.url.split('?')[0].replace(dash.url.split('/')[2].split(':')[0],
                                               '127.0.0.1')
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(base, timeout=5)
        assert err.value.code == 403
        hostile = '<script>window.__pwned=1</script><img src=x onerror="window.__pwned=2">'
        import rclpy

        node = rclpy.create_node('hostile', namespace=ns, context=ros_context)
        pub = node.create_publisher(TestReport, 'test/report', QoSProfile(
            depth=20, reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        pub.publish(TestReport(serial=hostile, operator_name=hostile, plan_name=hostile,
                               verdict='running', reason=hostile))
        with chromium() as tab:
            tab.get(base)
            assert '403' in tab.find_element('tag name', 'body').text
            tab.get(f'{base}?token={token}')
            wait_for(lambda: hostile in (text(tab, 'ident') or ''), 20,
                     'the hostile serial on the page')
            assert tab.execute_script('return window.__pwned === undefined')
            assert tab.execute_script("return document.querySelectorAll('script').length") == 2
            assert tab.execute_script("return document.querySelectorAll('img').length") == 0
            assert hostile in text(tab, 'verdict-banner')
    finally:
        if node is not None:
            node.destroy_node()
        dash.stop()


@pytest.mark.slow
def test_rv_te_test_page_shows_steps_hysteresis_metrics_and_verdict(need_chromium, tmp_path):
    port = free_port()
    cmd = [sys.executable, '-m', 'rv_te_bench.cli.main', 'test', 'li2023-rv', '--serial',
           'LI-0042', '--operator', 'kim', '--launch', 'li2023-rv', '--out-dir', str(tmp_path),
           '--namespace', f'tst{os.getpid() % 10000}', '--dashboard', '--dashboard-port',
           str(port), '--no-foxglove', '--speed-factor', '1']   # real time: the page sees
    # each step (at 2x, on a machine at load 30, the tab connected after the TE step)
    proc = subprocess.Popen(cmd, env=env(), cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    shot = tmp_path / 'dashboard.png'
    rows_js = ("return [...document.querySelectorAll('#metrics tbody tr')].map("
               "tr => [...tr.children].map(td => td.textContent));")
    with chromium(1400, 2400) as tab:
        wait_for(lambda: _try_get(tab, f'http://127.0.0.1:{port}/'), 60, 'the page')
        wait_for(lambda: len(tab.execute_script('return window.rvte.S.curve') or []) > 200,
                 60, 'the hysteresis curve')
        wait_for(lambda: (page_state(tab) or {}).get('verdict') in {'pass', 'fail'} or
                 proc.poll() is not None, 90, 'the verdict')
        time.sleep(0.5)
        tab.save_screenshot(str(shot))
        verdict = page_state(tab)['verdict']
        rows = tab.execute_script(rows_js)
        steps = text(tab, 'steps')
        loop = page_state(tab)['drawn']['hyst']
        assert page_state(tab)['errors'] == []
        log = tab.execute_script('return window.rvte.testLog')
    _, err = proc.communicate(timeout=120)
    assert proc.returncode in (0, 3), err
    report = json.loads(next(tmp_path.glob('LI-0042_*/report/report.json')).read_text())
    assert verdict == report['verdict']
    by_label = {r[0]: r for r in rows}
    for m in report['metrics']:
        if m['value'] is None or m['unit'] != 'rad':
            continue
        row = next(r for label, r in by_label.items() if label.endswith('[arcmin]') and
                   r[4] == m['verdict'] and abs(float(r[1]) - m['value'] * ARCMIN) <=
                   5e-4 * abs(m['value'] * ARCMIN))
        assert row
    assert 'hysteresis' in steps and 'finished' in steps
    # a metric was on screen against its limit as soon as it was decided: the first TE
    # direction's, while the TE step (its second direction) still ran
    early = [e for e in log if ['te', 'started'] in e['steps']
             and any(r[3] in {'pass', 'fail'} for r in e['rows'])]
    assert early, log
    decided = [r for r in early[0]['rows'] if r[3] in {'pass', 'fail'}]
    assert decided[0][0].startswith('TE p-p, ccw') and decided[0][2].startswith('<='), decided
    assert 'pending' in {r[3] for r in early[0]['rows']}
    # the loop drawn as two branches (lines through the torque columns), spanning the
    # step's torque range (the plan's rated torque, 450 N m, both ways)
    for name in ('rising', 'falling'):
        assert loop['branches'][name]['columns'] >= 20, loop
    assert loop['torque_min'] < -400 and loop['torque_max'] > 400, loop
    if os.environ.get('RV_TE_UPDATE_SCREENSHOT') == '1':
        (REPO / 'docs' / 'dashboard.png').write_bytes(shot.read_bytes())


def _try_get(tab, url: str) -> bool:
    try:
        tab.get(url)
    except Exception:  # noqa: BLE001 - not up yet
        return False
    return bool(tab.execute_script('return !!window.rvte'))
