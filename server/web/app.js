// Moreau's web page: the job list with live state (server-sent events), a form to submit a scene, and
// each job's report in plain words, its figures and downloads. Plain JavaScript, no build step: served by
// moreau-server from files compiled into it (server/web/).
//
// Everything shown comes from the server or the user and is put in the page as text (textContent,
// element.append(string)), never as HTML: a scene named "<script>..." shows those characters. And as
// visible text (visible()): a bidirectional override reorders what follows it (a name shown as
// "ctl...live" was "ctl", U+202E, "...evil"), so the overrides and the control characters are shown as
// escapes: "ctl\u{202e}...evil".
// The token, when the server has one, is kept in this tab's sessionStorage and sent as a bearer header;
// that is why figures, downloads and event streams are fetched (an <img src> or EventSource cannot send
// a header) and shown from blob: URLs.
'use strict';

const FINAL = new Set(['done', 'failed', 'cancelled']);
const JOB_FIGURES = ['state', 'energy', 'step', 'phase'];
const $ = (id) => document.getElementById(id);

let token = sessionStorage.getItem('moreau-token') || '';
const rows = new Map();       // job id -> {tr, job}
const following = new Set();  // job ids whose event stream is open
// Browsers open at most 6 connections to a server: streams are kept for the chosen job and a few others;
// the rest are updated by the list's refresh. A stream that ended early is not reopened for a while.
const MAX_STREAMS = 3;
const STREAM_RETRY_MS = 2000;
const streamRetryAt = new Map();  // job id -> time before which its stream is not reopened
const deleted = new Set();        // jobs deleted from this page: an answer still in flight must not bring them back
let selected = null;
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

const jobUrl = (id) => '/v1/jobs/' + encodeURIComponent(id);

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

function showError(id, err) {
  setText($(id), err ? (err.message || String(err)) : '');
}

function fraction(job) {
  const p = job.progress || {};
  if (typeof p.fraction === 'number') return p.fraction;
  return 0;
}

function when(unixSeconds) {
  return typeof unixSeconds === 'number' ? new Date(unixSeconds * 1000).toLocaleTimeString() : '';
}

// ---- the job list -------------------------------------------------------------------------------

function renderRow(job) {
  if (deleted.has(job.id)) return;
  let entry = rows.get(job.id);
  if (!entry) {
    const tr = el('tr', { 'data-id': job.id });
    tr.addEventListener('click', () => select(job.id));
    entry = { tr, job };
    rows.set(job.id, entry);
    $('jobs').tBodies[0].prepend(tr);  // newest first
  }
  entry.job = job;
  const bar = el('progress', { max: '1', value: String(fraction(job)) });
  entry.tr.replaceChildren(
    el('td', { class: 'scene' }, job.scene || ''),
    el('td', { class: 'state state-' + job.state }, job.state + (job.queue_position ? ` (#${job.queue_position} in the queue)` : '') +
       (job.reason ? ` (${job.reason})` : '')),
    el('td', {}, bar, ` ${Math.round(100 * fraction(job))}%`),
    el('td', {}, when(job.created)),
    el('td', { class: 'id' }, job.id));
  entry.tr.classList.toggle('selected', job.id === selected);
  maybeFollow(job);
}

function maybeFollow(job) {
  if (FINAL.has(job.state) || following.has(job.id)) return;
  if (Date.now() < (streamRetryAt.get(job.id) || 0)) return;
  if (job.id !== selected && following.size >= MAX_STREAMS) return;
  follow(job.id);
}

async function refreshList() {
  try {
    const list = await api('GET', '/v1/jobs?limit=50');
    showError('list-error', null);
    for (const job of list.jobs) renderRow(job);
    // Jobs no longer listed (deleted here or elsewhere, or older than the 50 shown) leave the table.
    const listed = new Set(list.jobs.map((j) => j.id));
    for (const [id, entry] of rows) {
      if (listed.has(id)) continue;
      entry.tr.remove();
      rows.delete(id);
    }
  } catch (e) {
    showError('list-error', e);
  }
}

// The job's event stream, read with fetch so that it carries the token: each `state` and `progress`
// event updates its row; when the stream ends (after the final state) the row and, if shown, the job are
// read again.
async function follow(id) {
  if (following.has(id)) return;
  following.add(id);
  try {
    const r = await request('GET', jobUrl(id) + '/events', undefined, { Accept: 'text/event-stream' });
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
    }
  } catch (e) {
    showError('list-error', e);
  } finally {
    following.delete(id);
    streamRetryAt.set(id, Date.now() + STREAM_RETRY_MS);
  }
  try {
    const job = await api('GET', jobUrl(id));
    renderRow(job);
    if (id === selected) showJob(job);
  } catch (e) {
    showError('list-error', e);
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

function onEvent(id, event) {
  const entry = rows.get(id);
  if (!entry || !event.data) return;
  let data;
  try { data = JSON.parse(event.data); } catch (e) { return; }
  const job = Object.assign({}, entry.job);
  if (event.name === 'state') {
    job.state = data.state;
    if (data.reason) job.reason = data.reason;
    if (job.state !== 'queued') delete job.queue_position;
  } else if (event.name === 'progress') {
    const span = data.t_end - data.t0;
    job.progress = Object.assign({}, job.progress, { fraction: span > 0 ? Math.min(1, Math.max(0, (data.t - data.t0) / span)) : 0 });
  } else {
    return;
  }
  renderRow(job);
}

// ---- one job ------------------------------------------------------------------------------------

async function select(id) {
  selected = id;
  const entry = rows.get(id);
  if (entry) maybeFollow(entry.job);
  for (const [rid, entry] of rows) entry.tr.classList.toggle('selected', rid === id);
  try {
    showJob(await api('GET', jobUrl(id)));
  } catch (e) {
    showError('list-error', e);
  }
}

function showJob(job) {
  $('job-section').hidden = false;
  setText($('job-id'), job.id);
  const r = job.report;
  const facts = [['scene', job.scene], ['state', job.state + (job.reason ? ` (${job.reason})` : '')]];
  if (r) {
    facts.push(['status', r.status]);
    facts.push(['steps', `${r.steps} to t = ${r.t_final}` + (r.scheme ? ` (${r.scheme}, step rule ${r.step_rule})` : '')]);
    if (r.convergence) {
      const c = r.convergence;
      facts.push(['convergence', c.finding + (typeof c.rest_time === 'number' ? `; at rest from t = ${c.rest_time} (step ${c.rest_step})` : '')]);
    }
    if (r.energy) facts.push(['energy', `from ${r.energy.initial} to ${r.energy.final}` + (r.energy_nonincreasing === false ? ' (not monotone)' : '')]);
    if (r.final && r.final.q) facts.push(['final state', `q = [${r.final.q.join(', ')}], v = [${(r.final.v || []).join(', ')}]`]);
  } else {
    facts.push(['report', FINAL.has(job.state) ? 'none' : 'when the job is final']);
  }
  const dl = el('dl');
  for (const [k, v] of facts) dl.append(el('dt', {}, k), el('dd', {}, String(v)));
  $('job-summary').replaceChildren(dl);
  showActions(job);
  // A URDF robot's job: its 3D view (robot3d.js), drawn from the server's link poses.
  if (window.MoreauRobot3D && window.MoreauRobot3D.jobId() !== job.id) window.MoreauRobot3D.close();
  if (job.links && job.links.kinematics && window.MoreauRobot3D) {
    const b = el('button', { type: 'button', id: 'robot3d-button' }, '3D view');
    b.addEventListener('click', () => window.MoreauRobot3D.open($('job-robot3d'), job.id, (path) => request('GET', path)));
    $('job-actions').append(b);
  }

  const ul = $('job-guarantees');
  ul.replaceChildren();
  for (const g of (r && r.guarantees) || []) {
    const hyps = el('ul');
    for (const h of g.hypotheses || []) {
      hyps.append(el('li', {}, el('span', { class: 'verdict-' + String(h.verdict).replace(/ /g, '-') }, h.verdict), ': ', h.hypothesis,
                     h.detail ? el('div', { class: 'detail' }, h.detail) : null));
    }
    ul.append(el('li', {}, el('strong', {}, g.result), ' ', el('span', { class: 'verdict-' + String(g.verdict).replace(/ /g, '-') }, g.verdict),
                  g.relied_on ? ' (relied on)' : '', el('div', {}, g.claim), hyps));
  }
  if (!ul.children.length) ul.append(el('li', {}, r ? 'none listed' : 'when the job is final'));

  setText($('job-report'), r ? JSON.stringify(r, null, 2) : '');
  showFigures(job);
  showDownloads(job);
}

// Cancel a job that is not final; delete (purge) one that is, with its results.
function showActions(job) {
  const box = $('job-actions');
  box.replaceChildren();
  const final = FINAL.has(job.state);
  const button = el('button', { type: 'button', id: final ? 'delete-button' : 'cancel-button' }, final ? 'Delete job and results' : 'Cancel');
  button.addEventListener('click', async () => {
    try {
      if (final) {
        await api('DELETE', jobUrl(job.id) + '?purge=true');
        deleted.add(job.id);
        const entry = rows.get(job.id);
        if (entry) entry.tr.remove();
        rows.delete(job.id);
        selected = null;
        $('job-section').hidden = true;
      } else {
        renderRow(await api('DELETE', jobUrl(job.id)));
        follow(job.id);
      }
    } catch (e) {
      showError('list-error', e);
    }
  });
  if (job.state !== 'cancelling') box.append(button);
}

function showFigures(job) {
  for (const u of figureUrls) URL.revokeObjectURL(u);
  figureUrls = [];
  const box = $('job-figures');
  box.replaceChildren();
  if (!job.links || !job.links.figure) {
    box.append(FINAL.has(job.state) ? 'no trajectory, so no figures' : 'figures appear when the job is final');
    return;
  }
  for (const kind of JOB_FIGURES) {
    const img = el('img', { alt: kind + ' figure', 'data-kind': kind });
    const caption = el('figcaption', {}, kind);
    box.append(el('figure', {}, img, caption));
    request('GET', `${jobUrl(job.id)}/figure?kind=${kind}`)
      .then((r) => r.blob())
      .then((blob) => { const u = URL.createObjectURL(blob); figureUrls.push(u); img.src = u; })
      .catch((e) => { setText(caption, `${kind}: ${e.message}`); caption.className = 'error'; });
  }
}

function showDownloads(job) {
  const box = $('job-downloads');
  box.replaceChildren();
  const items = [];
  if (job.links && job.links.report) items.push(['report.json', `${jobUrl(job.id)}/report`]);
  if (job.links && job.links.trajectory) {
    items.push(['trajectory.csv', `${jobUrl(job.id)}/trajectory?format=csv`]);
    items.push(['trajectory.json', `${jobUrl(job.id)}/trajectory`]);
  }
  for (const [name, path] of items) {
    const a = el('a', { href: '#', 'data-path': path }, name);
    a.addEventListener('click', async (ev) => {
      ev.preventDefault();
      try {
        const blob = await (await request('GET', path)).blob();
        const u = URL.createObjectURL(blob);
        const tmp = el('a', { href: u, download: `${job.id}-${name}` });
        document.body.append(tmp);
        tmp.click();
        tmp.remove();
        setTimeout(() => URL.revokeObjectURL(u), 10000);
      } catch (e) {
        showError('list-error', e);
      }
    });
    box.append(a);
  }
  if (!items.length) box.append('when the job is final');
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
  } catch (e) {
    showError('submit-error', e);
  }
}

async function submit(ev) {
  ev.preventDefault();
  showError('submit-error', null);
  const body = {};
  if (document.querySelector('input[name=source]:checked').value === 'pasted') {
    try {
      body.scene = JSON.parse($('scene-text').value);
    } catch (e) {
      showError('submit-error', new Error('the scene is not valid JSON: ' + e.message));
      return;
    }
  } else {
    body.scene = $('scene-select').value;
  }
  const overrides = $('overrides').value.split('\n').map((s) => s.trim()).filter((s) => s.length > 0);
  if (overrides.length) body.overrides = overrides;
  try {
    const job = await api('POST', '/v1/jobs', body);
    renderRow(job);
    select(job.id);
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
  });
  $('scene-text').addEventListener('input', () => { document.querySelector('input[value=pasted]').checked = true; });
  $('scene-select').addEventListener('change', () => { document.querySelector('input[value=shipped]').checked = true; });
  $('submit-form').addEventListener('submit', submit);
  loadScenes();
  refreshList();
  setInterval(refreshList, 2000);  // jobs submitted elsewhere, queue positions, and jobs without a stream
});
