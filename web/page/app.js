// The stlrefine page: choose a mesh, submit it as a job (POST v1/jobs), poll the job, then
// show the refined part, its size and units, its layers (the job's own contour file) and
// the download links. Large files are read in a worker (preview.js), and a result of
// more than PREVIEW_TRIANGLES is drawn decimated, said on the page. URLs are relative, so
// the page also works behind a reverse proxy that serves it under a path prefix.
import { CONTOUR_FILES } from './contours.js';
import { LayerView } from './layers.js';
import { PartView } from './viewer.js';

const $ = (id) => document.getElementById(id);
const form = $('job-form');
const FALLBACK_SCHEMES = ['butterfly', 'loop', 'lsf'];
const POLL_MS = 250;
// Triangles drawn at most per side: more (a 4 M triangle result) would stall the page and
// a software-rendered browser; such a part is shown decimated.
const PREVIEW_TRIANGLES = 250000;
const DESCRIPTIONS = {
  'result.stl': 'refined part (binary STL)',
  'result.3mf': 'refined part (3MF)',
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

// ---- the worker (preview.js) ----------------------------------------------------------------

const workers = new Map(); // worker -> 'before' | 'after'

// Ends the workers of one side (a new file, a new job), whose answers nobody waits for.
function endWorkers(side) {
  for (const [w, s] of workers) {
    if (s !== side) continue;
    w.terminate();
    workers.delete(w);
  }
}

// One task in a fresh module worker for `side`; rejects with a Problem.
function inWorker(side, message, transfer = []) {
  return new Promise((resolve, reject) => {
    const worker = new Worker(new URL('preview.js', import.meta.url), { type: 'module' });
    workers.set(worker, side);
    const done = () => {
      worker.terminate();
      workers.delete(worker);
    };
    worker.onmessage = (e) => {
      done();
      if (e.data && e.data.error) reject(new Problem(e.data.error));
      else resolve(e.data);
    };
    worker.onerror = (e) => {
      done();
      reject(new Problem({ title: 'The page could not read this', detail: e.message }));
    };
    worker.postMessage({ ...message, headers: withKey() }, transfer);
  });
}

const absolute = (url) => new URL(url, document.baseURI).href;

// What a file is, by its first bytes, as the server tells formats apart.
function sniff(bytes) {
  const head = new Uint8Array(bytes, 0, Math.min(bytes.byteLength, 512));
  const text = new TextDecoder('latin1').decode(head);
  if (text.startsWith('PK\x03\x04')) return '3mf';
  if (/^ply\r?\n/.test(text)) return 'ply';
  if (bytes.byteLength >= 84 && 84 + 50 * new DataView(bytes).getUint32(80, true) === bytes.byteLength) return 'stl';
  if (/^\s*solid/.test(text)) return 'stl';
  if (/^\s*(v|vn|vt|f|o|g|mtllib|usemtl|#)[ \t]/m.test(text)) return 'obj';
  return 'stl';
}

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
  if (problem.line != null) where.push(`line ${problem.line} of the file`);
  if (problem.byte_offset != null) where.push(`byte ${problem.byte_offset} of the file`);
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
  const fields = ['units', 'scheme', 'levels', 'crease_angle', 'adaptive_tol', 'max_level'];
  if ($('slice-on').checked) fields.push('layer_height', 'slice_format');
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
  input = { name: file.name, file, bytes: await file.arrayBuffer() };
  input.format = sniff(input.bytes);
  $('file-info').textContent = `${file.name}, ${file.size.toLocaleString()} bytes (${input.format.toUpperCase()})`;
  resetResults();
  endWorkers('before');
  if (!view) return;
  view.remove(0);
  if (input.format !== 'stl') {
    $('view-info').textContent = `Before: a ${input.format.toUpperCase()} file is drawn here only once refined (the server reads it).`;
    return;
  }
  const binary = input.bytes.byteLength >= 84 ? new DataView(input.bytes).getUint32(80, true) : 0;
  try {
    if (84 + 50 * binary === input.bytes.byteLength && binary > PREVIEW_TRIANGLES) {
      $('view-info').textContent = `Before: ${binary.toLocaleString()} triangles, preparing a preview...`;
      const chosen = input;
      const p = await inWorker('before', { kind: 'mesh', buffer: input.bytes, cap: PREVIEW_TRIANGLES });
      if (input !== chosen) return; // another file was chosen meanwhile
      view.showPositions(0, p.positions);
      $('view-info').textContent = `Before: ${previewText(p)}.`;
    } else {
      const n = view.show(0, input.bytes);
      $('view-info').textContent = `Before: ${n.toLocaleString()} triangles.`;
    }
  } catch {
    view.remove(0);
    $('view-info').textContent = 'Before: this is not an STL the page can draw. It is sent as it is; the server reads STL, 3MF, OBJ and PLY and says what is wrong with it.';
  }
}

function previewText(p) {
  const n = p.triangles.toLocaleString();
  return p.shown === p.triangles ? `${n} triangles`
    : `${n} triangles, drawn as a decimated preview of ${p.shown.toLocaleString()} (the download has them all)`;
}

// The part's size and the units it was read in (report.input.units), and the warnings.
function showPart(report) {
  const units = report.input && report.input.units;
  const info = $('part-info');
  if (units && Array.isArray(units.size_mm)) {
    const size = units.size_mm.map((x) => Number(x.toPrecision(4)).toLocaleString()).join(' × ');
    let how = units.declared ? `declared by the file (${units.declared})` : units.assumed ? 'assumed' : 'as asked';
    if (units.scale != null && units.scale !== 1) how += `, scaled by ${units.scale}`;
    info.textContent = `Part size: ${size} mm. Units: ${units.units}, ${how}.`;
    info.dataset.units = units.units;
  } else {
    info.textContent = '';
  }
  $('warnings').replaceChildren(...(report.warnings || []).map((w) => Object.assign(document.createElement('li'), {
    textContent: `Warning: ${w.message}`,
  })));
}

function resetResults() {
  job = null;
  endWorkers('after');
  if (view) view.remove(1);
  delete $('view3d').dataset.after;
  delete $('view3d').dataset.shown;
  $('part-info').textContent = '';
  $('warnings').replaceChildren();
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
    showError({ title: 'No file', detail: 'Choose or drop a mesh file first.', field: 'file' });
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
      headers: { 'Content-Type': input.format === 'stl' ? 'model/stl' : 'application/octet-stream', 'Content-Disposition': disposition },
      body: input.file, // a Blob: sent from the file, not copied on the page's thread
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

const baseName = (href) => href.slice(href.lastIndexOf('/') + 1);

function downloadItem(j, name, description) {
  const a = document.createElement('a');
  a.href = jobUrl(j.id, name);
  a.download = name;
  a.textContent = name;
  if ($('api-key').value.trim()) a.addEventListener('click', (e) => downloadWithKey(e, a)); // a plain link cannot send it
  const li = document.createElement('li');
  li.append(a, ` — ${description}`);
  return li;
}

async function finished(j, q) {
  const report = j.report || {};
  $('report').textContent = JSON.stringify(report, null, 2);
  // Every file of the job; a job of several parts (a zip, a multi-object 3MF) lists each
  // part's files under parts[] and links.result is then result.zip.
  const list = $('downloads');
  list.replaceChildren();
  for (const [key, href] of Object.entries(j.links || {})) {
    if (key === 'self') continue;
    const name = baseName(href);
    list.append(downloadItem(j, name, DESCRIPTIONS[name] || (name === 'result.zip' ? 'every part\'s files and the report (zip)' : key)));
  }
  const parts = Array.isArray(j.parts) ? j.parts : [];
  for (const part of parts) {
    for (const [key, href] of Object.entries(part.links || {})) {
      list.append(downloadItem(j, baseName(href), `${part.name}: ${key === 'result' ? 'refined part' : 'layer contours'}`));
    }
  }

  // The part drawn: the job's, or the first of its parts (said on the page).
  const shown = parts.length ? parts[0] : null;
  // (report.parts[k].report is part k's own report, with its input's size and units.)
  const partReport = (shown && Array.isArray(report.parts) && report.parts[0] && report.parts[0].report) || report;
  showPart(partReport);
  const results = Object.values((shown || j).links || {}).map(baseName);
  const resultName = results.find((n) => n.endsWith('.stl') && n !== 'report.json');
  const which = shown ? `Part 1 of ${parts.length} (${shown.name}). ` : '';

  // The refined part, read and (when large) decimated in the worker.
  if (view && resultName) {
    $('view-info').textContent = 'Reading the refined part...';
    const p = await inWorker('after', { kind: 'mesh', url: absolute(jobUrl(j.id, resultName)), cap: PREVIEW_TRIANGLES });
    if (job !== j) return; // a new job started meanwhile
    view.showPositions(1, p.positions);
    const before = partReport.input ? partReport.input.faces : undefined;
    $('view-info').textContent = `${which}Before: ${before != null ? before.toLocaleString() : '?'} triangles. After: ${previewText(p)}.`;
    $('view3d').dataset.after = String(p.triangles);
    $('view3d').dataset.shown = String(p.shown);
  } else if (view) {
    $('view-info').textContent = 'The refined part is not an STL the page draws; download it.';
  }

  // The job's own contour file, in the format it was asked for.
  // (A part's contour file is part<k>.contours.<ext>: read by its extension.)
  const contourFile = results.find((n) => CONTOUR_FILES.some((c) => n.endsWith(c.slice('contours'.length)) && n.includes('contours')));
  const contours = contourFile && CONTOUR_FILES.find((c) => contourFile.endsWith(c.slice('contours'.length)));
  if (!q.has('layer_height')) {
    layers.clear('Slicing was not asked for.');
  } else if (!contours) {
    layers.clear('The job wrote no contour file.');
  } else {
    layers.clear(`Reading ${contourFile}...`);
    const doc = await inWorker('after', { kind: 'contours', url: absolute(jobUrl(j.id, contourFile)), name: contours });
    if (job !== j) return;
    layers.load(doc);
    $('layer-canvas').dataset.source = doc.format;
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
  $('layer_height').disabled = !$('slice-on').checked;
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
