// The layer view: one layer of the job's contours (read by contours.js from whichever format
// the job wrote) at a time on a 2D canvas, seen from above (+z), picked with a range slider.
const FILL = '#d9e4f2';
const LINE = '#1f5fae';
const OPEN = '#c0392b';
const BACKGROUND = '#f4f5f7';

function fmt(x, digits = 3) {
  return Number.isFinite(x) ? String(Number(x.toFixed(digits))) : '?';
}

export class LayerView {
  constructor(canvas, slider, label, info) {
    Object.assign(this, { canvas, slider, label, info, doc: null });
    slider.addEventListener('input', () => this.draw());
    new ResizeObserver(() => this.draw()).observe(canvas);
    this.clear();
  }

  clear(message = 'No contours yet.') {
    this.doc = null;
    this.slider.disabled = true;
    this.slider.max = 0;
    this.slider.value = 0;
    this.label.textContent = 'none';
    this.info.textContent = message;
    delete this.canvas.dataset.loops;
    this.draw();
  }

  load(doc) {
    const n = Array.isArray(doc.layers) ? doc.layers.length : 0;
    if (n === 0) return this.clear('The slice has no layers.');
    this.doc = doc;
    this.slider.max = n - 1;
    this.slider.value = Math.floor((n - 1) / 2);
    this.slider.disabled = false;
    this.draw();
  }

  draw() {
    const { canvas } = this;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, canvas.clientWidth);
    const h = Math.max(1, canvas.clientHeight);
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
    const ctx = canvas.getContext('2d');
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = BACKGROUND;
    ctx.fillRect(0, 0, w, h);
    if (!this.doc) return;

    const layers = this.doc.layers;
    const k = Number(this.slider.value);
    const layer = layers[k];
    const polygons = layer.loops.filter((l) => l.type !== 'open');
    const open = layer.loops.filter((l) => l.type === 'open');

    // The part's xy bounds fill the canvas (same scale in x and y), y up.
    const b = this.doc.bounds;
    const spanX = Math.max(b.max[0] - b.min[0], 1e-9);
    const spanY = Math.max(b.max[1] - b.min[1], 1e-9);
    const margin = 12;
    const scale = Math.min((w - 2 * margin) / spanX, (h - 2 * margin) / spanY);
    const ox = (w - spanX * scale) / 2;
    const oy = (h - spanY * scale) / 2;
    // Points are flat [x0, y0, x1, y1, ...] (Float32Array).
    const trace = (target, pts) => {
      for (let i = 0; i < pts.length; i += 2) {
        const x = ox + (pts[i] - b.min[0]) * scale;
        const y = h - oy - (pts[i + 1] - b.min[1]) * scale;
        if (i === 0) target.moveTo(x, y);
        else target.lineTo(x, y);
      }
    };

    const path = new Path2D();
    for (const poly of polygons) {
      trace(path, poly.points);
      path.closePath();
    }
    ctx.fillStyle = FILL;
    ctx.fill(path, 'evenodd'); // holes stay holes
    ctx.strokeStyle = LINE;
    ctx.lineWidth = 1.5;
    ctx.stroke(path);
    ctx.strokeStyle = OPEN;
    for (const line of open) {
      ctx.beginPath();
      trace(ctx, line.points);
      ctx.stroke();
    }

    const outer = polygons.filter((p) => p.type === 'outer').length;
    const holes = polygons.length - outer;
    this.label.textContent = `${k + 1} of ${layers.length}, z = ${fmt(layer.z)} mm`;
    let text = `${outer} outer loop${outer === 1 ? '' : 's'}, ${holes} hole${holes === 1 ? '' : 's'}`;
    if (Number.isFinite(layer.area)) text += `, area ${fmt(layer.area, 2)} mm²`;
    if (open.length) text += `, ${open.length} open polyline${open.length === 1 ? '' : 's'} (red: the mesh is not closed here)`;
    this.info.textContent = text + '.';
    this.canvas.setAttribute('aria-label', `Layer ${k + 1} at z = ${fmt(layer.z)} mm: ${text}`);
    this.canvas.dataset.loops = String(polygons.length + open.length);
  }
}
