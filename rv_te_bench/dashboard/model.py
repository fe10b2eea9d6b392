"""What the live page shows, kept by the server: the session so far, in SI units, no ROS.

The bridge node (:mod:`rv_te_bench.dashboard.bridge`) feeds plain values in from its
callbacks (the ROS executor's thread); the web server (:mod:`rv_te_bench.dashboard.server`)
folds the pending encoder samples in and takes each client's update (its asyncio thread).
One lock guards both sides; the bridge only appends under it (a callback never waits for a
browser).

An update for a client is everything that changed since the client's cursor (a generation
number): a new tab has cursor 0 and gets the whole session so far (the table of every
revolution, every event and step, the current envelopes), an open tab gets the bins and
rows changed since its last update. Units: TE, angles in rad, torque in N m, times in s;
the page converts (arcmin, deg, rpm) at its edge.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rv_te_bench.core.te import output_phase_and_te
from rv_te_bench.dashboard.envelope import AngleEnvelopes, TimeEnvelopes
from rv_te_bench.dashboard.loop import HysteresisLoop

__all__ = ['MAX_EVENTS', 'MAX_PENDING_SAMPLES', 'DashboardModel', 'EncoderSamples']

#: Events (losses, gaps, crashes) kept; older ones are counted, not kept.
MAX_EVENTS = 2000
#: Samples waiting for the gear ratio (bench/info) or for the next fold; beyond it the
#: oldest are dropped and counted as a page-side loss (the session itself loses nothing).
MAX_PENDING_SAMPLES = 5_000_000


@dataclass
class EncoderSamples:
    """One EncoderBlock's samples as the bridge hands them over (SI units)."""

    seq: int
    stamp_s: float
    time_offset_s: np.ndarray
    theta_in_rad: np.ndarray
    theta_out_rad: np.ndarray
    torque_out_nm: np.ndarray
    received_wall_s: float = field(default_factory=time.time)


class DashboardModel:
    """The session as the page shows it (see the module docstring)."""

    def __init__(self, *, namespace: str = '/', source: str = 'live', angle_bins: int = 2048,
                 max_columns: int = 2048) -> None:
        """An empty session; ``source`` says what drives it ('live', 'replay BAG', ...)."""
        self.lock = threading.Lock()
        self.namespace = namespace
        self.source = source
        self._angle_bins = angle_bins
        self._max_columns = max_columns
        self.session_id = 0
        self._reset(new_id=False)

    # -- session lifecycle ------------------------------------------------------------------
    def _reset(self, *, new_id: bool = True) -> None:
        if new_id:
            self.session_id += 1
        self.gen = 1
        self.started_wall_s = time.time()
        self.info: dict[str, Any] = {}
        self.info_gen = 0
        self.angle = AngleEnvelopes(self._angle_bins, keep=2)
        self.times = TimeEnvelopes(max_columns=self._max_columns)
        self.pending: deque[EncoderSamples] = deque()
        self.pending_samples = 0
        self.dropped_page_samples = 0
        self.blocks = 0
        self.samples = 0
        self.last_seq: int | None = None
        self.first_seq: int | None = None
        self.t0_s = math.nan
        self.last_sample_s = math.nan
        self.last_rx_wall_s = math.nan
        self.last_block_wall_s = math.nan
        self.torque_present = False
        self.windows: list[dict[str, Any]] = []
        self.open_window: dict[str, Any] | None = None
        self.window_gen = 0
        self.spectrum: dict[str, Any] | None = None
        self.spectrum_gen = 0
        self.advice: dict[str, dict[str, Any]] = {}
        self.advice_gen = 0
        self.recorder: dict[str, Any] = {}
        self.recorder_gen = 0
        self.nodes: dict[str, dict[str, Any]] = {}
        self.nodes_gen = 0
        self.state = 'waiting for the bench'
        self.state_gen = 0
        self.events: list[dict[str, Any]] = []
        self.events_dropped = 0
        self.steps: list[dict[str, Any]] = []
        self.steps_gen = 0
        self.feedback: dict[str, Any] = {}
        self.feedback_gen = 0
        self.report: dict[str, Any] = {}
        self.report_gen = 0
        self.curve = HysteresisLoop()
        self._hysteresis_active = False

    def _bump(self) -> int:
        self.gen += 1
        return self.gen

    def event(self, kind: str, text: str, *, level: str = 'warn') -> None:
        """Record a loss, a gap, a crash (shown as it happens, kept for late tabs)."""
        with self.lock:
            self._event(kind, text, level)

    def _event(self, kind: str, text: str, level: str) -> None:
        if len(self.events) >= MAX_EVENTS:
            self.events_dropped += 1
            return
        self.events.append({'gen': self._bump(), 'wall_s': time.time(), 'kind': kind,
                            'level': level, 'text': text})

    def set_state(self, state: str) -> None:
        """Bench running / finished / ... as the launcher or the bridge sees it."""
        with self.lock:
            if state != self.state:
                self.state = state
                self.state_gen = self._bump()

    # -- inputs -----------------------------------------------------------------------------
    def on_bench_info(self, info: dict[str, Any]) -> None:
        """BenchInfo fields (gear_ratio, sample_rate_hz, preset, bench_id, ...)."""
        with self.lock:
            if info == self.info:
                return
            self.info = dict(info)
            self.info_gen = self._bump()

    def on_encoders(self, block: EncoderSamples) -> None:
        """A block of samples: queued for the next fold (cheap; called per message)."""
        with self.lock:
            if self.last_seq is not None and block.seq < self.last_seq and (
                    self.state.startswith('finished') or block.seq == 0):
                self._reset()   # a new session (a new bench, a replay again) starts
            if self.first_seq is None:
                self.first_seq = block.seq
                if block.seq != 0:
                    self._event('leading loss', f'the page joined the stream at block '
                                f'{block.seq}: blocks 0..{block.seq - 1} are not on it',
                                'info')
            elif block.seq != self.last_seq + 1:
                self._event('seq gap', f'encoder blocks jump from seq {self.last_seq} to '
                            f'{block.seq} ({block.seq - self.last_seq - 1} missing)', 'error')
            self.last_seq = block.seq
            self.blocks += 1
            self.last_block_wall_s = block.received_wall_s
            if self.state != 'running':
                self.state = 'running'
                self.state_gen = self._bump()
            self.pending.append(block)
            self.pending_samples += len(block.time_offset_s)
            while self.pending_samples > MAX_PENDING_SAMPLES:
                old = self.pending.popleft()
                self.pending_samples -= len(old.time_offset_s)
                self.dropped_page_samples += len(old.time_offset_s)

    def on_window(self, w: dict[str, Any]) -> None:
        """te/statistics: one window's statistics (complete: a row of the table)."""
        with self.lock:
            w = {**w, 'gen': self._bump()}
            if w.get('complete'):
                self.windows = [x for x in self.windows if x['index'] != w['index']]
                self.windows.append(w)
                self.windows.sort(key=lambda x: x['index'])
                if self.open_window and self.open_window['index'] <= w['index']:
                    self.open_window = None
            else:
                self.open_window = w
            self.window_gen = w['gen']

    def on_spectrum(self, s: dict[str, Any]) -> None:
        """te/spectrum: the order spectrum of the last closed window."""
        with self.lock:
            self.spectrum = dict(s)
            self.spectrum_gen = self._bump()

    def on_advice(self, a: dict[str, Any]) -> None:
        """compensation/advice, one per method."""
        with self.lock:
            self.advice[a['method']] = dict(a)
            self.advice_gen = self._bump()

    def on_recorder(self, r: dict[str, Any]) -> None:
        """The recorder's diagnostics (bag, state, counts, losses)."""
        with self.lock:
            old = self.recorder
            if old:
                for key, kind in (('lost_messages', 'disk full'), ('missing_blocks',
                                  'recorder missed blocks'), ('write_errors', 'write error')):
                    if r.get(key, 0) > old.get(key, 0):
                        self._event(kind, f'recorder: {key.replace("_", " ")} '
                                    f'{old.get(key, 0)} -> {r[key]} ({r.get("bag", "")})',
                                    'error')
                if 'DISK FULL' in r.get('message', '') and 'DISK FULL' not in old.get(
                        'message', ''):
                    self._event('disk full', f'recorder: {r["message"]}', 'error')
                if 'FOREIGN' in r.get('message', '') and 'FOREIGN' not in old.get('message',
                                                                                   ''):
                    self._event('foreign publisher', f'recorder: {r["message"]}', 'error')
            elif r.get('missing_blocks', 0):
                self._event('leading loss', f'recorder: {r["missing_blocks"]} blocks missing '
                            'from the bag', 'error')
            self.recorder = dict(r)
            self.recorder_gen = self._bump()

    def on_recorder_gone(self) -> None:
        """The recorder left the graph: a status still saying 'recording' is not true any
        more (its final 'closed' status, when it came, stays as it is)."""
        with self.lock:
            r = self.recorder
            if not r or str(r.get('message', '')).startswith('closed'):
                return
            self.recorder = {**r, 'level': 2, 'message': 'recorder gone without saying the bag '
                             f'was closed (its last status: {r.get("message", "")})'}
            self.recorder_gen = self._bump()
            self._event('recorder gone', f'recorder: {self.recorder["message"]} '
                        f'({r.get("bag", "")})', 'error')

    def on_node_status(self, name: str, status: dict[str, Any]) -> None:
        """A node's diagnostics (level, message, gaps / drops) or its disappearance."""
        with self.lock:
            old = self.nodes.get(name, {})
            if status.get('gaps', 0) > old.get('gaps', 0):
                self._event('gap', f'{name}: gaps {old.get("gaps", 0)} -> {status["gaps"]} '
                            f'({status.get("message", "")})', 'warn')
            if status.get('dropped', 0) > old.get('dropped', 0):
                self._event('dropped', f'{name}: dropped {old.get("dropped", 0)} -> '
                            f'{status["dropped"]} messages', 'warn')
            if status.get('gone') and not old.get('gone'):
                self._event('node gone', f'node {name} {status.get("message", "is gone")}',
                            'error')
            self.nodes[name] = {**old, **status}
            self.nodes_gen = self._bump()

    def on_step(self, s: dict[str, Any]) -> None:
        """test/step: a step started / finished / cancelled."""
        with self.lock:
            key = (s['step_index'], s['step_name'])
            self.steps = [x for x in self.steps if (x['step_index'], x['step_name']) != key]
            self.steps.append(dict(s))
            self.steps.sort(key=lambda x: x['step_index'])
            self._hysteresis_active = s['step_kind'] == 'hysteresis' and s['state'] == 'started'
            if self._hysteresis_active:
                self.curve.clear()
            self.steps_gen = self._bump()
            if s['state'] == 'finished':
                self._judge()

    def on_feedback(self, fb: dict[str, Any]) -> None:
        """The test action's feedback (step progress, plan progress, live value)."""
        with self.lock:
            self.feedback = dict(fb)
            self.feedback_gen = self._bump()

    def on_report(self, r: dict[str, Any]) -> None:
        """test/report: plan, metrics against limits, verdict as it is decided."""
        from rv_te_bench.dashboard.verdicts import plan_steps

        with self.lock:
            old_plan = self.report.get('plan_yaml')
            self.report = {**r, 'plan_steps': self.report.get('plan_steps', [])}
            if r.get('plan_yaml') != old_plan or not self.report['plan_steps']:
                self.report['plan_steps'] = plan_steps(r.get('plan_yaml', ''))
            self._judge()

    def _judge(self) -> None:
        """The metric table: finished steps against the limits, or the final report's."""
        from rv_te_bench.dashboard.verdicts import live_rows

        if not self.report and not self.steps:
            return
        self.report = {**self.report, 'rows': live_rows(self.report, self.steps,
                                                        str(self.info.get('preset', '')))}
        self.report_gen = self._bump()

    # -- folding the samples in (server thread) --------------------------------------------
    def fold(self) -> None:
        """Fold the queued samples into the envelopes (once the gear ratio is known)."""
        with self.lock:
            ratio = float(self.info.get('gear_ratio') or 0.0)
            if not self.pending or not ratio > 0:
                return
            blocks, self.pending = list(self.pending), deque()
            self.pending_samples = 0
            gen = self._bump()
            t = np.concatenate([b.stamp_s + np.asarray(b.time_offset_s) for b in blocks])
            th_in = np.concatenate([b.theta_in_rad for b in blocks])
            th_out = np.concatenate([b.theta_out_rad for b in blocks])
            n = len(t)
            if all(len(b.torque_out_nm) == len(b.time_offset_s) for b in blocks):
                torque = np.concatenate([b.torque_out_nm for b in blocks])
                self.torque_present = self.torque_present or bool(len(torque))
            else:
                torque = None
            _, te = output_phase_and_te(th_in, th_out, gear_ratio=ratio, check=False)
            if math.isnan(self.t0_s) and n:
                self.t0_s = float(t[0])
            first = self.times.push(t - self.t0_s, th_in, th_out, te, torque, gen)
            self.angle.push(th_out, te, first, gen)
            self.samples += n
            if n:
                self.last_sample_s = float(t[-1])
                self.last_rx_wall_s = blocks[-1].received_wall_s
            if self._hysteresis_active and torque is not None:
                self.curve.push(t, te, torque)

    # -- output (server thread) -------------------------------------------------------------
    def update(self, cursor: dict[str, Any] | None) -> tuple[dict[str, Any], dict[str, Any]]:
        """Everything changed since ``cursor`` (None: a new client) and the new cursor."""
        with self.lock:
            return self._update(cursor)

    def _update(self, cursor: dict[str, Any] | None) -> tuple[dict[str, Any], dict[str, Any]]:
        full = cursor is None or cursor.get('session_id') != self.session_id
        since = 0 if full else cursor['gen']
        views = {} if full else dict(cursor.get('views', {}))
        out: dict[str, Any] = {'type': 'full' if full else 'delta',
                               'session_id': self.session_id, 'gen': self.gen,
                               'server_wall_s': time.time()}
        out['status'] = self._status()
        if self.info_gen > since:
            out['info'] = self.info
        out['revs'] = self._revs(since)
        for name, first_sample in (('recent', self._recent_start()), ('overview', 0)):
            view = self.times.view(first_sample)
            if view is None:
                continue
            old = views.get(name)
            redo = old is None or old[0] != view.level or old[1] != view.first_bin
            first_bin, cols = self.times.rows(view, 0 if redo else since)
            out[name] = {'level': view.level, 'samples_per_bin': view.samples_per_bin,
                         'first_bin': view.first_bin, 'last_bin': view.last_bin,
                         'replace': redo, 'from_bin': first_bin,
                         'cols': {k: _clean(v) for k, v in cols.items()}}
            views[name] = (view.level, view.first_bin)
        if self.window_gen > since:
            out['windows'] = [w for w in self.windows if w['gen'] > since]
            out['open_window'] = self.open_window
        for name, gen, value in (('spectrum', self.spectrum_gen, self.spectrum),
                                 ('advice', self.advice_gen, self.advice),
                                 ('recorder', self.recorder_gen, self.recorder),
                                 ('nodes', self.nodes_gen, self.nodes),
                                 ('steps', self.steps_gen, self.steps),
                                 ('feedback', self.feedback_gen, self.feedback),
                                 ('report', self.report_gen, self.report)):
            if gen > since and value is not None:
                out[name] = value
        new_events = [e for e in self.events if e['gen'] > since]
        if new_events:
            out['events'] = new_events
        curve_cursor = None if full else cursor.get('curve')
        if len(self.curve) and (full or self.gen > since):
            out['curve'], curve_cursor = self.curve.since(curve_cursor)
        new_cursor = {'session_id': self.session_id, 'gen': self.gen, 'views': views,
                      'curve': curve_cursor}
        return out, new_cursor

    def _status(self) -> dict[str, Any]:
        return {'namespace': self.namespace, 'source': self.source, 'state': self.state,
                'blocks': self.blocks, 'samples': self.samples, 'first_seq': self.first_seq,
                'last_seq': self.last_seq, 't_s': (self.last_sample_s - self.t0_s
                                                   if self.samples else None),
                'last_sample_s': _num(self.last_sample_s),
                'last_rx_wall_s': _num(self.last_rx_wall_s),
                'torque_present': self.torque_present,
                'events_dropped': self.events_dropped,
                'dropped_page_samples': self.dropped_page_samples,
                'angle_bins': self.angle.n_bins}

    def _recent_start(self) -> int:
        """First sample of the previous revolution (the time plot shows it and the current)."""
        prev = self.angle.previous()
        cur = self.angle.current
        starts = [self.angle.rev_start_sample.get(k) for k in (prev, cur) if k is not None]
        starts = [s for s in starts if s is not None]
        return min(starts) if starts else 0

    def _revs(self, since: int) -> list[dict[str, Any]]:
        out = []
        cur, prev = self.angle.current, self.angle.previous()
        for role, k in (('current', cur), ('previous', prev)):
            if k is None:
                continue
            lo, hi, g = self.angle.revs[k]
            changed = np.flatnonzero(g > since)
            if not len(changed):
                out.append({'role': role, 'rev': k, 'from_bin': 0, 'min': [], 'max': []})
                continue
            a, b = int(changed[0]), int(changed[-1]) + 1
            out.append({'role': role, 'rev': k, 'from_bin': a,
                        'min': _clean(np.where(np.isfinite(lo[a:b]), lo[a:b], np.nan)),
                        'max': _clean(np.where(np.isfinite(hi[a:b]), hi[a:b], np.nan))})
        return out


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _clean(a: np.ndarray) -> list[Any]:
    """An array as a JSON-able list, NaN / inf as None (exact doubles, no rounding)."""
    a = np.asarray(a, dtype=np.float64)
    if np.isfinite(a).all():
        return a.tolist()
    obj = a.astype(object)
    obj[~np.isfinite(a)] = None
    return obj.tolist()
