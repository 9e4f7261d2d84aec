// The StereoSplat live view's script: polls the node's /api/state, keeps the splat viewer
// (@mkkellogg/gaussian-splats-3d on three.js, both served by the node) on the fused map's
// tiles near its camera, swaps in the latest bin's pictures and draws a latency chart per
// stage.
//
// The map is loaded tile by tile (/api/tiles lists the tiles within RADIUS_M of the camera,
// nearest first, until the page's budget of Gaussians, the last tile cut to its most opaque;
// /map/tile.ply serves one), each tile its own splat scene: a change reloads only the tiles
// whose version or cut changed, and what the page draws is bounded by the budget however
// large the map grows. The budget follows the frame time: above FRAME_MS it shrinks to what
// the measured rate draws in FRAME_MS, well below it grows again, up to BUDGET, so a slow
// renderer (software WebGL) shows fewer splats at a usable rate rather than all of them at
// seconds a frame. `?radius=R&budget=N&frame_ms=T` override the three (`frame_ms=0`: a fixed
// budget of N; the default in test mode, below).
//
// Test mode (`?pinhole=fx,fy,cx,cy,width,height&pose=r00,..,r22,x,y,z`): only the splat
// canvas, at exactly width x height, seen by that pinhole camera (OpenCV axes, camera to
// map frame: rotation rows then position), for comparison with the project's own render.
// `window.__view` reports progress to the headless check (view/check.mjs).
import * as THREE from 'three';
import * as GS from '/lib/splats/gaussian-splats-3d.module.js';

const POLL_MS = 700;
const MAP_RELOAD_MS = 2500;
const params = new URLSearchParams(location.search);
const pinhole = params.get('pinhole')?.split(',').map(Number);
const pose = params.get('pose')?.split(',').map(Number);
const test = Boolean(pinhole && pose);
const RADIUS_M = Number(params.get('radius') ?? 160);
const BUDGET = Number(params.get('budget') ?? 1000000);
// Test mode compares pictures, so it draws every listed splat unless asked otherwise.
const FRAME_MS = Number(params.get('frame_ms') ?? (test ? 0 : 100));
// The adaptive budget starts here (a page on a fast renderer grows to BUDGET in a few
// steps), never drops below MIN_BUDGET, and is judged on the median of FRAME_WINDOW frames.
const START_BUDGET = FRAME_MS > 0 ? Math.min(BUDGET, 250000) : BUDGET;
const MIN_BUDGET = 1000;
const FRAME_WINDOW = 5;
window.__view = {
  splatReady: false, mapVersion: null, loads: 0, plottedBins: 0, error: null,
  tiles: 0, gaussians: 0, tileLoads: 0,
  budget: START_BUDGET, budgetChanges: 0, budgetChangedAt: 0, frameMs: null,
};

const $ = (id) => document.getElementById(id);
const splatEl = $('splat');
let camera = null;
if (test) {
  document.body.classList.add('test');
  const [fx, fy, cx, cy, w, h] = pinhole;
  splatEl.classList.add('fixed');
  splatEl.style.width = `${w}px`;
  splatEl.style.height = `${h}px`;
  camera = pinholeCamera(fx, fy, cx, cy, w, h, 0.01, 1000);
  placeOpenCv(camera, pose.slice(0, 9), pose.slice(9, 12));
}

const viewer = new GS.Viewer({
  rootElement: splatEl,
  camera: camera ?? undefined,
  useBuiltInControls: !test,
  cameraUp: [0, 0, 1],
  initialCameraPosition: [0, -10, 5],
  initialCameraLookAt: [0, 10, 0],
  selfDrivenMode: true,
  sharedMemoryForWorkers: false,
  gpuAcceleratedSort: false,
  antialiased: false,
  sphericalHarmonicsDegree: 0,
  ignoreDevicePixelRatio: true,
  sceneRevealMode: GS.SceneRevealMode.Instant,
  renderMode: GS.RenderMode.Always,
  logLevel: GS.LogLevel.None,
});
viewer.start();

// A three.js camera whose projection is the pinhole's (pixel centres at integers, as the
// project's renderer), kept fixed whatever the viewer asks.
function pinholeCamera(fx, fy, cx, cy, w, h, near, far) {
  const cam = new THREE.PerspectiveCamera(60, w / h, near, far);
  const m = new THREE.Matrix4().set(
    2 * fx / w, 0, 1 - 2 * (cx + 0.5) / w, 0,
    0, 2 * fy / h, 2 * (cy + 0.5) / h - 1, 0,
    0, 0, -(far + near) / (far - near), -2 * far * near / (far - near),
    0, 0, -1, 0);
  cam.updateProjectionMatrix = () => {
    cam.projectionMatrix.copy(m);
    cam.projectionMatrixInverse.copy(m).invert();
  };
  cam.updateProjectionMatrix();
  return cam;
}

// Puts `cam` where an OpenCV camera (x right, y down, z forward) with camera-to-map
// rotation `rows` (row-major 3x3) and centre `p` is; three.js cameras look down -z, y up.
function placeOpenCv(cam, rows, p) {
  const r = rows;
  const m = new THREE.Matrix4().set(
    r[0], -r[1], -r[2], p[0],
    r[3], -r[4], -r[5], p[1],
    r[6], -r[7], -r[8], p[2],
    0, 0, 0, 1);
  m.decompose(cam.position, cam.quaternion, new THREE.Vector3());
  cam.updateMatrixWorld(true);
}

// Follow mode: just behind the latest bin's input camera, looking where it looked, with its
// vertical field of view (the map was made from this view; from far above, the sky's
// splats hide the street).
function follow(bin, k) {
  const r = bin.rotation_rows;
  const fwd = new THREE.Vector3(r[0][2], r[1][2], r[2][2]);
  const p = new THREE.Vector3(...bin.position);
  const cam = viewer.camera;
  if (k && cam.isPerspectiveCamera) {
    cam.fov = THREE.MathUtils.radToDeg(2 * Math.atan(k.height / 2 / k.fy));
    cam.updateProjectionMatrix();
  }
  cam.position.copy(p).addScaledVector(fwd, -1);
  const target = p.clone().addScaledVector(fwd, 15);
  if (viewer.controls) viewer.controls.target.copy(target);
  cam.lookAt(target);
}

let loading = false;
let loadedVersion = null;
let lastLoad = 0;
let followedBin = null;
// The tiles shown, in the viewer's scene order: { key, version, take }.
let shown = [];
let budget = START_BUDGET;
// Set when the budget changed and the tiles must be listed again.
let budgetDue = false;
// Where the camera was when the tiles were last listed; moving a quarter of a tile from
// there lists them again.
let listedAt = null;
let tileM = 64;

// Brings the viewer to the tiles near its camera at map `version`: drops the tiles no
// longer listed or changed, adds the new and changed ones (a tile still being fetched from
// the node is left for the next round). Counts as loaded only when every listed tile is.
async function loadMap(version) {
  loading = true;
  try {
    const p = viewer.camera.position;
    listedAt = p.clone();
    budgetDue = false;
    const res = await fetch(`/api/tiles?x=${p.x}&y=${p.y}&radius=${RADIUS_M}&budget=${budget}`,
      { cache: 'no-store' });
    if (!res.ok) return;
    const listing = await res.json();
    tileM = listing.tile_m;
    const want = new Map(listing.tiles.map((t) => [`${t.x}_${t.y}`, t]));
    const same = (s) => want.get(s.key)?.version === s.version && want.get(s.key)?.take === s.take;
    const keep = shown.filter(same);
    const drop = shown.map((s, i) => (keep.includes(s) ? -1 : i)).filter((i) => i >= 0);
    const have = new Set(keep.map((s) => s.key));
    const added = [];
    let complete = true;
    for (const [key, t] of want) {
      if (have.has(key)) continue;
      const cut = t.take < t.gaussians ? `&take=${t.take}` : '';
      const r = await fetch(`/map/tile.ply?x=${t.x}&y=${t.y}&v=${t.version}${cut}`, { cache: 'no-store' });
      if (!r.ok) { complete = false; continue; }
      const v = Number(r.headers.get('X-Tile-Version'));
      added.push({ key, version: v, take: t.take, url: URL.createObjectURL(await r.blob()) });
    }
    if (drop.length) await viewer.removeSplatScenes(drop, false);
    if (added.length) {
      await viewer.addSplatScenes(added.map((a) => ({
        path: a.url,
        format: GS.SceneFormat.Ply,
        splatAlphaRemovalThreshold: 1,
      })), false);
    }
    for (const a of added) URL.revokeObjectURL(a.url);
    shown = keep.concat(added.map(({ key, version, take }) => ({ key, version, take })));
    window.__view.tiles = shown.length;
    window.__view.gaussians = shown.reduce((n, s) => n + s.take, 0);
    window.__view.tileLoads += added.length;
    if (complete) {
      loadedVersion = listing.version;
      window.__view.loads += 1;
      if (test) await settle(listing.version);
    }
  } catch (e) {
    window.__view.error = String(e);
  } finally {
    loading = false;
    lastLoad = performance.now();
  }
}

// Test mode: ready once the worker's depth sort has come back and a few frames were drawn.
async function settle(version) {
  const frame = () => new Promise((r) => requestAnimationFrame(r));
  for (let i = 0; i < 600 && (viewer.sortRunning || !viewer.splatRenderReady); i++) await frame();
  for (let i = 0; i < 10; i++) await frame();
  window.__view.mapVersion = version;
  window.__view.splatReady = true;
}

function setPicture(img, name, id) {
  if (id === null || id === undefined || img.dataset.id === String(id)) return;
  img.dataset.id = String(id);
  img.src = `/${name}.png?b=${id}`;
}

const STAGE_COLOURS = ['#6cf', '#fc6', '#9e7', '#f88', '#c9f', '#7dd', '#fa7'];

function drawCharts(rows) {
  const box = $('charts');
  const stages = rows.length ? Object.keys(rows[0].stages_ms) : [];
  stages.forEach((name, i) => {
    let canvas = box.querySelector(`canvas[data-stage="${name}"]`);
    if (!canvas) {
      const fig = document.createElement('div');
      fig.innerHTML = `<div class="muted">${name}</div>`;
      canvas = document.createElement('canvas');
      canvas.className = 'chart';
      canvas.dataset.stage = name;
      fig.appendChild(canvas);
      box.appendChild(fig);
    }
    const values = rows.map((r) => r.stages_ms[name]);
    drawChart(canvas, values, STAGE_COLOURS[i % STAGE_COLOURS.length]);
    canvas.parentElement.firstChild.textContent =
      `${name}: last ${fmt(values[values.length - 1])} ms, max ${fmt(Math.max(...values.filter(Number.isFinite)))} ms`;
  });
  box.dataset.bins = String(rows.length);
  window.__view.plottedBins = rows.length;
  $('chart-info').textContent = `${rows.length} bins`;
}

function fmt(v) { return Number.isFinite(v) ? v.toFixed(1) : '–'; }

function drawChart(canvas, values, colour) {
  const w = canvas.width = canvas.clientWidth || 260;
  const h = canvas.height = canvas.clientHeight || 120;
  const g = canvas.getContext('2d');
  g.fillStyle = '#121417';
  g.fillRect(0, 0, w, h);
  const finite = values.filter(Number.isFinite);
  // The range holds 0 and every value (the before-close margin may be negative).
  const lo = Math.min(0, ...finite);
  const hi = Math.max(lo + 1, ...finite);
  const span = (hi - lo) * 1.1;
  const y = (v) => h - 14 - (h - 20) * ((v - lo) / span);
  g.strokeStyle = '#333';
  g.fillStyle = '#778';
  g.font = '10px sans-serif';
  for (const v of [lo, 0, hi]) {
    g.beginPath(); g.moveTo(28, y(v)); g.lineTo(w, y(v)); g.stroke();
    g.fillText(v.toFixed(0), 2, y(v) + 3);
  }
  const x = (i) => 30 + (w - 34) * (values.length < 2 ? 0.5 : i / (values.length - 1));
  g.strokeStyle = colour;
  g.fillStyle = colour;
  g.beginPath();
  let pen = false;
  values.forEach((v, i) => {
    if (!Number.isFinite(v)) { pen = false; return; }
    if (pen) g.lineTo(x(i), y(v)); else g.moveTo(x(i), y(v));
    pen = true;
  });
  g.stroke();
  values.forEach((v, i) => { if (Number.isFinite(v)) g.fillRect(x(i) - 1.5, y(v) - 1.5, 3, 3); });
}

function drawCounters(counters) {
  const rows = Object.entries(counters).map(([k, v]) =>
    `<tr><td>${k}</td><td${/error|refused|bad|drop/.test(k) && v > 0 ? ' class="bad"' : ''}>${v}</td></tr>`);
  $('counters').innerHTML = rows.join('') || '<tr><td class="muted">none yet</td></tr>';
}

async function poll() {
  try {
    const res = await fetch('/api/state', { cache: 'no-store' });
    const s = await res.json();
    const map = s.map;
    $('status').textContent =
      `${s.bins_seen} bins · ${map.gaussians} Gaussians · map version ${map.version}`;
    $('map-info').textContent = loadedVersion === null ? '' :
      `(showing version ${loadedVersion}: ${shown.length} tiles, ${window.__view.gaussians} Gaussians)`;
    const due = test ? loadedVersion === null : performance.now() - lastLoad > MAP_RELOAD_MS;
    const moved = listedAt !== null && viewer.camera.position.distanceTo(listedAt) > tileM / 4;
    const changed = map.version !== loadedVersion || moved;
    if (map.origin && !loading && ((changed && due) || budgetDue)) loadMap(map.version);
    if (!test) {
      const latest = s.bins[s.bins.length - 1];
      if (latest && $('follow').checked && followedBin !== latest.position.join()) {
        followedBin = latest.position.join();
        follow(latest, s.intrinsics);
      }
      setPicture($('render'), 'render', s.pictures.render);
      setPicture($('input'), 'input', s.pictures.input);
      setPicture($('bev'), 'bev', s.pictures.bev === null ? null : `${s.pictures.bev}-${map.version}`);
      const l = s.latency[s.latency.length - 1];
      $('bin-info').textContent = s.pictures.render === null ? '' : `bin ${s.pictures.render}` +
        (l ? ` · check ${['not run', 'pass', 'FAIL', 'undetermined'][l.check_verdict] ?? '?'} ${l.check_score.toFixed(2)}` : '') +
        (l && l.operating_point ? ` · point ${l.operating_point}` : '');
      drawCharts(s.latency);
      drawCounters(s.counters);
    }
  } catch (e) {
    $('status').textContent = `node not answering (${e})`;
  }
  setTimeout(poll, POLL_MS);
}
// The budget's governor: the median interval of the last FRAME_WINDOW frames drawn with the
// current tiles. Over 1.25 FRAME_MS: the budget becomes what that rate draws in 0.9
// FRAME_MS; under half of it, with the budget binding: 1.5 times more, up to BUDGET. The
// frames are judged only once the tiles of the last change are shown.
const frames = [];
function watchFrames(ts) {
  const settled = FRAME_MS > 0 && !loading && !budgetDue && loadedVersion !== null &&
    !viewer.sortRunning;
  if (!settled) frames.length = 0;
  else frames.push(ts);
  if (frames.length > FRAME_WINDOW) {
    const gaps = frames.slice(1).map((t, i) => t - frames[i]).sort((a, b) => a - b);
    const median = gaps[Math.floor(gaps.length / 2)];
    frames.shift();
    window.__view.frameMs = median;
    const drawn = window.__view.gaussians;
    let next = budget;
    if (median > 1.25 * FRAME_MS) next = Math.max(MIN_BUDGET, Math.floor(drawn * 0.9 * FRAME_MS / median));
    else if (median < 0.5 * FRAME_MS && drawn >= 0.95 * budget) next = Math.min(BUDGET, Math.ceil(budget * 1.5));
    if (next !== budget) {
      budget = next;
      budgetDue = true;
      Object.assign(window.__view, {
        budget, budgetChanges: window.__view.budgetChanges + 1, budgetChangedAt: performance.now(),
      });
    }
  }
  requestAnimationFrame(watchFrames);
}
requestAnimationFrame(watchFrames);
poll();
