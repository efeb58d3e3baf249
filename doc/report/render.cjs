// Renders the report's figures through lapmesh's own viewer: starts `lapmesh view MESH...`,
// opens one URL per figure in Debian's headless Chromium (playwright-core), waits for the page
// to finish the operations named in the URL (body[data-ready="1"]), checks that it shows no
// error, and saves a PNG screenshot. Called by scripts/report.sh; see doc/report.md.
//
// Usage: node render.cjs JOBS.json
//   JOBS.json: {"cli": "build/src/lapmesh", "node_modules": "...", "chromium": "/usr/bin/chromium",
//               "meshes": [{"key": "cow", "file": "a/cow.off"}, ...], "out_dir": "doc/images/report",
//               "results": "r.json", "width": 600, "height": 450,
//               "download": [{"mesh": "bumpy-sphere", "to": "bumpy.off"}],      (optional, a viewer id)
//               "figures": [{"name": "cow_mean_uniform", "mesh": "cow", "query": "op=curvature&..."}]}
//   A figure names its mesh by key; the viewer's id for it (which the viewer makes from the
//   file name, so two cow.off are "cow" and "cow-2") is looked up by the file's position.
//   (A mesh given as a plain path, and a figure without "mesh" whose query holds mesh=ID, work
//   too: the query is then used as it is.)
//   In a query, RANGE_OF(NAME) stands for the manual colour range of the earlier figure NAME.
//   Writes out_dir/NAME.png per figure and, in "results", per figure: the colour range shown,
//   the data range, and the answers of the operations the page ran (lambda, sigma, bound, ...).
// Any failure (no URL from the server, an error shown in the page, a timeout) exits non-zero
// with one line on stderr.
'use strict';
const { spawn } = require('node:child_process');
const fs = require('node:fs');
const os = require('node:os');
const path = require('node:path');

function fail(message) {
  process.stderr.write(`render.cjs: ${message}\n`);
  process.exit(1);
}

const jobs = JSON.parse(fs.readFileSync(process.argv[2] || fail('usage: node render.cjs JOBS.json'), 'utf8'));
jobs.meshes = (jobs.meshes || []).map((m) => (typeof m === 'string' ? { key: null, file: m } : m));
let chromium;
try {
  ({ chromium } = require(path.resolve(jobs.node_modules, 'playwright-core')));
} catch (e) {
  fail(`playwright-core not found in ${jobs.node_modules} (build the target lapmesh_cli first): ${e.message}`);
}

function startServer() {
  const proc = spawn(jobs.cli, ['view', ...jobs.meshes.map((m) => m.file)], { stdio: ['ignore', 'pipe', 'pipe'] });
  let stderr = '';
  proc.stderr.on('data', (d) => { stderr += d; });
  const url = new Promise((resolve, reject) => {
    let out = '';
    const timer = setTimeout(() => reject(new Error(`no URL from lapmesh view within 120 s; stderr: ${stderr.trim()}`)), 120000);
    proc.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/http:\/\/127\.0\.0\.1:(\d+)\//);
      if (m) { clearTimeout(timer); resolve(m[0]); }
    });
    proc.on('exit', (code) => { clearTimeout(timer); reject(new Error(`lapmesh view exited with status ${code}: ${stderr.trim()}`)); });
    proc.on('error', (e) => { clearTimeout(timer); reject(e); });
  });
  return { proc, url };
}

async function main() {
  const { proc, url: urlPromise } = startServer();
  let context = null;
  try {
    const url = await urlPromise;
    for (const d of jobs.download || []) {
      const r = await fetch(new URL(`api/meshes/${d.mesh}/download?format=off`, url));
      if (!r.ok) throw new Error(`download of ${d.mesh}: HTTP ${r.status} ${await r.text()}`);
      fs.writeFileSync(d.to, Buffer.from(await r.arrayBuffer()));
    }
    // The viewer lists the files given first, in order, then its built-in meshes.
    const listed = (await (await fetch(new URL('api/meshes', url))).json()).meshes;
    const idOf = {};
    jobs.meshes.forEach((m, i) => {
      const v = listed[i];
      if (!v || v.kind !== 'file' || v.label !== path.basename(m.file))
        throw new Error(`the viewer lists ${JSON.stringify(v)} where ${m.file} was expected`);
      if (m.key !== null) idOf[m.key] = v.id;
    });
    const figures = jobs.figures || [];
    if (figures.length === 0) return;
    fs.mkdirSync(jobs.out_dir, { recursive: true });
    const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'lapmesh-report-chromium-'));
    context = await chromium.launchPersistentContext(userDataDir, {
      executablePath: jobs.chromium,
      headless: true,
      viewport: { width: jobs.width || 600, height: jobs.height || 450 },
      args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
        '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
    });
    const page = context.pages()[0] || await context.newPage();
    const pageErrors = [];
    page.on('pageerror', (e) => pageErrors.push(e.message));
    let answers = [];
    page.on('response', async (r) => {
      const m = r.url().match(/\/api\/meshes\/[^/]+\/(curvature|reconstruct|smooth|noise)$/);
      if (!m || r.request().method() !== 'POST') return;
      try { answers.push({ op: m[1], ...(await r.json()) }); } catch { /* an error answer: the page shows it */ }
    });
    const results = {};
    for (const fig of figures) {
      const t0 = Date.now();
      answers = [];
      // RANGE_OF(other): the colour range an earlier figure showed, so that two figures compare
      const query = fig.query.replace(/RANGE_OF\(([^)]+)\)/g, (_, other) => {
        if (!results[other]) throw new Error(`figure ${fig.name}: RANGE_OF(${other}) before that figure`);
        const [lo, hi] = results[other].colour_range;
        return `range=manual&min=${lo}&max=${hi}`;
      });
      if (fig.mesh !== undefined && !idOf[fig.mesh]) throw new Error(`figure ${fig.name}: unknown mesh key ${fig.mesh}`);
      fig.query = fig.mesh === undefined ? query : `mesh=${encodeURIComponent(idOf[fig.mesh])}&${query}`;
      await page.goto(`${url}?${fig.query}`);
      await page.waitForFunction(() => document.body.dataset.ready === '1', null, { timeout: 300000 });
      const shown = await page.evaluate(() => {
        const e = document.getElementById('error');
        const box = document.getElementById('colorbar-box');
        return { error: e.hidden ? '' : e.textContent, min: Number(box.dataset.min), max: Number(box.dataset.max),
          title: document.getElementById('colorbar-title').textContent };
      });
      if (shown.error) throw new Error(`figure ${fig.name} (${fig.query}): the page shows the error: ${shown.error}`);
      if (pageErrors.length) throw new Error(`figure ${fig.name}: page error: ${pageErrors.join('; ')}`);
      await page.waitForTimeout(100);
      await page.screenshot({ path: path.join(jobs.out_dir, `${fig.name}.png`) });
      results[fig.name] = { query: fig.query, colour_range: [shown.min, shown.max], colour_title: shown.title,
        answers, seconds: (Date.now() - t0) / 1000 };
      process.stdout.write(`  ${fig.name}.png (${((Date.now() - t0) / 1000).toFixed(1)} s)\n`);
    }
    if (jobs.results) fs.writeFileSync(jobs.results, JSON.stringify(results, null, 1));
  } finally {
    if (context) await context.close();
    proc.kill('SIGTERM');
  }
}

main().catch((e) => fail(e.message.split('\n')[0]));
