// zeroset studio: the page. It talks only to the studio's HTTP API (docs/studio.md): the state
// as JSON, surfaces as binary meshes (ZSM1), the input points as ZSP1.
//
// Coordinates: the server sends positions minus `state.offset` (so that f32 keeps the precision
// of large coordinates); the scene is drawn in those centred coordinates, and the mask is kept as
// integer indices of the restoration grid's cell faces, turned into world coordinates only for
// the API and the corner inputs.

import * as THREE from 'three';
import { OrbitControls } from './OrbitControls.js';

const $ = (id) => document.getElementById(id);
const TOKEN = new URLSearchParams(location.search).get('token') ?? '';
const AXES = ['x', 'y', 'z'];
// The order of THREE.BoxGeometry's material groups.
const FACES = ['+x', '-x', '+y', '-y', '+z', '-z'];
// The thinnest mask the handles make, in cells (a protrusion fixes a layer on each side).
const MIN_CELLS = 3;
// A press that moves less than this (pixels) is a click.
const CLICK_SLOP = 4;

// ---------------------------------------------------------------------------------------------
// Automation hooks (docs/studio.md, "The page's automation hooks")

let resolveReady;
const studio = {
  ready: new Promise((resolve) => { resolveReady = resolve; }),
  frames: [],
  state: null,
};
window.studio = studio;

// ---------------------------------------------------------------------------------------------
// HTTP API

class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

/** A request with the token; throws ApiError with the server's `{"error": …}` sentence. */
async function api(method, path, body) {
  const headers = { 'X-Zeroset-Token': TOKEN };
  const init = { method, headers, cache: 'no-store' };
  if (body !== undefined) {
    headers['Content-Type'] = 'application/json';
    init.body = JSON.stringify(body);
  }
  let response;
  try {
    response = await fetch(path, init);
  } catch (e) {
    throw new ApiError(0, `the studio server cannot be reached (${e.message}); is zeroset studio still running?`);
  }
  if (!response.ok) {
    let message = `${method} /${path}: HTTP ${response.status}`;
    try {
      const answer = await response.json();
      if (answer && typeof answer.error === 'string') message = answer.error;
    } catch { /* not JSON: keep the generic message */ }
    throw new ApiError(response.status, message);
  }
  return response;
}

const getJSON = async (path) => (await api('GET', path)).json();
const postJSON = async (path, body) => (await api('POST', path, body)).json();
/** A binary mesh; `received` is when it arrived (for the round trip's breakdown). */
const fetchMesh = async (method, path, body) => {
  const mesh = parseMesh(await (await api(method, path, body)).arrayBuffer());
  mesh.received = performance.now();
  return mesh;
};

function checkMagic(view, magic) {
  const got = String.fromCharCode(...[0, 1, 2, 3].map((i) => view.getUint8(i)));
  if (got !== magic) throw new Error(`expected a ${magic} answer, got ${JSON.stringify(got)}`);
}

/** ZSM1: magic, u32 J, J bytes of JSON report, u32 V, u32 T, f32 positions, i16 normals, u32 indices. */
function parseMesh(buffer) {
  const view = new DataView(buffer);
  if (buffer.byteLength < 16) throw new Error('truncated mesh');
  checkMagic(view, 'ZSM1');
  const reportLength = view.getUint32(4, true);
  const report = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 8, reportLength)));
  let at = 8 + reportLength;
  const vertices = view.getUint32(at, true);
  const triangles = view.getUint32(at + 4, true);
  at += 8;
  const end = at + 12 * vertices + 6 * vertices + (vertices % 2) * 2 + 12 * triangles;
  if (end !== buffer.byteLength) {
    throw new Error(`mesh of ${vertices} vertices and ${triangles} triangles should be ${end} bytes, got ${buffer.byteLength}`);
  }
  // J is a multiple of 4, so every array below is aligned.
  const positions = new Float32Array(buffer, at, 3 * vertices);
  at += 12 * vertices;
  const normals = new Int16Array(buffer, at, 3 * vertices);
  at += 6 * vertices + (vertices % 2) * 2;
  const indices = new Uint32Array(buffer, at, 3 * triangles);
  return { report, vertices, triangles, positions, normals, indices };
}

/** ZSP1: magic, u32 N, f32 positions. */
function parsePoints(buffer) {
  const view = new DataView(buffer);
  checkMagic(view, 'ZSP1');
  const count = view.getUint32(4, true);
  if (buffer.byteLength !== 8 + 12 * count) throw new Error('truncated point set');
  return new Float32Array(buffer, 8, 3 * count);
}

// ---------------------------------------------------------------------------------------------
// Page state

const page = {
  state: null,            // the last state JSON
  grid: null,             // see setupGrid
  mask: null,             // { lo: [k, k, k], hi: [k, k, k] }: cell-face indices
  face: '-y',             // or null
  alphaTouched: false,    // the user moved the α slider: send its value, not null
  defaultAlpha: null,     // the last report's default_alpha (the field's mean slope)
  alphaDecimals: 6,       // the α sent is rounded to the slider step's decimals
  lastReport: null,       // the report of the surface on screen as "after"
  dirty: false,           // the live surface is a preview not yet applied
  showBefore: false,
  roundTrip: null,        // ms of the last preview's round trip
};

// ---------------------------------------------------------------------------------------------
// Scene

const canvas = $('view');
/**
 * The WebGL renderer's name, and whether it draws on the CPU (SwiftShader, llvmpipe: headless
 * browsers, VMs, remote desktops). There multisampling and high-DPI pixels cost several times
 * the frame, so the studio draws without them to stay live.
 */
function probeRenderer() {
  const gl = document.createElement('canvas').getContext('webgl2');
  const info = gl && gl.getExtension('WEBGL_debug_renderer_info');
  const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : '';
  gl?.getExtension('WEBGL_lose_context')?.loseContext();
  return { name, software: /SwiftShader|llvmpipe|softpipe|Software/i.test(name) };
}
const gpu = probeRenderer();
studio.renderer = gpu;
const renderer = new THREE.WebGLRenderer({ canvas, antialias: !gpu.software });
renderer.setPixelRatio(gpu.software ? 1 : Math.min(window.devicePixelRatio, 2));
renderer.setClearColor(0x15181d);
const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
scene.add(camera);
// A key light that follows the camera (light and target are the camera's children), and a sky.
const keyLight = new THREE.DirectionalLight(0xffffff, 1.9);
keyLight.position.set(0.6, 0.8, 0.2);
keyLight.target.position.set(0, 0, -1);
camera.add(keyLight, keyLight.target);
scene.add(new THREE.HemisphereLight(0xdde6f0, 0x30343a, 0.9));

// The surface is matte: a physically based material with a broad highlight on a GPU; on a CPU
// renderer, where its per-pixel lighting costs most of the frame, Lambert shading (the same
// diffuse light, no highlight).
const surfaceMaterial = gpu.software
  ? new THREE.MeshLambertMaterial({ color: 0xbcc6d2, side: THREE.DoubleSide })
  : new THREE.MeshStandardMaterial({ color: 0xbcc6d2, roughness: 0.6, metalness: 0.0, side: THREE.DoubleSide });
const committedMesh = new THREE.Mesh(new THREE.BufferGeometry(), surfaceMaterial);
const liveMesh = new THREE.Mesh(new THREE.BufferGeometry(), surfaceMaterial);
scene.add(committedMesh, liveMesh);
let pointCloud = null;

// Our pointer handler is registered before OrbitControls' so that grabbing a handle can disable
// the orbit before it starts.
canvas.addEventListener('pointerdown', onPointerDown, { capture: true });
const controls = new OrbitControls(camera, canvas);
controls.addEventListener('change', requestRender);

function geometryOf(mesh) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(mesh.positions, 3));
  geometry.setAttribute('normal', new THREE.BufferAttribute(mesh.normals, 3, true));
  geometry.setIndex(new THREE.BufferAttribute(mesh.indices, 1));
  if (mesh.vertices > 0) geometry.computeBoundingSphere();
  else geometry.boundingSphere = new THREE.Sphere(new THREE.Vector3(), 0);   // nothing left to draw
  return geometry;
}

/** Replaces a mesh's geometry, disposing the old one unless the other mesh still uses it. */
function setGeometry(target, geometry) {
  const old = target.geometry;
  target.geometry = geometry;
  const other = target === liveMesh ? committedMesh : liveMesh;
  if (old !== geometry && old !== other.geometry) old.dispose();
}

function showSurfaces() {
  committedMesh.visible = page.showBefore;
  liveMesh.visible = !page.showBefore;
  const badge = $('showing');
  badge.textContent = page.showBefore ? 'before: committed surface'
    : page.dirty ? 'after: live preview (not applied)' : 'after: committed surface';
  badge.classList.toggle('before', page.showBefore);
  $('before-after').setAttribute('aria-pressed', String(page.showBefore));
  requestRender();
}

/** Points the camera at the field's box from the front, a little above and to the right. */
function resetView() {
  const { lo, hi } = page.grid.sceneBounds;
  const centre = new THREE.Vector3().addVectors(lo, hi).multiplyScalar(0.5);
  const radius = Math.max(lo.distanceTo(hi) / 2, 1e-9);
  const distance = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2)) * 1.05;
  camera.near = radius / 200;
  camera.far = radius * 200;
  camera.position.copy(centre).add(new THREE.Vector3(0.45, 0.35, 1).normalize().multiplyScalar(distance));
  camera.updateProjectionMatrix();
  controls.target.copy(centre);
  controls.minDistance = radius * 0.02;
  controls.maxDistance = radius * 50;
  controls.update();
  page.grid.radius = radius;
  requestRender();
}

function resize() {
  const { clientWidth: width, clientHeight: height } = canvas;
  if (width === 0 || height === 0) return;
  renderer.setSize(width, height, false);
  camera.aspect = width / height;
  camera.updateProjectionMatrix();
  requestRender();
}
new ResizeObserver(resize).observe(canvas);

// Rendering on demand: one frame per change; frames waiting to be recorded in studio.frames are
// pushed in the animation frame after the one that rendered them.
let renderQueued = false;
let framesToRecord = [];

/** Draws the scene in the next animation frame (once, however often it is asked). */
function requestRender() {
  if (renderQueued) return;
  renderQueued = true;
  requestAnimationFrame(renderFrame);
}

studio.redraw = requestRender;

function renderFrame() {
  renderQueued = false;
  scaleHandles();
  renderer.render(scene, camera);
  if (framesToRecord.length === 0) return;
  const drawn = framesToRecord;
  framesToRecord = [];
  requestAnimationFrame(() => drawn.forEach(recordFrame));
}

let frameSeq = 0;
function recordFrame({ trigger, t0, mesh }) {
  const ms = performance.now() - t0;
  // The round trip and its parts: the server's restore + mesh, the whole request (server,
  // transfer, parsing), and the rest (geometry upload, drawing, the frame that shows it).
  const report = mesh.report ?? {};
  studio.frames.push({
    seq: ++frameSeq, trigger, ms, vertices: mesh.vertices, triangles: mesh.triangles,
    server_ms: (report.restore_ms ?? 0) + (report.mesh_ms ?? 0),
    request_ms: mesh.received === undefined ? null : mesh.received - t0,
  });
  if (trigger !== 'load' && trigger !== 'before-after') page.roundTrip = ms;
  updateInfo();
  resolveReady();
}

/** Shows a mesh (committed: as both "before" and "after"; else as the live preview). */
function drawMesh(mesh, { committed, trigger, t0 }) {
  const geometry = geometryOf(mesh);
  if (committed) {
    setGeometry(committedMesh, geometry);
    setGeometry(liveMesh, geometry);
  } else {
    setGeometry(liveMesh, geometry);
  }
  page.lastReport = mesh.report;
  page.dirty = !committed;
  page.stale = false;
  framesToRecord.push({ trigger, t0, mesh });
  showSurfaces();
  updateButtons();
  updateCommands();
  updateInfo();
}

// ---------------------------------------------------------------------------------------------
// The restoration grid and the mask

/** Cell faces of the grid: base + k·spacing, k in kmin ..= kmax (inside the field's box). */
function setupGrid(state) {
  const { counts, first, spacing } = state.grid;
  const [blo, bhi] = state.bounds;
  const base = first.map((f, a) => f - spacing[a] / 2);
  const kmin = base.map((b, a) => Math.max(0, Math.ceil((blo[a] - b) / spacing[a] - 1e-6)));
  const kmax = base.map((b, a) => Math.min(counts[a], Math.floor((bhi[a] - b) / spacing[a] + 1e-6)));
  const offset = state.offset;
  const scene3 = (p) => new THREE.Vector3(...p.map((v, a) => v - offset[a]));
  page.grid = {
    counts, spacing, base, kmin, kmax, blo, bhi, offset,
    sceneBounds: { lo: scene3(blo), hi: scene3(bhi) },
    minCells: kmax.map((k, a) => Math.min(MIN_CELLS, k - kmin[a])),
    digits: spacing.map((s) => Math.min(10, Math.max(0, Math.ceil(-Math.log10(s)) + 1))),
  };
}

/**
 * The world coordinate of cell face k on an axis, kept inside the field's box; rounded to 1e-5
 * of a cell (far from the cell centres, which decide the mask's cells) so that the command lines
 * read 0.1, not 0.10000000000000003.
 */
function faceCoordinate(axis, k) {
  const g = page.grid;
  const exact = g.base[axis] + k * g.spacing[axis];
  const rounded = Number(exact.toFixed(Math.min(g.digits[axis] + 4, 20)));
  return Math.min(g.bhi[axis], Math.max(g.blo[axis], rounded));
}

const nearestFace = (axis, world) => Math.round((world - page.grid.base[axis]) / page.grid.spacing[axis]);
const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));

function maskCorners() {
  const { lo, hi } = page.mask;
  return [lo.map((k, a) => faceCoordinate(a, k)), hi.map((k, a) => faceCoordinate(a, k))];
}

const maskCells = () => page.mask.hi.map((k, a) => k - page.mask.lo[a]);

/** Moves one face of the mask to cell face k, keeping the mask at least minCells thick. */
function setMaskFace(axis, upper, k) {
  const g = page.grid;
  const { lo, hi } = page.mask;
  if (upper) hi[axis] = clamp(k, lo[axis] + g.minCells[axis], g.kmax[axis]);
  else lo[axis] = clamp(k, g.kmin[axis], hi[axis] - g.minCells[axis]);
}

/**
 * The first mask: the middle half of the box across x and z and its top part along y (from 60%
 * of the cells to one cell below the top), with face -y — the way the paper removes the bunny's
 * ears: something on top of the shape, grown from the mask's bottom face.
 */
function defaultMask() {
  const g = page.grid;
  const at = (a, t) => Math.round(g.kmin[a] + t * (g.kmax[a] - g.kmin[a]));
  const lo = [at(0, 0.25), at(1, 0.6), at(2, 0.25)];
  const hi = [at(0, 0.75), g.kmax[1] - Math.max(1, Math.round((g.kmax[1] - g.kmin[1]) / 32)), at(2, 0.75)];
  page.mask = { lo, hi };
  // Enforce the minimum thickness (small grids).
  for (let a = 0; a < 3; a++) setMaskFace(a, true, hi[a]);
  for (let a = 0; a < 3; a++) setMaskFace(a, false, lo[a]);
}

// ---- the mask's visuals: translucent box, edges, six face handles and a centre handle

const FACE_COLOR = 0x4da3ff;
const PICKED_COLOR = 0xff9f43;
const boxMaterials = FACES.map(() => new THREE.MeshBasicMaterial({
  color: FACE_COLOR, transparent: true, opacity: 0.1, depthWrite: false, side: THREE.DoubleSide,
}));
const unitBox = new THREE.BoxGeometry(1, 1, 1);
const maskBox = new THREE.Mesh(unitBox, boxMaterials);
maskBox.renderOrder = 1;
const maskEdges = new THREE.LineSegments(
  new THREE.EdgesGeometry(unitBox),
  new THREE.LineBasicMaterial({ color: FACE_COLOR, transparent: true, opacity: 0.9 }),
);
const AXIS_COLORS = [0xef5350, 0x66bb6a, 0x42a5f5];
const handleGeometry = new THREE.SphereGeometry(1, 20, 14);
// Handles are drawn over everything, so that they can be grabbed wherever the surface is.
const handleMaterial = (color) => new THREE.MeshBasicMaterial({ color, depthTest: false, transparent: true });
const faceHandles = FACES.map((name, i) => {
  const handle = new THREE.Mesh(handleGeometry, handleMaterial(AXIS_COLORS[i >> 1]));
  handle.userData = { kind: 'face', axis: i >> 1, upper: i % 2 === 0, name, size: 1 };
  return handle;
});
const centreHandle = new THREE.Mesh(new THREE.BoxGeometry(2, 2, 2), handleMaterial(0xffffff));
centreHandle.userData = { kind: 'move', size: 0.9 };
const handles = [...faceHandles, centreHandle];
handles.forEach((h) => { h.renderOrder = 3; });
const maskGroup = new THREE.Group();
maskGroup.add(maskBox, maskEdges, ...handles);
scene.add(maskGroup);

/**
 * Where a handle is on the canvas, in CSS pixels of the page ('+x' … '-z', or 'centre'): for
 * tests and scripts that drag it with a real mouse.
 */
studio.handleAt = (name) => {
  const handle = name === 'centre' ? centreHandle : faceHandles[FACES.indexOf(name)];
  if (!handle) throw new Error(`no handle ${name}`);
  const p = handle.getWorldPosition(new THREE.Vector3()).project(camera);
  const r = canvas.getBoundingClientRect();
  return [r.left + (p.x + 1) / 2 * r.width, r.top + (1 - p.y) / 2 * r.height];
};

function updateMaskVisuals() {
  const [lo, hi] = maskCorners().map((p) => p.map((v, a) => v - page.grid.offset[a]));
  const size = new THREE.Vector3(...hi.map((v, a) => Math.max(v - lo[a], 1e-12)));
  const centre = new THREE.Vector3(...hi.map((v, a) => (v + lo[a]) / 2));
  for (const object of [maskBox, maskEdges]) {
    object.position.copy(centre);
    object.scale.copy(size);
  }
  centreHandle.position.copy(centre);
  faceHandles.forEach((handle) => {
    const { axis, upper } = handle.userData;
    handle.position.copy(centre).setComponent(axis, upper ? hi[axis] : lo[axis]);
  });
  boxMaterials.forEach((material, i) => {
    const picked = FACES[i] === page.face && page.mode() === 'protrusion';
    material.color.setHex(picked ? PICKED_COLOR : FACE_COLOR);
    material.opacity = picked ? 0.35 : 0.1;
  });
  requestRender();
}

/** Keeps the handles the same size on screen. */
function scaleHandles() {
  const perPixel = 2 * Math.tan(THREE.MathUtils.degToRad(camera.fov / 2)) / Math.max(canvas.clientHeight, 1);
  for (const handle of handles) {
    const distance = camera.position.distanceTo(handle.position);
    handle.scale.setScalar(distance * perPixel * 6 * handle.userData.size);
  }
}

// ---------------------------------------------------------------------------------------------
// Pointer: drag handles, click faces

const raycaster = new THREE.Raycaster();
let press = null;   // { x, y }: where the left button went down
let drag = null;    // the handle drag in progress

function rayAt(event) {
  const rect = canvas.getBoundingClientRect();
  const ndc = new THREE.Vector2(
    ((event.clientX - rect.left) / rect.width) * 2 - 1,
    -((event.clientY - rect.top) / rect.height) * 2 + 1,
  );
  raycaster.setFromCamera(ndc, camera);
  return raycaster.ray;
}

/** The handle under the pointer; where handles overlap on screen, the one centred nearest it. */
function handleAt(event) {
  if (!page.mask) return null;
  const ray = rayAt(event);
  const hits = raycaster.intersectObjects(handles, false);
  const offCentre = (handle) => ray.distanceSqToPoint(handle.position) / camera.position.distanceToSquared(handle.position);
  let best = null;
  for (const { object } of hits) {
    if (!best || offCentre(object) < offCentre(best)) best = object;
  }
  return best;
}

/** The parameter along the line origin + t·direction closest to the ray, or null if parallel. */
function closestOnLine(ray, origin, direction) {
  const w = new THREE.Vector3().subVectors(origin, ray.origin);
  const b = direction.dot(ray.direction);
  const denominator = 1 - b * b;
  if (denominator < 1e-6) return null;
  return (b * w.dot(ray.direction) - w.dot(direction)) / denominator;
}

function onPointerDown(event) {
  if (event.button !== 0) return;
  press = { x: event.clientX, y: event.clientY };
  const handle = handleAt(event);
  if (!handle) return;
  controls.enabled = false;
  canvas.setPointerCapture(event.pointerId);
  const { lo, hi } = page.mask;
  drag = { handle, lo: [...lo], hi: [...hi], origin: handle.position.clone() };
  const ray = rayAt(event);
  if (handle.userData.kind === 'face') {
    drag.direction = new THREE.Vector3().setComponent(handle.userData.axis, 1);
    drag.t0 = closestOnLine(ray, drag.origin, drag.direction) ?? 0;
  } else {
    // Move in the plane through the box's centre facing the camera.
    drag.plane = new THREE.Plane().setFromNormalAndCoplanarPoint(
      camera.getWorldDirection(new THREE.Vector3()), drag.origin);
    drag.start = ray.intersectPlane(drag.plane, new THREE.Vector3()) ?? drag.origin.clone();
  }
  canvas.style.cursor = 'grabbing';
  event.preventDefault();
}

function onPointerMove(event) {
  if (!drag) {
    if (event.buttons === 0) canvas.style.cursor = handleAt(event) ? 'grab' : '';
    return;
  }
  const ray = rayAt(event);
  const before = JSON.stringify(page.mask);
  const { handle } = drag;
  if (handle.userData.kind === 'face') {
    const { axis, upper } = handle.userData;
    const t = closestOnLine(ray, drag.origin, drag.direction);
    if (t === null) return;
    const world = drag.origin.getComponent(axis) + (t - drag.t0) + page.grid.offset[axis];
    setMaskFace(axis, upper, nearestFace(axis, world));
  } else {
    const point = ray.intersectPlane(drag.plane, new THREE.Vector3());
    if (!point) return;
    moveMask(point.sub(drag.start));
  }
  if (JSON.stringify(page.mask) !== before) maskChanged();
}

/** Shifts the mask from where the drag started by whole cells, staying inside the box. */
function moveMask(delta) {
  const g = page.grid;
  for (let a = 0; a < 3; a++) {
    const k = Math.round(delta.getComponent(a) / g.spacing[a]);
    const shift = clamp(k, g.kmin[a] - drag.lo[a], g.kmax[a] - drag.hi[a]);
    page.mask.lo[a] = drag.lo[a] + shift;
    page.mask.hi[a] = drag.hi[a] + shift;
  }
}

function onPointerUp(event) {
  if (event.button !== 0) return;
  const grabbed = drag?.handle;
  if (drag) {
    drag = null;
    controls.enabled = true;
    if (canvas.hasPointerCapture(event.pointerId)) canvas.releasePointerCapture(event.pointerId);
    canvas.style.cursor = handleAt(event) ? 'grab' : '';
  }
  const click = press && Math.hypot(event.clientX - press.x, event.clientY - press.y) < CLICK_SLOP;
  press = null;
  if (!click) return;
  // A click on a face handle picks its face; elsewhere, the face of the box under the pointer.
  if (grabbed?.userData.kind === 'face') pickFace(grabbed.userData.name);
  else pickFaceAt(event);
}

/** A click on the box: its nearest face becomes the protrusion's face. */
function pickFaceAt(event) {
  if (!page.mask) return;
  rayAt(event);
  const hit = raycaster.intersectObject(maskBox, false)[0];
  if (hit?.face) pickFace(FACES[hit.face.materialIndex]);
}

function pickFace(face) {
  if (face === page.face) return;
  setFace(face);
  if (page.mode() === 'protrusion') change('face');
}

canvas.addEventListener('pointermove', onPointerMove);
canvas.addEventListener('pointerup', onPointerUp);
canvas.addEventListener('pointercancel', onPointerUp);

// ---------------------------------------------------------------------------------------------
// Controls

page.mode = () => $('mode').value;

const cornerInputs = ['lo', 'hi'].flatMap((end) => AXES.map((axis) => $(`${end}-${axis}`)));

function updateCornerInputs() {
  const g = page.grid;
  const corners = maskCorners();
  cornerInputs.forEach((input, i) => {
    const axis = i % 3;
    input.value = corners[i < 3 ? 0 : 1][axis].toFixed(g.digits[axis]);
  });
  const cells = maskCells();
  $('mask-cells').textContent = `${cells.join(' × ')} cells of ${g.counts.join(' × ')}`;
}

function setupCornerInputs() {
  const g = page.grid;
  cornerInputs.forEach((input, i) => {
    const axis = i % 3;
    input.min = faceCoordinate(axis, g.kmin[axis]);
    input.max = faceCoordinate(axis, g.kmax[axis]);
    input.step = g.spacing[axis];
    input.title = `snapped to the grid's cell faces (spacing ${g.spacing[axis]})`;
  });
}

/** A typed corner: snapped to the nearest cell face, kept inside the box and ordered. */
function cornerTyped(event) {
  const i = cornerInputs.indexOf(event.target);
  const axis = i % 3;
  const value = Number(event.target.value);
  const before = JSON.stringify(page.mask);
  if (event.target.value.trim() !== '' && Number.isFinite(value)) {
    setMaskFace(axis, i >= 3, nearestFace(axis, value));
  }
  if (JSON.stringify(page.mask) !== before) maskChanged();
  else updateCornerInputs();   // shows the snapped value
}
cornerInputs.forEach((input) => input.addEventListener('change', cornerTyped));

function maskChanged() {
  updateCornerInputs();
  updateMaskVisuals();
  updateCoarseRange();
  change('mask');
}

function setFace(face) {
  page.face = face;
  $('face').value = face ?? 'none';
  updateMaskVisuals();
}

$('face').addEventListener('change', () => {
  const value = $('face').value;
  setFace(value === 'none' ? null : value);
  change('face');
});

function modeChanged() {
  const protrusion = page.mode() === 'protrusion';
  $('protrusion-controls').hidden = !protrusion;
  $('denoise-controls').hidden = protrusion;
  updateMaskVisuals();
}

$('mode').addEventListener('change', () => {
  modeChanged();
  change('mode');
});

// ---- α: its range and default come from the last preview's report

const alphaInput = $('alpha');

/** The α to send: null (the field's default) until the user moves the slider. */
function alphaValue() {
  return page.alphaTouched ? Number(Number(alphaInput.value).toFixed(page.alphaDecimals)) : null;
}

/** Sets the slider from a report: its range, the default's mark, and the value while untouched. */
function updateAlpha(report) {
  const range = report?.alpha_range;
  const hasRange = Array.isArray(range) && range.length === 2 && range.every(Number.isFinite) && range[1] > range[0];
  alphaInput.disabled = !hasRange;
  $('alpha-reset').disabled = !hasRange || !page.alphaTouched;
  const mark = $('alpha-mark');
  if (!hasRange) {
    mark.hidden = true;
    $('alpha-value').textContent = page.face ? '—' : 'no face';
    $('alpha-default').textContent = page.face ? 'default α: —' : 'no face: harmonic fill, no slope';
    return;
  }
  let [lo, hi] = range;
  const current = Number(alphaInput.value);
  if (page.alphaTouched) {
    // Keep the user's value on the slider.
    lo = Math.min(lo, current);
    hi = Math.max(hi, current);
  }
  // A round step, about a 500th of the range; the value sent is rounded to its decimals.
  const exponent = Math.floor(Math.log10((hi - lo) / 500));
  page.alphaDecimals = clamp(-exponent, 0, 12);
  alphaInput.min = lo;
  alphaInput.max = hi;
  alphaInput.step = 10 ** exponent;
  const preferred = Number.isFinite(report.default_alpha) ? report.default_alpha : null;
  page.defaultAlpha = preferred;
  alphaInput.value = page.alphaTouched ? current : preferred ?? current;
  mark.hidden = preferred === null;
  if (preferred !== null) mark.style.setProperty('--p', String(clamp((preferred - lo) / (hi - lo), 0, 1)));
  $('alpha-default').textContent = preferred === null ? 'default α: —' : `default α: ${formatAlpha(preferred)}`;
  showAlphaValue();
}

const formatAlpha = (a) => (Math.abs(a) >= 1000 || (Math.abs(a) < 1e-3 && a !== 0) ? a.toExponential(3) : a.toFixed(4));

/** The α shown: the slider's once moved, else the default (exact, not the slider's step). */
function showAlphaValue() {
  const value = page.alphaTouched ? alphaValue() : page.defaultAlpha;
  $('alpha-value').textContent = value === null ? '—' : formatAlpha(value) + (page.alphaTouched ? '' : ' (default)');
}

alphaInput.addEventListener('input', () => {
  page.alphaTouched = true;
  $('alpha-reset').disabled = false;
  showAlphaValue();
  change('alpha');
});

$('alpha-reset').addEventListener('click', () => {
  page.alphaTouched = false;
  $('alpha-reset').disabled = true;
  if (page.defaultAlpha !== null) alphaInput.value = page.defaultAlpha;
  showAlphaValue();
  change('alpha');
});

// ---- coarse: one slider for all axes, clamped to each axis' mask cells

const coarseInput = $('coarse');
const coarseCounts = () => maskCells().map((cells) => clamp(Number(coarseInput.value), 1, Math.max(cells, 1)));

function updateCoarseRange() {
  const value = Number(coarseInput.value);
  coarseInput.max = Math.max(...maskCells(), 1);
  coarseInput.value = Math.min(value, Number(coarseInput.max));
  $('coarse-value').textContent = coarseCounts().join(' × ');
}

coarseInput.addEventListener('input', () => {
  updateCoarseRange();
  change('coarse');
});

$('resampling').addEventListener('change', () => change('resampling'));

function restoration() {
  const mask = maskCorners();
  if (page.mode() === 'denoise') {
    return { mode: 'denoise', mask, coarse: coarseCounts(), resampling: $('resampling').value };
  }
  return { mode: 'protrusion', mask, face: page.face, alpha: alphaValue() };
}

// ---------------------------------------------------------------------------------------------
// Live previews and actions: one request in flight; the latest preview request waits its turn

const queue = {
  busy: false,
  pendingPreview: null,   // the latest change not yet sent: { trigger, t0 }
  actions: [],            // apply / undo / redo / save, in order
  epoch: 0,               // bumped by every action: previews from before it are stale
};

/** A control changed: preview the restoration (the surface shown switches to "after"). */
function change(trigger) {
  if (!page.state) return;
  if (page.showBefore) {
    page.showBefore = false;
    showSurfaces();
  }
  queue.pendingPreview = { trigger, t0: performance.now() };
  pump();
}

function enqueueAction(action) {
  queue.epoch++;
  queue.pendingPreview = null;
  queue.actions.push(action);
  pump();
}

function pump() {
  if (queue.busy) return;
  let job;
  if (queue.actions.length) {
    job = queue.actions.shift();
  } else if (queue.pendingPreview) {
    const pending = queue.pendingPreview;
    queue.pendingPreview = null;
    job = () => preview(pending);
  } else {
    return;
  }
  queue.busy = true;
  updateButtons();
  job().catch(showError).finally(() => {
    queue.busy = false;
    updateButtons();
    pump();
  });
}

async function preview({ trigger, t0 }) {
  const epoch = queue.epoch;
  setStatus('restoring…', 'busy');
  const mesh = await fetchMesh('POST', 'api/preview', restoration());
  if (epoch !== queue.epoch) return;   // an apply/undo/redo came in meanwhile
  drawMesh(mesh, { committed: false, trigger, t0 });
  if (page.mode() === 'protrusion') updateAlpha(mesh.report);
  setStatus(`preview: ${mesh.triangles.toLocaleString()} triangles, ${fmtMs(mesh.report.restore_ms)} restore + ${fmtMs(mesh.report.mesh_ms)} mesh`, 'ok');
}

/** Loads the state and the committed mesh, and shows it as both "before" and "after". */
async function reload(trigger, t0) {
  setState(await getJSON('api/state'));
  const mesh = await fetchMesh('GET', 'api/mesh');
  drawMesh(mesh, { committed: true, trigger, t0 });
  return mesh;
}

async function applyNow() {
  const t0 = performance.now();
  setState(await postJSON('api/apply', restoration()));
  await reload('apply', t0);
  setStatus(`applied: step ${page.state.position} of ${page.state.steps.length}`, 'ok');
}

function historyStep(kind) {
  return async () => {
    const t0 = performance.now();
    setState(await postJSON(`api/${kind}`, {}));
    await reload(kind, t0);
    setStatus(`${kind}: step ${page.state.position} of ${page.state.steps.length}`, 'ok');
  };
}

async function saveNow() {
  if (page.dirty) await applyNow();
  const saved = await postJSON('api/save', { mesh: $('save-mesh').checked });
  const size = Number.isFinite(saved.bytes) ? ` (${saved.bytes.toLocaleString()} bytes)` : '';
  const stale = saved.stale_mesh ? ` (${saved.stale_mesh} beside it is an earlier mesh: tick "also the mesh" to replace it)` : '';
  setStatus(`saved ${saved.field}${size}${saved.mesh ? ` and ${saved.mesh}` : ''}${stale}`, 'ok');
}

$('apply').addEventListener('click', () => enqueueAction(applyNow));
$('undo').addEventListener('click', () => enqueueAction(historyStep('undo')));
$('redo').addEventListener('click', () => enqueueAction(historyStep('redo')));
$('save').addEventListener('click', () => enqueueAction(saveNow));

$('before-after').addEventListener('click', () => {
  page.showBefore = !page.showBefore;
  showSurfaces();
  const shown = page.showBefore ? committedMesh : liveMesh;
  const index = shown.geometry.index;
  framesToRecord.push({
    trigger: 'before-after',
    t0: performance.now(),
    mesh: { vertices: shown.geometry.attributes.position?.count ?? 0, triangles: index ? index.count / 3 : 0 },
  });
});

document.addEventListener('keydown', (event) => {
  const typing = event.target instanceof HTMLInputElement && event.target.type !== 'range' && event.target.type !== 'checkbox';
  if (typing || !(event.ctrlKey || event.metaKey)) return;
  const key = event.key.toLowerCase();
  if (key === 'z' && !event.shiftKey && page.state?.can_undo) {
    enqueueAction(historyStep('undo'));
  } else if ((key === 'z' && event.shiftKey) || key === 'y') {
    if (page.state?.can_redo) enqueueAction(historyStep('redo'));
  } else {
    return;
  }
  event.preventDefault();
});

// ---- points overlay

$('points').addEventListener('change', async () => {
  const on = $('points').checked;
  if (on && !pointCloud) {
    try {
      const positions = parsePoints(await (await api('GET', 'api/points')).arrayBuffer());
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
      pointCloud = new THREE.Points(geometry, new THREE.PointsMaterial({
        color: 0xffb74d, size: 2.5, sizeAttenuation: false,
      }));
      scene.add(pointCloud);
    } catch (e) {
      $('points').checked = false;
      showError(e);
      return;
    }
  }
  if (pointCloud) pointCloud.visible = on;
  requestRender();
});

$('reset-view').addEventListener('click', resetView);

// ---- commands

function commandLines() {
  const fromPreview = page.dirty && Array.isArray(page.lastReport?.commands);
  return (fromPreview ? page.lastReport.commands : page.state?.commands) ?? [];
}

function updateCommands() {
  const lines = commandLines();
  const text = lines.length ? lines.join('\n') : '(no restoration yet)';
  $('commands').textContent = page.stale
    ? `# the last change failed (see the message above): these lines are for the surface shown\n${text}`
    : text;
}

$('copy').addEventListener('click', async () => {
  const text = commandLines().join('\n');
  try {
    await navigator.clipboard.writeText(text);
    setStatus('command lines copied', 'ok');
  } catch {
    // No clipboard access (an insecure context, a denied permission): select the text instead.
    const selection = getSelection();
    const range = document.createRange();
    range.selectNodeContents($('commands'));
    selection.removeAllRanges();
    selection.addRange(range);
    const copied = document.execCommand?.('copy');
    setStatus(copied ? 'command lines copied' : 'command lines selected: press Ctrl+C to copy', 'ok');
  }
});

// ---------------------------------------------------------------------------------------------
// State, status and info

function setState(state) {
  page.state = state;
  studio.state = state;
  updateButtons();
  updateCommands();
  updateInfo();
}

function updateButtons() {
  const s = page.state;
  $('undo').disabled = !s?.can_undo;
  $('redo').disabled = !s?.can_redo;
  // Apply commits the live preview; with none (the surface shown is the committed one) there is
  // nothing to apply, and a second click would add the same step again.
  $('apply').disabled = !s || !page.dirty;
  const canSave = Boolean(s && s.output !== null && s.output !== undefined);
  $('save').disabled = !canSave;
  $('save-mesh').disabled = !canSave;
  $('save').title = canSave ? `write ${s.output}` : 'start zeroset studio with -o OUT.zsf to save';
  $('output').textContent = canSave ? `to ${s.output}` : 'start zeroset studio with -o OUT.zsf to save';
  $('points').disabled = !(s && s.points !== null && s.points !== undefined);
  $('dirty').textContent = !s ? '' : page.dirty ? 'the live surface is a preview: Apply commits it'
    : `step ${s.position} of ${s.steps.length}`;
}

function setStatus(message, kind = '') {
  const status = $('status');
  status.textContent = message;
  status.className = `status ${kind}`;
  status.title = message;
}

function showError(error) {
  console.warn(error);
  const message = error instanceof ApiError ? error.message : `error: ${error.message}`;
  setStatus(message, 'error');
  // The surface and the command lines still show the last change that worked, not the
  // controls: say so where the lines are copied from.
  page.stale = true;
  updateCommands();
}

const fmtMs = (ms) => (Number.isFinite(ms) ? `${ms < 10 ? ms.toFixed(1) : Math.round(ms)} ms` : '—');

function updateInfo() {
  const s = page.state;
  if (!s) return;
  const r = page.lastReport;
  const rows = [
    ['input', s.input],
    ['field', s.description],
    ['grid', `${s.grid.counts.join(' × ')} cells, spacing ${s.grid.spacing.map((v) => v.toPrecision(3)).join(', ')}`],
    ['points', s.points === null ? '— (field file)' : Number(s.points).toLocaleString()],
    ['surface', r ? `${r.vertices.toLocaleString()} vertices, ${r.triangles.toLocaleString()} triangles` : '—'],
    ['restore', r ? fmtMs(r.restore_ms) : '—'],
    ['mesh', r ? fmtMs(r.mesh_ms) : '—'],
    ['round trip', fmtMs(page.roundTrip)],
  ];
  if (r && Number.isFinite(r.alpha_used)) rows.push(['α used', formatAlpha(r.alpha_used)]);
  const info = $('info');
  info.replaceChildren(...rows.flatMap(([term, value]) => {
    const dt = document.createElement('dt');
    dt.textContent = term;
    const dd = document.createElement('dd');
    dd.textContent = value ?? '—';
    return [dt, dd];
  }));
}

// ---------------------------------------------------------------------------------------------
// Start

async function start() {
  if (!TOKEN) setStatus('no ?token= in the address: open the address zeroset studio printed', 'error');
  const t0 = performance.now();
  const state = await getJSON('api/state');
  setupGrid(state);
  defaultMask();
  setState(state);
  setupCornerInputs();
  setFace('-y');
  modeChanged();
  updateCornerInputs();
  updateCoarseRange();
  updateAlpha(null);
  resetView();
  resize();
  const mesh = await fetchMesh('GET', 'api/mesh');
  drawMesh(mesh, { committed: true, trigger: 'load', t0 });
  setStatus('ready', 'ok');
  // The first preview: the default mask, α null (it brings the default α and the slider's range).
  change('init');
}

start().catch(showError);
