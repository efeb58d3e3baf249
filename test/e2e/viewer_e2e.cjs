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
    viewport: { width: 1000, height: 700 },
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
    const idle = () => page.waitForFunction(() => document.body.dataset.ready === '1' && !document.body.dataset.busy);
    const press = async (id) => {
      await page.click(`#${id}`);
      await page.waitForTimeout(50);
      await idle();
    };
    const positions = () => page.evaluate(() => Array.from(window.lapmeshViewer.geometry.positions));
    const colorbar = async () => page.evaluate(() => [Number(document.getElementById('colorbar-box').dataset.min),
      Number(document.getElementById('colorbar-box').dataset.max)]);
    const errorText = () => page.evaluate(() => { const e = document.getElementById('error'); return e.hidden ? '' : e.textContent; });

    await page.goto(url);
    await idle();
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
    await page.fill('#clip', '1');
    await page.selectOption('#range-mode', 'percentile');
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
    await page.fill('#clip', '2');
    await page.dispatchEvent('#clip', 'change');
    await idle();
    await page.waitForFunction(() => window.lapmeshViewer.scalars.header.quantity === 'gaussian' &&
      window.lapmeshViewer.scalars.header.clip === 2);
    const sym = await colorbar();
    assert.equal(sym[0], -sym[1]);
    assert.deepEqual(sym, (await apiFrame(`/api/meshes/${meshId}/scalars?quantity=gaussian&range=symmetric&clip=2`)).header.range);
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

    // --- progress and cancel of a long smoothing run on the bumpy sphere.
    await page.selectOption('#mesh', 'bumpy-sphere');
    await page.waitForFunction(() => window.lapmeshViewer.geometry.header.id === 'bumpy-sphere');
    await idle();
    await page.selectOption('#sm-scheme', 'implicit');
    await page.fill('#sm-lambda', '0.001');
    await page.selectOption('#sm-unit', 'absolute');
    await page.selectOption('#sm-laplacian', 'cotangent');
    await page.uncheck('#sm-fixed');
    await page.fill('#sm-iterations', '10000');
    await page.click('#run-smooth');
    await page.waitForFunction(() => /smooth · smoothing · \d+\/10000/.test(document.getElementById('progress-text').textContent));
    await shot('progress');
    await page.click('#cancel');
    await idle();
    assert.equal(await errorText(), 'cancelled');

    // --- a figure through URL parameters (what a report script does), without the panel.
    await page.goto(`${url}?mesh=${meshId}&op=curvature&area=mixed&quantity=mean&colormap=coolwarm&range=percentile&clip=1&ui=0&azimuth=60&elevation=10`);
    await idle();
    assert.equal(await errorText(), '');
    assert.deepEqual(await colorbar(), clipped.header.range);
    await shot('url_figure');

    assert.deepEqual(pageErrors, [], 'errors in the page');
    log('viewer_e2e: all checks passed');
  } finally {
    await context.close();
    proc.kill('SIGTERM');
    fs.rmSync(userDataDir, { recursive: true, force: true });
  }
}

main().catch((e) => {
  console.error('viewer_e2e FAILED:', e && e.stack ? e.stack : e);
  process.exit(1);
});
