// End-to-end test of `lapmesh view`: starts the server on a free port with a mesh that is not
// in the repository, drives the page in Debian's headless Chromium through playwright-core,
// presses every control, and checks what the page shows against the API and against
// `lapmesh curvature`. Screenshots go to LAPMESH_E2E_OUT, and to doc/images/viewer when
// LAPMESH_UPDATE_DOC_IMAGES=1.
//
// Environment (set by ctest, test/CMakeLists.txt): LAPMESH_CLI, LAPMESH_NODE_MODULES,
// LAPMESH_CHROMIUM, LAPMESH_E2E_OUT, LAPMESH_DOC_IMAGES, LAPMESH_E2E_MESH.
'use strict';
const { spawn, execFileSync } = require('node:child_process');
const fs = require('node:fs');
const os = require('node:os');
const path = require('node:path');
const assert = require('node:assert/strict');

const env = (name, fallback) => {
  const v = process.env[name] ?? fallback;
  if (v === undefined) throw new Error(`${name} is not set`);
  return v;
};
const cli = env('LAPMESH_CLI');
const { chromium } = require(path.join(env('LAPMESH_NODE_MODULES'), 'playwright-core'));
const chromiumPath = env('LAPMESH_CHROMIUM', '/usr/bin/chromium');
const outDir = env('LAPMESH_E2E_OUT', path.join(os.tmpdir(), 'lapmesh-e2e'));
const docDir = process.env.LAPMESH_UPDATE_DOC_IMAGES === '1' ? env('LAPMESH_DOC_IMAGES') : null;
const meshPath = env('LAPMESH_E2E_MESH');
const meshId = path.basename(meshPath).replace(/\.[^.]*$/, '');
fs.mkdirSync(outDir, { recursive: true });
if (docDir) fs.mkdirSync(docDir, { recursive: true });

const t0 = Date.now();
const log = (...a) => console.log(`[${((Date.now() - t0) / 1000).toFixed(1)} s]`, ...a);

function decodeFrame(buf) {
  const len = buf.readUInt32LE(0);
  const header = JSON.parse(buf.subarray(4, 4 + len).toString('utf8'));
  const base = 4 + len;
  const out = { header };
  for (const [name, b] of Object.entries(header.buffers)) {
    const size = { float64: 8, uint32: 4, uint8: 1 }[b.type];
    const slice = buf.subarray(base + b.offset, base + b.offset + b.count * size);
    const copy = new Uint8Array(slice).buffer;
    out[name] = b.type === 'float64' ? new Float64Array(copy) : b.type === 'uint32' ? new Uint32Array(copy) : new Uint8Array(copy);
  }
  return out;
}

async function startServer() {
  const proc = spawn(cli, ['view', meshPath], { stdio: ['ignore', 'pipe', 'pipe'] });
  let stderr = '';
  proc.stderr.on('data', (d) => { stderr += d; });
  const url = await new Promise((resolve, reject) => {
    let out = '';
    const timer = setTimeout(() => reject(new Error(`no URL from lapmesh view within 60 s; stderr: ${stderr}`)), 60000);
    proc.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/http:\/\/127\.0\.0\.1:(\d+)\//);
      if (m) { clearTimeout(timer); resolve(m[0]); }
    });
    proc.on('exit', (code) => reject(new Error(`lapmesh view exited with ${code}: ${stderr}`)));
  });
  return { proc, url };
}

async function main() {
  const { proc, url } = await startServer();
  log('server at', url);
  const api = async (p) => {
    const r = await fetch(new URL(p, url));
    if (!r.ok) throw new Error(`${p}: HTTP ${r.status} ${await r.text()}`);
    return r;
  };
  const apiFrame = async (p) => decodeFrame(Buffer.from(await (await api(p)).arrayBuffer()));

  const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'lapmesh-e2e-chromium-'));
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: chromiumPath,
    headless: true,
    viewport: { width: 1280, height: 800 },  // the size the layout is checked at
    acceptDownloads: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
  });
  const pageErrors = [];
  try {
    const page = context.pages()[0] || await context.newPage();
    page.on('pageerror', (e) => pageErrors.push(e.message));
    page.on('console', (m) => { if (m.type() === 'error' && !/status of 4\d\d/.test(m.text())) pageErrors.push(m.text()); });
    const shot = async (name) => {
      await page.waitForTimeout(100);
      const file = path.join(outDir, `${name}.png`);
      await page.screenshot({ path: file });
      if (docDir) fs.copyFileSync(file, path.join(docDir, `${name}.png`));
      return fs.readFileSync(file);
    };
    // Long runs (100 smoothing iterations) on a loaded 2-core machine can take well over
    // Playwright's default 30 s.
    const idle = () => page.waitForFunction(() => document.body.dataset.ready === '1' && !document.body.dataset.busy,
      null, { timeout: 120000 });
    const press = async (id) => {
      await page.click(`#${id}`);
      await page.waitForTimeout(50);
      await idle();
    };
    const positions = () => page.evaluate(() => Array.from(window.lapmeshViewer.geometry.positions));
    const colorbar = async () => page.evaluate(() => [Number(document.getElementById('colorbar-box').dataset.min),
      Number(document.getElementById('colorbar-box').dataset.max)]);
    const errorText = () => page.evaluate(() => { const e = document.getElementById('error'); return e.hidden ? '' : e.textContent; });
    const warningText = () => page.evaluate(() => { const e = document.getElementById('warning'); return e.hidden ? '' : e.textContent; });
    // Vertices of the served geometry in normalized device coordinates of the page's camera.
    const ndcOfGeometry = async () => {
      const cam = await page.evaluate(() => window.lapmeshViewer.cameraState());
      const P = await positions();
      const [V, Pr] = [cam.view, cam.projection];  // column-major 4x4
      const mul = (M, x) => [0, 1, 2, 3].map((r) => M[r] * x[0] + M[4 + r] * x[1] + M[8 + r] * x[2] + M[12 + r] * x[3]);
      let maxAbs = 0, outside = 0;
      for (let i = 0; i < P.length; i += 3) {
        const e = mul(V, [P[i] - cam.center[0], P[i + 1] - cam.center[1], P[i + 2] - cam.center[2], 1]);
        const c = mul(Pr, e);
        const m = Math.max(Math.abs(c[0] / c[3]), Math.abs(c[1] / c[3]));
        // Outside by more than float32 round-off: a mesh collapsed by smoothing is framed
        // tightly, and a vertex on the frame may land a few ulps past it.
        if (c[3] <= 0 || m > 1 + 1e-5) outside += 1;
        maxAbs = Math.max(maxAbs, m);
      }
      return { maxAbs, outside };
    };
    // Layout at 1280 x 800: the boxes of the given visible elements must not overlap.
    const boxes = (ids) => page.evaluate((list) => list.map((id) => {
      const e = document.getElementById(id);
      if (!e || e.hidden || e.offsetParent === null) return null;
      const r = e.getBoundingClientRect();
      return { id, x: r.x, y: r.y, w: r.width, h: r.height };
    }).filter(Boolean), ids);
    const assertNoOverlap = async (ids) => {
      const b = await boxes(ids);
      for (let i = 0; i < b.length; i++) for (let j = i + 1; j < b.length; j++) {
        const [p, q] = [b[i], b[j]];
        const overlap = p.x < q.x + q.w && q.x < p.x + p.w && p.y < q.y + q.h && q.y < p.y + p.h;
        assert.ok(!overlap, `${p.id} overlaps ${q.id}: ${JSON.stringify(p)} ${JSON.stringify(q)}`);
      }
      return b.map((x) => x.id);
    };

    await page.goto(url);
    await idle();

    // --- layout at 1280 x 800: no sideways scrolling in the panel, no clipped button or
    // dropdown, the Colour and View sections visible without scrolling.
    const layout = await page.evaluate(() => {
      const panel = document.getElementById('panel');
      const ctx = document.createElement('canvas').getContext('2d');
      const clippedSelects = [];
      for (const sel of panel.querySelectorAll('select')) {
        ctx.font = getComputedStyle(sel).font;
        for (const o of sel.options) {
          // the text plus the arrow and padding of the control
          if (ctx.measureText(o.text).width + 28 > sel.getBoundingClientRect().width) clippedSelects.push(`${sel.id}: ${o.text}`);
        }
      }
      const clippedButtons = [...document.querySelectorAll('button')].filter((b) => b.scrollWidth > b.clientWidth + 1).map((b) => b.id);
      const outside = [...panel.querySelectorAll('input, select, button')].filter((e) => {
        const r = e.getBoundingClientRect(), p = panel.getBoundingClientRect();
        return r.right > p.right - 1 || r.left < p.left;
      }).map((e) => e.id);
      const section = (title) => [...panel.querySelectorAll('section')].find((x) => x.querySelector('h2').textContent === title).getBoundingClientRect();
      return { sideways: panel.scrollWidth - panel.clientWidth, clippedSelects, clippedButtons, outside,
        colourBottom: section('Colour').bottom, viewBottom: section('View').bottom, height: window.innerHeight };
    });
    assert.equal(layout.sideways, 0, 'the side panel scrolls sideways');
    assert.deepEqual(layout.clippedSelects, [], 'dropdowns too narrow for their options');
    assert.deepEqual(layout.clippedButtons, [], 'buttons with clipped labels');
    assert.deepEqual(layout.outside, [], 'controls beyond the panel');
    assert.ok(layout.colourBottom <= layout.height && layout.viewBottom <= layout.height, `Colour/View below the fold: ${JSON.stringify(layout)}`);
    const options = await page.$$eval('#mesh option', (o) => o.map((x) => x.value));
    assert.deepEqual(options.slice(0, 1), [meshId]);
    for (const builtin of ['icosphere', 'torus', 'bumpy-sphere']) assert.ok(options.includes(builtin), builtin);
    await page.selectOption('#mesh', meshId);
    await page.waitForFunction((id) => window.lapmeshViewer.geometry && window.lapmeshViewer.geometry.header.id === id, meshId);
    await press('reset');
    const original = await positions();
    log(`mesh ${meshId}: ${original.length / 3} vertices`);

    // --- curvature: the colour bar range is the API's and the one `lapmesh curvature` uses.
    const csv = path.join(outDir, `${meshId}_curvature.csv`);
    const cliOut = execFileSync(cli, ['curvature', meshPath, '-o', csv, '--area', 'mixed']).toString();
    const rows = fs.readFileSync(csv, 'utf8').trim().split('\n').slice(1).map((l) => l.split(',').map(Number));
    for (const [lap, area] of [['uniform', 'barycentric'], ['cotangent', 'voronoi'], ['cotangent', 'mixed']]) {
      await page.selectOption('#curv-laplacian', lap);
      await page.selectOption('#curv-area', area);
      await press('run-curvature');
      assert.equal(await errorText(), '');
      assert.match(await page.textContent('#status'), /curvature: [\d.]+ ms on the server/);
    }
    for (const [column, quantity] of [[1, 'mean'], [2, 'gaussian'], [3, 'k1'], [4, 'k2']]) {
      await page.selectOption('#quantity', quantity);
      await page.selectOption('#range-mode', 'auto');
      await idle();
      await page.waitForFunction((q) => window.lapmeshViewer.scalars.header.quantity === q, quantity);
      const bar = await colorbar();
      const served = await apiFrame(`/api/meshes/${meshId}/scalars?quantity=${quantity}&range=auto`);
      assert.deepEqual(bar, served.header.range, `${quantity}: colour bar vs API`);
      // The values the CLI wrote (17 digits) are the ones served, bitwise; and the range is
      // [min, max], made symmetric when both signs occur (doc/cli.md).
      const col = rows.map((r) => r[column]);
      col.forEach((x, i) => { if (x !== served.values[i]) throw new Error(`${quantity}[${i}]: CLI ${x} vs served ${served.values[i]}`); });
      let lo = Math.min(...col), hi = Math.max(...col);
      if (lo < 0 && hi > 0) { const a = Math.max(-lo, hi); lo = -a; hi = a; }
      assert.deepEqual(bar, [lo, hi], `${quantity}: colour bar vs lapmesh curvature`);
    }
    assert.match(cliOut, /colour range/);
    await page.selectOption('#quantity', 'mean');
    await page.selectOption('#colormap', 'coolwarm');
    await page.selectOption('#range-mode', 'percentile');  // the clip field is for this mode only
    await page.fill('#clip', '1');
    await page.dispatchEvent('#clip', 'change');
    await idle();
    await page.waitForFunction(() => window.lapmeshViewer.scalars.header.range_mode === 'percentile' &&
      window.lapmeshViewer.scalars.header.colormap === 'coolwarm');
    const clipped = await apiFrame(`/api/meshes/${meshId}/scalars?quantity=mean&range=percentile&clip=1`);
    assert.deepEqual(await colorbar(), clipped.header.range);
    // The value read-out under the mouse.
    const box = await page.locator('canvas.three').boundingBox();
    await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
    await page.mouse.move(box.x + box.width / 2 + 3, box.y + box.height / 2 + 2);
    await page.waitForSelector('#readout:not([hidden])');
    const readout = await page.textContent('#readout');
    const v = Number(await page.getAttribute('#readout', 'data-vertex'));
    assert.match(readout, /^vertex \d+: mean = /);
    assert.equal(Number(readout.split('= ')[1]), Number(clipped.values[v].toPrecision(6)));
    await shot('curvature_mean');
    await page.mouse.move(5, 5);
    for (const map of ['jet', 'viridis', 'gray']) {
      await page.selectOption('#colormap', map);
      await idle();
    }
    await page.selectOption('#quantity', 'gaussian');
    await page.selectOption('#colormap', 'coolwarm');
    await page.selectOption('#range-mode', 'symmetric');
    await idle();
    // Symmetric is [-max|x|, max|x|]: no clip goes with it (the clip field is for percentile only).
    await page.waitForFunction(() => window.lapmeshViewer.scalars.header.quantity === 'gaussian' &&
      window.lapmeshViewer.scalars.header.range_mode === 'symmetric');
    assert.equal(await page.isDisabled('#clip'), true);
    const symFrame = await page.evaluate(() => window.lapmeshViewer.scalars.header);
    assert.equal(symFrame.clip, 0);
    const sym = await colorbar();
    assert.equal(sym[0], -sym[1]);
    const gaussianServed = await apiFrame(`/api/meshes/${meshId}/scalars?quantity=gaussian&range=symmetric`);
    assert.deepEqual(sym, gaussianServed.header.range);
    const maxAbs = Math.max(...Array.from(gaussianServed.values).map(Math.abs));
    assert.equal(sym[1], maxAbs, 'symmetric range is max |x|');
    assert.notDeepEqual(sym, (await apiFrame(`/api/meshes/${meshId}/scalars?quantity=gaussian&range=symmetric&clip=1`)).header.range);
    assert.match(await page.textContent('#colorbar-mode'), /symmetric/);
    await page.selectOption('#range-mode', 'percentile');
    await idle();
    await page.waitForFunction(() => window.lapmeshViewer.scalars.header.range_mode === 'percentile');
    assert.match(await page.textContent('#colorbar-mode'), /percentile clip 1% at each end/);
    await page.selectOption('#range-mode', 'symmetric');
    await idle();
    await page.waitForFunction(() => window.lapmeshViewer.scalars.header.range_mode === 'symmetric');
    await shot('curvature_gaussian');
    await page.selectOption('#range-mode', 'manual');
    await page.fill('#range-min', '-50');
    await page.fill('#range-max', '50');
    await page.dispatchEvent('#range-max', 'change');
    await page.waitForFunction(() => window.lapmeshViewer.scalars.header.range_mode === 'manual' &&
      window.lapmeshViewer.scalars.header.range[1] === 50);
    assert.deepEqual(await colorbar(), [-50, 50]);
    await page.fill('#range-max', '-60');
    await page.dispatchEvent('#range-max', 'change');
    await page.waitForFunction(() => !document.getElementById('error').hidden);
    assert.match(await errorText(), /min/);
    await page.selectOption('#range-mode', 'auto');
    await idle();

    // --- "Reset camera" frames the current geometry: noise that spreads the mesh beyond the
    // loaded framing, then a collapse by strong implicit smoothing.
    await press('reset');
    await page.selectOption('#noise-scale', 'bbox');
    await page.fill('#noise-level', '1');
    await page.fill('#noise-seed', '5');
    await press('run-noise');
    // Noise of the size of the mesh: a surface folded over itself many times per pixel is
    // drawn as edges only, and frames stay fast.
    assert.equal(await page.evaluate(() => document.body.dataset.edgesOnly), '1');
    assert.match(await warningText(), /only its edges are drawn/);
    let t0 = Date.now();
    await page.screenshot();
    assert.ok(Date.now() - t0 < 5000, `a frame of the noisy mesh took ${Date.now() - t0} ms`);
    const spread = await ndcOfGeometry();
    assert.ok(spread.outside > 0, 'the noisy mesh should leave the loaded framing');
    await page.click('#reset-camera');
    const framed = await ndcOfGeometry();
    assert.equal(framed.outside, 0, 'reset camera: every vertex in view');
    assert.ok(framed.maxAbs > 0.5, `reset camera: the mesh fills the view (${framed.maxAbs})`);
    await press('reset');
    await page.selectOption('#sm-scheme', 'implicit');
    await page.fill('#sm-lambda', '1e3');
    await page.selectOption('#sm-unit', 'edge2');
    await page.fill('#sm-iterations', '5');
    await page.selectOption('#sm-laplacian', 'uniform');  // a fixed uniform operator stays positive definite
    await page.check('#sm-fixed');
    await press('run-smooth');
    assert.equal(await errorText(), '');
    await page.click('#reset-camera');
    const collapsed = await ndcOfGeometry();
    assert.equal(collapsed.outside, 0);
    assert.equal(await page.evaluate(() => document.body.dataset.edgesOnly), '');
    assert.ok(collapsed.maxAbs > 0.5, `reset camera on a collapsed mesh: it fills the view (${collapsed.maxAbs})`);
    await page.fill('#sm-lambda', 'auto');
    await page.selectOption('#sm-unit', 'absolute');
    await page.fill('#sm-iterations', '5');
    await page.selectOption('#sm-laplacian', 'cotangent');
    await page.uncheck('#sm-fixed');
    await page.selectOption('#noise-scale', 'mean-edge');
    await page.fill('#noise-level', '0.1');
    await page.fill('#noise-seed', '0');
    await press('reset');
    await press('run-curvature');  // the downloads below expect the curvatures

    // --- view controls: wireframe, flat shading, orbit, zoom, camera reset, PNG.
    await page.check('#wireframe');
    await page.selectOption('#shading', 'flat');
    const wireShot = await shot('wireframe_flat');
    await page.mouse.move(box.x + 300, box.y + 300);
    await page.mouse.down();
    await page.mouse.move(box.x + 420, box.y + 340, { steps: 5 });
    await page.mouse.up();
    await page.mouse.wheel(0, -400);
    await page.waitForTimeout(200);
    const orbited = await page.screenshot();
    assert.notDeepEqual(orbited, wireShot, 'orbit/zoom changed nothing');
    await page.click('#reset-camera');
    await page.uncheck('#wireframe');
    await page.selectOption('#shading', 'smooth');
    const [png] = await Promise.all([page.waitForEvent('download'), page.click('#screenshot')]);
    const pngFile = path.join(outDir, 'download.png');
    await png.saveAs(pngFile);
    assert.equal(fs.readFileSync(pngFile).subarray(1, 4).toString(), 'PNG');

    // --- downloads: PLY with the scalars, OFF with colours.
    const [ply] = await Promise.all([page.waitForEvent('download'), page.click('#download-ply')]);
    const plyFile = path.join(outDir, 'download.ply');
    await ply.saveAs(plyFile);
    const plyText = fs.readFileSync(plyFile, 'utf8');
    assert.match(plyText, /^ply\n/);
    for (const p of ['mean', 'gaussian', 'k1', 'k2', 'red']) assert.ok(plyText.includes(`property double ${p}\n`) || p === 'red', p);
    assert.ok(plyText.includes('property uchar red'));
    const [off] = await Promise.all([page.waitForEvent('download'), page.click('#download-off')]);
    const offFile = path.join(outDir, 'download.off');
    await off.saveAs(offFile);
    assert.match(fs.readFileSync(offFile, 'utf8'), new RegExp(`^COFF\\n${original.length / 3} `));

    // --- reconstruction, and an invalid k shown as an error in the page.
    await page.fill('#rec-k', '0');
    await press('run-reconstruct');
    assert.match(await errorText(), /'k' must be an integer in \[1, /);
    await shot('error_invalid_k');
    await page.fill('#rec-k', '100000000');
    await press('run-reconstruct');
    assert.match(await errorText(), /'k'/);
    assert.deepEqual(await positions(), original, 'a refused request changed the mesh');
    await page.fill('#rec-k', '60');
    await page.selectOption('#rec-area', 'mixed');
    await press('run-reconstruct');
    assert.equal(await errorText(), '');
    assert.match(await page.textContent('#status'), /reconstruct: [\d.]+ ms on the server, k = 60/);
    const reconstructed = await positions();
    assert.notDeepEqual(reconstructed, original);
    await shot('reconstruct_k60');

    // --- smoothing changes the vertex positions (page = API), reset restores them.
    await press('reset');
    assert.deepEqual(await positions(), original);
    await page.selectOption('#sm-scheme', 'implicit');
    await page.fill('#sm-lambda', 'auto');
    await page.fill('#sm-iterations', '5');
    await press('run-smooth');
    assert.equal(await errorText(), '');
    const smoothed = await positions();
    let moved = 0;
    smoothed.forEach((x, i) => { moved = Math.max(moved, Math.abs(x - original[i])); });
    assert.ok(moved > 0, 'smoothing did not move any vertex');
    assert.deepEqual(smoothed, Array.from((await apiFrame(`/api/meshes/${meshId}/geometry`)).positions));
    assert.equal(await page.inputValue('#quantity'), 'displacement');
    await shot('smooth_implicit');
    // The other schemes start from the input: the implicit steps above leave slivers (doubled area
    // about 6e-8 of the longest edge squared) that the conformal step then flattens to the
    // degenerate-face tolerance, where whether it refuses depends on round-off.
    await press('reset');
    for (const [scheme, lambda, unit, fixed] of [['explicit', '0.5', 'bound', true], ['conformal', '1', 'edge2', false]]) {
      await page.selectOption('#sm-scheme', scheme);
      await page.fill('#sm-lambda', lambda);
      await page.selectOption('#sm-unit', unit);
      await page.fill('#sm-iterations', '3');
      await page.selectOption('#sm-laplacian', scheme === 'explicit' ? 'uniform' : 'cotangent');
      await page.selectOption('#sm-area', 'mixed');
      if (fixed) await page.check('#sm-fixed'); else await page.uncheck('#sm-fixed');
      await page.check('#sm-restore');
      await press('run-smooth');
      assert.equal(await errorText(), '', scheme);
    }
    await page.check('#sm-restore-area');
    await press('run-smooth');
    assert.match(await errorText(), /not both/);
    await page.uncheck('#sm-restore');
    await page.check('#sm-free-boundary');
    await press('reset');
    await page.selectOption('#sm-scheme', 'implicit');
    await press('run-smooth');
    assert.equal(await errorText(), '', 'restore area, free boundary');
    await page.uncheck('#sm-restore-area');
    await page.uncheck('#sm-free-boundary');
    await page.fill('#sm-lambda', '-1');
    await press('run-smooth');
    assert.match(await errorText(), /lambda/);

    // --- noise, seeded: the same seed twice from the input gives the same mesh.
    await press('reset');
    await page.fill('#noise-level', '0.2');
    await page.fill('#noise-seed', '42');
    await page.selectOption('#noise-direction', 'normal');
    await press('run-noise');
    const noisy = await positions();
    await press('reset');
    await press('run-noise');
    assert.deepEqual(await positions(), noisy);
    assert.notDeepEqual(noisy, original);
    await page.selectOption('#noise-scale', 'bbox');
    await page.selectOption('#noise-direction', 'isotropic');
    await page.fill('#noise-level', '0.002');
    await press('run-noise');
    await shot('noise');
    await page.fill('#noise-level', '-1');
    await press('run-noise');
    assert.match(await errorText(), /level/);

    // --- a blown-up mesh (explicit smoothing far above its stability bound): not drawn, said
    // so, and the page keeps rendering; Reset brings it back.
    await page.selectOption('#mesh', 'bumpy-sphere');
    await page.waitForFunction(() => window.lapmeshViewer.geometry.header.id === 'bumpy-sphere');
    await idle();
    await press('reset');
    await page.selectOption('#sm-scheme', 'explicit');
    await page.fill('#sm-lambda', '50');
    await page.selectOption('#sm-unit', 'bound');
    // a fixed uniform operator: the growth stays finite (about 100x per step), no face degenerates
    await page.selectOption('#sm-laplacian', 'uniform');
    await page.check('#sm-fixed');
    await page.uncheck('#sm-restore');
    await page.fill('#sm-iterations', '10');
    await press('run-smooth');
    assert.equal(await errorText(), '');
    assert.match(await warningText(), /not drawn/);
    assert.equal(await page.evaluate(() => document.body.dataset.blownUp), '1');
    let t = Date.now();
    await shot('blown_up');
    assert.ok(Date.now() - t < 5000, `a frame of the blown-up mesh took ${Date.now() - t} ms`);
    await page.mouse.move(box.x + 300, box.y + 300);
    await page.mouse.down();
    await page.mouse.move(box.x + 380, box.y + 330, { steps: 3 });
    await page.mouse.up();
    t = Date.now();
    await page.screenshot();
    assert.ok(Date.now() - t < 5000, 'frames freeze after orbiting the blown-up mesh');
    await press('reset');
    assert.equal(await warningText(), '');
    assert.equal(await page.evaluate(() => window.lapmeshViewer.cameraState().drawn), true);

    // --- a warning (explicit step above the bound), then a long run with progress and Cancel:
    // at 1280 x 800 none of status, warning, progress, colour bar and error overlap.
    await page.fill('#sm-lambda', '1.5');
    await page.fill('#sm-iterations', '1');
    await press('run-smooth');
    assert.match(await warningText(), /exceeds the explicit stability bound/);
    await page.selectOption('#sm-scheme', 'implicit');
    await page.fill('#sm-lambda', '0.001');
    await page.selectOption('#sm-unit', 'absolute');
    await page.selectOption('#sm-laplacian', 'cotangent');
    await page.uncheck('#sm-fixed');
    await page.fill('#sm-iterations', '10000');
    await page.click('#run-smooth');
    await page.waitForFunction(() => /bumpy-sphere: smooth · smoothing · \d+\/10000/.test(document.getElementById('progress-text').textContent));
    const shown = await assertNoOverlap(['status', 'warning', 'progress', 'colorbar-box', 'error']);
    for (const id of ['warning', 'progress', 'colorbar-box']) assert.ok(shown.includes(id), `${id} not shown`);
    await shot('progress');

    // --- switching mesh during the run: progress stays that of the bumpy sphere, Cancel
    // cancels it (not the icosphere), and the icosphere is not labelled with its result.
    const icoBefore = Array.from((await apiFrame('/api/meshes/icosphere/geometry')).positions);
    await page.selectOption('#mesh', 'icosphere');
    await page.waitForFunction(() => window.lapmeshViewer.geometry.header.id === 'icosphere');
    const progressOf = () => page.textContent('#progress-text');
    const p1 = await progressOf();
    await page.waitForFunction((before) => {
      const now = document.getElementById('progress-text').textContent;
      return now !== before && /^bumpy-sphere: smooth · smoothing · \d+\/10000/.test(now);
    }, p1);
    await page.click('#cancel');
    await idle();
    assert.equal(await errorText(), 'bumpy-sphere: cancelled');
    const bumpyProgress = await (await api('/api/meshes/bumpy-sphere/progress')).json();
    assert.equal(bumpyProgress.running, false);
    assert.equal(bumpyProgress.cancel_requested, true);
    assert.equal(await page.evaluate(() => window.lapmeshViewer.geometry.header.id), 'icosphere');
    assert.deepEqual(await positions(), icoBefore);
    assert.doesNotMatch(await page.textContent('#status'), /smooth/);
    await assertNoOverlap(['status', 'warning', 'progress', 'colorbar-box', 'error']);

    // A run that finishes while another mesh is shown: the status names its mesh.
    await page.selectOption('#mesh', 'bumpy-sphere');
    await page.waitForFunction(() => window.lapmeshViewer.geometry.header.id === 'bumpy-sphere');
    await page.fill('#sm-iterations', '100');
    await page.click('#run-smooth');
    await page.waitForFunction(() => /^bumpy-sphere: smooth/.test(document.getElementById('progress-text').textContent));
    await page.selectOption('#mesh', 'icosphere');
    await page.waitForFunction(() => window.lapmeshViewer.geometry.header.id === 'icosphere');
    await idle();
    assert.equal(await errorText(), '');
    assert.match(await page.textContent('#status'), /^smooth on bumpy-sphere finished/);
    assert.deepEqual(await positions(), icoBefore);
    await page.selectOption('#mesh', 'bumpy-sphere');
    await page.waitForFunction(() => window.lapmeshViewer.geometry.header.id === 'bumpy-sphere');
    await idle();
    await press('reset');

    // --- a figure through URL parameters (what a report script does), without the panel.
    await page.goto(`${url}?mesh=${meshId}&op=curvature&area=mixed&quantity=mean&colormap=coolwarm&range=percentile&clip=1&ui=0&azimuth=60&elevation=10`);
    await idle();
    assert.equal(await errorText(), '');
    assert.deepEqual(await colorbar(), clipped.header.range);
    await shot('url_figure');

    assert.deepEqual(pageErrors, [], 'errors in the page');
    log('viewer_e2e: all checks passed');
  } finally {
    if (pageErrors.length) console.error('errors in the page:', pageErrors.join('\n'));
    await context.close();
    proc.kill('SIGTERM');
    fs.rmSync(userDataDir, { recursive: true, force: true });
  }
}

main().catch((e) => {
  console.error('viewer_e2e FAILED:', e && e.stack ? e.stack : e);
  process.exit(1);
});
