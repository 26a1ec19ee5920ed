// The 3D view: the part before refinement (left half of the canvas) and after (right
// half), drawn by three.js with one camera, so both sides turn and zoom together.
import {
  BufferAttribute,
  BufferGeometry,
  Color,
  DirectionalLight,
  HemisphereLight,
  Mesh,
  MeshBasicMaterial,
  MeshStandardMaterial,
  PerspectiveCamera,
  Scene,
  Vector3,
  WebGLRenderer,
} from './three.module.js';
import { OrbitControls } from './OrbitControls.js';
import { STLLoader } from './STLLoader.js';

export const BACKGROUND = 0xf4f5f7;
const COLOURS = [0x8a9bb0, 0xd08a3c]; // before: grey-blue, after: orange

export class PartView {
  constructor(canvas) {
    this.canvas = canvas;
    // preserveDrawingBuffer: the picture stays readable after it was shown (screenshots,
    // the end-to-end test reading pixels back).
    this.renderer = new WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.renderer.setScissorTest(true);
    this.camera = new PerspectiveCamera(35, 1, 0.01, 1000);
    this.camera.up.set(0, 0, 1); // STL parts stand on z
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener('change', () => this.render());
    this.sides = [0, 1].map((side) => this.makeSide(side));
    this.edges = false;
    this.framed = false;
    new ResizeObserver(() => this.resize()).observe(canvas);
    this.resize();
  }

  makeSide(side) {
    const scene = new Scene();
    scene.background = new Color(BACKGROUND);
    scene.add(new HemisphereLight(0xffffff, 0x707880, 1.5));
    const light = new DirectionalLight(0xffffff, 2.0);
    scene.add(light);
    return { scene, light, mesh: null, colour: COLOURS[side] };
  }

  /** Shows STL bytes (an ArrayBuffer) on side 0 (before) or 1 (after); returns the triangle count. */
  show(side, buffer) {
    return this.showGeometry(side, new STLLoader().parse(buffer));
  }

  /** Shows triangles given as 9 floats each (a preview made in preview.js). */
  showPositions(side, positions) {
    const geometry = new BufferGeometry();
    geometry.setAttribute('position', new BufferAttribute(positions, 3));
    return this.showGeometry(side, geometry);
  }

  showGeometry(side, geometry) {
    const s = this.sides[side];
    this.remove(side);
    const material = new MeshStandardMaterial({
      color: s.colour, flatShading: true, metalness: 0.05, roughness: 0.7,
      polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1,
    });
    s.mesh = new Mesh(geometry, material);
    const wire = new Mesh(geometry, new MeshBasicMaterial({
      color: 0x1d2330, wireframe: true, transparent: true, opacity: 0.35,
    }));
    wire.visible = this.edges;
    s.mesh.add(wire);
    s.scene.add(s.mesh);
    if (side === 0 || !this.framed) this.frame(geometry);
    this.render();
    return geometry.attributes.position.count / 3;
  }

  remove(side) {
    const s = this.sides[side];
    if (!s.mesh) return;
    s.scene.remove(s.mesh);
    s.mesh.geometry.dispose();
    s.mesh.material.dispose();
    s.mesh.children.forEach((c) => c.material.dispose());
    s.mesh = null;
    this.render();
  }

  setEdges(on) {
    this.edges = on;
    for (const s of this.sides) if (s.mesh) s.mesh.children.forEach((c) => { c.visible = on; });
    this.render();
  }

  // Points the camera at the part from the front, a little from the right and above.
  frame(geometry) {
    geometry.computeBoundingSphere();
    const { center, radius } = geometry.boundingSphere;
    const r = radius > 0 ? radius : 1;
    const dir = new Vector3(0.9, -1.6, 1.0).normalize();
    this.camera.position.copy(center).addScaledVector(dir, r * 3.4);
    this.camera.near = r / 100;
    this.camera.far = r * 100;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(center);
    this.controls.update();
    this.framed = true;
  }

  resize() {
    const w = Math.max(2, this.canvas.clientWidth);
    const h = Math.max(1, this.canvas.clientHeight);
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / 2 / h;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  render() {
    const w = Math.max(2, this.canvas.clientWidth);
    const h = Math.max(1, this.canvas.clientHeight);
    const half = Math.floor(w / 2);
    this.sides.forEach((s, side) => {
      // A head lamp: light comes from where one looks (its target stays at the origin).
      s.light.position.copy(this.camera.position).sub(this.controls.target);
      this.renderer.setViewport(side * half, 0, half, h);
      this.renderer.setScissor(side * half, 0, half, h);
      this.renderer.render(s.scene, this.camera);
    });
  }
}
