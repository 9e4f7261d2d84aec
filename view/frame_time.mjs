// Frame time of the live view's splat viewer in headless Chromium (Debian's, through
// playwright-core; never a downloaded browser), called by `stereosplat bench view`: opens
// the page in its fixed-camera mode at the given pinhole and pose with the given tile radius
// and Gaussian budget, waits until the splats are drawn and (with a frame-time target) until
// the page's budget has not changed for `--settle` seconds, then records
// requestAnimationFrame times for a while. Prints one JSON line; exits non-zero with a
// message when something fails.
//
//   node view/frame_time.mjs --url URL --pinhole fx,fy,cx,cy,w,h --pose r00,..,r22,x,y,z
//        --radius R --budget N [--frame-ms T] [--settle S] [--seconds S] [--timeout S]
import { chromium } from 'playwright-core';
import { chromiumArgs } from '../scripts/chromium_args.mjs';

const arg = (name, fallback) => {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 ? process.argv[i + 1] : fallback;
};
const base = arg('url');
const pinhole = arg('pinhole');
const pose = arg('pose');
if (!base || !pinhole || !pose) {
  console.error('usage: frame_time.mjs --url URL --pinhole ... --pose ... --radius R --budget N');
  process.exit(2);
}
const seconds = Number(arg('seconds', '10'));
const timeoutMs = Number(arg('timeout', '600')) * 1000;
const [, , , , width, height] = pinhole.split(',').map(Number);

const browser = await chromium.launch({
  executablePath: arg('chromium', '/usr/bin/chromium'),
  headless: true,
  args: chromiumArgs,
});
const fail = async (message) => {
  console.log(JSON.stringify({ ok: false, error: message }));
  await browser.close();
  process.exit(1);
};
const page = await browser.newPage({ viewport: { width, height }, deviceScaleFactor: 1 });
const errors = [];
page.on('pageerror', (e) => errors.push(String(e)));
const started = Date.now();
const frameMs = arg('frame-ms', '0');
const query = `?pinhole=${pinhole}&pose=${pose}&radius=${arg('radius', '160')}` +
  `&budget=${arg('budget', '1000000')}&frame_ms=${frameMs}`;
await page.goto(base + query, { waitUntil: 'load' });
await page.waitForFunction(() => window.__view.splatReady || window.__view.error, null, { timeout: timeoutMs })
  .catch(() => fail('the splat viewer never became ready'));
// With a target, the page adapts its budget: wait until it has held still for `settle`
// seconds with its tiles shown.
if (Number(frameMs) > 0) {
  const settleMs = Number(arg('settle', '30')) * 1000;
  await page.waitForFunction((ms) => {
    const v = window.__view;
    const quiet = performance.now() - Math.max(v.budgetChangedAt, 0) > ms;
    return v.error || (v.splatReady && v.frameMs !== null && quiet && v.tiles > 0);
  }, settleMs, { timeout: Math.max(1000, timeoutMs - (Date.now() - started)), polling: 500 })
    .catch(() => fail('the page budget never settled'));
}
const loadS = (Date.now() - started) / 1000;
const shown = await page.evaluate(() => window.__view);
if (shown.error) await fail(`the viewer failed: ${shown.error}`);

// Frame times: every requestAnimationFrame for `seconds` (the viewer draws in its own
// callback of each frame, so the interval between frames is what drawing the splats costs).
const stamps = await page.evaluate((ms) => new Promise((resolve) => {
  const t = [];
  const frame = (ts) => {
    t.push(ts);
    if (ts - t[0] < ms || t.length < 3) requestAnimationFrame(frame); else resolve(t);
  };
  requestAnimationFrame(frame);
}), seconds * 1000);
const intervals = stamps.slice(1).map((t, i) => t - stamps[i]).sort((a, b) => a - b);
const quantile = (q) => intervals[Math.min(intervals.length - 1, Math.floor(q * intervals.length))];
const webgl = await page.evaluate(() => {
  const gl = document.createElement('canvas').getContext('webgl2');
  const ext = gl && gl.getExtension('WEBGL_debug_renderer_info');
  return gl ? (ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : 'webgl2') : null;
});
console.log(JSON.stringify({
  ok: true,
  load_s: loadS,
  tiles: shown.tiles,
  gaussians: shown.gaussians,
  frame_ms_target: Number(frameMs),
  budget: shown.budget,
  budget_changes: shown.budgetChanges,
  frames: intervals.length,
  frame_ms_median: quantile(0.5),
  frame_ms_p90: quantile(0.9),
  frame_ms_max: intervals[intervals.length - 1],
  page_errors: errors,
  webgl,
}));
await browser.close();
