// rv-te live page. Read-only: it receives updates over one WebSocket and draws them.
// Every text that comes from the session goes in through textContent (never as HTML).
// Envelopes: the server sends min/max per bin; the page merges bins into its pixel columns
// (min of mins, max of maxes), so every sample lies inside the drawn band of its column.
'use strict';
(function () {
  const ARCMIN = 10800 / Math.PI, ARCSEC = 648000 / Math.PI, RPM = 30 / Math.PI;
  const S = newSession();
  let shown = S;            // what is drawn (a finished session stays until new data comes)
  let old = null;
  const dash = window.rvte = { S, draws: 0, updates: 0, drawWall: [], latency: [],
    rxLatency: [], drawn: {}, connected: false, messages: 0, testLog: [],
    drawMs: [], applyMs: [], msgWall: [], errors: [] };

  function newSession() {
    return { id: null, status: {}, info: {}, revs: {}, views: {}, windows: new Map(),
      openWindow: null, spectrum: null, advice: {}, recorder: {}, nodes: {}, events: [],
      steps: [], feedback: {}, report: {}, curve: [] };
  }
  const $ = (id) => document.getElementById(id);
  function el(tag, text, cls) {
    const e = document.createElement(tag);
    if (text !== undefined && text !== null) e.textContent = String(text);
    if (cls) e.className = cls;
    return e;
  }
  function fmt(x, d) { return (x === null || x === undefined || !isFinite(x)) ? '-' : Number(x).toFixed(d); }
  function sig(x, d) { return (x === null || x === undefined || !isFinite(x)) ? '-' : Number(x).toPrecision(d); }
  function row(tbody, cells, cls) {
    const tr = el('tr', null, cls);
    for (const c of cells) { const td = el('td'); if (c instanceof Node) td.appendChild(c); else td.textContent = c; tr.appendChild(td); }
    tbody.appendChild(tr);
    return tr;
  }

  // ---------------------------------------------------------------- applying updates
  function apply(u) {
    if (u.type === 'full') {
      if (S.id !== null && u.session_id !== S.id) old = snapshotOf(S);
      Object.assign(S, newSession());
      S.id = u.session_id;
    }
    S.status = u.status || S.status;
    if (u.info) S.info = u.info;
    if (u.revs && u.revs.length) for (const e of Object.values(S.revs)) e.role = null;   // roles move on
    for (const r of (u.revs || [])) applyRev(r);
    for (const name of ['recent', 'overview']) if (u[name]) applyView(name, u[name]);
    for (const w of (u.windows || [])) S.windows.set(w.index, w);
    if ('open_window' in u) S.openWindow = u.open_window;
    for (const k of ['spectrum', 'advice', 'recorder', 'nodes', 'steps', 'feedback', 'report']) if (u[k]) S[k] = u[k];
    if (u.report && dash.testLog.length < 500) {   // what the table said when (for checks)
      dash.testLog.push({ steps: S.steps.map((x) => [x.step_name, x.state]),
        rows: (u.report.rows || []).map((m) => [m.label, m.value, m.limit, m.verdict]) });
    }
    if (u.events) S.events.push(...u.events);
    if (u.curve) { S.curve.length = u.curve.from; for (const p of u.curve.points) S.curve.push(p); }
    const hasData = (S.status.blocks || 0) > 0 || S.windows.size > 0 || S.steps.length > 0;
    const was = shown;
    shown = (!hasData && old) ? old : S;
    if (hasData) old = null;
    // what the next frame redraws: only the panels whose data came (a frame is then short)
    if (u.type === 'full' || shown !== was) for (const k of Object.keys(changed)) changed[k] = true;
    if (u.revs && u.revs.length) changed.angle = true;
    if (u.recent || u.overview) changed.time = true;
    if (u.spectrum) changed.spectrum = true;
    if (u.windows || 'open_window' in u) changed.windows = true;
    changed.session = true;   // the status (blocks, session time) comes with every update
    if (u.steps || u.feedback || u.report || u.curve) changed.test = true;
    dash.updates++;
  }
  const changed = { angle: true, time: true, spectrum: true, windows: true, session: true, test: true };
  function snapshotOf(s) { return Object.assign(newSession(), s, { windows: new Map(s.windows) }); }
  function applyRev(r) {
    const n = S.status.angle_bins || 2048;
    let e = S.revs[r.rev];
    if (!e) { e = S.revs[r.rev] = { min: new Float64Array(n).fill(NaN), max: new Float64Array(n).fill(NaN) }; }
    e.role = r.role;
    for (let i = 0; i < r.min.length; i++) {
      e.min[r.from_bin + i] = r.min[i] === null ? NaN : r.min[i];
      e.max[r.from_bin + i] = r.max[i] === null ? NaN : r.max[i];
    }
    e.seen = dash.updates;
    const keep = Object.keys(S.revs).sort((a, b) => S.revs[b].seen - S.revs[a].seen).slice(0, 4);
    for (const k of Object.keys(S.revs)) if (!keep.includes(k)) delete S.revs[k];
  }
  function applyView(name, v) {
    const n = v.last_bin - v.first_bin + 1;
    let cur = S.views[name];
    if (v.replace || !cur || cur.level !== v.level) {
      cur = { level: v.level, first: v.first_bin, cols: {} };
      for (const k of Object.keys(v.cols)) cur.cols[k] = [];
    } else if (v.first_bin !== cur.first) {
      const drop = v.first_bin - cur.first;
      for (const k of Object.keys(cur.cols)) cur.cols[k] = cur.cols[k].slice(drop);
      cur.first = v.first_bin;
    }
    const off = v.from_bin - cur.first;
    for (const k of Object.keys(v.cols)) {
      const dst = cur.cols[k] || (cur.cols[k] = []);
      dst.length = Math.max(off, 0);
      for (const x of v.cols[k]) dst.push(x === null ? NaN : x);
    }
    for (const k of Object.keys(cur.cols)) cur.cols[k].length = n;
    cur.last = v.last_bin;
    S.views[name] = cur;
  }

  // ---------------------------------------------------------------- envelopes -> columns
  function columns(nbins, ncols, getMin, getMax) {
    const lo = new Array(ncols).fill(null), hi = new Array(ncols).fill(null);
    for (let b = 0; b < nbins; b++) {
      const a = getMin(b), z = getMax(b);
      if (!isFinite(a) || !isFinite(z)) continue;
      const c = Math.floor(b * ncols / nbins);
      if (lo[c] === null || a < lo[c]) lo[c] = a;
      if (hi[c] === null || z > hi[c]) hi[c] = z;
    }
    return [lo, hi];
  }
  function plotCols(u) { return Math.max(16, Math.floor(u.bbox.width / (window.devicePixelRatio || 1))); }

  // ---------------------------------------------------------------- plots
  const plots = {};
  function mkPlot(id, opts) {
    const host = $(id);
    const w = Math.max(300, host.clientWidth), h = host.classList.contains('small') ? 180 : 250;
    return new uPlot(Object.assign({ width: w, height: h, legend: { live: false }, cursor: { show: false } }, opts),
      opts.data || [[]], host);
  }
  function band(label, color) {
    return [{ label: label + ' max', stroke: color, width: 1, spanGaps: false },
            { label: label + ' min', stroke: color, width: 1, spanGaps: false }];
  }
  function makePlots() {
    plots.angle = mkPlot('plot-angle', {
      scales: { x: { time: false, range: [0, 360] } },
      axes: [{ label: 'output angle from the start position [deg]' }, { label: 'TE [arcmin]' }],
      series: [{}, ...band('previous rev', '#9ca3af'), ...band('current rev', '#2563eb')],
      bands: [{ series: [1, 2], fill: 'rgba(156,163,175,0.35)' }, { series: [3, 4], fill: 'rgba(37,99,235,0.35)' }],
      data: [[], [], [], [], []] });
    plots.recent = mkPlot('plot-recent', {
      scales: { x: { time: false } }, axes: [{ label: 'session time [s]' }, { label: 'TE [arcmin]' }],
      series: [{}, ...band('TE', '#2563eb')], bands: [{ series: [1, 2], fill: 'rgba(37,99,235,0.35)' }],
      data: [[], [], []] });
    plots.speed = mkPlot('plot-speed', {
      scales: { x: { time: false }, in: {}, out: {} },
      axes: [{ label: 'session time [s]' }, { scale: 'in', label: 'input [rpm]' }, { scale: 'out', side: 1, label: 'output [rpm]', grid: { show: false } }],
      series: [{}, { label: 'input', scale: 'in', stroke: '#dc2626' }, { label: 'output', scale: 'out', stroke: '#059669' }],
      data: [[], [], []] });
    plots.torque = mkPlot('plot-torque', {
      scales: { x: { time: false } }, axes: [{ label: 'session time [s]' }, { label: 'output torque [N m]' }],
      series: [{}, ...band('torque', '#7c3aed')], bands: [{ series: [1, 2], fill: 'rgba(124,58,237,0.3)' }],
      data: [[], [], []] });
    plots.overview = mkPlot('plot-overview', {
      scales: { x: { time: false } }, axes: [{ label: 'session time [s]' }, { label: 'TE [arcmin]' }],
      series: [{}, ...band('TE', '#0f766e')], bands: [{ series: [1, 2], fill: 'rgba(15,118,110,0.35)' }],
      data: [[], [], []] });
    plots.spectrum = mkPlot('plot-spectrum', {
      scales: { x: { time: false, distr: 3 }, y: { distr: 1 } },
      axes: [{ label: 'output order [cycles per output revolution]' }, { label: 'amplitude [arcsec]' }],
      series: [{}, { label: 'line amplitude', stroke: '#b45309', fill: 'rgba(180,83,9,0.5)', paths: uPlot.paths.bars({ size: [0.6, 8] }), points: { show: true, size: 5 } }],
      hooks: { draw: [drawLineLabels] }, data: [[], []] });
    // the loop: per branch (torque rising / falling) one line through the mean angle of each
    // torque column, and the band of the column's min..max (a dwell's creep, the cycles)
    const branch = (label, color, fill) => [
      { label: label, stroke: color, width: 2, spanGaps: true, points: { show: false } },
      { label: label + ' max', stroke: fill, width: 1, spanGaps: false, points: { show: false } },
      { label: label + ' min', stroke: fill, width: 1, spanGaps: false, points: { show: false } }];
    plots.hyst = mkPlot('plot-hyst', {
      legend: { show: false },   // the caption under the plot says which colour is which
      scales: { x: { time: false } }, axes: [{ label: 'applied output torque [N m]' }, { label: 'torsion angle [arcmin]' }],
      series: [{}, ...branch('torque rising', '#1d4ed8', 'rgba(29,78,216,0.45)'), ...branch('torque falling', '#c2410c', 'rgba(194,65,12,0.45)')],
      bands: [{ series: [2, 3], fill: 'rgba(29,78,216,0.18)' }, { series: [5, 6], fill: 'rgba(194,65,12,0.18)' }],
      data: [[], [], [], [], [], [], []] });
  }
  function drawLineLabels(u) {
    const lab = u._labels || [];
    const ctx = u.ctx;
    ctx.save();
    ctx.font = `${11 * (window.devicePixelRatio || 1)}px system-ui`;
    ctx.fillStyle = '#7c2d12';
    ctx.textAlign = 'center';
    for (const [x, y, text] of lab) {
      const px = u.valToPos(x, 'x', true), py = u.valToPos(y, 'y', true);
      if (isFinite(px) && isFinite(py)) ctx.fillText(text, px, py - 6);
    }
    ctx.restore();
  }

  // ---------------------------------------------------------------- drawing
  function drawAngle(s) {
    const u = plots.angle, ncols = plotCols(u), n = s.status.angle_bins || 2048;
    const xs = Array.from({ length: ncols }, (_, c) => (c + 0.5) * 360 / ncols);
    const data = [xs];
    const drawn = { ncols, nbins: n };
    for (const role of ['previous', 'current']) {
      const k = Object.keys(s.revs).find((r) => s.revs[r].role === role);
      let lo = new Array(ncols).fill(null), hi = lo;
      if (k !== undefined) {
        const e = s.revs[k];
        [lo, hi] = columns(n, ncols, (b) => e.min[b] * ARCMIN, (b) => e.max[b] * ARCMIN);
        drawn[role] = { rev: Number(k), min: lo, max: hi };
      }
      data.push(hi, lo);
    }
    dash.drawn.angle = drawn;
    u.setData(data);
  }
  function viewColumns(v, u, keys) {
    const n = v.cols.t_first ? v.cols.t_first.length : 0, ncols = Math.min(plotCols(u), Math.max(n, 1));
    const x = new Array(ncols).fill(null), lo = new Array(ncols).fill(null), hi = new Array(ncols).fill(null);
    const [kmin, kmax, scale] = keys;
    for (let b = 0; b < n; b++) {
      const c = Math.floor(b * ncols / n), t = v.cols.t_first[b];
      if (isFinite(t) && (x[c] === null || t < x[c])) x[c] = t;
      const a = v.cols[kmin][b] * scale, z = v.cols[kmax][b] * scale;
      if (!isFinite(a) || !isFinite(z)) continue;
      if (lo[c] === null || a < lo[c]) lo[c] = a;
      if (hi[c] === null || z > hi[c]) hi[c] = z;
    }
    const keep = x.map((t, i) => t !== null ? i : -1).filter((i) => i >= 0);
    return { ncols, nbins: n, colLo: lo, colHi: hi, x: keep.map((i) => x[i]), lo: keep.map((i) => lo[i]), hi: keep.map((i) => hi[i]) };
  }
  function speeds(v, u) {
    const n = v.cols.t_first ? v.cols.t_first.length : 0, ncols = Math.min(plotCols(u), Math.max(n, 1));
    const acc = Array.from({ length: ncols }, () => ({ t0: NaN, t1: NaN, i0: NaN, i1: NaN, o0: NaN, o1: NaN }));
    for (let b = 0; b < n; b++) {
      const c = acc[Math.floor(b * ncols / n)], C = v.cols;
      if (!isFinite(C.t_first[b])) continue;
      if (!isFinite(c.t0)) { c.t0 = C.t_first[b]; c.i0 = C.theta_in_first[b]; c.o0 = C.theta_out_first[b]; }
      c.t1 = C.t_last[b]; c.i1 = C.theta_in_last[b]; c.o1 = C.theta_out_last[b];
    }
    const ok = acc.filter((c) => isFinite(c.t0) && c.t1 > c.t0);
    return [ok.map((c) => c.t0), ok.map((c) => (c.i1 - c.i0) / (c.t1 - c.t0) * RPM), ok.map((c) => (c.o1 - c.o0) / (c.t1 - c.t0) * RPM)];
  }
  function drawTime(s) {
    const r = s.views.recent;
    if (r) {
      const c = viewColumns(r, plots.recent, ['te_min', 'te_max', ARCMIN]);
      plots.recent.setData([c.x, c.hi, c.lo]);
      dash.drawn.recent = { ncols: c.ncols, first_bin: r.first, level: r.level, x: c.x, min: c.lo, max: c.hi };
      plots.speed.setData(speeds(r, plots.speed));
      const t = viewColumns(r, plots.torque, ['torque_min', 'torque_max', 1]);
      plots.torque.setData([t.x, t.hi, t.lo]);
    }
    $('card-torque').classList.toggle('hidden', !s.status.torque_present);
    const o = s.views.overview;
    if (o) {
      const c = viewColumns(o, plots.overview, ['te_min', 'te_max', ARCMIN]);
      plots.overview.setData([c.x, c.hi, c.lo]);
      dash.drawn.overview = { ncols: c.ncols, nbins: c.nbins, first_bin: o.first, level: o.level,
        samples_per_bin: 8 << o.level, min: c.colLo, max: c.colHi };
    }
  }
  function drawSpectrum(s) {
    const sp = s.spectrum;
    const body = $('lines').tBodies[0];
    body.replaceChildren();
    if (!sp) return;
    $('spec-title').textContent = `of window ${sp.window_index} (${fmt(sp.revolutions, 2)} rev, f_w = ${fmt(sp.crank_hz, 3)} Hz)`;
    const lines = sp.lines.filter((l) => isFinite(l.amplitude_rad) && l.output_order > 0).slice().sort((a, b) => a.output_order - b.output_order);
    const byAmp = lines.slice().sort((a, b) => b.amplitude_rad - a.amplitude_rad);
    const top = byAmp[0];
    $('dominant').textContent = top ? `${top.label}: ${fmt(top.amplitude_rad * ARCSEC, 3)} arcsec (${fmt(top.amplitude_rad * ARCMIN, 4)} arcmin) at order ${sig(top.output_order, 5)}` : '-';
    dash.dominant = top ? { label: top.label, amplitude_rad: top.amplitude_rad } : null;
    const labelled = [];
    for (const l of byAmp.slice(0, 6)) {
      // skip a label that would overlap a stronger one's (within 15 % in order), as the report does
      if (labelled.some(([x]) => Math.abs(Math.log(x / l.output_order)) < 0.14)) continue;
      labelled.push([l.output_order, l.amplitude_rad * ARCSEC, l.label.length > 16 ? l.label.split(' (')[0] : l.label]);
    }
    plots.spectrum._labels = labelled;
    plots.spectrum.setData([lines.map((l) => l.output_order), lines.map((l) => l.amplitude_rad * ARCSEC)]);
    for (const l of byAmp.slice(0, 14)) row(body, [l.label, sig(l.output_order, 5), fmt(l.frequency_hz, 3), fmt(l.amplitude_rad * ARCSEC, 3)]);
  }
  function drawWindows(s) {
    const body = $('windows').tBodies[0];
    const ws = [...s.windows.values()].sort((a, b) => b.index - a.index);
    if (body.childElementCount !== ws.length + (s.openWindow ? 1 : 0) || dash.updates % 10 === 0) {
      body.replaceChildren();
      if (s.openWindow) row(body, [`${s.openWindow.index} (open)`, fmt(s.openWindow.revolutions, 2), fmt(s.openWindow.pp_rad * ARCMIN, 4), fmt(s.openWindow.mean_rad * ARCMIN, 4), fmt(s.openWindow.std_rad * ARCMIN, 4), fmt(s.openWindow.amplitude_rad * ARCMIN, 4)], 'muted');
      for (const w of ws) row(body, [w.index, fmt(w.revolutions, 2), fmt(w.pp_rad * ARCMIN, 4), fmt(w.mean_rad * ARCMIN, 4), fmt(w.std_rad * ARCMIN, 4), fmt(w.amplitude_rad * ARCMIN, 4)]);
    }
    const last = ws[0];
    $('last-pp').textContent = last ? fmt(last.pp_rad * ARCMIN, 4) : '-';
    const cum = last ? last.cumulative_pp_rad : (s.openWindow ? s.openWindow.cumulative_pp_rad : NaN);
    $('cum-pp').textContent = fmt(cum * ARCMIN, 4);
  }
  // a small table updated in place: only cells whose text changed are touched (rebuilding
  // the rows every update made the browser lay the page out again each frame)
  function kv(tbody, pairs) {
    if (tbody.rows.length !== pairs.length) {
      tbody.replaceChildren();
      for (const cells of pairs) row(tbody, cells);
      return;
    }
    pairs.forEach((cells, i) => cells.forEach((text, j) => {
      const td = tbody.rows[i].cells[j], t = String(text);
      if (td.textContent !== t) td.textContent = t;
    }));
  }
  function drawSession(s) {
    const st = s.status, info = s.info;
    $('ns').textContent = `${st.namespace || '/'} (${st.source || ''})`;
    const badge = $('state');
    badge.textContent = st.state || '-';
    badge.className = 'badge ' + (String(st.state).startsWith('running') ? 'running' : String(st.state).startsWith('finished') ? 'finished' : '');
    kv($('session').tBodies[0], [
      ['bench', `${info.bench_id || '-'} · preset ${info.preset || '-'} · i = ${sig(info.gear_ratio, 6)}`],
      ['encoders', `${info.encoder_in_model || '-'} / ${info.encoder_out_model || '-'} at ${fmt(info.sample_rate_hz, 0)} Hz`],
      ['blocks / samples', `${st.blocks || 0} / ${st.samples || 0} (seq ${st.first_seq ?? '-'}..${st.last_seq ?? '-'})`],
      ['session time', `${fmt(st.t_s, 2)} s`]]);
    const r = s.recorder;
    kv($('recorder').tBodies[0], r && r.bag !== undefined ? [
      ['state', r.message], ['bag', r.bag],
      ['size', r.size_bytes === null || r.size_bytes === undefined ? '-' : `${(r.size_bytes / 1e6).toFixed(2)} MB`],
      ['messages', String(r.messages)], ['lost (disk full)', String(r.lost_messages)],
      ['gaps / missing blocks', `${r.gaps} / ${r.missing_blocks}`]] : [['state', 'no recorder seen']]);
    const nodes = Object.entries(s.nodes).sort();
    const nodeRows = nodes.map(([name, n]) => [name, n.gone ? 'GONE' : (['ok', 'warn', 'error', 'stale'][n.level] || '-'), n.message || '']);
    const nb = $('nodes').tBodies[0];
    kv(nb, nodeRows);
    nodes.forEach(([, n], i) => { nb.rows[i].className = n.gone || n.level >= 2 ? 'fail' : ''; });
    const ev = $('events');
    if (ev.childElementCount !== s.events.length) {
      ev.replaceChildren();
      if (!s.events.length) ev.appendChild(el('li', 'none so far', 'muted'));
      for (const e of s.events.slice().reverse()) {
        ev.appendChild(el('li', `${new Date(e.wall_s * 1000).toLocaleTimeString()} ${e.kind}: ${e.text}`, e.level));
      }
    }
    const adv = $('advice');
    const methods = Object.values(s.advice);
    if (methods.length) {
      adv.replaceChildren();
      adv.className = '';
      for (const a of methods) {
        adv.appendChild(el('p', `${a.method}: ${a.summary}`));
        adv.appendChild(el('p', `TE ${a.te_metric}: ${fmt(a.te_before_rad * ARCMIN, 4)} -> ${fmt(a.te_after_rad * ARCMIN, 4)} arcmin (predicted)`, 'muted'));
      }
    }
  }
  function drawTest(s) {
    const rep = s.report, fb = s.feedback;
    const active = s.steps.length || rep.plan_name || fb.step_name;
    $('card-test').classList.toggle('hidden', !active);
    if (active) {   // built while the card was hidden: fit it to its column now
      const host = $('plot-hyst'), w = Math.max(300, host.clientWidth);
      if (Math.abs(plots.hyst.width - w) > 2) { plots.hyst.setSize({ width: w, height: plots.hyst.height }); dash.hystDrawn = -1; }
    }
    const banner = $('verdict-banner');
    if (!active) { banner.classList.add('hidden'); return; }
    $('ident').textContent = `unit ${rep.serial || (s.steps[0] || {}).serial || '-'} · operator ${rep.operator_name || '-'} · plan ${rep.plan_name || '-'}`;
    $('test-title').textContent = `plan ${rep.plan_name || '-'}, unit ${rep.serial || '-'}`;
    const ol = $('steps');
    ol.replaceChildren();
    const names = (rep.plan_steps && rep.plan_steps.length) ? rep.plan_steps : s.steps.map((x) => ({ name: x.step_name, kind: x.step_kind }));
    names.forEach((p, i) => {
      const st = s.steps.find((x) => x.step_index === i);
      ol.appendChild(el('li', `${p.name} (${p.kind}) — ${st ? st.state : 'pending'}`, st ? st.state : 'pending'));
    });
    if (fb.step_count) {
      $('step-bar').style.width = `${100 * fb.step_progress}%`;
      $('plan-bar').style.width = `${100 * fb.plan_progress}%`;
      $('step-text').textContent = `step ${fb.step_index + 1}/${fb.step_count} ${fb.step_name}: ${fmt(100 * fb.step_progress, 1)} % · ${fb.live_metric} ${liveValue(fb)}`;
      $('plan-text').textContent = `plan: ${fmt(100 * fb.plan_progress, 1)} %`;
    }
    const verdict = rep.verdict || 'running';
    // while it runs, a metric out of its limit decides the unit's verdict (FAIL) at once
    const failedSoFar = (rep.rows || []).filter((m) => m.verdict === 'fail').map((m) => m.label);
    const decided = verdict === 'running' && failedSoFar.length ? 'fail' : verdict;
    banner.classList.remove('hidden');
    banner.className = 'banner ' + (['pass', 'fail', 'running'].includes(decided) ? decided : 'other');
    if (verdict !== 'running') banner.textContent = `VERDICT: ${verdict.toUpperCase()}  unit ${rep.serial || ''}: ${rep.reason || ''}`;
    else if (decided === 'fail') banner.textContent = `VERDICT: FAIL (decided, the test goes on)  unit ${rep.serial || ''}: out of limit: ${failedSoFar.join(', ')}`;
    else banner.textContent = `TEST RUNNING: unit ${rep.serial || ''}${rep.reason && rep.reason !== 'started' ? ' · ' + rep.reason : ''}`;
    dash.verdict = verdict;
    dash.decided = decided;
    const mb = $('metrics').tBodies[0];
    mb.replaceChildren();
    for (const m of (rep.rows || [])) {
      row(mb, [m.label, m.value, m.limit, m.margin, el('span', m.verdict, m.verdict), m.source]);
    }
    if (s.curve.length && s.curve.length !== dash.hystDrawn) drawLoop(s.curve);
  }
  // the curve's points [torque, angle, branch +1 rising / -1 falling / 0 not known yet] into
  // the plot's torque columns, per branch: mean (the line), min and max (the band)
  function drawLoop(curve) {
    const u = plots.hyst, ncols = Math.max(16, Math.floor(plotCols(u) / 2));
    let lo = Infinity, hi = -Infinity;
    for (const p of curve) { if (p[0] < lo) lo = p[0]; if (p[0] > hi) hi = p[0]; }
    const span = (hi - lo) || 1, w = span / ncols;
    const acc = [1, -1].map(() => ({ sum: new Float64Array(ncols), n: new Uint32Array(ncols),
      min: new Float64Array(ncols).fill(Infinity), max: new Float64Array(ncols).fill(-Infinity) }));
    for (const [t, a, b] of curve) {
      const k = b < 0 ? 1 : 0, c = Math.min(ncols - 1, Math.floor((t - lo) / w)), A = acc[k], y = a * ARCMIN;
      A.sum[c] += y; A.n[c]++;
      if (y < A.min[c]) A.min[c] = y;
      if (y > A.max[c]) A.max[c] = y;
    }
    const xs = Array.from({ length: ncols }, (_, c) => lo + (c + 0.5) * w);
    const data = [xs];
    const branches = {};
    acc.forEach((A, k) => {
      const mean = [], mn = [], mx = [];
      for (let c = 0; c < ncols; c++) {
        const ok = A.n[c] > 0;
        mean.push(ok ? A.sum[c] / A.n[c] : null); mn.push(ok ? A.min[c] : null); mx.push(ok ? A.max[c] : null);
      }
      data.push(mean, mx, mn);
      branches[k === 0 ? 'rising' : 'falling'] = { columns: mean.filter((v) => v !== null).length, points: A.n.reduce((x, y) => x + y, 0) };
    });
    u.setData(data);
    dash.hystDrawn = curve.length;
    dash.drawn.hyst = { ncols, torque_min: lo, torque_max: hi, branches };
  }
  function liveValue(fb) {
    if (!isFinite(fb.live_value)) return '-';
    if (String(fb.live_metric).endsWith('_rad')) return `${fmt(fb.live_value * ARCMIN, 4)} arcmin`;
    return `${sig(fb.live_value, 5)}`;
  }

  // how long the page spends per frame and per message [ms] (the benchmark reads them)
  function keep(a, x) { a.push(x); if (a.length > 5000) a.splice(0, 2500); }
  let dirty = false;
  function frame() {
    if (dirty) {
      dirty = false;
      const s = shown, t0 = performance.now();
      const draw = { angle: drawAngle, time: drawTime, spectrum: drawSpectrum, windows: drawWindows, session: drawSession, test: drawTest };
      for (const [k, f] of Object.entries(draw)) {
        if (!changed[k]) continue;
        changed[k] = false;
        try { f(s); } catch (e) { keep(dash.errors, `${k}: ${e}`); }   // one panel, not the page
      }
      keep(dash.drawMs, performance.now() - t0);
      const now = Date.now() / 1000;
      dash.draws++;
      dash.drawWall.push(now);
      if (dash.drawWall.length > 5000) dash.drawWall.splice(0, 2500);
      if (Number.isFinite(s.status.last_sample_s) && s.status.last_sample_s !== dash.lastSampleDrawn) {
        dash.lastSampleDrawn = s.status.last_sample_s;
        dash.latency.push(now - s.status.last_sample_s);
        dash.rxLatency.push(now - s.status.last_rx_wall_s);
        if (dash.latency.length > 20000) { dash.latency.splice(0, 10000); dash.rxLatency.splice(0, 10000); }
      }
    }
    requestAnimationFrame(frame);
  }

  // ---------------------------------------------------------------- connection
  function connect() {
    const token = new URLSearchParams(location.search).get('token');
    const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws${token ? '?token=' + encodeURIComponent(token) : ''}`;
    const ws = new WebSocket(url);
    ws.onopen = () => { dash.connected = true; $('conn').textContent = 'live'; $('conn').className = 'badge running'; };
    ws.onmessage = (ev) => {
      dash.messages++;
      const t0 = performance.now();
      apply(JSON.parse(ev.data));
      keep(dash.applyMs, performance.now() - t0);
      keep(dash.msgWall, Date.now() / 1000);
      dirty = true;
    };
    ws.onclose = () => {
      dash.connected = false;
      $('conn').textContent = 'disconnected: showing the last data';
      $('conn').className = 'badge bad';
      setTimeout(connect, 2000);
    };
  }
  makePlots();
  window.addEventListener('resize', () => {
    for (const [id, p] of Object.entries(plots)) {
      const host = p.root.parentElement;
      p.setSize({ width: Math.max(300, host.clientWidth), height: p.height });
      void id;
    }
    for (const k of Object.keys(changed)) changed[k] = true;
    dash.hystDrawn = -1;
    dirty = true;
  });
  requestAnimationFrame(frame);
  connect();
})();
