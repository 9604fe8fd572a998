// Moreau's web page: the list of jobs, studies and campaigns with live state (server-sent events), a form
// to submit a run, a study or a campaign, and each one's results in plain words, its figures and
// downloads; a live plot of a running job's state; the trajectories of chosen jobs overlaid. Plain
// JavaScript, no build step: served by moreau-server from files compiled into it (server/web/).
//
// Everything shown comes from the server or the user and is put in the page as text (textContent,
// element.append(string)), never as HTML: a scene named "<script>..." shows those characters. And as
// visible text (visible()): a bidirectional override reorders what follows it (a name shown as
// "ctl...live" was "ctl", U+202E, "...evil"), so the overrides and the control characters are shown as
// escapes: "ctl\u{202e}...evil". Plots are SVG elements made here, with numbers as their attributes.
// The token, when the server has one, is kept in this tab's sessionStorage and sent as a bearer header;
// that is why figures, downloads and event streams are fetched (an <img src> or EventSource cannot send
// a header) and shown from blob: URLs.
//
// Addresses: /#/jobs/ID, /#/studies/ID and /#/campaigns/ID open that item (route()); choosing an item
// sets the hash, so the browser's back and forward go between items.
'use strict';

const FINAL = new Set(['done', 'failed', 'cancelled']);
const SVG_NS = 'http://www.w3.org/2000/svg';
// What each kind is called, where the API has it, what its list answer holds, and its figures.
const KINDS = {
  run: { name: 'job', api: '/v1/jobs/', route: 'jobs', list: 'jobs', limit: 50, figures: ['state', 'energy', 'step', 'phase'] },
  study: { name: 'study', api: '/v1/studies/', route: 'studies', list: 'studies', limit: 20, figures: ['work', 'order'] },
  campaign: { name: 'campaign', api: '/v1/campaigns/', route: 'campaigns', list: 'campaigns', limit: 20,
              figures: ['convergence-cdf', 'inputs', 'success-map'] },
};
const ROUTE_KIND = { jobs: 'run', studies: 'study', campaigns: 'campaign' };
const $ = (id) => document.getElementById(id);

let token = sessionStorage.getItem('moreau-token') || '';
const rows = new Map();       // id -> {tr, item, kind}
const following = new Set();  // ids whose event stream is open
// Browsers open at most 6 connections to a server: streams are kept for the chosen item and a few others;
// the rest are updated by the list's refresh. A stream that ended early is not reopened for a while.
const MAX_STREAMS = 3;
const STREAM_RETRY_MS = 2000;
const streamRetryAt = new Map();  // id -> time before which its stream is not reopened
const deleted = new Set();        // items deleted from this page: an answer still in flight must not bring them back
const pace = new Map();           // id -> {at, fraction}: the first progress seen, for the time left
const live = new Map();           // job id -> {t0, t_end, n, indices, points: [{t, q, v, energy}]}
const MAX_LIVE_POINTS = 2000;     // per job; beyond it every other point is dropped
const compared = new Set();       // job ids ticked for comparison
let selected = null;              // {kind, id}
// Other views of a run: functions (job, box) that add a button or a panel to its detail area (#job-tools),
// called each time the job's view is drawn.
const jobTools = [];
let figureUrls = [];

// ---- HTTP ---------------------------------------------------------------------------------------

class ApiError extends Error {
  constructor(status, body, text) {
    super(describeError(status, body, text));
    this.status = status;
  }
}

function describeError(status, body, text) {
  if (body && typeof body === 'object' && body.error) {
    let s = `${status} ${body.error}`;
    if (body.pointer) s += ` at ${body.where ? body.where + ' ' : ''}${body.pointer}`;
    if (body.reason) s += `: ${body.reason}`;
    if (status === 401) s += token ? ' (the token entered was not accepted)' : ' (enter the server\'s token above)';
    return s;
  }
  return `${status} ${String(text).slice(0, 500)}`;
}

function authHeaders(extra) {
  const h = Object.assign({}, extra || {});
  if (token) h['Authorization'] = 'Bearer ' + token;
  return h;
}

async function request(method, path, body, extraHeaders) {
  const init = { method, headers: authHeaders(extraHeaders) };
  if (body !== undefined) {
    init.headers['Content-Type'] = 'application/json';
    init.body = JSON.stringify(body);
  }
  const r = await fetch(path, init);
  if (!r.ok) {
    const text = await r.text();
    let j = null;
    try { j = JSON.parse(text); } catch (e) { /* not JSON */ }
    throw new ApiError(r.status, j, text);
  }
  return r;
}

async function api(method, path, body) {
  return (await request(method, path, body)).json();
}

const itemUrl = (kind, id) => KINDS[kind].api + encodeURIComponent(id);
const jobUrl = (id) => itemUrl('run', id);

// ---- small DOM helpers --------------------------------------------------------------------------

// Text made visible: control characters (C0 but tab and newline, DEL, C1) and the bidirectional
// embeddings, overrides and isolates (U+202A-U+202E, U+2066-U+2069) as \u{1b}, \u{202e}. Every string
// the page shows goes through it (el(), setText()).
const INVISIBLE = /[\u0000-\u0008\u000b-\u001f\u007f-\u009f\u202a-\u202e\u2066-\u2069]/g;
function visible(s) {
  return String(s).replace(INVISIBLE, (c) => '\\u{' + c.charCodeAt(0).toString(16) + '}');
}

function setText(element, s) {
  element.textContent = visible(s);
}

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === 'class') e.className = v;
    else e.setAttribute(k, v);
  }
  for (const c of children) {
    if (c === null || c === undefined) continue;
    e.append(typeof c === 'string' ? visible(c) : c);  // strings become text nodes
  }
  return e;
}

function svg(tag, attrs) {
  const e = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, String(v));
  return e;
}

function showError(id, err) {
  setText($(id), err ? (err.message || String(err)) : '');
}

function when(unixSeconds) {
  return typeof unixSeconds === 'number' ? new Date(unixSeconds * 1000).toLocaleTimeString() : '';
}

// ---- numbers ------------------------------------------------------------------------------------

// A number as 6 significant digits; the full value (shortest round-trip form, as the server sent it) is
// its title, and copying it gives the full value (the copy handler below). Not a finite number: said so.
function short(x) {
  if (typeof x !== 'number') return x === null || x === undefined ? 'n/a' : String(x);
  if (!Number.isFinite(x)) return String(x);
  if (Number.isInteger(x) && Math.abs(x) < 1e15) return String(x);
  const r = Number(x.toPrecision(6));
  if (Math.abs(r) >= 1e6 || (r !== 0 && Math.abs(r) < 1e-4)) return r.toExponential().replace('e+', 'e');  // 1.23457e20, 2.5e-7
  return String(r);
}

function num(x) {
  const s = short(x);
  const span = el('span', { class: 'num' }, s);
  const full = String(x);
  if (typeof x === 'number' && Number.isFinite(x) && s !== full) {
    span.title = visible(full);
    span.dataset.full = full;
  }
  return span;
}

function numList(values) {
  const out = [];
  (Array.isArray(values) ? values : []).forEach((x, i) => {
    if (i) out.push(', ');
    out.push(num(x));
  });
  return out;
}

// Copying text that holds shortened numbers copies their full values.
document.addEventListener('copy', (ev) => {
  const sel = document.getSelection();
  if (!sel || sel.rangeCount === 0 || sel.isCollapsed) return;
  const box = document.createElement('div');
  for (let i = 0; i < sel.rangeCount; ++i) box.append(sel.getRangeAt(i).cloneContents());
  const nums = box.querySelectorAll('[data-full]');
  // A selection within one number: the fragment holds only its text.
  const anchor = sel.anchorNode && (sel.anchorNode.nodeType === 1 ? sel.anchorNode : sel.anchorNode.parentElement);
  const inside = anchor && anchor.closest('[data-full]');
  if (!nums.length && !(inside && inside.contains(sel.focusNode))) return;
  if (nums.length) for (const n of nums) n.textContent = n.dataset.full;
  const text = nums.length ? box.textContent : inside.dataset.full;
  ev.clipboardData.setData('text/plain', text);
  ev.preventDefault();
});

// ---- state and progress -------------------------------------------------------------------------

function fraction(item) {
  const p = item.progress || {};
  return typeof p.fraction === 'number' && Number.isFinite(p.fraction) ? Math.min(1, Math.max(0, p.fraction)) : 0;
}

// The state in words, said once: "cancelled by request at step 147968", not "cancelled (cancelled by
// request at step 147968)"; a queued item's place in the queue.
function stateText(item) {
  const state = String(item.state || '');
  let s = state;
  const reason = item.reason ? String(item.reason) : '';
  if (reason) s = reason.startsWith(state) ? reason : `${state} (${reason})`;
  if (item.queue_position) s += ` (#${item.queue_position} in the queue)`;
  return s;
}

// The time left, from the progress made since this page first saw it and the wall time that took.
function timeLeft(item) {
  if (item.state !== 'running') return '';
  const f = fraction(item);
  const now = performance.now();
  const first = pace.get(item.id);
  if (!first) {
    pace.set(item.id, { at: now, fraction: f });
    return '';
  }
  const seconds = (now - first.at) / 1000;
  if (f <= first.fraction || seconds < 0.5) return '';
  const left = (1 - f) * seconds / (f - first.fraction);
  return left < 60 ? `about ${Math.ceil(left)} s left` : `about ${Math.ceil(left / 60)} min left`;
}

function progressText(item) {
  const eta = timeLeft(item);
  return `${Math.round(100 * fraction(item))}%` + (eta ? `, ${eta}` : '');
}

// ---- the list -----------------------------------------------------------------------------------

function renderRow(item) {
  if (deleted.has(item.id)) return;
  const kind = KINDS[item.kind] ? item.kind : 'run';
  let entry = rows.get(item.id);
  if (!entry) {
    const tr = el('tr', { 'data-id': item.id, 'data-kind': kind });
    tr.addEventListener('click', (ev) => {
      if (ev.target.closest('td.pick')) return;
      choose(kind, item.id);
    });
    entry = { tr, item, kind };
    rows.set(item.id, entry);
    $('jobs').tBodies[0].prepend(tr);  // newest first
  }
  // A final state is the last one: a list fetched before the job's final event and answered after it
  // must not take the row back to "cancelling" or "running".
  if (FINAL.has(entry.item.state) && !FINAL.has(item.state)) item = entry.item;
  entry.item = item;
  const pick = el('td', { class: 'pick' });
  if (kind === 'run') {
    const box = el('input', { type: 'checkbox', 'aria-label': 'compare this job' });
    box.checked = compared.has(item.id);
    box.disabled = !(item.links && item.links.trajectory);
    box.addEventListener('change', () => {
      if (box.checked) compared.add(item.id);
      else compared.delete(item.id);
      showCompareChoice();
    });
    pick.append(box);
  }
  const bar = el('progress', { max: '1', value: String(fraction(item)) });
  entry.tr.replaceChildren(
    pick,
    el('td', { class: 'kind' }, KINDS[kind].name),
    el('td', { class: 'scene' }, item.scene || ''),
    el('td', { class: 'state state-' + item.state }, stateText(item)),
    el('td', { class: 'progress' }, bar, ' ' + progressText(item)),
    el('td', {}, when(item.created)),
    el('td', { class: 'id' }, item.id));
  entry.tr.classList.toggle('selected', !!selected && item.id === selected.id);
  maybeFollow(entry);
}

function maybeFollow(entry) {
  const item = entry.item;
  if (FINAL.has(item.state) || following.has(item.id)) return;
  if (Date.now() < (streamRetryAt.get(item.id) || 0)) return;
  if (!(selected && selected.id === item.id) && following.size >= MAX_STREAMS) return;
  follow(entry.kind, item.id);
}

async function refreshList() {
  try {
    const lists = await Promise.all(Object.entries(KINDS).map(async ([kind, k]) => {
      const list = await api('GET', `${k.api.slice(0, -1)}?limit=${k.limit}`);
      return (Array.isArray(list[k.list]) ? list[k.list] : []).map((item) => Object.assign({ kind }, item));
    }));
    showError('list-error', null);
    const all = lists.flat().sort((a, b) => (a.created || 0) - (b.created || 0));
    for (const item of all) renderRow(item);
    // Items no longer listed (deleted here or elsewhere, or older than those shown) leave the table.
    const listed = new Set(all.map((j) => j.id));
    for (const [id, entry] of rows) {
      if (listed.has(id)) continue;
      entry.tr.remove();
      rows.delete(id);
      compared.delete(id);
    }
    showCompareChoice();
  } catch (e) {
    showError('list-error', e);
  }
}

// The item's event stream, read with fetch so that it carries the token: each `state` and `progress`
// event updates its row, each `sample` the live plot; when the stream ends (after the final state) the
// row and, if shown, the item are read again.
async function follow(kind, id) {
  if (following.has(id)) return;
  following.add(id);
  try {
    const r = await request('GET', itemUrl(kind, id) + '/events', undefined, { Accept: 'text/event-stream' });
    const reader = r.body.getReader();
    const decoder = new TextDecoder();
    let buffer = '';
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      buffer += decoder.decode(value, { stream: true });
      let end;
      while ((end = buffer.indexOf('\n\n')) >= 0) {
        onEvent(id, parseEvent(buffer.slice(0, end)));
        buffer = buffer.slice(end + 2);
      }
      if (buffer.length > 1 << 20) break;  // no event is that long
    }
  } catch (e) {
    if (!(e instanceof ApiError && e.status === 404)) showError('list-error', e);
  } finally {
    following.delete(id);
    streamRetryAt.set(id, Date.now() + STREAM_RETRY_MS);
  }
  if (deleted.has(id)) return;
  try {
    const item = Object.assign({ kind }, await api('GET', itemUrl(kind, id)));
    renderRow(item);
    if (selected && selected.id === id) showItem(kind, item);
  } catch (e) {
    if (!(e instanceof ApiError && e.status === 404)) showError('list-error', e);
  }
}

function parseEvent(block) {
  const event = { name: 'message', data: '' };
  for (const line of block.split('\n')) {
    if (line.startsWith(':')) continue;
    const colon = line.indexOf(':');
    const field = colon < 0 ? line : line.slice(0, colon);
    const value = colon < 0 ? '' : line.slice(colon + 1).replace(/^ /, '');
    if (field === 'event') event.name = value;
    else if (field === 'data') event.data += value;
    else if (field === 'id') event.id = value;
  }
  return event;
}

const isNum = (x) => typeof x === 'number' && Number.isFinite(x);

function onEvent(id, event) {
  const entry = rows.get(id);
  if (!entry || !event.data) return;
  let data;
  try { data = JSON.parse(event.data); } catch (e) { return; }
  if (!data || typeof data !== 'object') return;
  const item = Object.assign({}, entry.item);
  if (event.name === 'state') {
    item.state = String(data.state);
    if (FINAL.has(item.state)) {  // its figures show the run from now on
      live.delete(id);
      pace.delete(id);
    }
    if (data.reason) item.reason = data.reason;
    if (item.state !== 'queued') delete item.queue_position;
  } else if (event.name === 'progress') {
    let f = null;
    if (isNum(data.t) && isNum(data.t0) && isNum(data.t_end) && data.t_end > data.t0) f = (data.t - data.t0) / (data.t_end - data.t0);
    else if (isNum(data.rows) && isNum(data.rows_total) && data.rows_total > 0) f = data.rows / data.rows_total;
    else if (isNum(data.samples) && isNum(data.samples_total) && data.samples_total > 0) f = data.samples / data.samples_total;
    if (f === null) return;
    item.progress = Object.assign({}, item.progress, { fraction: Math.min(1, Math.max(0, f)) });
    if (isNum(data.t)) item.progress.t = data.t;
  } else if (event.name === 'sample') {
    addSample(entry, data);
    return;
  } else {
    return;
  }
  renderRow(item);
  if (selected && selected.id === id) {
    if (event.name === 'state') select(entry.kind, id);  // the view follows the state (its buttons, results)
    else showProgress(item);
  }
}

// ---- the live plot of a running job -------------------------------------------------------------

function addSample(entry, data) {
  if (!isNum(data.t)) return;
  const p = entry.item.progress || {};
  let l = live.get(entry.item.id);
  if (!l) {
    l = { t0: isNum(p.t0) ? p.t0 : data.t, t_end: isNum(p.t_end) ? p.t_end : data.t, points: [] };
    live.set(entry.item.id, l);
  }
  l.n = isNum(data.n) ? data.n : 0;
  l.indices = Array.isArray(data.indices) ? data.indices : null;
  // The coordinates' names from the scene (shown as text, like everything the server sends).
  l.names = Array.isArray(data.names) ? data.names.slice(0, 64).map(String) : null;
  const last = l.points[l.points.length - 1];
  if (last && data.t <= last.t) return;  // a replay of what was drawn
  const values = (a) => (Array.isArray(a) ? a.slice(0, 64).map((x) => (isNum(x) ? x : null)) : []);
  l.points.push({ t: data.t, q: values(data.q), v: values(data.v), energy: isNum(data.energy) ? data.energy : null });
  if (l.points.length > MAX_LIVE_POINTS) l.points = l.points.filter((_, i) => i % 2 === 0);
  if (selected && selected.id === entry.item.id) drawLive();
}

// The chosen quantity's series from points, one per coordinate: [{name, xs, ys}].
function liveSeries(l, quantity) {
  if (quantity === 'energy') return [{ name: 'E', xs: l.points.map((p) => p.t), ys: l.points.map((p) => p.energy) }];
  const width = l.points.reduce((m, p) => Math.max(m, p[quantity].length), 0);
  const out = [];
  for (let i = 0; i < width; ++i) {
    const index = l.indices && isNum(l.indices[i]) ? l.indices[i] : i;
    const named = l.names && typeof l.names[i] === 'string' ? l.names[i] : null;
    out.push({ name: named !== null ? (quantity === 'v' ? `${named} (velocity)` : named) : `${quantity}[${index}]`, xs: l.points.map((p) => p.t), ys: l.points.map((p) => (i < p[quantity].length ? p[quantity][i] : null)) });
  }
  return out;
}

function drawLive() {
  const box = $('live-plot');
  if (!selected || selected.kind !== 'run') return;
  const l = live.get(selected.id);
  const quantity = $('live-quantity').value;
  if (!l || !l.points.length) {
    box.replaceChildren(el('p', {}, 'waiting for the first state from the run'));
    return;
  }
  const series = liveSeries(l, quantity);
  const plot = drawPlot(series, { xmin: l.t0, xmax: l.t_end, xlabel: 't', ylabel: quantity === 'energy' ? 'E' : quantity });
  plot.id = 'live-svg';
  plot.dataset.points = String(l.points.length);
  const note = l.indices ? `${l.indices.length} of the ${l.n} coordinates shown (evenly spread)` : '';
  const lastT = l.points[l.points.length - 1].t;
  box.replaceChildren(plot, legend(series), el('p', { class: 'note' }, `${l.points.length} states drawn, up to t = `, num(lastT), note ? `; ${note}` : ''));
}

// ---- plots (SVG drawn here) ---------------------------------------------------------------------

const COLORS = ['#0366d6', '#d73a49', '#28a745', '#6f42c1', '#e36209', '#1b7c83', '#b08800', '#5a32a3', '#cb2431', '#005cc5'];

// series: [{name, xs, ys}] (null or non-finite values break a line); options: xmin, xmax, xlabel, ylabel.
function drawPlot(series, options) {
  const W = 720, H = 300, L = 64, R = 12, T = 22, B = 36;
  const finite = (a) => a.filter(isNum);
  let xmin = isNum(options.xmin) ? options.xmin : Infinity, xmax = isNum(options.xmax) ? options.xmax : -Infinity;
  let ymin = Infinity, ymax = -Infinity;
  for (const s of series) {
    for (const x of finite(s.xs)) { xmin = Math.min(xmin, x); xmax = Math.max(xmax, x); }
    for (const y of finite(s.ys)) { ymin = Math.min(ymin, y); ymax = Math.max(ymax, y); }
  }
  if (!(xmax > xmin)) { xmin = isNum(xmin) ? xmin - 0.5 : 0; xmax = xmin + 1; }
  if (!(ymax > ymin)) { const c = isNum(ymin) ? ymin : 0; ymin = c - 1; ymax = c + 1; }
  const pad = 0.05 * (ymax - ymin);
  ymin -= pad; ymax += pad;
  const sx = (x) => L + (W - L - R) * (x - xmin) / (xmax - xmin);
  const sy = (y) => T + (H - T - B) * (1 - (y - ymin) / (ymax - ymin));
  const root = svg('svg', { viewBox: `0 0 ${W} ${H}`, class: 'plot', role: 'img' });
  root.append(svg('rect', { x: L, y: T, width: W - L - R, height: H - T - B, class: 'frame' }));
  const label = (x, y, text, anchor) => {
    const t = svg('text', { x, y, 'text-anchor': anchor || 'middle' });
    t.textContent = visible(text);
    return t;
  };
  for (let i = 0; i <= 4; ++i) {
    const y = ymin + (ymax - ymin) * i / 4, x = xmin + (xmax - xmin) * i / 4;
    root.append(svg('line', { x1: L, x2: W - R, y1: sy(y), y2: sy(y), class: 'grid' }));
    root.append(label(L - 4, sy(y) + 4, short(y), 'end'));
    root.append(label(sx(x), H - B + 16, short(x)));
  }
  root.append(label((L + W - R) / 2, H - 4, options.xlabel || ''));
  root.append(label(L, T - 8, options.ylabel || '', 'start'));
  series.forEach((s, k) => {
    // One polyline per unbroken run of finite points.
    let run = [];
    const lines = [];
    for (let i = 0; i < s.xs.length; ++i) {
      if (isNum(s.xs[i]) && isNum(s.ys[i])) run.push(`${sx(s.xs[i]).toFixed(1)},${sy(s.ys[i]).toFixed(1)}`);
      else if (run.length) { lines.push(run); run = []; }
    }
    if (run.length) lines.push(run);
    for (const r of lines) {
      const line = svg('polyline', { points: r.join(' '), fill: 'none', stroke: COLORS[k % COLORS.length], class: 'series', 'data-series': String(k) });
      root.append(line);
    }
  });
  return root;
}

function legend(series) {
  const ul = el('ul', { class: 'legend' });
  series.forEach((s, k) => {
    const swatch = el('span', { class: 'swatch' });
    swatch.style.background = COLORS[k % COLORS.length];
    ul.append(el('li', {}, swatch, s.name));
  });
  return ul;
}

// ---- one item -----------------------------------------------------------------------------------

// Chosen in the list (or after a submission): the address says which, so back and forward go between them.
function choose(kind, id) {
  const hash = `#/${KINDS[kind].route}/${encodeURIComponent(id)}`;
  if (location.hash !== hash) location.hash = hash;  // route() follows
  else select(kind, id);
}

function route() {
  const m = /^#\/(jobs|studies|campaigns)\/([^/]+)$/.exec(location.hash);
  if (!m) {
    selected = null;
    for (const [, entry] of rows) entry.tr.classList.remove('selected');
    $('job-section').hidden = true;
    return;
  }
  let id;
  try { id = decodeURIComponent(m[2]); } catch (e) { id = m[2]; }
  select(ROUTE_KIND[m[1]], id);
}

async function select(kind, id) {
  selected = { kind, id };
  const entry = rows.get(id);
  if (entry) maybeFollow(entry);
  for (const [rid, e] of rows) e.tr.classList.toggle('selected', rid === id);
  try {
    const item = Object.assign({ kind }, await api('GET', itemUrl(kind, id)));
    if (!selected || selected.id !== id) return;  // another was chosen meanwhile
    showItem(kind, item);
  } catch (e) {
    if (!selected || selected.id !== id) return;
    if (e instanceof ApiError && e.status === 404) showNotFound(kind, id);
    else showError('list-error', e);
  }
}

function showNotFound(kind, id) {
  shownKey = '';
  $('job-section').hidden = false;
  $('job-section').dataset.kind = kind;
  setText($('job-title'), KINDS[kind].name[0].toUpperCase() + KINDS[kind].name.slice(1));
  setText($('job-id'), id);
  $('job-notfound').hidden = false;
  setText($('job-notfound'), `Not found: this server has no ${KINDS[kind].name} ${id} (it may have been deleted, or the address is mistyped).`);
  $('job-details').hidden = true;
}

// What the detail area shows of an item besides its progress: when it is unchanged (the answer read
// again as a stream ends), the area is not drawn again, so figures shown stay as they are.
let shownKey = '';

// The detail area of an item: one function per kind, each filling the same boxes.
function showItem(kind, item) {
  const key = JSON.stringify([kind, item.id, item.state, item.reason || '', item.links || {}, item.queue_position || 0]);
  if (key === shownKey && !$('job-section').hidden && $('job-notfound').hidden) {
    showProgress(item);
    return;
  }
  shownKey = key;
  $('job-section').hidden = false;
  $('job-section').dataset.kind = kind;
  $('job-notfound').hidden = true;
  $('job-details').hidden = false;
  setText($('job-title'), KINDS[kind].name[0].toUpperCase() + KINDS[kind].name.slice(1));
  setText($('job-id'), item.id);
  showActions(kind, item);
  const running = !FINAL.has(item.state);
  $('live-section').hidden = !(kind === 'run' && running);
  $('guarantees-section').hidden = kind !== 'run';
  $('job-table').replaceChildren();
  $('job-plain').replaceChildren();
  $('job-tools').replaceChildren();
  if (kind !== 'run' && window.MoreauRobot3D) window.MoreauRobot3D.close();  // a study or a campaign has no robot to show
  if (kind === 'run') showJob(item);
  else if (kind === 'study') showStudy(item);
  else showCampaign(item);
  showFigures(kind, item);
  showDownloads(kind, item);
}

function facts(list) {
  const dl = el('dl');
  for (const [k, ...v] of list) dl.append(el('dt', {}, k), el('dd', {}, ...v.map((x) => (typeof x === 'number' ? num(x) : x))));
  return dl;
}

// The state and progress lines, kept up to date by the event stream without redrawing the rest.
function showProgress(item) {
  const box = $('job-progress');
  if (!box) return;
  setText(box, FINAL.has(item.state) ? '' : `${stateText(item)}: ${progressText(item)}`);
}

function showJob(job) {
  const r = job.report;
  const list = [['scene', job.scene], ['state', stateText(job)]];
  if (r) {
    list.push(['status', String(r.status)]);
    list.push(['steps', num(r.steps), ' to t = ', num(r.t_final),
               r.scheme ? ` (${r.scheme}, h = ` : '', r.scheme ? num(r.h) : '', r.scheme ? `, step rule ${r.step_rule})` : '']);
    if (r.convergence) {
      const c = r.convergence;
      list.push(['convergence', String(c.finding), ...(isNum(c.rest_time) ? ['; at rest from t = ', num(c.rest_time), ` (step ${c.rest_step})`] : [])]);
    }
    if (r.energy) list.push(['energy', 'from ', num(r.energy.initial), ' to ', num(r.energy.final), r.energy_nonincreasing === false ? ' (not monotone)' : '']);
    if (r.final && r.final.q) list.push(['final state', 'q = [', ...numList(r.final.q), '], v = [', ...numList(r.final.v || []), ']']);
  } else {
    list.push(['report', FINAL.has(job.state) ? 'none' : 'when the job is final']);
  }
  $('job-summary').replaceChildren(facts(list), el('p', { id: 'job-progress' }));
  showProgress(job);
  // One sentence for a student, written by the server; nothing when the report has none.
  if (r && typeof r.summary === 'string' && r.summary) $('job-plain').append(el('p', { class: 'plain' }, r.summary));
  // A URDF robot's job: its 3D view (robot3d.js), drawn from the server's link poses.
  if (window.MoreauRobot3D && window.MoreauRobot3D.jobId() !== job.id) window.MoreauRobot3D.close();
  if (job.links && job.links.kinematics && window.MoreauRobot3D) {
    const b = el('button', { type: 'button', id: 'robot3d-button' }, '3D view');
    b.addEventListener('click', () => window.MoreauRobot3D.open($('job-robot3d'), job.id, (path) => request('GET', path)));
    $('job-tools').append(b);
  }

  const ul = $('job-guarantees');
  ul.replaceChildren();
  for (const g of (r && Array.isArray(r.guarantees) && r.guarantees) || []) {
    const hyps = el('ul');
    for (const h of g.hypotheses || []) {
      hyps.append(el('li', {}, el('span', { class: 'verdict-' + String(h.verdict).replace(/ /g, '-') }, String(h.verdict)), ': ', String(h.hypothesis),
                     h.detail ? el('div', { class: 'detail' }, String(h.detail)) : null));
    }
    ul.append(el('li', {}, el('strong', {}, String(g.result)), ' ', el('span', { class: 'verdict-' + String(g.verdict).replace(/ /g, '-') }, String(g.verdict)),
                  g.relied_on ? ' (relied on)' : '', el('div', {}, String(g.claim)), hyps));
  }
  if (!ul.children.length) ul.append(el('li', {}, r ? 'none listed' : 'when the job is final'));
  setText($('job-report'), r ? JSON.stringify(r, null, 2) : '');
  if (!FINAL.has(job.state)) drawLive();
  for (const tool of jobTools) tool(job, $('job-tools'));
}

function showStudy(study) {
  const res = study.result;
  const p = study.progress || {};
  const list = [['scene', study.scene], ['state', stateText(study)], ['rows', num(p.rows), ' of ', num(p.rows_total)]];
  $('job-summary').replaceChildren(facts(list), el('p', { id: 'job-progress' }));
  showProgress(study);
  if (res && Array.isArray(res.rows)) {
    $('job-table').append(el('h3', {}, 'Errors and run times'),
                          table(res.rows, ['scheme', 'h', 'status', 'steps', 'wall_seconds', 'q_max_error', 'q_l2_error', 'final_error']));
  }
  if (res && Array.isArray(res.orders)) $('job-table').append(el('h3', {}, 'Fitted orders'), table(res.orders, ['scheme', 'q_max', 'v_max', 'theory', 'theory_note']));
  setText($('job-report'), res ? JSON.stringify(res, null, 2) : '');
}

// A table of rows (objects): the preferred columns first when present, then the other scalar ones.
function table(records, preferred) {
  const cols = [];
  for (const c of preferred) if (records.some((r) => r && typeof r === 'object' && c in r)) cols.push(c);
  for (const r of records) {
    if (!r || typeof r !== 'object') continue;
    for (const [k, v] of Object.entries(r)) if (!cols.includes(k) && (v === null || typeof v !== 'object') && cols.length < 14) cols.push(k);
  }
  const t = el('table', { class: 'results' });
  t.append(el('thead', {}, el('tr', {}, ...cols.map((c) => el('th', {}, c)))));
  const body = el('tbody');
  for (const r of records.slice(0, 500)) {
    if (!r || typeof r !== 'object') continue;
    body.append(el('tr', {}, ...cols.map((c) => {
      const v = r[c];
      return el('td', {}, typeof v === 'number' ? num(v) : v === null || v === undefined ? '' : typeof v === 'object' ? JSON.stringify(v) : String(v));
    })));
  }
  t.append(body);
  return t;
}

function showCampaign(campaign) {
  const s = campaign.summary;
  const p = campaign.progress || {};
  const list = [['scene', campaign.scene], ['state', stateText(campaign)], ['samples', num(p.samples), ' of ', num(p.samples_total)]];
  $('job-summary').replaceChildren(facts(list), el('p', { id: 'job-progress' }), el('pre', { id: 'campaign-text' }));
  showProgress(campaign);
  setText($('job-report'), s ? JSON.stringify(s, null, 2) : '');
  if (campaign.links && campaign.links.summary_text) {
    request('GET', `${itemUrl('campaign', campaign.id)}/summary?format=text`)
      .then((r) => boundedText(r, 1 << 20))
      .then((text) => { const pre = $('campaign-text'); if (pre) setText(pre, text.slice(0, 100000)); })
      .catch((e) => showError('list-error', e));
  }
}

// Cancel an item that is not final; delete (purge) one that is, with its results.
function showActions(kind, item) {
  const box = $('job-actions');
  box.replaceChildren();
  const final = FINAL.has(item.state);
  const button = el('button', { type: 'button', id: final ? 'delete-button' : 'cancel-button' },
                    final ? `Delete ${KINDS[kind].name} and results` : 'Cancel');
  button.addEventListener('click', async () => {
    try {
      if (final) {
        await api('DELETE', itemUrl(kind, item.id) + '?purge=true');
        deleted.add(item.id);
        compared.delete(item.id);
        const entry = rows.get(item.id);
        if (entry) entry.tr.remove();
        rows.delete(item.id);
        selected = null;
        $('job-section').hidden = true;
        history.replaceState(null, '', location.pathname + location.search);
      } else {
        renderRow(Object.assign({ kind }, await api('DELETE', itemUrl(kind, item.id))));
        follow(kind, item.id);
      }
    } catch (e) {
      showError('list-error', e);
    }
  });
  if (item.state !== 'cancelling') box.append(button);
}

// ---- figures ------------------------------------------------------------------------------------

function figureUrl(kind, id, figure, format) {
  return `${itemUrl(kind, id)}/figure?kind=${encodeURIComponent(figure)}` + (format ? `&format=${format}` : '');
}

function showFigures(kind, item) {
  for (const u of figureUrls) URL.revokeObjectURL(u);
  figureUrls = [];
  const box = $('job-figures');
  box.replaceChildren();
  const links = item.links || {};
  const ready = kind === 'run' ? links.figure : kind === 'study' ? links.table : links.summary;
  if (!ready) {
    box.append(FINAL.has(item.state) ? 'no results, so no figures'
               : kind === 'run' ? 'the figures replace the live plot when the job is final' : `figures appear when the ${KINDS[kind].name} is final`);
    return;
  }
  for (const figure of KINDS[kind].figures) {
    const img = el('img', { alt: figure + ' figure', 'data-kind': figure, title: 'click to enlarge' });
    const caption = el('figcaption', {}, figure + ' ');
    const png = el('a', { href: '#', class: 'figure-download', 'data-format': 'png' }, 'PNG');
    const svgLink = el('a', { href: '#', class: 'figure-download', 'data-format': 'svg' }, 'SVG');
    png.addEventListener('click', (ev) => { ev.preventDefault(); download(figureUrl(kind, item.id, figure), `${item.id}-${figure}.png`); });
    svgLink.addEventListener('click', (ev) => { ev.preventDefault(); download(figureUrl(kind, item.id, figure, 'svg'), `${item.id}-${figure}.svg`); });
    caption.append(png, ' ', svgLink);
    img.addEventListener('click', () => enlarge(img, figure));
    box.append(el('figure', {}, img, caption));
    request('GET', figureUrl(kind, item.id, figure))
      .then((r) => r.blob())
      .then((blob) => { const u = URL.createObjectURL(blob); figureUrls.push(u); img.src = u; })
      .catch((e) => { setText(caption, `${figure}: ${e.message}`); caption.className = 'error'; img.remove(); });
  }
}

function enlarge(img, name) {
  if (!img.src) return;
  const dialog = $('figure-dialog');
  $('figure-large').src = img.src;
  $('figure-large').alt = img.alt;
  setText($('figure-dialog-caption'), name + ' (Escape or click to close)');
  if (!dialog.open) dialog.showModal();
}

async function download(path, filename) {
  try {
    const blob = await (await request('GET', path)).blob();
    const u = URL.createObjectURL(blob);
    const tmp = el('a', { href: u, download: filename });
    document.body.append(tmp);
    tmp.click();
    tmp.remove();
    setTimeout(() => URL.revokeObjectURL(u), 10000);
  } catch (e) {
    showError('list-error', e);
  }
}

function showDownloads(kind, item) {
  const box = $('job-downloads');
  box.replaceChildren();
  const links = item.links || {};
  const url = itemUrl(kind, item.id);
  const items = [];
  if (kind === 'run') {
    if (links.report) items.push(['report.json', `${url}/report`]);
    if (links.trajectory) {
      items.push(['trajectory.csv', `${url}/trajectory?format=csv`]);
      items.push(['trajectory.json', `${url}/trajectory`]);
    }
  } else if (kind === 'study') {
    if (links.table) items.push(['table.csv', `${url}/table?format=csv`], ['table.json', `${url}/table`]);
  } else {
    if (links.summary) items.push(['summary.json', `${url}/summary`], ['summary.txt', `${url}/summary?format=text`]);
    if (links.samples) items.push(['samples.csv', `${url}/samples?format=csv`], ['samples.jsonl', `${url}/samples?format=jsonl`]);
  }
  for (const [name, path] of items) {
    const a = el('a', { href: '#', 'data-path': path }, name);
    a.addEventListener('click', (ev) => { ev.preventDefault(); download(path, `${item.id}-${name}`); });
    box.append(a);
  }
  if (!items.length) box.append(`when the ${KINDS[kind].name} is final`);
}

// A response's text, at most maxBytes of it (the rest is not read).
async function boundedText(response, maxBytes) {
  const reader = response.body.getReader();
  const decoder = new TextDecoder();
  let text = '', bytes = 0;
  for (;;) {
    const { value, done } = await reader.read();
    if (done) break;
    bytes += value.length;
    text += decoder.decode(value, { stream: true });
    if (bytes >= maxBytes) {
      reader.cancel();
      text = text.slice(0, text.lastIndexOf('\n') + 1);  // whole lines only
      break;
    }
  }
  return text;
}

// ---- comparing jobs -----------------------------------------------------------------------------

const MAX_COMPARE_ROWS = 2000;

function showCompareChoice() {
  const n = compared.size;
  $('compare-button').disabled = n < 2;
  setText($('compare-count'), n ? `${n} job${n > 1 ? 's' : ''} ticked` : 'tick two or more finished jobs in the list');
}

function parseCsv(text) {
  const lines = text.split('\n').filter((l) => l.length);
  const columns = (lines.shift() || '').split(',');
  const data = columns.map(() => []);
  for (const line of lines.slice(0, MAX_COMPARE_ROWS + 1)) {
    const cells = line.split(',');
    columns.forEach((_, i) => { const x = Number(cells[i]); data[i].push(cells[i] === undefined || cells[i] === '' ? null : x); });
  }
  return { columns, data };
}

// Each ticked job's trajectory (at most about MAX_COMPARE_ROWS rows: every K-th), in one plot of the
// chosen column, with a legend naming the job by its scene, scheme and step size.
async function compare() {
  showError('compare-error', null);
  const ids = [...compared];
  try {
    const runs = await Promise.all(ids.map(async (id) => {
      const job = await api('GET', jobUrl(id));
      const r = job.report || {};
      const p = job.progress || {};
      const steps = isNum(r.steps) ? r.steps : isNum(p.step) && p.step > 0 ? p.step : isNum(p.planned_steps) ? p.planned_steps : 0;
      const every = Math.max(1, Math.ceil((steps + 1) / MAX_COMPARE_ROWS));
      const text = await boundedText(await request('GET', `${jobUrl(id)}/trajectory?format=csv&every=${every}`), 16 << 20);
      const name = `${job.scene}` + (r.scheme ? `, ${r.scheme}, h = ${short(r.h)}` : '') + ` (${id.slice(0, 8)})`;
      return { id, name, csv: parseCsv(text) };
    }));
    // The columns the trajectories share (t and h aside).
    const common = runs[0].csv.columns.filter((c) => c !== 't' && c !== 'h' && runs.every((r) => r.csv.columns.includes(c)));
    const choice = $('compare-quantity');
    const previous = choice.value;
    choice.replaceChildren(...common.map((c) => el('option', { value: c }, c)));
    if (common.includes(previous)) choice.value = previous;
    else if (common.includes('energy')) choice.value = 'energy';
    if (!common.length) throw new Error('the ticked jobs share no column to compare');
    lastCompare = runs;
    drawCompare();
  } catch (e) {
    showError('compare-error', e);
  }
}

let lastCompare = null;

function drawCompare() {
  if (!lastCompare) return;
  const column = $('compare-quantity').value;
  const series = lastCompare.map((r) => {
    const t = r.csv.data[r.csv.columns.indexOf('t')] || [];
    const y = r.csv.data[r.csv.columns.indexOf(column)] || [];
    return { name: r.name, xs: t, ys: y };
  });
  const plot = drawPlot(series, { xlabel: 't', ylabel: column });
  plot.id = 'compare-svg';
  $('compare-plot').replaceChildren(plot, legend(series));
}

// ---- submitting ---------------------------------------------------------------------------------

async function loadScenes() {
  try {
    const list = await api('GET', '/v1/scenes');
    const select = $('scene-select');
    select.replaceChildren();
    for (const s of list.scenes) {
      const option = el('option', { value: s.name }, s.title ? `${s.name}: ${s.title}` : s.name);
      if (s.description) option.title = visible(s.description);
      select.append(option);
    }
    if (list.scenes.some((s) => s.name === 'manipulator')) select.value = 'manipulator';
    showError('submit-error', null);
  } catch (e) {
    showError('submit-error', e);
  }
}

function showMode() {
  const mode = document.querySelector('input[name=mode]:checked').value;
  $('study-fields').hidden = mode !== 'study';
  $('campaign-fields').hidden = mode !== 'campaign';
}

function addInputRow(path, low, high) {
  const row = el('div', { class: 'input-row' },
                 el('input', { class: 'input-path', placeholder: '/parameters/m1', value: path || '' }),
                 el('label', {}, 'from ', el('input', { class: 'input-low', type: 'number', step: 'any', value: low === undefined ? '' : String(low) })),
                 el('label', {}, 'to ', el('input', { class: 'input-high', type: 'number', step: 'any', value: high === undefined ? '' : String(high) })));
  const remove = el('button', { type: 'button', title: 'remove this input' }, 'remove');
  remove.addEventListener('click', () => row.remove());
  row.append(remove);
  $('campaign-inputs').append(row);
}

function studyOptions() {
  const study = {};
  const h = $('study-h').value.trim();
  if (h) study.h = h;
  const schemes = [...document.querySelectorAll('#study-schemes input:checked')].map((i) => i.value);
  if (!schemes.length) throw new Error('choose at least one scheme');
  study.schemes = schemes;
  const repeats = Number($('study-repeats').value);
  if (Number.isInteger(repeats) && repeats > 0) study.repeats = repeats;
  return study;
}

function campaignSpec() {
  const inputs = [];
  for (const row of document.querySelectorAll('#campaign-inputs .input-row')) {
    const path = row.querySelector('.input-path').value.trim();
    if (!path) continue;
    const low = Number(row.querySelector('.input-low').value), high = Number(row.querySelector('.input-high').value);
    if (!Number.isFinite(low) || !Number.isFinite(high) || !(low < high)) throw new Error(`the range of ${path} must be two numbers, the first below the second`);
    inputs.push({ path, distribution: { type: 'uniform', low, high } });
  }
  if (!inputs.length) throw new Error('name at least one input to vary (a path in the scene and its range)');
  const samples = Number($('campaign-samples').value);
  if (!Number.isInteger(samples) || samples < 1) throw new Error('the number of samples must be a whole number, at least 1');
  const spec = { inputs, samples, sampler: $('campaign-sampler').value };
  const seed = Number($('campaign-seed').value);
  if (Number.isInteger(seed) && seed >= 0) spec.seed = seed;
  return spec;
}

async function submit(ev) {
  ev.preventDefault();
  showError('submit-error', null);
  const mode = document.querySelector('input[name=mode]:checked').value;
  const body = {};
  try {
    if (document.querySelector('input[name=source]:checked').value === 'pasted') {
      try {
        body.scene = JSON.parse($('scene-text').value);
      } catch (e) {
        throw new Error('the scene is not valid JSON: ' + e.message);
      }
    } else {
      body.scene = $('scene-select').value;
    }
    const overrides = $('overrides').value.split('\n').map((s) => s.trim()).filter((s) => s.length > 0);
    if (overrides.length) body.overrides = overrides;
    if (mode === 'study') body.study = studyOptions();
    if (mode === 'campaign') body.campaign = campaignSpec();
  } catch (e) {
    showError('submit-error', e);
    return;
  }
  const kind = mode === 'study' ? 'study' : mode === 'campaign' ? 'campaign' : 'run';
  try {
    const item = Object.assign({ kind }, await api('POST', KINDS[kind].api.slice(0, -1), body));
    renderRow(item);
    choose(kind, item.id);
  } catch (e) {
    showError('submit-error', e);
  }
}

// ---- start --------------------------------------------------------------------------------------

function showTokenState() {
  setText($('token-state'), token ? 'token set for this tab' : 'no token');
}

document.addEventListener('DOMContentLoaded', () => {
  $('token').value = token;
  showTokenState();
  $('token-form').addEventListener('submit', (ev) => {
    ev.preventDefault();
    token = $('token').value.trim();
    if (token) sessionStorage.setItem('moreau-token', token);
    else sessionStorage.removeItem('moreau-token');
    showTokenState();
    loadScenes();
    refreshList();
    route();
  });
  $('scene-text').addEventListener('input', () => { document.querySelector('input[value=pasted]').checked = true; });
  $('scene-select').addEventListener('change', () => { document.querySelector('input[value=shipped]').checked = true; });
  for (const r of document.querySelectorAll('input[name=mode]')) r.addEventListener('change', showMode);
  $('add-input').addEventListener('click', () => addInputRow());
  addInputRow('/parameters/m1', 0.8, 1.2);
  showMode();
  $('submit-form').addEventListener('submit', submit);
  $('live-quantity').addEventListener('change', drawLive);
  $('compare-button').addEventListener('click', compare);
  $('compare-quantity').addEventListener('change', drawCompare);
  const dialog = $('figure-dialog');
  dialog.addEventListener('click', () => dialog.close());  // Escape closes it too (a modal dialog)
  window.addEventListener('hashchange', route);
  showCompareChoice();
  loadScenes();
  refreshList();
  route();
  setInterval(refreshList, 2000);  // items submitted elsewhere, queue positions, and items without a stream
  setInterval(() => { if (selected) for (const [id, e] of rows) if (id === selected.id) showProgress(e.item); }, 1000);
});
