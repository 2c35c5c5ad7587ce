// 3D replay of recorded motion with three.js (vendored): one connected surface mesh, as VoxCAD
// draws it: each lattice corner on the surface is one vertex, the mean of the corners of the
// voxels that share it (mesh.js, as sim/mesh.py), placed from the recorded centres
// (interpolated between frames); two triangles per exposed face. Active voxels' faces red,
// passive cyan, as in the paper; an active voxel's brightness is its actuation at that moment,
// sin(2 pi f (t - t_settle) + phase), so the phase pattern shows as a travelling shade.
// Units: metres and seconds, z up, the floor (on land) at z = 0.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { meshVertices, neighbours, voxelAxes } from "./mesh.js";
import { defaultWorld, world } from "./worlds.js";

const ACTIVE = new THREE.Color("#e8322b");
const PASSIVE = new THREE.Color("#27c6d9");
const MIN_BRIGHTNESS = 0.25; // of an active voxel fully contracted
// light baked into the faces by their normal (unlit: cheap on CPU-rendered WebGL), as if lit
// from above, front and right: shade of a face facing +x, -x, +y, -y, +z, -z
const SHADES = [0.62, 0.3, 0.26, 0.45, 1.0, 0.18];
const GRID_CELLS = 30; // floor grid, in voxel lengths (at least; more for a large robot)
const GRID_SEGMENT = 5; // cells per drawn segment of a grid line
const MAX_STEP_S = 0.1; // wall time a single tick may advance (after a hidden tab)

/** Actuation signal in [-1, 1] at phase angle `angle` (radians), as sim/kernels.py. */
export function actuation(waveform, angle) {
  if (waveform === "square") return Math.tanh(8 * Math.sin(angle)) / Math.tanh(8);
  if (waveform === "impulse") {
    let u = angle / (2 * Math.PI);
    u -= Math.floor(u);
    return u < 0.2 ? Math.cos((Math.PI * u) / 0.2) : -Math.cos((Math.PI * (u - 0.2)) / 0.8);
  }
  return Math.sin(angle);
}

/** A square grid of `cells` x `cells` cells of side `spacing` in the x-y plane, centred on
 * the origin. Lines are drawn as segments `GRID_SEGMENT` cells long: software WebGL drops a
 * whole line that passes behind the camera, which long lines do once the camera is inside
 * the grid; short segments lose only the piece at the camera. */
function gridSegments(cells, spacing) {
  const half = (cells * spacing) / 2;
  const step = GRID_SEGMENT * spacing;
  const points = [];
  for (let line = 0; line <= cells; line++) {
    const across = -half + line * spacing;
    for (let from = -half; from < half - 1e-9; from += step) {
      const to = Math.min(half, from + step);
      points.push(from, across, 0, to, across, 0, across, from, 0, across, to, 0);
    }
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.Float32BufferAttribute(points, 3));
  return geometry;
}

/** Shade of the triangle whose vertices are out[at..at+9): SHADES blended by the squares of
 * its unit normal's components (they sum to 1). */
function shadeOf(out, at) {
  const ux = out[at + 3] - out[at], uy = out[at + 4] - out[at + 1], uz = out[at + 5] - out[at + 2];
  const wx = out[at + 6] - out[at], wy = out[at + 7] - out[at + 1], wz = out[at + 8] - out[at + 2];
  const n = [uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx];
  const square = n[0] * n[0] + n[1] * n[1] + n[2] * n[2] || 1;
  let shade = 0;
  for (let axis = 0; axis < 3; axis++) shade += ((n[axis] * n[axis]) / square) * SHADES[2 * axis + (n[axis] > 0 ? 0 : 1)];
  return shade;
}

/** Phase (radians) of each recorded voxel, matched by lattice index; 0 where unknown. */
function phasesOf(motion, body) {
  const phase = new Float32Array(motion.voxelCount);
  if (!body) return phase;
  const byIndex = new Map(body.voxels.map(([i, j, k, , p]) => [`${i},${j},${k}`, p]));
  for (let v = 0; v < motion.voxelCount; v++) {
    const key = `${motion.lattice[3 * v]},${motion.lattice[3 * v + 1]},${motion.lattice[3 * v + 2]}`;
    phase[v] = byIndex.get(key) ?? 0;
  }
  return phase;
}

/** Voxel size (m) from the first frame: spread of centres over spread of lattice indices. */
function estimateVoxelSize(motion) {
  let best = 0;
  for (let axis = 0; axis < 3; axis++) {
    let lo = Infinity, hi = -Infinity, loIndex = Infinity, hiIndex = -Infinity;
    for (let v = 0; v < motion.voxelCount; v++) {
      const p = motion.positions[3 * v + axis], i = motion.lattice[3 * v + axis];
      lo = Math.min(lo, p); hi = Math.max(hi, p);
      loIndex = Math.min(loIndex, i); hiIndex = Math.max(hiIndex, i);
    }
    if (hiIndex > loIndex) best = Math.max(best, (hi - lo) / (hiIndex - loIndex));
  }
  return best > 0 ? best : 0.05;
}

/** Centre and radius (m) of the voxel centres of frame `frame`. */
function boundsOf(motion, frame) {
  const box = new THREE.Box3();
  const point = new THREE.Vector3();
  const base = frame * motion.voxelCount * 3;
  for (let v = 0; v < motion.voxelCount; v++) {
    box.expandByPoint(point.fromArray(motion.positions, base + 3 * v));
  }
  return { centre: box.getCenter(new THREE.Vector3()), radius: box.getSize(new THREE.Vector3()).length() / 2 };
}

export class Replay {
  /**
   * @param container element the canvas fills
   * @param motion decodeFrames(...) of GET /individuals/{id}/frames
   * @param body GET /dashboard/api/individuals/{id}/body (null: no phases, size estimated)
   * @param onTick called with the clock ({time, start, end, settling, cycle, cycles, phaseDegrees})
   */
  constructor(container, motion, body, onTick = () => {}) {
    this.motion = motion;
    this.body = body;
    this.onTick = onTick;
    this.speed = 0.5;
    this.playing = false;
    this.follow = true;
    this.start = motion.t[0];
    this.end = motion.t[motion.frameCount - 1];
    this.renderedFrames = 0;
    this.voxelSize = body ? body.voxel_size : estimateVoxelSize(motion);
    this.settle = body ? body.settle_seconds : 0;
    this.omega = body ? 2 * Math.PI * body.frequency : 0;
    this.waveform = body ? body.waveform : "sine";
    // play the evaluated motion: from the end of settling (if any) to the end, in a loop
    this.loopStart = Math.min(Math.max(this.start, this.settle), this.end);
    this.time = this.loopStart;
    this.phase = phasesOf(motion, body);
    this._cursor = 0;
    this._needsRender = true;
    this._last = null;
    this._buildScene(container, body ? body.environment : defaultWorld());
    this.renderer.setAnimationLoop((now) => this._tick(now));
  }

  play() { this.playing = true; if (this.time >= this.end) this.time = this.loopStart; }
  pause() { this.playing = false; this._needsRender = true; }
  setSpeed(speed) { this.speed = speed; }
  setFollow(follow) { this.follow = follow; }
  /** Jump to `fraction` (0..1) of the recording. */
  seek(fraction) { this.time = this.start + fraction * (this.end - this.start); this._needsRender = true; }
  get fraction() { return this.end > this.start ? (this.time - this.start) / (this.end - this.start) : 0; }

  dispose() {
    this.renderer.setAnimationLoop(null);
    this._resize.disconnect();
    this.controls.dispose();
    this.renderer.dispose();
    this.renderer.domElement.remove();
  }

  _buildScene(container, environment) {
    const renderer = new THREE.WebGLRenderer({ antialias: false });
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    container.append(renderer.domElement);
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(world(environment).background);

    const { centre, radius } = boundsOf(this.motion, 0);
    const size = Math.max(radius, 2 * this.voxelSize);
    this._radius = size;
    const camera = new THREE.PerspectiveCamera(40, 1, size / 20, size * 60);
    camera.up.set(0, 0, 1);
    camera.position.copy(centre).add(new THREE.Vector3(1.3, -2.2, 1.25).multiplyScalar(size * 2.1));
    const controls = new OrbitControls(camera, renderer.domElement);
    controls.target.copy(centre);
    controls.update();
    controls.addEventListener("change", () => { this._needsRender = true; });

    this.grid = this._floor(environment, centre);
    if (this.grid) scene.add(this.grid);
    this.mesh = this._surface();
    scene.add(this.mesh);
    Object.assign(this, { renderer, scene, camera, controls, container });
    this._place();
    this._com = this._centreOfMass(new THREE.Vector3());
    this._resize = new ResizeObserver(() => this._fit());
    this._resize.observe(container);
    this._fit();
  }

  /** The floor as a grid in voxel lengths, at z = 0, in a world with a floor; null in one
   * without (water): a grid there would read as a floor the robot swims above. */
  _floor(environment, centre) {
    if (!world(environment).floor) return null;
    const cells = Math.max(GRID_CELLS, 2 * Math.ceil((4 * this._radius) / this.voxelSize));
    const grid = new THREE.LineSegments(gridSegments(cells, this.voxelSize), new THREE.LineBasicMaterial({ color: 0xaab3c2 }));
    grid.position.set(centre.x, centre.y, 0);
    return grid;
  }

  /** The surface mesh: three vertices of its own per triangle (meshFace), so that each
   * triangle keeps its voxel's colour; positions and colours are rewritten every frame. */
  _surface() {
    const { meshFace, meshVert, lattice, voxelCount } = this.motion;
    this.triangleCount = meshFace.length / 4;
    this.nbr = neighbours(lattice, voxelCount);
    this.axes = new Float32Array(9 * voxelCount);
    this.vertices = new Float32Array((meshVert.length / 8) * 3);
    this.shade = new Float32Array(this.triangleCount);
    const geometry = new THREE.BufferGeometry();
    for (const name of ["position", "color"]) {
      const attribute = new THREE.BufferAttribute(new Float32Array(9 * this.triangleCount), 3);
      geometry.setAttribute(name, attribute.setUsage(THREE.DynamicDrawUsage));
    }
    const mesh = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({ vertexColors: true }));
    mesh.frustumCulled = false; // the robot moves away from the geometry's first bounds
    return mesh;
  }

  _fit() {
    const width = this.container.clientWidth || 1, height = this.container.clientHeight || 1;
    this.renderer.setSize(width, height);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
    this._needsRender = true;
  }

  /** Index k with t[k] <= time < t[k+1] (the last frame at the end). */
  _frameAt(time) {
    const t = this.motion.t;
    let k = this._cursor;
    if (!(t[k] <= time && (k + 1 >= t.length || time < t[k + 1]))) {
      let lo = 0, hi = t.length - 1;
      while (lo < hi) {
        const mid = (lo + hi + 1) >> 1;
        if (t[mid] <= time) lo = mid; else hi = mid - 1;
      }
      k = lo;
    }
    this._cursor = k;
    return k;
  }

  /** Interpolated positions of every voxel at this.time into this.current (V*3, m), the
   * mesh's vertices there (this.vertices, M*3), its triangles and their shades. */
  _place() {
    const { positions, voxelCount, t, meshFace, meshVert } = this.motion;
    const k = this._frameAt(this.time);
    const next = Math.min(k + 1, t.length - 1);
    const alpha = next > k ? Math.min(1, Math.max(0, (this.time - t[k]) / (t[next] - t[k]))) : 0;
    const a = k * voxelCount * 3, b = next * voxelCount * 3;
    this.current ??= new Float32Array(voxelCount * 3);
    for (let i = 0; i < voxelCount * 3; i++) {
      this.current[i] = positions[a + i] + alpha * (positions[b + i] - positions[a + i]);
    }
    voxelAxes(this.current, this.nbr, this.voxelSize, voxelCount, this.axes);
    meshVertices(meshVert, this.current, this.axes, this.vertices);
    const drawn = this.mesh.geometry.getAttribute("position");
    const out = drawn.array, vertices = this.vertices;
    for (let n = 0; n < this.triangleCount; n++) {
      for (let corner = 0; corner < 3; corner++) {
        const from = 3 * meshFace[4 * n + corner], to = 9 * n + 3 * corner;
        out[to] = vertices[from]; out[to + 1] = vertices[from + 1]; out[to + 2] = vertices[from + 2];
      }
      this.shade[n] = shadeOf(out, 9 * n);
    }
    drawn.needsUpdate = true;
  }

  /** Triangle colours: the voxel's material, active voxels' brightness from their actuation
   * now, times the triangle's shade. */
  _actuate() {
    const { meshFace, material } = this.motion;
    const colours = this.mesh.geometry.getAttribute("color");
    const actuated = this.time >= this.settle && this.omega > 0;
    const angle = this.omega * (this.time - this.settle);
    for (let n = 0; n < this.triangleCount; n++) {
      const v = meshFace[4 * n + 3];
      let brightness = this.shade[n], base = PASSIVE;
      if (material[v] === 2) {
        const signal = actuated ? actuation(this.waveform, angle + this.phase[v]) : 0;
        brightness *= MIN_BRIGHTNESS + ((1 - MIN_BRIGHTNESS) * (signal + 1)) / 2;
        base = ACTIVE;
      }
      for (let corner = 0; corner < 3; corner++) {
        colours.array[9 * n + 3 * corner] = base.r * brightness;
        colours.array[9 * n + 3 * corner + 1] = base.g * brightness;
        colours.array[9 * n + 3 * corner + 2] = base.b * brightness;
      }
    }
    colours.needsUpdate = true;
  }

  /** Mean of the current voxel centres in x and y (z = 0), metres. */
  _centreOfMass(target) {
    const count = this.motion.voxelCount;
    target.set(0, 0, 0);
    for (let v = 0; v < count; v++) target.x += this.current[3 * v], target.y += this.current[3 * v + 1];
    return target.multiplyScalar(1 / Math.max(1, count));
  }

  /** Keep the robot in view: move camera and target with the centre of mass (x, y only);
   * the grid jumps by whole cells to stay under the robot (its lines stay put in the world). */
  _followRobot() {
    const com = this._centreOfMass(new THREE.Vector3());
    if (this.grid) {
      this.grid.position.x = Math.round(com.x / this.voxelSize) * this.voxelSize;
      this.grid.position.y = Math.round(com.y / this.voxelSize) * this.voxelSize;
    }
    if (this.follow) {
      const shift = com.clone().sub(this._com);
      this.camera.position.add(shift);
      this.controls.target.add(shift);
    }
    this._com = com;
  }

  clock() {
    const cycleTime = this.time - this.settle;
    const settling = cycleTime < 0 || this.omega <= 0;
    const angle = settling ? 0 : this.omega * cycleTime;
    // cycles actuated: whole, or a fraction where the guard on seconds cut the evaluation short
    const exact = this.omega > 0 ? ((this.end - this.settle) * this.omega) / (2 * Math.PI) : 0;
    const cycles = Math.abs(exact - Math.round(exact)) < 0.05 ? Math.round(exact) : Math.round(exact * 10) / 10;
    return {
      time: this.time, start: this.start, end: this.end, settling, cycles,
      cycle: settling ? 0 : Math.min(Math.max(1, Math.ceil(cycles)), Math.floor(angle / (2 * Math.PI)) + 1),
      phaseDegrees: settling ? 0 : ((angle * 180) / Math.PI) % 360,
    };
  }

  _tick(now) {
    const step = this._last === null ? 0 : Math.min(MAX_STEP_S, (now - this._last) / 1000);
    this._last = now;
    if (this.playing) {
      this.time += step * this.speed;
      if (this.time > this.end) this.time = this.loopStart + (this.time - this.end) % Math.max(1e-9, this.end - this.loopStart);
    }
    if (!this.playing && !this._needsRender) return;
    this._place();
    this._actuate();
    this._followRobot();
    this.controls.update();
    this.renderer.render(this.scene, this.camera);
    this._needsRender = false;
    this.renderedFrames += 1;
    this.onTick(this.clock());
  }
}
