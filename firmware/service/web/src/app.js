// mirrorscand's page: device state, a scan button, the posture to stand in (a drawing in
// index.html), live progress from the event stream, a live camera preview, the scans with
// download and delete, and a processed scan's pose check, previews, measurements and 3D
// mesh. Every call but /status sends the device token in an Authorization header (never in
// a URL); it is kept in this tab's sessionStorage only.
import { showMesh } from './viewer.js';

const API = '/api/v1';
const $ = (id) => document.getElementById(id);
const TOKEN_KEY = 'mirrorscan-token';
let token = sessionStorage.getItem(TOKEN_KEY) || '';
let status = null;
let events = null;        // AbortController of the running event stream
let selected = '';        // the scan shown under "Scan ..."
let lastEndedScan = '';
const blobUrls = [];

function say(text, error = false) {
  $('message').textContent = text;
  $('message').className = error ? 'error' : '';
}

function auth() {
  return token ? { Authorization: `Bearer ${token}` } : {};
}

// fetch with the token; a refusal becomes an Error carrying the device's message.
async function api(path, options = {}) {
  const response = await fetch(API + path, {
    ...options, headers: { ...auth(), ...(options.headers || {}) }, cache: 'no-store',
  });
  if (!response.ok) {
    let message = `HTTP ${response.status}`;
    try { message = (await response.json()).message || message; } catch (e) { /* not JSON */ }
    const error = new Error(message);
    error.status = response.status;
    throw error;
  }
  return response;
}

function megabytes(bytes) { return `${(bytes / 1e6).toFixed(1)} MB`; }

function loggedIn(on) {
  $('login').hidden = on;
  $('session').hidden = !on;
  updateButtons();
}

function updateButtons() {
  const s = status ? status.scan.state : 'idle';
  const running = ['homing', 'arming', 'sweeping', 'finishing'].includes(s);
  $('scan-button').disabled = !token || running || s === 'fault';
  $('abort-button').disabled = !token || !running;
}

function showProgress(scan) {
  const percent = Math.round((scan.progress || 0) * 100);
  $('state').textContent = scan.state;
  $('state').className = `badge ${scan.state}`;
  $('progress-bar').style.width = `${percent}%`;
  $('progress-text').textContent = `${percent} %`;
  $('progress-detail').textContent = scan.scan_id
    ? `scan ${scan.scan_id}: ${scan.frames} frames, ${scan.peaks} peaks, ${scan.position_mm.toFixed(0)} mm` +
      (scan.reason ? ` (${scan.reason})` : '')
    : 'no scan yet';
  if (status) status.scan = scan;
  updateButtons();
  // A scan that just ended appears in the list.
  if (['done', 'fault', 'aborted'].includes(scan.state) && scan.scan_id !== lastEndedScan) {
    lastEndedScan = scan.scan_id;
    if (token) refreshScans();
  }
}

async function refreshStatus() {
  try {
    status = await (await fetch(`${API}/status`, { cache: 'no-store' })).json();
  } catch (e) {
    say('The device does not answer.', true);
    return;
  }
  $('board').textContent = `board ${status.board}`;
  $('firmware').textContent = status.firmware_version;
  $('calibration').textContent = status.calibration_sha256
    ? `stored (${status.calibration_sha256.slice(0, 12)}…)`
    : `none${status.calibration_problem ? ': ' + status.calibration_problem : ''}`;
  $('disk').textContent = `${megabytes(status.disk.free_bytes)} free of ${megabytes(status.disk.total_bytes)}` +
    (status.disk.full ? ` — ${status.disk.problem}` : '');
  if (!events) showProgress(status.scan);
}

// Server-sent events read through fetch (EventSource cannot send the token).
async function followEvents() {
  if (events || !token) return;
  events = new AbortController();
  try {
    const response = await api('/events', { signal: events.signal });
    const reader = response.body.getReader();
    const decoder = new TextDecoder();
    let pending = '';
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      pending += decoder.decode(value, { stream: true });
      let end;
      while ((end = pending.indexOf('\n\n')) >= 0) {
        const block = pending.slice(0, end);
        pending = pending.slice(end + 2);
        const data = block.split('\n').find((line) => line.startsWith('data: '));
        if (data) showProgress(JSON.parse(data.slice(6)).scan);
      }
    }
  } catch (e) {
    if (e.name === 'AbortError') return;
  } finally {
    events = null;
  }
  // Dropped (device restart, all stream slots taken): poll the status and try again.
  setTimeout(followEvents, 2000);
}

function stopEvents() {
  if (events) events.abort();
  events = null;
}

async function login(candidate) {
  token = candidate;
  try {
    await api('/scans');
  } catch (e) {
    token = '';
    sessionStorage.removeItem(TOKEN_KEY);
    loggedIn(false);
    say(e.status === 403 ? 'Wrong token: refused by the device.' : `Log in failed: ${e.message}`, true);
    return false;
  }
  sessionStorage.setItem(TOKEN_KEY, token);
  loggedIn(true);
  say('Logged in.');
  followEvents();
  refreshScans();
  return true;
}

function logout() {
  token = '';
  sessionStorage.removeItem(TOKEN_KEY);
  stopEvents();
  loggedIn(false);
  $('scan-rows').innerHTML = '<tr><td colspan="7" class="muted">Log in to see the scans.</td></tr>';
  $('result').hidden = true;
  setPreview(false);
  say('Logged out.');
}

function cell(row, text) {
  const td = document.createElement('td');
  td.textContent = text;
  row.appendChild(td);
  return td;
}

function button(parent, label, action, name) {
  const b = document.createElement('button');
  b.type = 'button';
  b.textContent = label;
  b.dataset.action = name;
  b.addEventListener('click', action);
  parent.appendChild(b);
  return b;
}

async function refreshScans() {
  if (!token) return;
  let scans;
  try {
    scans = (await (await api('/scans')).json()).scans;
  } catch (e) {
    say(`Scans: ${e.message}`, true);
    return;
  }
  const rows = $('scan-rows');
  rows.innerHTML = '';
  if (scans.length === 0) {
    rows.innerHTML = '<tr><td colspan="7" class="muted">No scans on the device.</td></tr>';
  }
  for (const s of scans) {
    const row = document.createElement('tr');
    row.dataset.id = s.id;
    if (s.id === selected) row.className = 'selected';
    cell(row, s.id);
    cell(row, s.state);
    cell(row, s.created);
    cell(row, String(s.frames));
    cell(row, megabytes(s.bytes));
    cell(row, (s.results || []).includes('summary.json') ? 'processed' : '—');
    const actions = cell(row, '');
    if (s.state !== 'writing') {
      button(actions, 'Download', () => download(s.id), 'download');
      button(actions, 'Delete', () => remove(s.id), 'delete');
    }
    if ((s.results || []).length > 0) button(actions, 'Show', () => showResult(s.id), 'show');
    rows.appendChild(row);
  }
}

async function startScan() {
  try {
    const { id } = await (await api('/scans', { method: 'POST' })).json();
    say(`Scan ${id} started.`);
  } catch (e) {
    say(`Start: ${e.message}`, true);
  }
}

async function abortScan() {
  try {
    await api('/scans/current/abort', {
      method: 'POST', headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify({ reason: 'aborted on the web page' }),
    });
  } catch (e) {
    say(`Abort: ${e.message}`, true);
  }
}

function saveBlob(blob, name) {
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 60000);
}

async function download(id) {
  try {
    say(`Downloading ${id}…`);
    const response = await api(`/scans/${id}/archive`);
    const blob = await response.blob();
    saveBlob(blob, `${id}.mscan`);
    say(`Downloaded ${id}.mscan (${megabytes(blob.size)}, sha256 ${response.headers.get('X-Mirrorscan-SHA256')}).`);
  } catch (e) {
    say(`Download: ${e.message}`, true);
  }
}

async function remove(id) {
  if (!window.confirm(`Delete scan ${id} and its results from the device?`)) return;
  try {
    await api(`/scans/${id}`, { method: 'DELETE' });
    say(`Deleted ${id}.`);
    if (selected === id) $('result').hidden = true;
    refreshScans();
  } catch (e) {
    say(`Delete: ${e.message}`, true);
  }
}

function releaseBlobs() {
  while (blobUrls.length) URL.revokeObjectURL(blobUrls.pop());
}

function formatMm(value) {
  return value === null || value === undefined ? '—' : `${(value / 10).toFixed(1)} cm`;
}

// summary.json's "pose" (docs/pose-check.md): the verdict, what to say for a rescan, and
// the figures.
function showPose(pose) {
  $('pose').hidden = !pose;
  $('pose-advice').innerHTML = '';
  $('pose-figures').querySelector('tbody').innerHTML = '';
  if (!pose) return;
  const within = pose.within_protocol;
  $('pose-verdict').textContent = within
    ? 'Posture: within the standard scanning posture.'
    : pose.checked ? 'Posture: off the standard scanning posture. For a rescan, say:'
      : `Posture not checked: ${pose.reason}`;
  $('pose-verdict').className = within ? 'pose-ok' : 'pose-off';
  for (const sentence of pose.advice || []) {
    const li = document.createElement('li');
    li.textContent = sentence;
    $('pose-advice').appendChild(li);
  }
  if (!pose.checked) return;
  const off = new Set(pose.off_protocol || []);
  const deg = (v) => (v === null || v === undefined ? 'not measured' : `${v.toFixed(1)}°`);
  const mm = (v) => (v === null || v === undefined ? 'not measured' : `${v.toFixed(0)} mm`);
  const arms = pose.arm_abduction_deg || {};
  const rows = [
    ['feet apart', mm(pose.feet_spread_mm), 'feet_spread_mm', `legs ${mm(pose.hip_spread_mm)} apart at the hips`],
    ['left arm from the body', deg(arms.left), 'arm_abduction_left', 'the person\'s left'],
    ['right arm from the body', deg(arms.right), 'arm_abduction_right', ''],
    ['turned from the camera', deg(pose.yaw_deg), 'yaw_deg', '+ to their left'],
    ['lean', deg(pose.lean_deg), 'lean_deg', '+ forward'],
    ['head turn', deg(pose.head_turn_deg), 'head_turn_deg', '+ to their left'],
    ['top of the head', mm(pose.head_top_mm), 'head_top_mm',
      pose.reach_mm ? `the cabinet scans up to ${mm(pose.reach_mm)}` : ''],
  ];
  const body = $('pose-figures').querySelector('tbody');
  for (const [name, value, key, note] of rows) {
    const row = document.createElement('tr');
    row.dataset.figure = key;
    if (off.has(key)) row.className = 'pose-off';
    cell(row, name);
    cell(row, value);
    cell(row, (pose.notes && pose.notes[key]) || note);
    body.appendChild(row);
  }
}

async function showResult(id) {
  selected = id;
  for (const row of $('scan-rows').children) row.className = row.dataset.id === id ? 'selected' : '';
  $('result').hidden = false;
  $('result-id').textContent = id;
  $('previews').innerHTML = '';
  $('measurements').querySelector('tbody').innerHTML = '';
  $('result-summary').textContent = 'loading…';
  showPose(null);
  releaseBlobs();
  let results;
  try {
    results = (await (await api(`/scans/${id}/results`)).json()).results.map((r) => r.name);
  } catch (e) {
    $('result-summary').textContent = `results: ${e.message}`;
    return;
  }
  if (results.includes('summary.json')) {
    const summary = await (await api(`/scans/${id}/results/summary.json`)).json();
    const mesh = summary.mesh || {};
    $('result-summary').textContent = summary.ok
      ? `${summary.reconstruction ? summary.reconstruction.points : '?'} points, mesh of ${mesh.triangles} triangles, ` +
        `${mesh.holes ? mesh.holes.count : '?'} hole(s); processed in ${summary.timings_s.total.toFixed(0)} s`
      : `processing failed: ${summary.reason}`;
    showPose(summary.pose || null);
  } else {
    $('result-summary').textContent = 'processing…';
  }
  for (const name of results.filter((n) => n.endsWith('.png'))) {
    const blob = await (await api(`/scans/${id}/results/${name}`)).blob();
    const url = URL.createObjectURL(blob);
    blobUrls.push(url);
    const figure = document.createElement('figure');
    const img = document.createElement('img');
    img.src = url;
    img.alt = name;
    img.dataset.name = name;
    const caption = document.createElement('figcaption');
    caption.textContent = name.replace('preview-', '').replace('.png', '');
    figure.append(img, caption);
    $('previews').appendChild(figure);
  }
  if (results.includes('measurements.json')) {
    const m = await (await api(`/scans/${id}/results/measurements.json`)).json();
    const body = $('measurements').querySelector('tbody');
    const rows = m.measurements || [];  // stature among them, with its reason when withheld
    for (const entry of rows) {
      const row = document.createElement('tr');
      cell(row, entry.name.replace(/_/g, ' '));
      cell(row, formatMm(entry.value_mm));
      cell(row, entry.withheld || '');
      body.appendChild(row);
    }
  }
  if (results.includes('mesh.ply')) {
    const bytes = await (await api(`/scans/${id}/results/mesh.ply`)).arrayBuffer();
    const drawn = showMesh($('viewer'), bytes);
    $('viewer').dataset.triangles = String(drawn.triangles);
  }
}

// The live preview: one PNG at a time, at most once a second, only while ticked and the
// page is visible, so the device captures nothing while no one looks.
let previewTimer = null;
let previewUrl = '';
function setPreview(on) {
  $('preview-on').checked = on;
  if (previewTimer) clearTimeout(previewTimer);
  previewTimer = null;
  $('preview').hidden = !on;
  $('preview-note').textContent = on ? '' : 'Off. The device captures only while this is ticked and the page is in view.';
  if (on) previewLoop();
}

async function previewLoop() {
  previewTimer = null;
  if (!$('preview-on').checked || document.visibilityState !== 'visible' || !token) return;
  const camera = $('preview-camera').value;
  const lasers = $('preview-lasers').checked ? '&lasers=1' : '';
  try {
    const response = await api(`/preview?camera=${encodeURIComponent(camera)}${lasers}`);
    const url = URL.createObjectURL(await response.blob());
    $('preview').src = url;
    if (previewUrl) URL.revokeObjectURL(previewUrl);
    previewUrl = url;
    $('preview-note').textContent = `${response.headers.get('X-Mirrorscan-Peaks')} peaks drawn in red`;
  } catch (e) {
    $('preview-note').textContent = e.status === 409 ? 'Paused while scanning.' : `Preview: ${e.message}`;
  }
  if ($('preview-on').checked && !previewTimer) previewTimer = setTimeout(previewLoop, 1000);
}

async function init() {
  await refreshStatus();
  try {
    const cameras = (await (await fetch(`${API}/status`)).json()).cameras || ['upper'];
    $('preview-camera').innerHTML = '';
    for (const c of cameras) {
      const option = document.createElement('option');
      option.textContent = c;
      $('preview-camera').appendChild(option);
    }
  } catch (e) { /* the status poll reports it */ }
  setInterval(refreshStatus, 2000);
  $('login').addEventListener('submit', (e) => {
    e.preventDefault();
    const candidate = $('token').value.trim();
    $('token').value = '';
    if (candidate) login(candidate);
  });
  $('logout').addEventListener('click', logout);
  $('scan-button').addEventListener('click', startScan);
  $('abort-button').addEventListener('click', abortScan);
  $('preview-on').addEventListener('change', () => setPreview($('preview-on').checked));
  document.addEventListener('visibilitychange', () => {
    if (document.visibilityState === 'visible' && $('preview-on').checked) previewLoop();
  });
  if (token) await login(token); else loggedIn(false);
}

init();
