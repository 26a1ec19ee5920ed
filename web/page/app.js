// The stlrefine page: choose an STL, submit it as a job (POST v1/jobs), poll the job, then
// show the refined part, its layers and the download links. URLs are relative, so the
// page also works behind a reverse proxy that serves it under a path prefix.
import { LayerView } from './layers.js';
import { PartView } from './viewer.js';

const $ = (id) => document.getElementById(id);
const form = $('job-form');
const FALLBACK_SCHEMES = ['butterfly', 'loop', 'lsf'];
const POLL_MS = 250;
const MAX_VIEW_BYTES = 256 * 1024 * 1024; // larger results are downloaded, not drawn
const DESCRIPTIONS = {
  'result.stl': 'refined part (binary STL)',
  'contours.json': 'layer contours (JSON)',
  'contours.svg': 'layer contours (SVG)',
  'contours.cli': 'layer contours (CLI)',
  'report.json': 'report (JSON)',
};

let input = null; // { name, bytes } of the chosen file
let job = null; // the last job JSON
let cancelled = false;

let view = null;
try {
  view = new PartView($('view3d'));
} catch (err) {
  $('view-info').textContent = `The 3D view is not available in this browser (${err.message}).`;
}
const layers = new LayerView($('layer-canvas'), $('layer'), $('layer-label'), $('layer-info'));

// ---- talking to the API -------------------------------------------------------------------

class Problem extends Error {
  constructor(problem) {
    super(problem.detail || problem.title);
    this.problem = problem;
  }
}

function withKey(headers = {}) {
  const key = $('api-key').value.trim();
  return key ? { ...headers, Authorization: `Bearer ${key}` } : headers;
}

// fetch() that turns every answer >= 400 into a Problem (RFC 9457 body when there is one).
async function api(url, options = {}) {
  let res;
  try {
    res = await fetch(url, { ...options, headers: withKey(options.headers) });
  } catch (err) {
    throw new Problem({ title: 'The server cannot be reached', detail: err.message });
  }
  if (res.ok) return res;
  const problem = { status: res.status, title: res.statusText || 'Request failed' };
  const text = await res.text();
  try {
    Object.assign(problem, JSON.parse(text));
  } catch {
    if (text) problem.detail = text.slice(0, 300);
  }
  throw new Problem(problem);
}

const jobUrl = (id, file = '') => `v1/jobs/${encodeURIComponent(id)}${file ? `/${file}` : ''}`;

// ---- errors -------------------------------------------------------------------------------

function clearError() {
  $('error').hidden = true;
  $('error').replaceChildren();
  delete $('error').dataset.field;
  for (const el of form.querySelectorAll('[aria-invalid]')) {
    el.removeAttribute('aria-invalid');
    el.removeAttribute('aria-errormessage');
  }
  for (const el of form.querySelectorAll('.field-error')) el.remove();
}

// Shows a problem: title, status, detail, and the field it names, which is also marked.
function showError(problem) {
  clearError();
  const box = $('error');
  const title = document.createElement('p');
  const strong = document.createElement('strong');
  strong.textContent = problem.title || 'Error';
  title.append(strong);
  if (problem.status) title.append(` (HTTP ${problem.status})`);
  box.append(title);
  if (problem.detail) {
    const p = document.createElement('p');
    p.textContent = problem.detail;
    box.append(p);
  }
  const where = [];
  if (problem.field) where.push(`field: ${problem.field}`);
  if (problem.line != null) where.push(`line ${problem.line} of the STL`);
  if (problem.byte_offset != null) where.push(`byte ${problem.byte_offset} of the STL`);
  if (where.length) {
    const p = document.createElement('p');
    p.textContent = `Where: ${where.join(', ')}`;
    box.append(p);
  }
  box.dataset.field = problem.field || '';
  box.hidden = false;

  // 401: the key goes in the API key box, which is opened.
  const el = problem.status === 401 && !problem.field ? $('api-key') : problem.field && form.elements.namedItem(problem.field);
  if (el === $('api-key')) el.closest('details').open = true;
  if (el && el.setAttribute) {
    const msg = document.createElement('p');
    msg.className = 'field-error';
    msg.id = `${el.id}-error`;
    msg.textContent = problem.detail || problem.title;
    el.setAttribute('aria-invalid', 'true');
    el.setAttribute('aria-errormessage', msg.id);
    el.insertAdjacentElement('afterend', msg);
    el.focus();
  }
}

function fail(err) {
  showError(err instanceof Problem ? err.problem : { title: 'Error', detail: String(err.message || err) });
}

// ---- the form -----------------------------------------------------------------------------

async function loadSchemes() {
  let names = FALLBACK_SCHEMES;
  try {
    const doc = await (await api('v1/openapi.json')).json();
    const param = doc.paths['/v1/jobs'].post.parameters.find((p) => p.name === 'scheme');
    if (param && Array.isArray(param.schema.enum) && param.schema.enum.length) names = param.schema.enum;
  } catch {
    // an API key may be needed for the document: the fixed list matches this release
  }
  const select = $('scheme');
  const chosen = select.value || 'butterfly';
  select.replaceChildren(...names.map((n) => new Option(n, n, n === 'butterfly', n === chosen)));
}

// The query string: what the user typed, as typed; the server judges it and names the field.
function query() {
  const q = new URLSearchParams();
  const fields = ['scheme', 'levels', 'crease_angle', 'adaptive_tol', 'max_level'];
  if ($('slice-on').checked) fields.push('slice', 'slice_format');
  fields.push('primitives', 'primitive_tol', 'max_deviation');
  const adaptive = Number($('adaptive_tol').value) > 0;
  for (const name of fields) {
    const el = form.elements.namedItem(name);
    if (el.validity && el.validity.badInput) {
      throw new Problem({ title: 'Not a number', detail: `${el.labels[0].textContent} is not a number`, field: name });
    }
    const value = el.value.trim();
    if (value === '') continue; // the server's default
    if (name === 'max_level' && !adaptive) continue;
    if (name === 'levels' && adaptive) continue;
    q.set(name, value);
  }
  return q;
}

async function chooseFile(file) {
  if (!file) return;
  clearError();
  input = { name: file.name, bytes: await file.arrayBuffer() };
  $('file-info').textContent = `${file.name}, ${file.size.toLocaleString()} bytes`;
  resetResults();
  if (view) {
    try {
      const n = view.show(0, input.bytes);
      $('view-info').textContent = `Before: ${n.toLocaleString()} triangles.`;
    } catch (err) {
      view.remove(0);
      $('view-info').textContent = `The browser could not read this file as STL (${err.message}); the server will say more.`;
    }
  }
}

function resetResults() {
  job = null;
  if (view) view.remove(1);
  layers.clear();
  $('downloads').replaceChildren(Object.assign(document.createElement('li'), {
    className: 'hint', textContent: 'Results appear here when the job is done.',
  }));
  $('report').textContent = '';
  $('progress').value = 0;
  $('state').textContent = 'No job yet.';
  $('stage').textContent = '';
  document.body.dataset.state = '';
}

// ---- the job ------------------------------------------------------------------------------

function setBusy(busy) {
  $('submit').disabled = busy;
  $('file').disabled = busy; // a new file would reset the view of the running job
  $('cancel').hidden = !busy;
  form.setAttribute('aria-busy', String(busy));
}

function showJob(j) {
  $('progress').value = Number(j.progress) || 0;
  const state = `Job ${j.state}`;
  if ($('state').textContent !== state) $('state').textContent = state; // announced on change only
  const seconds = j.timings && j.timings.run_seconds;
  $('stage').textContent = `${j.stage || ''}${seconds != null ? ` · ${seconds.toFixed(2)} s` : ''}`;
  document.body.dataset.state = j.state;
  document.body.dataset.job = j.id;
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function run() {
  clearError();
  if (!input) {
    showError({ title: 'No file', detail: 'Choose or drop an STL file first.', field: 'file' });
    return;
  }
  let q;
  try {
    q = query();
  } catch (err) {
    fail(err);
    return;
  }
  resetResults();
  setBusy(true);
  cancelled = false;
  try {
    // The file's name goes along: the server names the downloads after it (part_refined.stl).
    const disposition = `attachment; filename*=UTF-8''${encodeURIComponent(input.name)}`;
    const res = await api(`v1/jobs?${q}`, {
      method: 'POST',
      headers: { 'Content-Type': 'model/stl', 'Content-Disposition': disposition },
      body: input.bytes,
    });
    job = await res.json();
    showJob(job);
    while (job.state === 'queued' || job.state === 'running') {
      await sleep(POLL_MS);
      job = await (await api(jobUrl(job.id))).json();
      showJob(job);
    }
    if (job.state === 'done') await finished(job, q);
    else if (job.problem && !cancelled) showError(job.problem);
  } catch (err) {
    fail(err);
  } finally {
    setBusy(false);
  }
}

async function finished(j, q) {
  const report = j.report || {};
  $('report').textContent = JSON.stringify(report, null, 2);
  const list = $('downloads');
  list.replaceChildren();
  const key = $('api-key').value.trim();
  for (const name of Object.keys(DESCRIPTIONS)) {
    if (!Object.values(j.links || {}).some((href) => href.endsWith(`/${name}`))) continue;
    const a = document.createElement('a');
    a.href = jobUrl(j.id, name);
    a.download = name;
    a.textContent = name;
    if (key) a.addEventListener('click', (e) => downloadWithKey(e, a)); // a plain link cannot send it
    const li = document.createElement('li');
    li.append(a, ` — ${DESCRIPTIONS[name]}`);
    list.append(li);
  }

  const outBytes = report.output && report.output.bytes;
  const small = !(outBytes > MAX_VIEW_BYTES);
  const hasJson = Boolean(j.results && j.results.includes('contours.json'));
  let stl = null;
  if (small && (view || (q.has('slice') && !hasJson))) {
    stl = await (await api(jobUrl(j.id, 'result.stl'))).arrayBuffer();
  }
  if (view && stl) {
    const n = view.show(1, stl);
    const before = report.input ? report.input.faces : undefined;
    $('view-info').textContent = `Before: ${before != null ? before.toLocaleString() : '?'} triangles. After: ${n.toLocaleString()} triangles.`;
    $('view3d').dataset.after = String(n);
  } else if (view) {
    $('view-info').textContent = `The refined part (${outBytes.toLocaleString()} bytes) is too large to draw here; download it.`;
  }

  // The layer view needs JSON: the job's own contours, or a JSON slice of the result.
  if (!q.has('slice')) {
    layers.clear('Slicing was not asked for.');
  } else if (hasJson) {
    layers.load(await (await api(jobUrl(j.id, 'contours.json'))).json());
  } else if (!stl) {
    layers.clear('The refined part is too large to slice again here; download the contours.');
  } else {
    const sq = new URLSearchParams({ layer_height: q.get('slice'), format: 'json' });
    const res = await api(`v1/slice?${sq}`, {
      method: 'POST', headers: { 'Content-Type': 'model/stl' }, body: stl,
    });
    layers.load(await res.json());
  }
}

async function downloadWithKey(event, a) {
  event.preventDefault();
  try {
    const blob = await (await api(a.href)).blob();
    const url = URL.createObjectURL(blob);
    const tmp = Object.assign(document.createElement('a'), { href: url, download: a.download });
    tmp.click();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
  } catch (err) {
    fail(err);
  }
}

// ---- wiring -------------------------------------------------------------------------------

form.addEventListener('submit', (e) => {
  e.preventDefault();
  run();
});
$('cancel').addEventListener('click', async () => {
  if (!job) return;
  cancelled = true;
  try {
    showJob(await (await api(jobUrl(job.id), { method: 'DELETE' })).json());
  } catch (err) {
    fail(err);
  }
});
$('file').addEventListener('change', () => chooseFile($('file').files[0]).catch(fail));
$('slice-on').addEventListener('change', () => {
  $('slice').disabled = !$('slice-on').checked;
  $('slice_format').disabled = !$('slice-on').checked;
});
$('api-key').addEventListener('change', () => loadSchemes()); // the document may need the key
$('edges').addEventListener('change', () => view && view.setEdges($('edges').checked));

// A file dropped beside the box must not replace the page.
window.addEventListener('dragover', (e) => e.preventDefault());
window.addEventListener('drop', (e) => e.preventDefault());
const drop = $('drop');
drop.addEventListener('dragover', (e) => {
  e.preventDefault();
  drop.classList.add('over');
});
drop.addEventListener('dragleave', () => drop.classList.remove('over'));
drop.addEventListener('drop', (e) => {
  e.preventDefault();
  drop.classList.remove('over');
  const file = e.dataTransfer.files[0];
  if (file && !$('file').disabled) chooseFile(file).catch(fail);
});

loadSchemes().finally(() => {
  document.body.dataset.ready = 'true';
});
