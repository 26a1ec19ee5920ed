// The job's contour file, whatever format it asked for (slicer/README.md: JSON, SVG, CLI
// ASCII, CLI binary), read into what the layer view draws:
//   { layers: [{ z, area, loops: [{ type: 'outer' | 'hole' | 'open', points: Float32Array
//     [x0, y0, x1, y1, ...] }] }], bounds: { min: [x, y], max: [x, y] },
//     format: 'json' | 'svg' | 'cli' | 'cli-binary' }   (mm)
// A job names both CLI encodings contours.cli: $$BINARY in the header tells them apart.
// Flat typed arrays: a large slice crosses from the worker (preview.js) without a copy of
// every point as an object. A file this cannot read throws an Error saying what and where.

export const CONTOUR_FILES = ['contours.json', 'contours.svg', 'contours.cli'];

export function parseContours(name, buffer) {
  switch (name) {
    case 'contours.json': return { ...fromJson(JSON.parse(new TextDecoder().decode(buffer))), format: 'json' };
    case 'contours.svg': return { ...fromSvg(new TextDecoder().decode(buffer)), format: 'svg' };
    case 'contours.cli': {
      const head = new TextDecoder('latin1').decode(new Uint8Array(buffer, 0, Math.min(buffer.byteLength, 64 * 1024)));
      const end = head.indexOf('$$HEADEREND');
      if (end >= 0 && head.slice(0, end).includes('$$BINARY')) return { ...fromCliBinary(buffer), format: 'cli-binary' };
      return { ...fromCli(new TextDecoder().decode(buffer)), format: 'cli' };
    }
    default: throw new Error(`${name} is not a contour file the page can read`);
  }
}

// Twice the signed area of a closed ring (counter-clockwise > 0).
function signedArea(points) {
  let a = 0;
  const n = points.length / 2;
  for (let i = 0, j = n - 1; i < n; j = i++) a += points[2 * j] * points[2 * i + 1] - points[2 * i] * points[2 * j + 1];
  return a / 2;
}

// Adds the bounds of every layer; a file without points gets a unit square.
function withBounds(layers) {
  const min = [Infinity, Infinity];
  const max = [-Infinity, -Infinity];
  for (const layer of layers) {
    for (const loop of layer.loops) {
      const p = loop.points;
      for (let i = 0; i < p.length; i += 2) {
        if (p[i] < min[0]) min[0] = p[i];
        if (p[i] > max[0]) max[0] = p[i];
        if (p[i + 1] < min[1]) min[1] = p[i + 1];
        if (p[i + 1] > max[1]) max[1] = p[i + 1];
      }
    }
  }
  if (!(min[0] <= max[0])) return { layers, bounds: { min: [0, 0], max: [1, 1] } };
  return { layers, bounds: { min, max } };
}

// A closed loop's type from its winding (the writers orient outers counter-clockwise).
function closed(points) {
  return { type: signedArea(points) >= 0 ? 'outer' : 'hole', points };
}

function fromJson(doc) {
  if (!doc || !Array.isArray(doc.layers)) throw new Error('contours.json has no "layers" list');
  const flat = (pts) => Float32Array.from(pts.flat());
  return withBounds(doc.layers.map((layer) => ({
    z: layer.z,
    area: layer.area,
    loops: [
      ...(layer.polygons || []).map((p) => ({ type: p.type === 'hole' ? 'hole' : 'outer', points: flat(p.points) })),
      ...(layer.open || []).map((p) => ({ type: 'open', points: flat(p.points) })),
    ],
  })));
}

const NUMBER = /[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?/g;

// Our SVG writer: one <g class="layer" data-z=...> per layer, its loops one <path d="M..L..Z">
// (absolute commands only), open polylines as <polyline points="x,y ...">.
function fromSvg(text) {
  const layers = [];
  const groups = text.split(/<g\s/).slice(1);
  for (const g of groups) {
    const z = /data-z="([^"]*)"/.exec(g);
    if (!/class="layer"/.test(g) || !z) continue;
    const loops = [];
    for (const m of g.matchAll(/<path[^>]*\sd="([^"]*)"/g)) {
      for (const ring of m[1].split(/[Zz]/)) {
        if (/[^MLml\s\d.eE+,-]/.test(ring)) throw new Error('contours.svg: a path command other than M, L, Z');
        const nums = (ring.match(NUMBER) || []).map(Number);
        if (nums.length >= 6) loops.push(closed(Float32Array.from(nums)));
      }
    }
    for (const m of g.matchAll(/<polyline[^>]*\spoints="([^"]*)"/g)) {
      loops.push({ type: 'open', points: Float32Array.from((m[1].match(NUMBER) || []).map(Number)) });
    }
    layers.push({ z: Number(z[1]), loops });
  }
  if (!layers.length && !/<svg[\s>]/.test(text)) throw new Error('contours.svg is not an SVG');
  return withBounds(layers);
}

// A polyline of CLI 2.0: dir 1 = outer, 0 = hole, 2 = open; closed ones repeat their start.
function cliLoop(dir, coords) {
  if (dir === 2) return { type: 'open', points: coords };
  const points = coords.length >= 4 && coords[0] === coords[coords.length - 2] && coords[1] === coords[coords.length - 1]
    ? coords.subarray(0, coords.length - 2) : coords;
  return { type: dir === 0 ? 'hole' : 'outer', points };
}

// $$UNITS/u: coordinates are in units of u mm.
function cliUnits(header) {
  const m = /\$\$UNITS\/\s*([^\s/]+)/.exec(header);
  const u = m ? Number(m[1]) : 1;
  if (!(u > 0)) throw new Error(`CLI: $$UNITS/${m && m[1]} is not a positive number`);
  return u;
}

function fromCli(text) {
  const end = text.indexOf('$$HEADEREND');
  if (!text.startsWith('$$HEADERSTART') || end < 0) throw new Error('contours.cli has no $$HEADERSTART ... $$HEADEREND');
  const u = cliUnits(text.slice(0, end));
  const layers = [];
  let lineNo = text.slice(0, end).split('\n').length;
  for (const line of text.slice(end).split('\n').slice(1)) {
    lineNo++;
    const t = line.trim();
    if (t.startsWith('$$LAYER/')) {
      layers.push({ z: Number(t.slice(8)) * u, loops: [] });
    } else if (t.startsWith('$$POLYLINE/')) {
      const v = t.slice(11).split(',').map(Number);
      const n = v[2];
      if (!layers.length || v.length !== 3 + 2 * n || v.some((x) => !Number.isFinite(x))) {
        throw new Error(`contours.cli line ${lineNo}: a $$POLYLINE this page cannot read`);
      }
      layers[layers.length - 1].loops.push(cliLoop(v[1], Float32Array.from(v.slice(3), (x) => x * u)));
    }
  }
  return withBounds(layers);
}

function fromCliBinary(buffer) {
  const bytes = new Uint8Array(buffer);
  const marker = '$$HEADEREND';
  const head = new TextDecoder('latin1').decode(bytes.subarray(0, Math.min(bytes.length, 64 * 1024)));
  const end = head.indexOf(marker);
  if (!head.startsWith('$$HEADERSTART') || end < 0) throw new Error('contours.cli (binary) has no $$HEADERSTART ... $$HEADEREND');
  const u = cliUnits(head.slice(0, end));
  const view = new DataView(buffer);
  const layers = [];
  let at = end + marker.length;
  const need = (n) => {
    if (at + n > buffer.byteLength) throw new Error(`contours.cli (binary) ends inside a command at byte ${at}`);
  };
  while (at < buffer.byteLength) {
    need(2);
    const command = view.getUint16(at, true);
    at += 2;
    if (command === 127) { // start layer: z
      need(4);
      layers.push({ z: view.getFloat32(at, true) * u, loops: [] });
      at += 4;
    } else if (command === 130) { // polyline: id, dir, n, n (x, y)
      need(12);
      const dir = view.getInt32(at + 4, true);
      const n = view.getInt32(at + 8, true);
      at += 12;
      if (n < 0 || !layers.length) throw new Error(`contours.cli (binary): a bad polyline at byte ${at - 14}`);
      need(8 * n);
      const coords = new Float32Array(2 * n);
      for (let i = 0; i < 2 * n; i++) coords[i] = view.getFloat32(at + 4 * i, true) * u;
      at += 8 * n;
      layers[layers.length - 1].loops.push(cliLoop(dir, coords));
    } else {
      throw new Error(`contours.cli (binary): command ${command} at byte ${at - 2} is not one this page reads`);
    }
  }
  return withBounds(layers);
}
