// A 3D view of the followed vessel with three.js: the Otter (a 2 m
// catamaran) on a north-up water grid, turned to its heading, each propeller
// coloured by its status with a thrust arrow scaled by its shaft speed and
// effectiveness (1 - loss), and the estimated water current as an arrow.
// Renders only when something changed, at most 10 times a second (5 when
// WebGL is drawn on the CPU, as in headless Chromium without a GPU).

import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { STATUS_COLOUR, text, f1 } from './svg.js';
import { toDeg } from './geo.js';

/** Whether WebGL works here, and whether it is drawn on the CPU (no GPU:
 *  SwiftShader, llvmpipe), where the view draws less often and plainer. */
function probeWebgl() {
  try {
    const c = document.createElement('canvas');
    const gl = c.getContext('webgl2') || c.getContext('webgl');
    if (!gl) return { ok: false, software: false };
    const ext = gl.getExtension('WEBGL_debug_renderer_info');
    const name = ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
    gl.getExtension('WEBGL_lose_context')?.loseContext();
    return { ok: true, software: /swiftshader|llvmpipe|softpipe|software/i.test(String(name)), name: String(name) };
  } catch {
    return { ok: false, software: false };
  }
}

export class View3d {
  constructor(root, caption, store, wanted = true) {
    this.root = root;
    this.caption = caption;
    this.store = store;
    const gl = wanted ? probeWebgl() : { ok: false, software: false };
    this.ok = gl.ok;
    root.dataset.webgl = this.ok ? (gl.software ? 'software' : 'yes') : 'no';
    // At most 10 redraws a second on a GPU, 5 when drawn on the CPU.
    this.minIntervalMs = gl.software ? 200 : 100;
    if (!this.ok) {
      const p = document.createElement('p');
      p.className = 'empty';
      p.textContent = wanted ? 'The 3D view needs WebGL, which this browser does not offer.' : 'The 3D view is off (#3d=off in the address).';
      root.appendChild(p);
      return;
    }
    const renderer = new THREE.WebGLRenderer({ antialias: !gl.software });
    renderer.setPixelRatio(gl.software ? 1 : Math.min(2, window.devicePixelRatio || 1));
    root.appendChild(renderer.domElement);
    renderer.domElement.dataset.testid = 'view3d-canvas';
    this.renderer = renderer;
    const scene = new THREE.Scene();
    scene.background = new THREE.Color('#0d1b2a');
    scene.fog = new THREE.Fog('#0d1b2a', 14, 40);
    this.scene = scene;
    // World: x east, y up, z south (north is -z).
    const camera = new THREE.PerspectiveCamera(40, 1, 0.1, 200);
    camera.position.set(-3.2, 2.6, 4.2);
    this.camera = camera;
    const controls = new OrbitControls(camera, renderer.domElement);
    controls.target.set(0, 0.2, 0);
    controls.maxPolarAngle = Math.PI * 0.48;
    controls.minDistance = 3;
    controls.maxDistance = 30;
    controls.addEventListener('change', () => this.store.dirty.add('view3d'));
    this.controls = controls;

    scene.add(new THREE.HemisphereLight('#cfe8ff', '#203040', 1.6));
    const sun = new THREE.DirectionalLight('#ffffff', 1.4);
    sun.position.set(5, 10, 4);
    scene.add(sun);

    const water = new THREE.Mesh(new THREE.CircleGeometry(40, 64), new THREE.MeshLambertMaterial({ color: '#12324d' }));
    water.rotation.x = -Math.PI / 2;
    scene.add(water);
    const grid = new THREE.GridHelper(40, 40, '#2f5d80', '#1d4263');
    grid.position.y = 0.005;
    scene.add(grid);
    // North marker on the water.
    const north = new THREE.Mesh(new THREE.ConeGeometry(0.35, 1.0, 3), new THREE.MeshBasicMaterial({ color: '#e6edf3' }));
    north.rotation.x = -Math.PI / 2;
    north.position.set(0, 0.02, -6);
    scene.add(north);

    // The Otter: two hulls 2.0 m long, 0.8 m apart, a deck, a mast.
    const boat = new THREE.Group();
    const hullMat = new THREE.MeshLambertMaterial({ color: '#f2c12e' });
    for (const y of [-0.4, 0.4]) {
      const hull = new THREE.Mesh(new THREE.CapsuleGeometry(0.14, 1.7, 6, 12), hullMat);
      hull.rotation.x = Math.PI / 2;
      hull.position.set(y, 0.1, 0);
      boat.add(hull);
    }
    const deck = new THREE.Mesh(new THREE.BoxGeometry(0.95, 0.08, 1.1), new THREE.MeshLambertMaterial({ color: '#3a4654' }));
    deck.position.set(0, 0.3, 0.05);
    boat.add(deck);
    const mast = new THREE.Mesh(new THREE.CylinderGeometry(0.03, 0.03, 0.7), new THREE.MeshLambertMaterial({ color: '#c9d1d9' }));
    mast.position.set(0, 0.65, -0.25);
    boat.add(mast);
    const antenna = new THREE.Mesh(new THREE.CylinderGeometry(0.09, 0.09, 0.05, 16), new THREE.MeshLambertMaterial({ color: '#e6edf3' }));
    antenna.position.set(0, 1.0, -0.25);
    boat.add(antenna);
    const bow = new THREE.Mesh(new THREE.ConeGeometry(0.12, 0.3, 12), new THREE.MeshBasicMaterial({ color: '#e6edf3' }));
    bow.rotation.x = -Math.PI / 2;
    bow.position.set(0, 0.38, -0.55);
    boat.add(bow);
    // Propellers (port is x = -0.4 with the bow toward -z) and thrust arrows.
    this.props = {};
    for (const [side, x] of [['port', -0.4], ['starboard', 0.4]]) {
      const mat = new THREE.MeshLambertMaterial({ color: STATUS_COLOUR.not_excited, emissive: '#000000' });
      const pod = new THREE.Mesh(new THREE.CylinderGeometry(0.09, 0.09, 0.22, 16), mat);
      pod.rotation.x = Math.PI / 2;
      pod.position.set(x, -0.05, 0.95);
      boat.add(pod);
      const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(x, -0.05, 1.08), 1, STATUS_COLOUR.not_excited, 0.2, 0.12);
      boat.add(arrow);
      this.props[side] = { mat, arrow };
    }
    scene.add(boat);
    this.boat = boat;
    this.current = new THREE.ArrowHelper(new THREE.Vector3(1, 0, 0), new THREE.Vector3(-3, 0.05, 3), 1, '#7ee0ff', 0.25, 0.15);
    scene.add(this.current);
    this.size = [0, 0];
    this.lastDraw = 0;
  }

  render(now) {
    if (!this.ok) return false;
    if (now - this.lastDraw < this.minIntervalMs) return false;
    this.lastDraw = now;
    const w = this.root.clientWidth;
    const h = this.root.clientHeight;
    if (w !== this.size[0] || h !== this.size[1]) {
      this.size = [w, h];
      this.renderer.setSize(w, h, false);
      this.renderer.domElement.style.width = `${w}px`;
      this.renderer.domElement.style.height = `${h}px`;
      this.camera.aspect = w / Math.max(1, h);
      this.camera.updateProjectionMatrix();
    }
    const v = this.store.vessels.get(this.store.followed);
    const s = v?.state;
    const f = v?.fault;
    const hdg = s ? (s.heading_rad ?? s.cog_rad) : 0;
    // Heading psi clockwise from north: the bow (-z) turns toward +x.
    this.boat.rotation.y = -hdg;
    const rpm = v?.actuators?.rpm;
    for (const side of ['port', 'starboard']) {
      const t = f?.thrusters?.[side];
      const status = f?.model === 'kinetic' ? (t?.status ?? 'not_excited') : 'not_excited';
      const colour = new THREE.Color(STATUS_COLOUR[status]);
      const p = this.props[side];
      p.mat.color = colour;
      p.mat.emissive = colour.clone().multiplyScalar(status === 'fault' ? 0.6 : 0.15);
      const eff = f?.model === 'kinetic' && Number.isFinite(t?.loss) ? 1 - t.loss : 1;
      const n = rpm ? Math.abs(rpm[side]) / 1000 : 0.7;
      const len = Math.max(0.15, 1.4 * eff * n * n);
      p.arrow.setColor(colour);
      p.arrow.setLength(len, Math.min(0.25, len * 0.4), 0.12);
    }
    const c = s?.current;
    this.current.visible = !!c;
    if (c) {
      // toward north/east -> (x = east, z = -north).
      this.current.setDirection(new THREE.Vector3(c.east_mps, 0, -c.north_mps).normalize());
      this.current.setLength(Math.max(0.3, 8 * c.speed_mps), 0.25, 0.15);
    }
    this.controls.update();
    this.renderer.render(this.scene, this.camera);
    text(
      this.caption,
      s
        ? `heading ${f1(toDeg(hdg))}°${s.heading_rad == null ? ' (course: no heading sensor)' : ''} · SOG ${f1(s.sog_mps)} m/s${c ? ` · current ${c.speed_mps.toFixed(2)} m/s → ${c.toward_deg.toFixed(0)}°` : ''} · drag to orbit`
        : 'no vessel',
    );
    this.caption.dataset.heading = s ? String(toDeg(hdg)) : '';
    return true;
  }
}
