// A module worker: the heavy reading the page must not do on its main thread (a 4 M
// triangle result is 200 MB of STL), so that the page stays responsive while it runs.
//  {kind: 'mesh', url | buffer, headers, cap} -> {positions (Float32Array, 9 per triangle),
//    triangles (in the file), shown (in the preview)}: a binary STL of more than `cap`
//    triangles is decimated by vertex clustering (corners snapped to a grid, averaged per
//    cell; triangles that collapse or repeat are dropped), finer grids first.
//  {kind: 'contours', url, name, headers} -> the layer view's document (contours.js).
// Failures answer {error: {title, detail, status}}: the server's problem when it sent one.
import { parseContours } from './contours.js';

async function fetchBytes(url, headers) {
  let res;
  try {
    res = await fetch(url, { headers });
  } catch (err) {
    throw { title: 'The server cannot be reached', detail: err.message };
  }
  if (!res.ok) {
    const problem = { status: res.status, title: res.statusText || 'Request failed' };
    const text = await res.text();
    try {
      Object.assign(problem, JSON.parse(text));
    } catch {
      if (text) problem.detail = text.slice(0, 300);
    }
    throw problem;
  }
  return res.arrayBuffer();
}

// The triangle count of a binary STL, or -1 when the bytes are not one (ASCII).
export function binaryStlTriangles(buffer) {
  if (buffer.byteLength < 84) return -1;
  const n = new DataView(buffer).getUint32(80, true);
  return 84 + 50 * n === buffer.byteLength ? n : -1;
}

function decimate(buffer, n, cap) {
  const view = new DataView(buffer);
  const min = [Infinity, Infinity, Infinity];
  const max = [-Infinity, -Infinity, -Infinity];
  for (let t = 0; t < n; t++) {
    for (let c = 0; c < 3; c++) {
      for (let k = 0; k < 3; k++) {
        const v = view.getFloat32(84 + 50 * t + 12 + 12 * c + 4 * k, true);
        if (v < min[k]) min[k] = v;
        if (v > max[k]) max[k] = v;
      }
    }
  }
  const span = Math.max(max[0] - min[0], max[1] - min[1], max[2] - min[2], 1e-9);
  let grid = 512;
  for (;;) {
    const out = cluster(view, n, min, span / grid);
    if (out.shown <= cap || grid <= 16) return out;
    grid = Math.max(16, Math.floor(grid * Math.sqrt(cap / out.shown) * 0.9));
  }
}

// An exact set of unordered vertex triples (open addressing on typed arrays: a JS Set of
// string keys would be slow and large at millions of triangles).
class TripleSet {
  constructor() {
    this.slots = new Int32Array(3 * 65536).fill(-1);
    this.size = 0;
  }

  // Adds {a, b, c}; false when it was there already.
  add(a, b, c) {
    if (2 * (this.size + 1) > this.slots.length / 3) this.grow();
    const lo = Math.min(a, b, c);
    const hi = Math.max(a, b, c);
    const mid = a + b + c - lo - hi;
    return this.insert(this.slots, lo, mid, hi);
  }

  insert(slots, lo, mid, hi) {
    const mask = slots.length / 3 - 1;
    let i = (Math.imul(lo, 73856093) ^ Math.imul(mid, 19349663) ^ Math.imul(hi, 83492791)) & mask;
    for (;; i = (i + 1) & mask) {
      if (slots[3 * i] === -1) {
        slots[3 * i] = lo;
        slots[3 * i + 1] = mid;
        slots[3 * i + 2] = hi;
        this.size++;
        return true;
      }
      if (slots[3 * i] === lo && slots[3 * i + 1] === mid && slots[3 * i + 2] === hi) return false;
    }
  }

  grow() {
    const old = this.slots;
    this.slots = new Int32Array(2 * old.length).fill(-1);
    this.size = 0;
    for (let i = 0; i < old.length; i += 3) if (old[i] !== -1) this.insert(this.slots, old[i], old[i + 1], old[i + 2]);
  }
}

function cluster(view, n, min, cell) {
  const index = new Map(); // grid cell -> preview vertex
  let sums = new Float64Array(3 * 65536);
  let counts = new Uint32Array(65536);
  let vertices = 0;
  const seen = new TripleSet();
  let tris = new Int32Array(3 * 65536);
  let shown = 0;
  const corner = [0, 0, 0];
  for (let t = 0; t < n; t++) {
    for (let c = 0; c < 3; c++) {
      const at = 84 + 50 * t + 12 + 12 * c;
      const x = view.getFloat32(at, true);
      const y = view.getFloat32(at + 4, true);
      const z = view.getFloat32(at + 8, true);
      // Cells per axis stay under 2^16 (grid <= 512): the key is exact.
      const key = (Math.floor((x - min[0]) / cell) * 65536 + Math.floor((y - min[1]) / cell)) * 65536 + Math.floor((z - min[2]) / cell);
      let v = index.get(key);
      if (v === undefined) {
        v = vertices++;
        index.set(key, v);
        if (v === counts.length) {
          const s = new Float64Array(2 * sums.length);
          s.set(sums);
          sums = s;
          const k = new Uint32Array(2 * counts.length);
          k.set(counts);
          counts = k;
        }
      }
      sums[3 * v] += x;
      sums[3 * v + 1] += y;
      sums[3 * v + 2] += z;
      counts[v]++;
      corner[c] = v;
    }
    const [a, b, c] = corner;
    // Collapsed, or the same three cells as an earlier triangle (which keeps its winding).
    if (a === b || b === c || a === c || !seen.add(a, b, c)) continue;
    if (3 * shown + 3 > tris.length) {
      const grown = new Int32Array(2 * tris.length);
      grown.set(tris);
      tris = grown;
    }
    tris.set(corner, 3 * shown++);
  }
  const positions = new Float32Array(9 * shown);
  for (let i = 0; i < 3 * shown; i++) {
    const v = tris[i];
    for (let k = 0; k < 3; k++) positions[3 * i + k] = sums[3 * v + k] / counts[v];
  }
  return { positions, triangles: n, shown };
}

async function mesh(msg) {
  const buffer = msg.buffer || await fetchBytes(msg.url, msg.headers);
  const n = binaryStlTriangles(buffer);
  if (n < 0) throw { title: 'Not a binary STL', detail: 'The preview reads binary STL only.' };
  if (n <= msg.cap) {
    const view = new DataView(buffer);
    const positions = new Float32Array(9 * n);
    for (let t = 0; t < n; t++) {
      for (let i = 0; i < 9; i++) positions[9 * t + i] = view.getFloat32(84 + 50 * t + 12 + 4 * i, true);
    }
    return { positions, triangles: n, shown: n };
  }
  return decimate(buffer, n, msg.cap);
}

self.onmessage = async (event) => {
  const msg = event.data;
  try {
    if (msg.kind === 'mesh') {
      const out = await mesh(msg);
      self.postMessage(out, [out.positions.buffer]);
    } else {
      const doc = parseContours(msg.name, await fetchBytes(msg.url, msg.headers));
      const transfer = doc.layers.flatMap((l) => l.loops.map((p) => p.points.buffer));
      self.postMessage(doc, transfer);
    }
  } catch (err) {
    self.postMessage({ error: err instanceof Error ? { title: 'The page cannot read this', detail: err.message } : err });
  }
};
