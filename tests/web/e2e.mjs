// End-to-end test of the web page, as a person uses it: stlrefined on an ephemeral loopback
// port with a temporary data directory, the page in Debian's chromium (headless, WebGL on
// SwiftShader) driven by playwright-core. Choose a mesh, butterfly 1 level + slicing,
// submit, wait for done; the 3D view drew both sides, the layer view draws contours, the
// part's size and units are shown, and the downloaded result.stl is byte for byte GET
// /v1/jobs/{id}/result.stl and a synchronous POST /v1/refine of the same parameters. Then:
// the layer view draws the job's own CLI, binary CLI and SVG contours (never a second upload
// to /v1/slice, never the deprecated `slice` parameter); a broken 3MF and a file that is no
// mesh get the server's problem detail, not a script error; a 4 M triangle result is drawn
// as a decimated preview, said on the page, while the page keeps answering (its longest
// main-thread stall is measured). A screenshot is kept in ARTIFACTS/web.png.
//
//   node e2e.mjs --node-modules DIR --daemon stlrefined --chromium PATH --artifacts DIR --mesh STL
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import { createRequire } from 'node:module';
import os from 'node:os';
import path from 'node:path';

const args = {};
for (let i = 2; i + 1 < process.argv.length; i += 2) args[process.argv[i].replace(/^--/, '')] = process.argv[i + 1];
for (const k of ['node-modules', 'daemon', 'chromium', 'artifacts', 'mesh']) {
  if (!args[k]) {
    console.error(`e2e.mjs: --${k} is missing`);
    process.exit(2);
  }
}
const require = createRequire(path.join(args['node-modules'], 'e2e.cjs'));
const { chromium } = require('playwright-core');

const t0 = Date.now();
const log = (msg) => console.log(`[${((Date.now() - t0) / 1000).toFixed(1)} s] ${msg}`);
let passed = 0;
let failed = 0;
function check(ok, what) {
  if (ok) passed++;
  else failed++;
  log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  return ok;
}

const PARAMS = { scheme: 'butterfly', levels: '1', crease_angle: '35' };
const LAYER_HEIGHT = '0.5';
const BACKGROUND = [0xf4, 0xf5, 0xf7]; // viewer.js and layers.js draw on this

let daemon = null;
const consoleErrors = []; // the page's, printed when the test fails
let browser = null;
const dataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'stlrefine-web-'));
// It takes 40-90 s (the 4 M triangle part is most of it); the watchdog (below ctest's
// TIMEOUT 300) only makes sure that a hang still ends with the daemon and the browser stopped.
const watchdog = setTimeout(() => {
  log('FAIL the test took more than 270 s');
  cleanup().finally(() => process.exit(1));
}, 270_000);

async function cleanup() {
  if (browser) await browser.close().catch(() => {});
  browser = null;
  if (daemon && daemon.exitCode === null) {
    const exited = new Promise((r) => daemon.once('exit', r));
    daemon.kill('SIGTERM');
    await Promise.race([exited, new Promise((r) => setTimeout(r, 5000))]);
    if (daemon.exitCode === null) daemon.kill('SIGKILL');
  }
  fs.rmSync(dataDir, { recursive: true, force: true });
}

function startDaemon() {
  return new Promise((resolve, reject) => {
    daemon = spawn(args.daemon, ['--host', '127.0.0.1', '--port', '0', '--data-dir', dataDir, '--compute-slots', '2'], {
      stdio: ['ignore', 'pipe', 'pipe'],
    });
    let out = '';
    let err = '';
    daemon.stderr.on('data', (d) => { err += d; });
    daemon.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/listening on (http:\/\/\S+)/);
      if (m) resolve(m[1]);
    });
    daemon.on('exit', (code) => reject(new Error(`stlrefined exited with ${code}: ${err}`)));
    setTimeout(() => reject(new Error(`stlrefined did not say where it listens: ${out} ${err}`)), 10_000);
  });
}

// Pixels of a canvas that are not the background, counted in the left and right halves.
// The WebGL canvas keeps its drawing buffer (preserveDrawingBuffer), so it can be copied.
function countDrawn(page, selector) {
  return page.evaluate(([sel, bg]) => {
    const c = document.querySelector(sel);
    const t = document.createElement('canvas');
    t.width = c.width;
    t.height = c.height;
    const g = t.getContext('2d');
    g.drawImage(c, 0, 0);
    const d = g.getImageData(0, 0, t.width, t.height).data;
    let left = 0;
    let right = 0;
    for (let i = 0; i < d.length; i += 4) {
      const off = Math.abs(d[i] - bg[0]) + Math.abs(d[i + 1] - bg[1]) + Math.abs(d[i + 2] - bg[2]);
      if (off > 24) {
        if ((i / 4) % t.width < t.width / 2) left++;
        else right++;
      }
    }
    return { left, right, pixels: t.width * t.height };
  }, [selector, BACKGROUND]);
}

// A closed torus of 2 u v triangles as binary STL (R 40 mm, r 15 mm); returns the count.
function writeTorus(file, u, v) {
  const n = 2 * u * v;
  const buf = Buffer.alloc(84 + 50 * n);
  buf.writeUInt32LE(n, 80);
  const p = (i, j) => {
    const a = (2 * Math.PI * (i % u)) / u; // the seam's corners are the same floats
    const b = (2 * Math.PI * (j % v)) / v;
    return [(40 + 15 * Math.cos(b)) * Math.cos(a), (40 + 15 * Math.cos(b)) * Math.sin(a), 15 * Math.sin(b) + 15];
  };
  let at = 84;
  const put = (...corners) => {
    at += 12; // normal: left zero, recomputed by every reader
    for (const c of corners) for (const x of c) { buf.writeFloatLE(x, at); at += 4; }
    at += 2;
  };
  for (let i = 0; i < u; i++) {
    for (let j = 0; j < v; j++) {
      const a = p(i, j); const b = p(i + 1, j); const c = p(i + 1, j + 1); const d = p(i, j + 1);
      put(a, b, c);
      put(a, c, d);
    }
  }
  fs.writeFileSync(file, buf);
  return n;
}

async function main() {
  const mesh = fs.readFileSync(args.mesh);
  const base = await startDaemon();
  log(`stlrefined at ${base}, data in ${dataDir}`);

  // The page's HTTP side: types, validators, 304, 404 problems.
  const index = await fetch(`${base}/`);
  check(index.status === 200 && index.headers.get('content-type').startsWith('text/html'), 'GET / is text/html');
  const etag = index.headers.get('etag');
  check(Boolean(etag) && index.headers.get('cache-control') === 'no-cache', `GET / has an ETag (${etag}) and Cache-Control: no-cache`);
  check((index.headers.get('content-security-policy') || '').includes("default-src 'self'"), 'GET / has a Content-Security-Policy');
  const again = await fetch(`${base}/`, { headers: { 'If-None-Match': etag } });
  check(again.status === 304, `GET / with If-None-Match answers 304 (got ${again.status})`);
  const js = await fetch(`${base}/assets/three.module.js`);
  check(js.status === 200 && js.headers.get('content-type').startsWith('text/javascript'), 'three.module.js is served as text/javascript');
  const missing = await fetch(`${base}/assets/nothing.js`);
  const missingBody = await missing.json().catch(() => ({}));
  check(missing.status === 404 && missing.headers.get('content-type') === 'application/problem+json' && missingBody.type === 'urn:stlrefine:problem:not-found',
    'an unknown asset is a 404 problem');

  browser = await chromium.launch({
    executablePath: args.chromium,
    headless: true,
    // No GPU here: WebGL on SwiftShader, which recent Chromium no longer picks by itself.
    args: ['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
  });
  log(`chromium ${browser.version()}`);
  const context = await browser.newContext({ acceptDownloads: true, viewport: { width: 1100, height: 1400 }, deviceScaleFactor: 1 });
  const page = await context.newPage();
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
  page.on('pageerror', (e) => consoleErrors.push(String(e)));
  const requested = [];
  page.on('request', (r) => requested.push(r.url()));

  await page.goto(`${base}/`);
  await page.waitForSelector('body[data-ready="true"]');
  const schemes = await page.$$eval('#scheme option', (os) => os.map((o) => o.value));
  const openapi = await (await fetch(`${base}/v1/openapi.json`)).json();
  const documented = openapi.paths['/v1/jobs'].post.parameters.find((p) => p.name === 'scheme').schema.enum;
  check(JSON.stringify(schemes) === JSON.stringify(documented), `the scheme list is the OpenAPI enum (${schemes.join(', ')})`);
  check(await page.$eval('#scheme', (s) => s.value) === 'butterfly', 'butterfly is preselected');

  await page.setInputFiles('#file', args.mesh);
  await page.waitForFunction(() => document.getElementById('view-info').textContent.startsWith('Before:'));
  log(await page.textContent('#view-info'));

  // A refused parameter: the problem is shown, naming the field, and the field is marked.
  await page.fill('#levels', '9');
  await page.click('#submit');
  await page.waitForSelector('#error:not([hidden])');
  const shown = await page.textContent('#error');
  check(await page.getAttribute('#error', 'data-field') === 'levels' && shown.includes('field: levels'),
    `levels=9 is refused and the error names the field: "${shown.trim().replace(/\s+/g, ' ')}"`);
  check(await page.getAttribute('#levels', 'aria-invalid') === 'true', 'the levels input is marked aria-invalid');

  // The job: butterfly, 1 level, sliced at 0.5 mm into JSON contours.
  await page.selectOption('#scheme', PARAMS.scheme);
  await page.fill('#levels', PARAMS.levels);
  await page.fill('#crease_angle', PARAMS.crease_angle);
  await page.fill('#adaptive_tol', '');
  await page.check('#slice-on');
  await page.fill('#layer_height', LAYER_HEIGHT);
  await page.selectOption('#slice_format', 'json');
  const submitted = Date.now();
  await page.click('#submit');
  await page.waitForSelector('body[data-state="done"]', { timeout: 30_000 });
  log(`job done ${((Date.now() - submitted) / 1000).toFixed(1)} s after submit`);
  check(await page.isHidden('#error'), 'no error is shown');
  const id = await page.getAttribute('body', 'data-job');

  await page.waitForSelector('#view3d[data-after]');
  const drawn = await countDrawn(page, '#view3d');
  check(drawn.left > drawn.pixels * 0.01 && drawn.right > drawn.pixels * 0.01,
    `the 3D view drew the part before (${drawn.left} px) and after (${drawn.right} px) of ${drawn.pixels}`);
  log(await page.textContent('#view-info'));
  const part = await page.textContent('#part-info');
  check(/^Part size: [\d.,]+ × [\d.,]+ × [\d.,]+ mm\. Units: mm, assumed\.$/.test(part), `the part's size and units are shown: "${part}"`);

  // The layer view: keyboard on the slider; the middle layer has loops and pixels.
  await page.waitForSelector('#layer-canvas[data-loops]');
  const contours = await (await fetch(`${base}/v1/jobs/${id}/contours.json`)).json();
  await page.focus('#layer');
  await page.keyboard.press('Home');
  check((await page.textContent('#layer-label')).startsWith(`1 of ${contours.layers.length}`), `Home shows layer 1 of ${contours.layers.length}`);
  await page.keyboard.press('ArrowRight');
  check((await page.textContent('#layer-label')).startsWith('2 of'), 'ArrowRight shows layer 2');
  const middle = Math.floor(contours.layers.length / 2);
  await page.$eval('#layer', (el, k) => { el.value = String(k); el.dispatchEvent(new Event('input')); }, middle);
  const loops = Number(await page.getAttribute('#layer-canvas', 'data-loops'));
  const layerPixels = await countDrawn(page, '#layer-canvas');
  check(loops > 0 && loops === contours.layers[middle].polygons.length + (contours.layers[middle].open || []).length,
    `layer ${middle + 1} shows its ${loops} loops (${await page.textContent('#layer-info')})`);
  check(layerPixels.left + layerPixels.right > layerPixels.pixels * 0.01, `the layer canvas drew them (${layerPixels.left + layerPixels.right} px)`);

  // Downloads: the link's bytes are the API's bytes and a synchronous refine's bytes.
  const names = await page.$$eval('#downloads a', (as) => as.map((a) => a.textContent));
  check(['result.stl', 'contours.json', 'report.json'].every((n) => names.includes(n)), `download links: ${names.join(', ')}`);
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#downloads a[download="result.stl"]')]);
  const downloaded = fs.readFileSync(await download.path());
  const fromJob = Buffer.from(await (await fetch(`${base}/v1/jobs/${id}/result.stl`)).arrayBuffer());
  const sync = await fetch(`${base}/v1/refine?${new URLSearchParams(PARAMS)}`, {
    method: 'POST', headers: { 'Content-Type': 'model/stl' }, body: mesh,
  });
  const fromRefine = Buffer.from(await sync.arrayBuffer());
  // Named by the server after the uploaded file (Content-Disposition).
  check(download.suggestedFilename() === 'torus_refined.stl', `the download is called torus_refined.stl (${download.suggestedFilename()})`);
  check(downloaded.length > 84 && downloaded.equals(fromJob), `the downloaded result.stl (${downloaded.length} bytes) is GET /v1/jobs/{id}/result.stl`);
  check(sync.status === 200 && downloaded.equals(fromRefine), 'and a synchronous POST /v1/refine of the same parameters');

  fs.mkdirSync(args.artifacts, { recursive: true });
  const shot = path.join(args.artifacts, 'web.png');
  await page.screenshot({ path: shot, fullPage: true });
  log(`screenshot: ${shot}`);

  // The job's own contours in every other format: the same layers and loops as the JSON.
  for (const format of ['cli', 'cli-binary', 'svg']) {
    await page.selectOption('#slice_format', format);
    await page.click('#submit');
    await page.waitForSelector(`#layer-canvas[data-source="${format}"]`, { timeout: 30_000 });
    await page.$eval('#layer', (el, k) => { el.value = String(k); el.dispatchEvent(new Event('input')); }, middle);
    const label = await page.textContent('#layer-label');
    const n = Number(await page.getAttribute('#layer-canvas', 'data-loops'));
    check(label.startsWith(`${middle + 1} of ${contours.layers.length}`) && n === loops,
      `${format} contours: layer ${label}, ${n} loops as in contours.json (${await page.textContent('#layer-info')})`);
  }
  check(!requested.some((u) => u.includes('/v1/slice')), 'the page never uploads the result again to /v1/slice');
  check(!requested.some((u) => /[?&]slice=/.test(u)) && requested.some((u) => /[?&]layer_height=/.test(u)),
    'the page sends layer_height, never the deprecated slice');

  // Files the server refuses: the problem's detail is shown, nothing breaks.
  const refusals = [
    { name: 'broken.3mf', bytes: Buffer.from('PK\x03\x04 this is not a zip at all', 'latin1'), says: 'not a readable zip' },
    { name: 'photo.png', bytes: Buffer.from('\x89PNG\r\n\x1a\n this is no mesh', 'latin1'), says: 'STL' },
  ];
  for (const r of refusals) {
    await page.setInputFiles('#file', { name: r.name, mimeType: 'application/octet-stream', buffer: r.bytes });
    await page.waitForFunction((name) => document.getElementById('file-info').textContent.startsWith(name), r.name);
    await page.click('#submit');
    await page.waitForSelector('#error:not([hidden])', { timeout: 30_000 });
    const text = (await page.textContent('#error')).trim().replace(/\s+/g, ' ');
    check(text.includes(r.says) && !/TypeError|RangeError|undefined/.test(text), `${r.name}: the error shows the server's detail: "${text}"`);
    log(`${r.name}: ${await page.textContent('#view-info')}`);
  }

  // A 3MF (the torus, as the daemon writes it): not drawn before, drawn after, its
  // declared unit said.
  const threeMf = await fetch(`${base}/v1/refine?levels=0&mesh_format=3mf&units=mm`, {
    method: 'POST', headers: { 'Content-Type': 'model/stl' }, body: mesh,
  });
  check(threeMf.status === 200, `the daemon writes the torus as 3MF (${threeMf.status})`);
  await page.setInputFiles('#file', { name: 'torus.3mf', mimeType: 'model/3mf', buffer: Buffer.from(await threeMf.arrayBuffer()) });
  await page.waitForFunction(() => document.getElementById('file-info').textContent.startsWith('torus.3mf'));
  const before3mf = await page.textContent('#view-info');
  await page.fill('#levels', '1');
  await page.check('#slice-on');
  await page.selectOption('#slice_format', 'json');
  await page.click('#submit');
  await page.waitForSelector('#view3d[data-after]', { timeout: 30_000 });
  const part3mf = await page.textContent('#part-info');
  check(before3mf.includes('3MF file is drawn here only once refined') && /After: 4,096 triangles/.test(await page.textContent('#view-info')) &&
    part3mf.includes('declared by the file (millimeter)'), `a 3MF: "${before3mf}", then drawn; "${part3mf}"`);

  // A 1 M triangle part refined one level into 4 M triangles. (Not a 4 M triangle upload:
  // playwright copies every request body the page sends into one string, and 200 MB is over
  // node's string limit.)
  const big = path.join(dataDir, 'big.stl');
  const triangles = 4 * writeTorus(big, 1000, 500);
  // Every stall of the main thread over 200 ms: [when, how long] (ms).
  await page.evaluate(() => {
    window.stalls = [];
    let last = performance.now();
    setInterval(() => {
      const t = performance.now();
      if (t - last > 200) window.stalls.push([Math.round(last), Math.round(t - last)]);
      last = t;
    }, 20);
  });
  const mark = (what) => page.evaluate((w) => window.stalls.push([Math.round(performance.now()), w]), what);
  await page.setInputFiles('#file', big);
  await page.waitForFunction(() => /decimated preview/.test(document.getElementById('view-info').textContent), null, { timeout: 60_000 });
  log(await page.textContent('#view-info'));
  await mark('submit');
  await page.fill('#levels', '1');
  await page.fill('#crease_angle', '');
  await page.uncheck('#slice-on');
  await page.click('#submit');
  await page.waitForSelector('#view3d[data-shown]', { timeout: 150_000 });
  const previewed = Number(await page.getAttribute("#view3d", "data-shown"));
  const after = await page.textContent('#view-info');
  check(Number(await page.getAttribute('#view3d', 'data-after')) === triangles && previewed > 10_000 && previewed <= 250_000 &&
    after.includes(`After: ${triangles.toLocaleString('en-US')} triangles, drawn as a decimated preview of`),
  `the ${triangles.toLocaleString('en-US')} triangle result is drawn as a preview of ${previewed}: "${after}"`);
  const bigDrawn = await countDrawn(page, '#view3d');
  check(bigDrawn.left > bigDrawn.pixels * 0.01 && bigDrawn.right > bigDrawn.pixels * 0.01, `and drawn (${bigDrawn.left} px before, ${bigDrawn.right} px after)`);
  const stalls = await page.evaluate(() => window.stalls);
  const gap = Math.max(0, ...stalls.map((s) => (typeof s[1] === 'number' ? s[1] : 0)));
  check(gap < 2000, `the page kept answering: longest main-thread stall ${gap} ms (< 2000); stalls [at ms, ms]: ${JSON.stringify(stalls)}`);
  check(await page.$eval('#downloads', (d) => Boolean(d.querySelector('a[download="result.stl"]'))), 'the full result.stl is still offered for download');

  // Chromium logs every answer >= 400 as a console error: the 400 and the two 422s asked
  // for above are fine.
  for (const status of [400, 422, 422]) {
    const expected = consoleErrors.findIndex((m) => new RegExp(`Failed to load resource: .* ${status}`).test(m));
    if (expected >= 0) consoleErrors.splice(expected, 1);
  }
  check(consoleErrors.length === 0, `no other console errors${consoleErrors.length ? `: ${consoleErrors.join(' | ')}` : ''}`);
}

let code = 0;
try {
  await main();
} catch (err) {
  log(`FAIL ${err.stack || err}`);
  if (consoleErrors.length) log(`the page's console errors: ${consoleErrors.join(' | ')}`);
  failed++;
}
await cleanup();
clearTimeout(watchdog);
console.log(`${passed} passed, ${failed} failed`);
code = failed === 0 ? 0 : 1;
process.exit(code);
