// The page of `lapmesh view`: a three.js front end of the viewer API (doc/viewer.md).
// No geometry and no colour map is computed here: positions, per-vertex values, colours,
// colour ranges and the colour-map tables all come from the server (the lapmesh headers).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);

// ---- API -------------------------------------------------------------------------------

/** Decodes a binary frame: uint32 LE header length, JSON header, buffers at header offsets. */
function decodeFrame(buf) {
  const len = new DataView(buf).getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, len)));
  const base = 4 + len;
  const types = { float64: Float64Array, uint32: Uint32Array, uint8: Uint8Array };
  const buffers = {};
  for (const [name, b] of Object.entries(header.buffers)) {
    buffers[name] = new types[b.type](buf.slice(base + b.offset, base + b.offset + b.count * types[b.type].BYTES_PER_ELEMENT));
  }
  return { header, buffers };
}

async function apiError(res) {
  try { return (await res.json()).error || `HTTP ${res.status}`; } catch { return `HTTP ${res.status}`; }
}
async function getJson(path) {
  const res = await fetch(path, { cache: 'no-store' });
  if (!res.ok) throw new Error(await apiError(res));
  return res.json();
}
async function getFrame(path) {
  const res = await fetch(path, { cache: 'no-store' });
  if (!res.ok) throw new Error(await apiError(res));
  return decodeFrame(await res.arrayBuffer());
}
async function post(path, body) {
  const res = await fetch(path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) });
  if (!res.ok) throw new Error(await apiError(res));
  return res.json();
}

// ---- state -----------------------------------------------------------------------------

const state = {
  mesh: null,          // id
  geometry: null,      // { header, positions: Float64Array, indices: Uint32Array }
  scalars: null,       // { header, values: Float64Array, colors: Uint8Array }
  scalarsAsked: 0,     // the latest scalars request: an earlier one answering later is stale
  colormaps: null,     // name -> Uint8 RGB x 256
  busy: false,
  op: null,            // the running operation: { mesh, op, requestId }
  lastResult: null,
  errors: 0,
  loadRadius: 1,       // bounding radius of the mesh as loaded (the guard's yardstick)
  drawn: true,         // false while the geometry is refused by the guard
};
let requestCounter = 0;
window.lapmeshViewer = state;  // for tests and report scripts

// ---- three.js scene --------------------------------------------------------------------

const view = $('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.domElement.classList.add('three');
view.prepend(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xffffff);
const camera = new THREE.PerspectiveCamera(35, 1, 0.001, 1000);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = false;
// For tests: the camera as the page uses it (positions are drawn relative to state.center).
state.cameraState = () => {
  camera.updateMatrixWorld();
  return { position: camera.position.toArray(), target: controls.target.toArray(), fov: camera.fov,
    projection: Array.from(camera.projectionMatrix.elements), view: Array.from(camera.matrixWorldInverse.elements),
    center: state.center, drawn: state.drawn };
};
scene.add(new THREE.AmbientLight(0xffffff, 0.9));
const headlight = new THREE.DirectionalLight(0xffffff, 2.2);
headlight.position.set(0.3, 0.5, 1);
camera.add(headlight);
scene.add(camera);

const surfaceMaterial = new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide, flatShading: false,
  polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1 });
const wireMaterial = new THREE.MeshBasicMaterial({ color: 0x000000, wireframe: true, transparent: true, opacity: 0.35 });
let surface = null, wire = null, bufferGeometry = null, radius = 1;

function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  render();
}
function render() { renderer.render(scene, camera); }
controls.addEventListener('change', render);
window.addEventListener('resize', resize);

/** Coordinates beyond this many loaded radii are not drawn (the renderer stalls on them). */
const MAX_EXTENT_RADII = 1e4;

/** Above this many layers of surface per pixel (surface area over the area of the framing
 *  disc) a filled surface takes seconds per frame in a software renderer: draw edges only. */
const MAX_LAYERS = 64;
let surfaceTooDeep = false;

/** Surface area of the served triangles over the area of a disc of the given radius. */
function layersOf(P, T, r) {
  let area = 0;
  for (let t = 0; t < T.length; t += 3) {
    const a = 3 * T[t], b = 3 * T[t + 1], c = 3 * T[t + 2];
    const ux = P[b] - P[a], uy = P[b + 1] - P[a + 1], uz = P[b + 2] - P[a + 2];
    const vx = P[c] - P[a], vy = P[c + 1] - P[a + 1], vz = P[c + 2] - P[a + 2];
    area += 0.5 * Math.hypot(uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx);
  }
  return area / (Math.PI * r * r);
}

/** Shows the filled surface, or only its edges when it is too deep to fill in time. */
function applyVisibility() {
  if (!surface) return;
  surface.visible = state.drawn && !surfaceTooDeep;
  wire.visible = state.drawn && ($('wireframe').checked || surfaceTooDeep);
}

/** Non-finite coordinates and the largest distance from the loaded centre, in loaded radii. */
function extentOf(P) {
  const c = state.center;
  let worst = 0, finite = true;
  for (let i = 0; i < P.length; i += 3) {
    const dx = P[i] - c[0], dy = P[i + 1] - c[1], dz = P[i + 2] - c[2];
    const d = dx * dx + dy * dy + dz * dz;
    if (!Number.isFinite(d)) { finite = false; break; }
    if (d > worst) worst = d;
  }
  return { finite, radii: Math.sqrt(worst) / state.loadRadius };
}

function showWarning(text) {
  $('warning').textContent = text;
  $('warning').hidden = !text;
}

/** Builds the three.js geometry from the served positions (centred, in Float32). */
function setGeometry(frame, keepCamera) {
  const P = frame.buffers.positions, n = P.length / 3;
  if (!keepCamera || !state.center) {
    let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < n; i++) for (let a = 0; a < 3; a++) { lo[a] = Math.min(lo[a], P[3 * i + a]); hi[a] = Math.max(hi[a], P[3 * i + a]); }
    const box = new THREE.Box3(new THREE.Vector3(...lo), new THREE.Vector3(...hi));
    const r = 0.5 * box.getSize(new THREE.Vector3()).length();
    state.center = lo.map((x, a) => 0.5 * (x + hi[a]));
    radius = Number.isFinite(r) && r > 0 ? r : 1;
    state.loadRadius = radius;
    if (!Number.isFinite(r)) state.center = [0, 0, 0];
  }
  // Guard: a blown-up mesh (e.g. explicit smoothing above the stability bound) is not uploaded.
  const ext = extentOf(P);
  if (!ext.finite || ext.radii > MAX_EXTENT_RADII) {
    state.drawn = false;
    document.body.dataset.blownUp = '1';
    applyVisibility();
    showWarning(`The geometry ${ext.finite ? `reaches ${ext.radii.toExponential(1)} times the size of the mesh as loaded` : 'has non-finite coordinates'}` +
      ' (did the smoothing exceed its stability bound?): it is not drawn. Reset brings back the mesh as loaded.');
    render();
    return;
  }
  state.drawn = true;
  delete document.body.dataset.blownUp;
  showWarning(ext.radii > 10 ? `The geometry reaches ${ext.radii.toFixed(0)} times the size of the mesh as loaded; the camera was reset to frame it.` : '');
  const c = state.center, pos = new Float32Array(P.length);
  for (let i = 0; i < n; i++) for (let a = 0; a < 3; a++) pos[3 * i + a] = P[3 * i + a] - c[a];
  if (bufferGeometry) bufferGeometry.dispose();
  bufferGeometry = new THREE.BufferGeometry();
  bufferGeometry.setAttribute('position', new THREE.BufferAttribute(pos, 3));
  bufferGeometry.setIndex(new THREE.BufferAttribute(frame.buffers.indices, 1));
  bufferGeometry.computeVertexNormals();
  bufferGeometry.computeBoundingSphere();
  applyColors();
  if (!surface) {
    surface = new THREE.Mesh(bufferGeometry, surfaceMaterial);
    wire = new THREE.Mesh(bufferGeometry, wireMaterial);
    scene.add(surface, wire);
  } else {
    surface.geometry = bufferGeometry;
    wire.geometry = bufferGeometry;
  }
  if (!keepCamera || ext.radii > 10) resetCamera();
  const layers = layersOf(P, frame.buffers.indices, radius);
  surfaceTooDeep = layers > MAX_LAYERS;
  if (surfaceTooDeep) {
    showWarning(`The surface folds over itself about ${layers.toFixed(0)} times per pixel (noise or an unstable step?): ` +
      'only its edges are drawn. Reset brings back the mesh as loaded.');
  }
  document.body.dataset.edgesOnly = surfaceTooDeep ? '1' : '';
  applyVisibility();
  render();
}

/** Frames the current geometry (its bounding sphere), from the given direction. */
function resetCamera(azimuthDeg = 30, elevationDeg = 20, zoom = 1) {
  const target = new THREE.Vector3(0, 0, 0);
  if (bufferGeometry && state.drawn && bufferGeometry.boundingSphere && bufferGeometry.boundingSphere.radius > 0) {
    target.copy(bufferGeometry.boundingSphere.center);
    radius = bufferGeometry.boundingSphere.radius;
  }
  const az = THREE.MathUtils.degToRad(azimuthDeg), el = THREE.MathUtils.degToRad(elevationDeg);
  const d = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2)) * 1.05 / zoom;
  camera.position.set(target.x + d * Math.cos(el) * Math.sin(az), target.y + d * Math.sin(el), target.z + d * Math.cos(el) * Math.cos(az));
  camera.near = radius / 100; camera.far = radius * 100 + d;
  camera.updateProjectionMatrix();
  controls.target.copy(target);
  controls.update();
  render();
}

/** Vertex colours: the server's sRGB bytes, converted to linear for three.js's pipeline. */
function applyColors() {
  if (!bufferGeometry) return;
  const n = bufferGeometry.attributes.position.count, col = new Float32Array(3 * n);
  const rgb = state.scalars && state.scalars.colors.length === 3 * n ? state.scalars.colors : null;
  const c = new THREE.Color();
  for (let i = 0; i < n; i++) {
    if (rgb) c.setRGB(rgb[3 * i] / 255, rgb[3 * i + 1] / 255, rgb[3 * i + 2] / 255, THREE.SRGBColorSpace);
    else c.setRGB(0.8, 0.8, 0.8, THREE.SRGBColorSpace);
    col[3 * i] = c.r; col[3 * i + 1] = c.g; col[3 * i + 2] = c.b;
  }
  bufferGeometry.setAttribute('color', new THREE.BufferAttribute(col, 3));
  render();
}

// ---- UI helpers ------------------------------------------------------------------------

function showError(message) {
  const e = $('error');
  e.textContent = message;
  e.hidden = false;
  state.errors += 1;
}
function clearError() { $('error').hidden = true; $('error').textContent = ''; }
function setStatus(text) { $('status').textContent = text; }
const fmt = (x) => (Math.abs(x) >= 1e4 || (Math.abs(x) < 1e-3 && x !== 0) ? x.toExponential(3) : Number(x.toPrecision(4)).toString());

function colourQuery() {
  const q = new URLSearchParams();
  q.set('quantity', $('quantity').value);
  q.set('colormap', $('colormap').value);
  const mode = $('range-mode').value;
  q.set('range', mode);
  if (mode === 'percentile') q.set('clip', $('clip').value || '0');  // the other modes take no clip
  if (mode === 'manual') { q.set('min', $('range-min').value); q.set('max', $('range-max').value); }
  return q;
}

function drawColorbar() {
  const box = $('colorbar-box');
  const s = state.scalars;
  if (!s || !state.colormaps) { box.hidden = true; return; }
  const table = state.colormaps[s.header.colormap];
  const ctx = $('colorbar').getContext('2d');
  const img = ctx.createImageData(256, 14);
  for (let x = 0; x < 256; x++) for (let y = 0; y < 14; y++) {
    const o = 4 * (y * 256 + x);
    img.data[o] = table[3 * x]; img.data[o + 1] = table[3 * x + 1]; img.data[o + 2] = table[3 * x + 2]; img.data[o + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
  const [lo, hi] = s.header.range;
  for (const [id, v] of [['cbar-min', lo], ['cbar-mid', 0.5 * (lo + hi)], ['cbar-max', hi]]) {
    $(id).textContent = fmt(v);
    $(id).dataset.value = String(v);  // full precision, for tests
  }
  const info = s.header.info || {};
  const extra = info.source === 'curvature' ? ` (${info.laplacian}, ${info.area} area)` : '';
  $('colorbar-title').textContent = `${s.header.quantity}${extra}; data in [${fmt(s.header.data_range[0])}, ${fmt(s.header.data_range[1])}]`;
  const modeText = {
    auto: 'range: auto ([min, max], symmetric when both signs occur)',
    symmetric: s.header.clip > 0 ? `range: symmetric, ${s.header.clip}% clipped` : 'range: symmetric ([−max |x|, max |x|])',
    percentile: `range: percentile clip ${s.header.clip}% at each end`,
    manual: 'range: manual',
  }[s.header.range_mode] || `range: ${s.header.range_mode}`;
  $('colorbar-mode').textContent = modeText;
  box.dataset.mode = s.header.range_mode;
  box.dataset.clip = String(s.header.clip);
  box.dataset.min = String(lo);
  box.dataset.max = String(hi);
  box.hidden = false;
  if ($('range-mode').value !== 'manual') { $('range-min').value = lo; $('range-max').value = hi; }
}

function setQuantities(names, preferred) {
  const sel = $('quantity');
  const keep = preferred && names.includes(preferred) ? preferred : names.includes(sel.value) ? sel.value : names.includes('mean') ? 'mean' : names[0];
  sel.innerHTML = '';
  for (const n of names) sel.add(new Option(n, n));
  if (keep) sel.value = keep;
  sel.disabled = names.length === 0;
}

async function loadScalars() {
  const asked = ++state.scalarsAsked;
  if (!state.mesh || $('quantity').options.length === 0) {
    state.scalars = null;
    applyColors(); drawColorbar();
    return;
  }
  const mesh = state.mesh;
  const f = await getFrame(`/api/meshes/${mesh}/scalars?${colourQuery()}`);
  // Another mesh picked, or newer settings asked for, meanwhile (answers may come out of order).
  if (state.mesh !== mesh || asked !== state.scalarsAsked) return;
  state.scalars = { header: f.header, values: f.buffers.values, colors: f.buffers.colors };
  applyColors();
  drawColorbar();
}

async function loadGeometry(keepCamera) {
  const mesh = state.mesh;
  const f = await getFrame(`/api/meshes/${mesh}/geometry`);
  if (state.mesh !== mesh) return;  // a stale answer
  state.geometry = { header: f.header, positions: f.buffers.positions, indices: f.buffers.indices };
  $('mesh-info').textContent = `${f.header.vertices} vertices, ${f.header.faces} faces`;
  // What the reader found and kept (zero-area faces, non-manifold edges, ...): one line each.
  $('mesh-notes').replaceChildren(...(f.header.notes || []).map((n) => {
    const li = document.createElement('li');
    li.textContent = `note: ${n}`;
    return li;
  }));
  $('rec-k').max = f.header.vertices;
  setGeometry(f, keepCamera);
  setQuantities(f.header.scalars);
  await loadScalars();
}

/** Runs a UI action, errors shown in the page (naming the mesh when it is not the one shown). */
async function guard(action, mesh) {
  clearError();
  try {
    await action();
  } catch (e) {
    showError(mesh && mesh !== state.mesh ? `${mesh}: ${e.message}` : e.message);
  }
}

let pollTimer = null;
function startProgress(run) {
  $('cancel').disabled = false;
  $('progress-text').textContent = `${run.mesh}: ${run.op}…`;
  pollTimer = setInterval(async () => {
    try {
      const p = await getJson(`/api/meshes/${run.mesh}/progress`);
      if (state.op !== run || !p.running || p.request_id !== run.requestId) return;
      const parts = [`${run.mesh}: ${p.operation}`, p.stage];
      if (p.total > 0) parts.push(`${p.done}/${p.total}`);
      else if (p.done > 0) parts.push(`${p.done} solves`);
      if (p.elapsed_ms !== undefined) parts.push(`${(p.elapsed_ms / 1000).toFixed(1)} s`);
      $('progress-text').textContent = parts.filter(Boolean).join(' · ');
    } catch { /* the next poll tries again */ }
  }, 250);
}
function stopProgress() {
  clearInterval(pollTimer);
  $('cancel').disabled = true;
  $('progress-text').textContent = '';
}

const buttons = ['reset', 'run-curvature', 'run-reconstruct', 'run-smooth', 'run-noise'];
/** Runs an operation on the current mesh. It carries its mesh and a request id: progress,
 *  cancel and the answer concern that mesh even if the user picks another one meanwhile. */
async function runOperation(op, body) {
  if (state.busy) return;
  const run = { mesh: state.mesh, op, requestId: `${Date.now().toString(36)}-${++requestCounter}` };
  state.busy = true;
  state.op = run;
  for (const b of buttons) $(b).disabled = true;
  document.body.dataset.busy = '1';
  startProgress(run);
  try {
    await guard(async () => {
      const r = await post(`/api/meshes/${run.mesh}/${op}`, { ...body, request_id: run.requestId });
      if (r.mesh !== run.mesh || r.request_id !== run.requestId) throw new Error(`an answer for another operation arrived (${r.mesh}, ${r.request_id})`);
      state.lastResult = r;
      const extra = op === 'smooth' ? `, λ = ${fmt(r.lambda)}` : op === 'noise' ? `, σ = ${fmt(r.sigma)}` : op === 'reconstruct' ? `, k = ${r.k}${r.basis_cached ? ' (basis reused)' : ''}` : '';
      if (state.mesh !== run.mesh) {
        // The user looks at another mesh now: say so, and leave that mesh's view alone.
        setStatus(`${op} on ${run.mesh} finished (${r.elapsed_ms.toFixed(1)} ms); pick ${run.mesh} to see it`);
        return;
      }
      setStatus(`${op}: ${r.elapsed_ms.toFixed(1)} ms on the server${extra}`);
      $('status').dataset.elapsed = String(r.elapsed_ms);
      $('status').dataset.mesh = run.mesh;
      const preferred = op === 'curvature' ? (urlParams.get('quantity') || undefined) : undefined;
      const f = await getFrame(`/api/meshes/${run.mesh}/geometry`);
      if (state.mesh !== run.mesh) return;
      state.geometry = { header: f.header, positions: f.buffers.positions, indices: f.buffers.indices };
      setGeometry(f, true);
      if (r.warning) showWarning(`warning: ${r.warning}${$('warning').hidden ? '' : ' — ' + $('warning').textContent}`);
      setQuantities(f.header.scalars, op === 'curvature' ? preferred || $('quantity').value || 'mean' : 'displacement');
      await loadScalars();
    }, run.mesh);
  } finally {
    stopProgress();
    state.busy = false;
    state.op = null;
    for (const b of buttons) $(b).disabled = false;
    delete document.body.dataset.busy;
  }
}

function intOrText(v) { return /^-?\d+$/.test(v.trim()) ? Number(v) : v; }
function numOrText(v) { const x = Number(v); return v.trim() !== '' && Number.isFinite(x) ? x : v; }

const operations = {
  curvature: () => ({ laplacian: $('curv-laplacian').value, area: $('curv-area').value,
    mollification: numOrText($('curv-mollification').value) }),
  reconstruct: () => ({ k: intOrText($('rec-k').value), laplacian: $('rec-laplacian').value, area: $('rec-area').value,
    mollification: numOrText($('rec-mollification').value) }),
  smooth: () => {
    const lam = $('sm-lambda').value.trim();
    return {
      scheme: $('sm-scheme').value, lambda: lam === 'auto' ? 'auto' : numOrText(lam), lambda_unit: $('sm-unit').value,
      iterations: intOrText($('sm-iterations').value), laplacian: $('sm-laplacian').value, area: $('sm-area').value,
      mollification: numOrText($('sm-mollification').value),
      fixed_operator: $('sm-fixed').checked, restore_volume: $('sm-restore').checked,
      restore_area: $('sm-restore-area').checked, fix_boundary: !$('sm-free-boundary').checked,
    };
  },
  noise: () => ({ level: numOrText($('noise-level').value), seed: intOrText($('noise-seed').value),
    scale: $('noise-scale').value, direction: $('noise-direction').value }),
};

function download(format) {
  const q = colourQuery();
  if ($('quantity').options.length === 0) q.delete('quantity'), q.delete('colormap'), q.delete('range'), q.delete('clip'), q.delete('min'), q.delete('max');
  q.set('format', format);
  const a = document.createElement('a');
  a.href = `/api/meshes/${state.mesh}/download?${q}`;
  a.download = '';
  document.body.append(a);
  a.click();
  a.remove();
}

function screenshot() {
  render();
  const a = document.createElement('a');
  a.href = renderer.domElement.toDataURL('image/png');
  a.download = `lapmesh_${state.mesh}${state.scalars ? '_' + state.scalars.header.quantity : ''}.png`;
  document.body.append(a);
  a.click();
  a.remove();
}

// ---- value read-out under the mouse -----------------------------------------------------

const raycaster = new THREE.Raycaster();
renderer.domElement.addEventListener('pointermove', (ev) => {
  const out = $('readout');
  if (!surface || !state.geometry || !state.drawn) { out.hidden = true; return; }
  const r = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.intersectObject(surface, false)[0];
  if (!hit) { out.hidden = true; return; }
  // The corner of the hit triangle closest to the hit point.
  const pos = bufferGeometry.attributes.position, local = surface.worldToLocal(hit.point.clone());
  let best = hit.face.a, bestD = Infinity;
  for (const v of [hit.face.a, hit.face.b, hit.face.c]) {
    const d = local.distanceToSquared(new THREE.Vector3().fromBufferAttribute(pos, v));
    if (d < bestD) { bestD = d; best = v; }
  }
  const s = state.scalars;
  out.textContent = s ? `vertex ${best}: ${s.header.quantity} = ${s.values[best].toPrecision(6)}` : `vertex ${best}`;
  out.dataset.vertex = String(best);
  out.style.left = `${ev.clientX - view.getBoundingClientRect().left + 14}px`;
  out.style.top = `${ev.clientY - view.getBoundingClientRect().top + 10}px`;
  out.hidden = false;
});
renderer.domElement.addEventListener('pointerleave', () => { $('readout').hidden = true; });

// ---- wiring ----------------------------------------------------------------------------

$('mesh').addEventListener('change', () => guard(async () => {
  state.mesh = $('mesh').value;
  state.center = null;
  state.scalars = null;
  showWarning('');
  setStatus('');
  await loadGeometry(false);
}));
$('reset').addEventListener('click', () => runOperation('reset', {}));
$('run-curvature').addEventListener('click', () => runOperation('curvature', operations.curvature()));
$('run-reconstruct').addEventListener('click', () => runOperation('reconstruct', operations.reconstruct()));
$('run-smooth').addEventListener('click', () => runOperation('smooth', operations.smooth()));
$('run-noise').addEventListener('click', () => runOperation('noise', operations.noise()));
$('cancel').addEventListener('click', () => {
  const run = state.op;  // the operation shown, on its own mesh, whichever mesh is in view
  if (run) guard(() => post(`/api/meshes/${run.mesh}/cancel`, { request_id: run.requestId }));
});
function syncRangeFields() { $('clip').disabled = $('range-mode').value !== 'percentile'; }
$('range-mode').addEventListener('change', syncRangeFields);
for (const id of ['quantity', 'colormap', 'range-mode', 'clip', 'range-min', 'range-max'])
  $(id).addEventListener('change', () => guard(loadScalars));
$('wireframe').addEventListener('change', () => { applyVisibility(); render(); });
$('shading').addEventListener('change', () => { surfaceMaterial.flatShading = $('shading').value === 'flat'; surfaceMaterial.needsUpdate = true; render(); });
$('reset-camera').addEventListener('click', () => resetCamera());
$('screenshot').addEventListener('click', screenshot);
$('download-off').addEventListener('click', () => download('off'));
$('download-ply').addEventListener('click', () => download('ply'));

// ---- URL parameters: ?mesh=cow&op=curvature&area=mixed&quantity=mean&colormap=coolwarm&... --

const urlParams = new URLSearchParams(window.location.search);
const fieldOf = {
  laplacian: ['curv-laplacian', 'rec-laplacian', 'sm-laplacian'], area: ['curv-area', 'rec-area', 'sm-area'], k: ['rec-k'],
  mollification: ['curv-mollification', 'rec-mollification', 'sm-mollification'],
  scheme: ['sm-scheme'], lambda: ['sm-lambda'], lambda_unit: ['sm-unit'], iterations: ['sm-iterations'],
  level: ['noise-level'], seed: ['noise-seed'], scale: ['noise-scale'], direction: ['noise-direction'],
  colormap: ['colormap'], range: ['range-mode'], clip: ['clip'], min: ['range-min'], max: ['range-max'], shading: ['shading'],
};
/** The dropdowns of the operations' choices, by the parameter they set: their values, their
 *  descriptions and the default selection are the server's name tables (GET /api/info). */
const choiceFields = {
  laplacian: ['curv-laplacian', 'rec-laplacian', 'sm-laplacian'], area: ['curv-area', 'rec-area', 'sm-area'],
  scheme: ['sm-scheme'], lambda_unit: ['sm-unit'], scale: ['noise-scale'], direction: ['noise-direction'],
  colormap: ['colormap'],
};
function fillChoices(choices) {
  for (const [key, ids] of Object.entries(choiceFields)) {
    const table = choices[key];
    if (!table) throw new Error(`the server offers no choices for '${key}'`);
    for (const id of ids) {
      const select = $(id);
      select.replaceChildren();
      for (const v of table.values) {
        const o = new Option(v.name, v.name, false, v.name === table.default);
        o.title = v.description;
        select.add(o);
      }
      select.value = table.default;
    }
  }
}

function applyUrlFields() {
  for (const [key, ids] of Object.entries(fieldOf)) {
    if (!urlParams.has(key)) continue;
    for (const id of ids) $(id).value = urlParams.get(key);
  }
  for (const [key, id] of [['fixed_operator', 'sm-fixed'], ['restore_volume', 'sm-restore'], ['restore_area', 'sm-restore-area'],
    ['free_boundary', 'sm-free-boundary'], ['wireframe', 'wireframe']])
    if (urlParams.has(key)) $(id).checked = urlParams.get(key) === '1' || urlParams.get(key) === 'true';
  if (urlParams.get('ui') === '0') document.body.classList.add('no-ui');
  syncRangeFields();
  surfaceMaterial.flatShading = $('shading').value === 'flat';
}

async function main() {
  resize();
  await guard(async () => fillChoices((await getJson('/api/info')).choices));
  applyUrlFields();
  await guard(async () => {
    const maps = await getJson('/api/colormaps');
    state.colormaps = Object.fromEntries(Object.entries(maps.maps).map(([k, v]) => [k, Uint8Array.from(v)]));
    const list = (await getJson('/api/meshes')).meshes;
    for (const m of list) $('mesh').add(new Option(m.label, m.id));
    const wanted = urlParams.get('mesh');
    if (wanted && !list.some((m) => m.id === wanted)) throw new Error(`unknown mesh '${wanted}' in the URL`);
    state.mesh = wanted || list[0].id;
    $('mesh').value = state.mesh;
    if (urlParams.get('reset') !== '0' && urlParams.has('op')) await post(`/api/meshes/${state.mesh}/reset`, {});
    await loadGeometry(false);
    if (urlParams.has('azimuth') || urlParams.has('elevation') || urlParams.has('zoom'))
      resetCamera(Number(urlParams.get('azimuth') ?? 30), Number(urlParams.get('elevation') ?? 20), Number(urlParams.get('zoom') ?? 1));
  });
  for (const op of (urlParams.get('op') || '').split(',').filter(Boolean)) {
    if (!operations[op]) { showError(`unknown operation '${op}' in the URL`); break; }
    const before = state.errors;
    await runOperation(op, operations[op]());
    if (state.errors !== before) break;
  }
  if (urlParams.has('quantity') && [...$('quantity').options].some((o) => o.value === urlParams.get('quantity'))) {
    $('quantity').value = urlParams.get('quantity');
    await guard(loadScalars);
  }
  render();
  document.body.dataset.ready = '1';
}
main();
