// The two halves of scripts/report.sh that need more than shell:
//   node report.cjs jobs WORK CLI NODE_MODULES CHROMIUM IMAGES   -> jobs JSON for render.cjs (stdout)
//   node report.cjs report WORK SECONDS STUDY                    -> doc/report.md (stdout)
// WORK holds what report.sh measured: meshes.tsv (KEY, ORIGIN, PATH per mesh), bounds.csv,
// recon_KEY.csv, study_KEY.csv (lapmesh denoise-study) and, after rendering, results.json.
// Everything is keyed by the mesh's key, which report.sh makes unique per path.
'use strict';
const fs = require('node:fs');
const path = require('node:path');

const [mode, work] = process.argv.slice(2, 4);
const fail = (m) => { process.stderr.write(`report.cjs: ${m}\n`); process.exit(1); };
if (!mode || !work) fail('usage: node report.cjs jobs|report WORK ...');

const meshes = fs.readFileSync(path.join(work, 'meshes.tsv'), 'utf8').split('\n').filter(Boolean)
  .map((line) => { const [key, origin, file] = line.split('\t'); return { key, origin, file }; });
if (new Set(meshes.map((m) => m.key)).size !== meshes.length) fail('meshes.tsv: two meshes share a key');
const BOX = 'bumpy-box';   // report.sh's generated mesh: lapmesh::bumpy_box(seed 1)
function csv(file) {
  const lines = fs.readFileSync(file, 'utf8').trim().split('\n');
  const head = lines[0].split(',');
  return lines.slice(1).map((l) => Object.fromEntries(l.split(',').map((v, i) => [head[i], v])));
}
const bounds = csv(path.join(work, 'bounds.csv'));
const bound = (mesh, lap) => Number(bounds.find((b) => b.mesh === mesh && b.laplacian === lap).stability_bound);
const edge2 = (mesh) => Number(bounds.find((b) => b.mesh === mesh).mean_edge2);
const diagonal = (mesh) => { const r = csv(path.join(work, `recon_${mesh}.csv`))[0]; return Number(r.rms_distance) / Number(r.rms_over_diagonal); };
const vertices = (mesh) => Number(bounds.find((b) => b.mesh === mesh).vertices);
const studyFile = (mesh) => path.join(work, `study_${mesh}.csv`);
const study = (mesh) => (fs.existsSync(studyFile(mesh)) ? csv(studyFile(mesh)).map((r) => ({ ...r,
  noise_level: Number(r.noise_level), iteration: Number(r.iteration), rms: Number(r.rms_distance),
  lambda: Number(r.lambda), step: Number(r[Object.keys(r).find((k) => k.startsWith('lambda_'))]) })) : null);
const ok = (r) => r.status !== 'diverged' && Number.isFinite(r.rms);
const LEVELS = [0.02, 0.05, 0.1, 0.3];   // the study's (report.sh STUDY_OPTIONS)
const FIGURE_LEVELS = [0.02, 0.1, 0.3];
// Explicit steps above the bound: enough growth to show the artefacts, not so much that the
// exploded mesh fills the screen (1.5 x the uniform bound for 15 steps makes the cow 166 diagonals large).
const LARGE = { uniform: { factor: 1.2, iterations: 15 }, cotangent: { factor: 1.5, iterations: 20 } };
// The issue #3 figure grid (k = 5, 10, 30, 100, 300) on CGAL's bunny00 (report.sh lists the
// built-in meshes first: their keys are their names).
const GRID_MESH = 'bunny00';
const GRID_K = [5, 10, 30, 100, 300];
// The course's meshes (not in the repository), measured with this version by
// `scripts/report.sh path/to/bumpy.off path/to/cow.off path/to/bunny.off` and `lapmesh smooth`:
// vertices, bounding box, cotangent and uniform explicit stability bounds (barycentric mass),
// mean edge length squared, reconstruction error / diagonal at k = 5, 10, 30.
const COURSE = {
  date: '2026-11-22',
  bumpy: { vertices: 1250, box: 4.378, cotangent: 0.0187721, uniform: 1.33877, edge2: 0.157933 },
  cow: { vertices: 2762, cotangent: 1.46899e-6, uniform: 1.33939, edge2: 0.00050825 },
  bunny: { vertices: 3485, cotangent: 1.93003e-7, uniform: 1.35878, edge2: 2.17258e-5 },
  bumpyRecon: [0.0206713, 0.0205911, 0.0155211],   // every one of these k splits a repeated eigenvalue
  bumpyEigen: [0.365969, 0.725848, 2.41192],        // lambda_{k-1} at k = 5, 10, 30
  // the seed's 5e-7 on the course's bunny.off: largest displacement / diagonal after 10 and 100 steps
  bunnyRebuilt: [0.0148, 0.0705], bunnyFixed10: 337,
  notes: (x) => {
    const box = csv(path.join(work, `recon_${x.BOX}.csv`));
    const eig = [5, 10, 30].map((k) => Number(box.find((r) => Number(r.k) === k).eigenvalue));
    return [
      '**The bumpy box against the course\'s bumpy.off.** Both are a rounded cube with one bump along each axis, about ' +
      `1.2k vertices, a bounding box of ±4.4 and a mean edge of 0.4 (${g(Math.sqrt(COURSE.bumpy.edge2))} and ${g(Math.sqrt(x.edge2(x.BOX)))}). ` +
      'The course\'s mesh is triangulated with the cube\'s full symmetry (valences 4-8, angles 36-96°); the box is ' +
      'sampled at random (valences 4-9, angles 30-118°). Their low spectra agree (λ_4, λ_9, λ_29 = ' +
      `${COURSE.bumpyEigen.map((e) => g(e)).join(', ')} against ${eig.map((e) => g(e)).join(', ')}), and so does the ` +
      'reconstruction error at k = 5, 10, 30. The course\'s symmetry makes its eigenvalues repeat: k = 5, 10, 30 and 100 all cut ' +
      'through an eigenspace there, so its k-images depend on the basis the solver picks; the box has simple eigenvalues. ' +
      `Its cotangent bound is ${g(x.bound(x.BOX, 'cotangent') / COURSE.bumpy.cotangent, 2)} × the course mesh\'s: the ` +
      'random sample has no triangle as small as the course mesh\'s smallest. Rendered side by side with the same URLs ' +
      '(not committed: the course\'s mesh is not ours to publish), the two show the same artefacts: 15 uniform steps at 1.2 × ' +
      'the bound turn both into a ball of spikes (largest displacement 13% of the diagonal on the course\'s mesh, 46% on the box), ' +
      '20 cotangent steps at 1.5 × the bound crumple only the bump tips on both (23% and 15%), and 20 cotangent steps at ' +
      'the seed\'s λ = 0.01 smooth both and lower the bumps without artefacts. Their cotangent mean curvature maps agree on the faces, edges and ' +
      'bumps; the box\'s concave creases where the bumps meet it are sharper (no fillet), so its negative range is wider.',
      '',
      '**Where a conclusion differs on the course\'s meshes.** The seed\'s λ = 5e-7 for the bunny is ' +
      `${g(5e-7 / COURSE.bunny.cotangent, 2)} × the cotangent bound of the course\'s bunny.off (${g(COURSE.bunny.cotangent)}, ` +
      `${COURSE.bunny.vertices} vertices); the ${g(5e-7 / x.bound('bunny00', 'cotangent'), 2)} × of the λ section is against CGAL\'s ` +
      `bunny00.off (${x.vertices('bunny00')} vertices), another mesh. Measured with \`lapmesh smooth --scheme explicit --lambda 5e-7\` ` +
      'on the course\'s bunny: with the operator rebuilt every step (the default) the largest displacement is ' +
      `${g(100 * COURSE.bunnyRebuilt[0], 2)}% of the diagonal after 10 steps and ${g(100 * COURSE.bunnyRebuilt[1], 2)}% after 100, ` +
      'because the unstable modes sit on a few small triangles that the flow itself enlarges; with `--fixed-operator` ' +
      `10 steps blow the bunny up to ${COURSE.bunnyFixed10} diagonals. The seed\'s value looked right only because its operator followed the ` +
      `mesh. Its 1e-6 for the cow is ${g(1e-6 / COURSE.cow.cotangent, 2)} × the bound of the course\'s cow.off ` +
      `(${COURSE.cow.vertices} vertices; CGAL\'s has ${x.vertices('cow')}), and 0.01 is ${g(0.01 / COURSE.bumpy.cotangent, 2)} × that of its bumpy.off.`,
    ];
  },
};
const view = 'ui=0&azimuth=60&elevation=10&zoom=1.3';
const viewOf = (m) => (m === 'bunny00' ? 'ui=0&azimuth=0&elevation=10&zoom=1.3' : view);

// Best (smallest RMS) run of a scheme at a noise level, from the study's CSV.
function best(rows, level, scheme) {
  let b = null;
  for (const r of rows) if (r.noise_level === level && r.scheme === scheme && r.iteration > 0 && ok(r) && (!b || r.rms < b.rms)) b = r;
  return b;
}
// Fallback settings when `lapmesh denoise-study` is not available.
const fallback = { explicit: { laplacian: 'cotangent', lambda: '0.9', unit: 'bound', iterations: 10 },
  implicit: { laplacian: 'cotangent', lambda: '1', unit: 'edge2', iterations: 2 } };
function denoiseSettings(mesh, level, scheme) {
  const rows = study(mesh);
  const b = rows && best(rows, level, scheme);
  if (!b) return { ...fallback[scheme], from: 'fixed' };
  return { laplacian: b.laplacian, lambda: String(b.lambda), unit: 'absolute', iterations: b.iteration, from: 'study', row: b };
}

function figures() {
  const figs = [];
  for (const { key: m } of meshes) {
    const add = (name, query) => figs.push({ name, mesh: m, query });
    const v = viewOf(m);
    const cm = 'colormap=coolwarm&range=percentile&clip=1';
    add(`${m}_mean_uniform`, `op=curvature&laplacian=uniform&area=barycentric&quantity=mean&${cm}&${v}`);
    add(`${m}_gaussian`, `op=curvature&laplacian=uniform&area=barycentric&quantity=gaussian&${cm}&${v}`);
    add(`${m}_mean_cotangent`, `op=curvature&laplacian=cotangent&area=mixed&quantity=mean&${cm}&${v}`);
    for (const k of m === GRID_MESH ? GRID_K : [5, 10, 30])
      add(`${m}_reconstruct_k${k}`, `op=reconstruct&k=${k}&laplacian=cotangent&area=mixed&colormap=viridis&${v}`);
    for (const lap of ['uniform', 'cotangent']) {
      add(`${m}_explicit_${lap}_stable`, `op=smooth&scheme=explicit&laplacian=${lap}&lambda=0.9&lambda_unit=bound&iterations=20&colormap=viridis&${v}`);
      add(`${m}_explicit_${lap}_large`, `op=smooth&scheme=explicit&laplacian=${lap}&lambda=${LARGE[lap].factor}&lambda_unit=bound&iterations=${LARGE[lap].iterations}&colormap=viridis&${v}`);
    }
    for (const lam of ['1', '1e-3', '1e-5'])
      add(`${m}_implicit_${lam}`, `op=smooth&scheme=implicit&laplacian=cotangent&lambda=${lam}&lambda_unit=absolute&iterations=1&colormap=viridis&${v}`);
    // Gaussian curvature (angle deficit / barycentric area) does not depend on the Laplacian, but
    // the URL's one `laplacian` sets the smoothing's and the curvature's, and the colour bar names
    // it: the clean and noisy maps use the same (uniform), a denoised map names its smoothing's,
    // and every figure is captioned with what was computed (caption()). Barycentric is also the
    // study's area.
    const ref = `${m}_gaussian`;
    // denoising figures: the meshes the study ran on (all meshes with fixed settings when there is no study)
    if (!study(m) && meshes.some((x) => study(x.key))) continue;
    for (const level of FIGURE_LEVELS) {
      const noise = `level=${level}&seed=1&scale=mean-edge&direction=isotropic`;
      add(`${m}_noisy_${level}`, `op=noise,curvature&${noise}&laplacian=uniform&area=barycentric&quantity=gaussian&colormap=coolwarm&RANGE_OF(${ref})&${v}`);
      for (const scheme of ['explicit', 'implicit']) {
        const s = denoiseSettings(m, level, scheme);
        add(`${m}_denoised_${scheme}_${level}`, `op=noise,smooth,curvature&${noise}&scheme=${scheme}&lambda=${s.lambda}` +
          `&lambda_unit=${s.unit}&iterations=${s.iterations}&area=barycentric&laplacian=${s.laplacian}&quantity=gaussian&colormap=coolwarm&RANGE_OF(${ref})&${v}`);
      }
    }
  }
  return figs;
}

if (mode === 'jobs') {
  const [cli, nodeModules, chromium, images] = process.argv.slice(4, 8);
  process.stdout.write(JSON.stringify({ cli, node_modules: nodeModules, chromium, meshes: meshes.map(({ key, file }) => ({ key, file })),
    out_dir: images, results: path.join(work, 'results.json'), width: 480, height: 360, figures: figures() }, null, 1));
  process.exit(0);
}
if (mode !== 'report') fail(`unknown mode ${mode}`);

// ---------------------------------------------------------------- the report ------------
const [seconds, studyAvailable, studyOptions, studyMax] = process.argv.slice(4, 8);
const results = JSON.parse(fs.readFileSync(path.join(work, 'results.json'), 'utf8'));
const g = (x, d = 3) => (x === undefined || !Number.isFinite(Number(x)) ? String(x) : Number(Number(x).toPrecision(d)).toString());
const img = (name, alt) => `![${alt}](images/report/${name}.png)`;
const answer = (fig, op) => (results[fig].answers || []).filter((a) => a.op === op).pop() || {};
const range = (fig) => results[fig].colour_range.map((x) => g(x)).join(', ');
// What a figure shows, from the operations the page ran (their answers) and its query.
function caption(fig) {
  const q = new URLSearchParams(results[fig].query);
  const parts = [];
  for (const op of (q.get('op') || '').split(',')) {
    const a = answer(fig, op);
    if (op === 'noise') parts.push(`noise σ = ${g(a.sigma)}`);
    else if (op === 'smooth') parts.push(`${q.get('scheme')} ${q.get('laplacian')} smoothing, λ = ${g(a.lambda)}, ${q.get('iterations')} it.`);
    else if (op === 'reconstruct') parts.push(`k = ${q.get('k')} (cotangent, ${q.get('area')} area)`);
    else if (op === 'curvature') parts.push(q.get('quantity') === 'gaussian' ? `K: angle deficit / ${q.get('area')} area`
      : `${q.get('quantity')} curvature (${q.get('laplacian')}, ${q.get('area')} area)`);
  }
  return parts.join(' → ');
}
const cell = (fig, alt) => `${img(fig, alt)}<br>${caption(fig)}`;
const names = meshes.map((m) => m.key);
const out = [];
const p = (...lines) => out.push(...lines);
const row = (cells) => `| ${cells.join(' | ')} |`;
const table = (head, rows) => [row(head), row(head.map(() => '---')), ...rows.map(row)];

p('# The seed report, reproduced with lapmesh', '',
  `Generated by \`scripts/report.sh\` (\`cmake --build build --target report\`) on ${new Date().toISOString().slice(0, 10)}, ` +
  `in ${seconds} s on a 2-core machine shared with other builds. Do not edit by hand: change the script and run it again.`,
  '', 'Every image is a screenshot of `lapmesh view` (the project\'s viewer, driven by headless Chromium through ' +
  'URL parameters, see [viewer.md](viewer.md)); every number comes from `lapmesh smooth`, `lapmesh denoise-study` or the ' +
  'example program `examples/reconstruction_error.cpp`, run by the script. The viewer URL of every figure is listed at the end.',
  '', 'Meshes: `bumpy-box`, generated by lapmesh\'s own code (`lapmesh::bumpy_box()` in `lapmesh/shapes.h`, seed 1, written ' +
  'by the example program `make_shape`): a rounded box with a cylindrical bump on each face, irregularly triangulated, ' +
  'standing in for the seed\'s `bumpy.off` (how the two compare: see "The course\'s own meshes" below); and CGAL\'s `cow.off` ' +
  'and `bunny00.off` (Debian package `libcgal-demo`). Every row, file and figure is keyed by the mesh\'s path: a mesh given ' +
  'on the command line whose name is taken gets its folder\'s name in front (a course\'s `data/cow.off` becomes `data-cow`).', '',
  ...table(['mesh', 'file', 'vertices', 'mean edge length²'], meshes.map((m) => [m.key,
    m.origin === 'generated' ? '`make_shape bumpy-box` (seed 1)' : m.origin === 'cgal' ? `CGAL's \`${path.basename(m.file)}\`` : `\`${m.file}\``,
    vertices(m.key), g(edge2(m.key))])), '');

p('## Curvature (seed Figures 2, 4 and 5)', '',
  'Uniform "mean curvature" ½|L_u x| (the seed\'s Figure 2), Gaussian curvature by angle deficit over the barycentric area ' +
  '(Figure 4), and the cotangent mean curvature with mixed areas (Figure 5). Colour map coolwarm, range clipped at 1% on each side.', '',
  ...table(['mesh', 'uniform mean', 'Gaussian (no Laplacian: the colour bar names the URL\'s)', 'cotangent mean (mixed area)'],
    names.map((m) => [m, cell(`${m}_mean_uniform`, `${m} uniform mean`), cell(`${m}_gaussian`, `${m} Gaussian`), cell(`${m}_mean_cotangent`, `${m} cotangent mean`)])),
  '', ...table(['mesh', 'uniform mean: colour range', 'Gaussian: colour range', 'cotangent mean: colour range'],
    names.map((m) => [m, range(`${m}_mean_uniform`), range(`${m}_gaussian`), range(`${m}_mean_cotangent`)])), '',
  'The uniform quantity is not a curvature: it scales like a length (its range on the cow, whose mean edge is ' +
  `${g(Math.sqrt(edge2('cow')))}, is ${range('cow_mean_uniform')}, against ${range('cow_mean_cotangent')} for the cotangent one) ` +
  'and it follows the sampling, which is why the uniform maps are patchy where the cotangent maps are smooth ' +
  '(see [conventions.md](conventions.md)). On the bumpy box the uniform map is speckled by the irregular sampling even on the ' +
  'flat faces, while the cotangent map is near zero there and picks out the rounded edges, the bumps and the concave creases ' +
  'where they meet the box. The cotangent mean curvature is positive on convex parts and negative in the ' +
  'saddles and concavities (with outward normals).', '');

p('## Spectral reconstruction (seed Figure 6, issue #3 grid)', '',
  'Positions projected on the first k eigenvectors of the cotangent Laplacian (mixed areas), coloured by the distance ' +
  'each vertex moved (viridis, auto range).', '',
  ...table(['mesh', 'k = 5', 'k = 10', 'k = 30'], names.map((m) => [m, ...[5, 10, 30].map((k) => img(`${m}_reconstruct_k${k}`, `${m} k=${k}`))])), '',
  `The figure grid of issue #3 on \`${GRID_MESH}\` (${vertices(GRID_MESH)} vertices):`, '',
  ...table(GRID_K.map((k) => `k = ${k}`), [GRID_K.map((k) => img(`${GRID_MESH}_reconstruct_k${k}`, `${GRID_MESH} k=${k}`))]), '',
  'Reconstruction error (RMS vertex distance over the bounding-box diagonal, `reconstruction_error MESH`):', '');
const recon = Object.fromEntries(names.map((m) => [m, csv(path.join(work, `recon_${m}.csv`))]));
const ks = [...new Set(names.flatMap((m) => recon[m].map((r) => Number(r.k))))].sort((a, b) => a - b);
p(...table(['mesh', ...ks.map((k) => `k = ${k}`)], names.map((m) => [m, ...ks.map((k) => {
  const r = recon[m].find((x) => Number(x.k) === k);
  return r ? `${g(r.rms_over_diagonal)}${r.splits_eigenspace === '1' ? ' *' : ''}` : '-';
})])), '', '\\* k cuts through a repeated eigenvalue (λ_{k−1} = λ_k to 1e-8): the result then depends on the basis ' +
  'the solver picked inside that eigenspace, and `lapmesh reconstruct` warns. The bumpy box\'s triangulation has no ' +
  'symmetry, so its eigenvalues are simple and its images do not depend on the solver\'s choices.', '');
const reconAt = (m, k) => Number((recon[m].find((x) => Number(x.k) === k) || {}).rms_over_diagonal);
p(`How many eigenvectors are needed: with 5 the shape is a blob (${names.map((m) => `${m} ${g(100 * reconAt(m, 5), 2)}%`).join(', ')} ` +
  `of the diagonal); 30 give the overall shape (${names.map((m) => `${g(100 * reconAt(m, 30), 2)}%`).join(', ')}); ` +
  `the legs, ears and bumps need 100-300 (${names.map((m) => `${g(100 * reconAt(m, 300), 2)}%`).join(', ')} at k = 300). ` +
  'On the bumpy box k = 5 and 10 are rounded, octahedron-like blobs that differ in where they bulge (their errors ' +
  `are close: ${g(100 * reconAt(BOX, 5), 2)}% and ${g(100 * reconAt(BOX, 10), 2)}%), and the bumps rise from k = 30 on, as on the course's bumpy.off; ` +
  'the error falls slowest on the bunny, whose detail is spread over the whole spectrum.', '');

p('## Explicit smoothing and the stable time step (seed Figures 7-9 and its table of λ)', '',
  'The explicit step P ← P + λ L P is stable only for λ < 2/μ_max (μ_max the largest eigenvalue of −L). ' +
  '`lapmesh smooth --scheme explicit --lambda auto` computes that bound (Lanczos) and uses 0.9 of it; the table is what it ' +
  'prints, with one mean edge length squared (what `--lambda auto` gives the implicit scheme) for scale.', '',
  ...table(['mesh', 'uniform: bound', 'cotangent: bound', 'mean edge²', 'cotangent bound / mean edge²'],
    names.map((m) => [m, g(bound(m, 'uniform')), g(bound(m, 'cotangent')), g(edge2(m)), g(bound(m, 'cotangent') / edge2(m))])), '',
  'The seed\'s hand-found "perfect" λ were 0.01, 1e-6 and 5e-7 (read here as bumpy, cow, bunny). Its three meshes have very ' +
  'different sizes, so no single number could work for all three. CGAL\'s `cow.off` and `bunny00.off` are not the course\'s ' +
  `files: against them the seed\'s 1e-6 is ${g(1e-6 / bound('cow', 'cotangent'), 2)} × the cotangent bound of cow.off and 5e-7 is ` +
  `${g(5e-7 / bound('bunny00', 'cotangent'), 2)} × the bound of bunny00.off. On the course\'s own meshes (see "The course's own meshes" below) ` +
  `0.01 is ${g(0.01 / COURSE.bumpy.cotangent, 2)} ×, 1e-6 ${g(1e-6 / COURSE.cow.cotangent, 2)} × and 5e-7 ${g(5e-7 / COURSE.bunny.cotangent, 2)} × ` +
  'the cotangent bound: the bunny\'s value is above it, so it was not a stable explicit cotangent step there. ' +
  'The uniform bound is about 1 on every mesh (' +
  `${names.map((m) => g(bound(m, 'uniform'))).join(', ')}, since uniform λ is dimensionless). ` +
  'For the cotangent Laplacian λ has units of length², and the bound is set by the smallest, worst-shaped triangles: ' +
  `${names.map((m) => `${g(bound(m, 'cotangent') / edge2(m))}`).join(', ')} mean edge² here. A scale-free time step ` +
  '(λ in units of mean edge², `--lambda-unit edge2`, or of the bound, `--lambda-unit bound`, or simply `--lambda auto`) ' +
  'is the number that transfers from one mesh to another.', '',
  `Each figure: 20 steps at 0.9 × the bound ("stable"); uniform: ${LARGE.uniform.iterations} steps at ${LARGE.uniform.factor} × the bound, ` +
  `cotangent: ${LARGE.cotangent.iterations} steps at ${LARGE.cotangent.factor} × the bound ("large"); colour = distance moved, ` +
  'camera fixed on the input mesh.', '',
  ...table(['mesh', 'uniform, stable', `uniform, ${LARGE.uniform.factor} × bound`, 'cotangent, stable', `cotangent, ${LARGE.cotangent.factor} × bound`],
    names.map((m) => [m, ...['uniform_stable', 'uniform_large', 'cotangent_stable', 'cotangent_large'].map((s) => img(`${m}_explicit_${s}`, `${m} ${s}`))])), '',
  ...table(['mesh', 'largest displacement / bbox diagonal: uniform stable', 'uniform large', 'cotangent stable', 'cotangent large'],
    names.map((m) => [m, ...['uniform_stable', 'uniform_large', 'cotangent_stable', 'cotangent_large'].map((s) => `${g(100 * results[`${m}_explicit_${s}`].colour_range[1] / diagonal(m), 2)}%`)])), '',
  'Above the bound the highest-frequency mode is multiplied by |1 − λμ_max| per step (1.4 at 1.2 × the bound, 2 at ' +
  `1.5 ×). With the uniform Laplacian that mode spans the whole mesh: after ${LARGE.uniform.iterations} steps the largest ` +
  `displacement is ${names.map((m) => `${g(100 * results[`${m}_explicit_uniform_large`].colour_range[1] / diagonal(m), 2)}%`).join(', ')} ` +
  'of the diagonal and the surface turns into spikes and zig-zags (the seed\'s Figures 8-9). With the cotangent ' +
  'Laplacian the bound is set by the few smallest, worst-shaped triangles and the unstable modes live there, so the ' +
  `damage stays local (${names.map((m) => `${g(100 * results[`${m}_explicit_cotangent_large`].colour_range[1] / diagonal(m), 2)}%`).join(', ')}) ` +
  'and grows only slowly. Below the bound the cotangent step is a small fraction of a mean edge² (' +
  `${names.map((m) => g(0.9 * bound(m, 'cotangent') / edge2(m), 2)).join(', ')}), so 20 steps move the finely sampled meshes little ` +
  `(${names.map((m) => `${m} ${g(100 * results[`${m}_explicit_cotangent_stable`].colour_range[1] / diagonal(m), 2)}%`).join(', ')}): ` +
  'explicit cotangent smoothing of a fine mesh needs thousands of steps, which is the reason to go implicit.', '');

p('## Implicit smoothing (seed Figure 10)', '',
  'One backward-Euler step (M − λS) P\' = M P, cotangent Laplacian, at the seed\'s absolute λ = 1, 1e-3, 1e-5; colour = distance moved.', '',
  ...table(['mesh', 'λ = 1', 'λ = 1e-3', 'λ = 1e-5', 'λ in mean edge²'], names.map((m) => [m,
    ...['1', '1e-3', '1e-5'].map((l) => img(`${m}_implicit_${l}`, `${m} lambda ${l}`)),
    ['1', '1e-3', '1e-5'].map((l) => g(Number(l) / edge2(m), 2)).join(' / ')])), '',
  'Every step is stable whatever λ. What λ does depends on the mesh\'s size: λ = 1 is hundreds to thousands of mean edge² on these ' +
  'meshes and shrinks them to a near-point (the flow has run far past the shape), λ = 1e-5 is a fraction of one ' +
  'mean edge² and only removes the finest wiggles. One to a few mean edge² per step (`--lambda auto`) is a useful ' +
  'default on any mesh.', '');

p('## Denoising (seed Figures 12-15)', '', 'The study itself, its measures and a longer run on other settings are described in [denoising.md](denoising.md).', '');
const haveStudy = studyAvailable === '1';
if (!haveStudy) {
  p('**TODO: `lapmesh denoise-study` was not available in this build, so the error-vs-iterations tables are missing; ' +
    'the figures below use fixed settings (explicit: 0.9 × bound, 10 steps; implicit: 1 × mean edge², 2 steps).**', '');
} else {
  p('Isotropic Gaussian noise of σ = level × mean edge length (seed 1) at the seed\'s levels 0.02, 0.05 and 0.1, and a ' +
    'stronger 0.3, then smoothing with both schemes and both Laplacians. ' +
    `\`lapmesh denoise-study MESH -o study.csv --plot study.svg ${studyOptions}\` measures after every step the RMS ` +
    'distance to the clean mesh over the bounding-box diagonal (λ in mean edge² for the cotangent Laplacian; the ' +
    'uniform Laplacian\'s λ is dimensionless and taken as is). ' +
    `It ran on the meshes of at most ${studyMax} vertices (${names.filter((m) => study(m)).join(', ')}); ` +
    `${names.filter((m) => !study(m)).join(', ') || 'none'} left out for time. Best run per noise level and scheme:`, '');
  const rowsBest = [];
  for (const m of names) {
    const rows = study(m);
    if (!rows) continue;
    for (const level of LEVELS) {
      const noisy = rows.find((r) => r.noise_level === level && r.iteration === 0);
      for (const scheme of ['explicit', 'implicit']) {
        const b = best(rows, level, scheme);
        rowsBest.push([m, level, scheme, noisy ? g(noisy.rms) : '-', b ? `${b.laplacian}, λ = ${g(b.step)}${b.laplacian === 'cotangent' ? ' mean edge²' : ''}, ${b.iteration} it.` : 'none bounded',
          b ? g(b.rms) : '-', b && noisy ? `${g(100 * (1 - b.rms / noisy.rms), 2)}%` : '-']);
      }
    }
  }
  p(...table(['mesh', 'noise level', 'scheme', 'RMS error, noisy', 'best setting', 'RMS error, best', 'error removed'], rowsBest), '');
  const removed = (m, level) => {
    const rows = study(m); if (!rows) return NaN;
    const noisy = rows.find((r) => r.noise_level === level && r.iteration === 0);
    const bs = ['explicit', 'implicit'].map((s) => best(rows, level, s)).filter(Boolean);
    return bs.length && noisy ? 100 * (1 - Math.min(...bs.map((b) => b.rms)) / noisy.rms) : NaN;
  };
  const gap = (m, level) => {
    const rows = study(m); const e = best(rows, level, 'explicit'), i = best(rows, level, 'implicit');
    return e && i ? 100 * Math.abs(e.rms - i.rms) / Math.min(e.rms, i.rms) : NaN;
  };
  const sm = names.filter((m) => study(m));
  p('What the numbers say:',
    `- **Noise level.** The share of the error the best smoothing removes grows with the noise: ${sm.map((m) =>
      `${m} ${LEVELS.map((l) => `${g(removed(m, l), 2)}%`).join(' / ')}`).join('; ')} at levels ${LEVELS.join(' / ')}. ` +
    'At 0.02 of an edge the noise is below the smoothing\'s own shape error on the cow, so every smoothing step makes ' +
    'it worse; the seed\'s levels are mild, and smoothing pays from about 0.1 of an edge up.',
    `- **Explicit vs implicit.** Each at its best λ and step count, the two schemes end within ${g(Math.max(...sm.flatMap((m) =>
      LEVELS.map((l) => gap(m, l)))), 2)}% of each other. Implicit is not more accurate; it is stable at any λ, which is what ` +
    'matters when the right λ is not known. ' +
    'Explicit is guaranteed stable only below the bound: the "λ / explicit bound" column shows best explicit ' +
    'cotangent runs far above the bound of the noisy mesh, which stayed bounded for 10 steps, presumably because the unstable ' +
    'modes sit on a few tiny noisy triangles; over more steps that component keeps growing (previous section).',
    '- **Good λ and Laplacian.** The best runs use the uniform Laplacian with λ = 0.03-1 (dimensionless) and a few to ten ' +
    'steps. Isotropic noise moves vertices along the surface as well as across it; the cotangent flow moves vertices ' +
    'mostly along the normal (L x = −2H n on a smooth surface), so it undoes little of the tangential part, which the uniform Laplacian (which also evens out ' +
    'the sampling) does. On the cow most cotangent rows have their best at the smallest λ tried (0.03 mean edge²), ' +
    'so the cotangent flow would need still smaller steps there. '+
    'Past the optimum every run drifts away (the flow shrinks the shape), ' +
    'so the number of iterations is a parameter to choose, not "more is better".', '');
  p('Error against iterations (RMS distance / diagonal) for each scheme and Laplacian at its best λ:', '');
  const its = [0, 1, 2, 3, 5, 10];
  for (const m of names) {
    const rows = study(m);
    if (!rows) continue;
    const tr = [];
    for (const level of LEVELS)
      for (const scheme of ['explicit', 'implicit'])
        for (const lap of ['uniform', 'cotangent']) {
          const sub = rows.filter((r) => r.noise_level === level && r.scheme === scheme && r.laplacian === lap);
          let b = null;
          for (const r of sub) if (r.iteration > 0 && ok(r) && (!b || r.rms < b.rms)) b = r;
          if (!b) { tr.push([level, scheme, lap, 'all diverged', '-', ...its.map(() => '-')]); continue; }
          tr.push([level, scheme, lap, g(b.step), g(b.lambda / Number(b.stability_bound), 2), ...its.map((i) => {
            const r = sub.find((x) => x.step === b.step && x.iteration === i);
            return r ? (ok(r) ? g(r.rms) : r.status) : '-';
          })]);
        }
    p(`**${m}** ([plot](images/report/denoise_study_${m}.svg)):`, '',
      ...table(['level', 'scheme', 'Laplacian', 'best λ (cotangent: mean edge²)', 'λ / explicit bound', ...its.map((i) => `${i} it.`)], tr), '');
  }
}
p('Figures: the Gaussian curvature (angle deficit over the barycentric area, in the clean mesh\'s colour range of ' +
  'Figure 4 above) of the noisy mesh and of the best explicit and implicit results of the study (same noise, scheme, ' +
  'Laplacian, λ and step count): a second-order quantity, so it makes the remaining noise visible. Each caption says what was ' +
  'computed. The angle deficit uses no Laplacian, but the colour bar names the URL\'s one `laplacian` parameter, which also ' +
  'sets the smoothing\'s: it reads "uniform" on the clean and noisy maps and names the smoothing\'s Laplacian on a denoised one.', '');
for (const m of names.filter((x) => study(x) || !names.some(study))) {
  p(`**${m}**${study(m) ? '' : ' (no study: fixed settings)'}`, '', ...table(['noise level', 'noisy', 'explicit', 'implicit'], FIGURE_LEVELS.map((level) => [level,
    cell(`${m}_noisy_${level}`, `${m} noisy ${level}`), cell(`${m}_denoised_explicit_${level}`, `${m} explicit ${level}`),
    cell(`${m}_denoised_implicit_${level}`, `${m} implicit ${level}`)])), '');
  const settings = FIGURE_LEVELS.map((level) => ['explicit', 'implicit'].map((s) => {
    const a = answer(`${m}_denoised_${s}_${level}`, 'smooth');
    const q = new URLSearchParams(results[`${m}_denoised_${s}_${level}`].query);
    return `${level} ${s}: ${q.get('laplacian')}, λ = ${g(a.lambda)}, ${q.get('iterations')} it.`;
  }).join('; ')).join('; ');
  p(`Settings (${m}): ${settings}`, '');
}
const boxRecon = (k) => reconAt(BOX, k);
p('## The course\'s own meshes', '',
  'The course\'s `bumpy.off`, `cow.off` and `bunny.off` are not in the repository. To run everything above on them too:', '',
  '```sh', 'scripts/report.sh path/to/bumpy.off path/to/cow.off path/to/bunny.off        # figures, tables, this page',
  'scripts/report.sh --tables-only path/to/bumpy.off path/to/cow.off path/to/bunny.off  # only the measured tables, in build/report/',
  '```', '',
  'Each mesh is keyed by its path: `bumpy.off` keeps the key `bumpy`, while the course\'s `cow.off` (in a folder `data`) becomes ' +
  '`data-cow`, beside CGAL\'s `cow`, with its own rows and figures. The course\'s meshes as measured on ' +
  `${COURSE.date} with this version (the report run above and \`lapmesh smooth\`), beside the generated bumpy box:`, '',
  ...table(['', 'course bumpy.off', 'bumpy-box (generated)', 'course cow.off', 'course bunny.off'], [
    ['vertices', COURSE.bumpy.vertices, vertices(BOX), COURSE.cow.vertices, COURSE.bunny.vertices],
    ['bounding box', `±${COURSE.bumpy.box} (cube)`, `±${g(diagonal(BOX) / Math.sqrt(12), 3)} (cube)`, '', ''],
    ['mean edge²', g(COURSE.bumpy.edge2), g(edge2(BOX)), g(COURSE.cow.edge2), g(COURSE.bunny.edge2)],
    ['explicit bound, uniform', g(COURSE.bumpy.uniform), g(bound(BOX, 'uniform')), g(COURSE.cow.uniform), g(COURSE.bunny.uniform)],
    ['explicit bound, cotangent', g(COURSE.bumpy.cotangent), g(bound(BOX, 'cotangent')), g(COURSE.cow.cotangent), g(COURSE.bunny.cotangent)],
    ['cotangent bound / mean edge²', g(COURSE.bumpy.cotangent / COURSE.bumpy.edge2), g(bound(BOX, 'cotangent') / edge2(BOX)),
      g(COURSE.cow.cotangent / COURSE.cow.edge2), g(COURSE.bunny.cotangent / COURSE.bunny.edge2)],
    ['seed\'s λ / cotangent bound', g(0.01 / COURSE.bumpy.cotangent, 2), g(0.01 / bound(BOX, 'cotangent'), 2), g(1e-6 / COURSE.cow.cotangent, 2), g(5e-7 / COURSE.bunny.cotangent, 2)],
    ['reconstruction error / diagonal, k = 5, 10, 30', COURSE.bumpyRecon.map((x) => g(x, 2)).join(', '), [5, 10, 30].map((k) => g(boxRecon(k), 2)).join(', '), '', ''],
  ]), '', ...COURSE.notes({ g, bound, edge2, vertices, diagonal, results, BOX }), '');
p('## Figure URLs', '', 'Each image is `lapmesh view` at `http://127.0.0.1:PORT/?QUERY` (parameters: [viewer.md](viewer.md#figures-from-a-script-url-parameters)); the manual colour ranges of the noise figures are those the clean mesh\'s Gaussian curvature figure showed.', '',
  ...table(['image', 'query', 'seconds'], Object.entries(results).map(([name, r]) => [`${name}.png`, `\`${r.query}\``, g(r.seconds, 2)])), '');
fs.writeFileSync(1, `${out.join('\n')}\n`);
