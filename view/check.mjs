// Headless check of the live view (called by node/tests/view_page.rs): opens the page in
// Debian's Chromium through playwright-core (never a downloaded browser), watches the
// latency charts grow as bins arrive, screenshots the page, then opens the splat viewer
// alone at the first bin's camera and screenshots its canvas, saving the state and the map
// PLY it showed; last, opens that view with a frame-time target no renderer meets (1 ms) and
// waits for its budget to fall to the floor. Prints `page loaded` once the page polls the
// node, then one JSON line; exits non-zero with a message when something fails.
//
//   node view/check.mjs --url http://127.0.0.1:PORT/ --out DIR --bins N [--timeout S]
import { chromium } from 'playwright-core';
import { writeFileSync, mkdirSync } from 'node:fs';
import { join } from 'node:path';
import { chromiumArgs } from '../scripts/chromium_args.mjs';

const arg = (name, fallback) => {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 ? process.argv[i + 1] : fallback;
};
const base = arg('url');
const out = arg('out');
const wantBins = Number(arg('bins', '2'));
const timeoutMs = Number(arg('timeout', '240')) * 1000;
const executablePath = arg('chromium', '/usr/bin/chromium');
if (!base || !out) {
  console.error('usage: check.mjs --url URL --out DIR --bins N');
  process.exit(2);
}
mkdirSync(out, { recursive: true });
const started = Date.now();
const left = () => timeoutMs - (Date.now() - started);
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

const browser = await chromium.launch({
  executablePath,
  headless: true,
  args: chromiumArgs,
});
const requests = [];
const consoleErrors = [];
const isLocal = (u) => {
  const url = new URL(u);
  if (url.protocol === 'data:' || url.protocol === 'blob:') return true;
  return ['127.0.0.1', 'localhost', '[::1]'].includes(url.hostname);
};
const context = await browser.newContext({ viewport: { width: 960, height: 640 }, deviceScaleFactor: 1 });
context.on('request', (r) => requests.push(r.url()));
context.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });

async function fail(message) {
  console.log(JSON.stringify({ ok: false, error: message, requests, console_errors: consoleErrors }));
  await browser.close();
  process.exit(1);
}

async function state(page) {
  return page.evaluate(async () => (await fetch('/api/state', { cache: 'no-store' })).json());
}

// 1. The live page: the charts' plotted bin count, sampled as bins arrive.
const page = await context.newPage();
page.on('pageerror', (e) => consoleErrors.push(String(e)));
await page.goto(base, { waitUntil: 'load' });
await page.waitForSelector('#splat canvas', { timeout: 30000 }).catch(() => fail('no splat canvas on the page'));
const plotted = [];
let last = -1;
while (left() > 0) {
  const n = await page.evaluate(() => window.__view.plottedBins);
  if (n !== last) {
    plotted.push([Date.now() - started, n]);
    // The caller starts feeding the node once the page is up.
    if (last < 0) console.log('page loaded');
    last = n;
  }
  if (n >= wantBins) break;
  await sleep(200);
}
if (last < wantBins) await fail(`the charts plotted ${last} bins, ${wantBins} wanted, in ${timeoutMs / 1000} s`);

// 2. Wait until the map stops changing and the page shows its latest version.
let s = await state(page);
for (let stable = 0; stable < 3 && left() > 0; await sleep(1000)) {
  const next = await state(page);
  stable = next.map.version === s.map.version ? stable + 1 : 0;
  s = next;
}
while (left() > 0 && !(await page.locator('#map-info').textContent()).includes(`version ${s.map.version}:`)) {
  await sleep(300);
}
await sleep(3000);
await page.screenshot({ path: join(out, 'page.png'), timeout: 60000 });
writeFileSync(join(out, 'state.json'), JSON.stringify(s));
const ply = await page.evaluate(async () => {
  const r = await fetch('/map.ply', { cache: 'no-store' });
  const b = new Uint8Array(await r.arrayBuffer());
  let bin = '';
  for (let i = 0; i < b.length; i += 0x8000) bin += String.fromCharCode(...b.subarray(i, i + 0x8000));
  return { version: Number(r.headers.get('X-Map-Version')), b64: btoa(bin) };
});
writeFileSync(join(out, 'map.ply'), Buffer.from(ply.b64, 'base64'));
const webgl = await page.evaluate(() => {
  const gl = document.createElement('canvas').getContext('webgl2');
  const ext = gl && gl.getExtension('WEBGL_debug_renderer_info');
  return gl ? (ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : 'webgl2') : null;
});

// 3. The splat viewer alone at the first bin's camera.
const k = s.intrinsics;
const bin = s.bins[0];
if (!k || !bin) await fail('the state has no intrinsics or no bin camera');
const rows = bin.rotation_rows.flat();
const query = `?pinhole=${[k.fx, k.fy, k.cx, k.cy, k.width, k.height].join(',')}` +
  `&pose=${[...rows, ...bin.position].join(',')}`;
// The live page's own viewer would compete for the CPU with the one under test.
await page.close();
const testPage = await context.newPage();
testPage.on('pageerror', (e) => consoleErrors.push(String(e)));
await testPage.goto(base + query, { waitUntil: 'load' });
await testPage.waitForFunction(() => window.__view.splatReady, null, { timeout: Math.max(left(), 60000) })
  .catch(() => fail('the splat viewer never became ready'));
const shown = await testPage.evaluate(() => window.__view);
await testPage.locator('#splat').screenshot({ path: join(out, 'splat.png'), timeout: 60000 });
await testPage.close();

// 4. The same view with a 1 ms frame-time target: the budget shrinks until the floor, the
// last tile cut to its most opaque splats.
const slowPage = await context.newPage();
slowPage.on('pageerror', (e) => consoleErrors.push(String(e)));
await slowPage.goto(`${base}${query}&frame_ms=1`, { waitUntil: 'load' });
await slowPage.waitForFunction(() => {
  const v = window.__view;
  return v.error || (v.budget === 1000 && v.splatReady && v.gaussians <= v.budget && v.frameMs !== null);
}, null, { timeout: Math.max(left(), 60000), polling: 250 })
  .catch(() => fail('the budget never came down to its floor'));
const adaptive = await slowPage.evaluate(() => window.__view);

const nonLoopback = requests.filter((u) => !isLocal(u));
const summary = {
  ok: true,
  plotted,
  requests: requests.length,
  non_loopback: nonLoopback,
  console_errors: consoleErrors,
  map_version: ply.version,
  splat_version: shown.mapVersion,
  splat_tiles: shown.tiles,
  splat_gaussians: shown.gaussians,
  viewer_error: shown.error ?? adaptive.error,
  adaptive: {
    budget: adaptive.budget,
    budget_changes: adaptive.budgetChanges,
    tiles: adaptive.tiles,
    gaussians: adaptive.gaussians,
    frame_ms: adaptive.frameMs,
  },
  webgl,
  camera: { bin_id: bin.bin_id, intrinsics: k },
  seconds: (Date.now() - started) / 1000,
};
console.log(JSON.stringify(summary));
await browser.close();
