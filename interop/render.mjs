// Renders a map file in a viewer no one here wrote, in Debian's headless Chromium driven by
// playwright-core (software WebGL through SwiftShader), from the map frame's own camera, and
// screenshots the canvas (node/tests/integration/formats_interop.rs compares it with the CPU
// rasterizer):
//   --viewer babylon: a .glb with KHR_gaussian_splatting through Babylon.js's own glTF loader
//     (the pinned `babylonjs` and `babylonjs-loaders` UMD builds);
//   --viewer spark: an .spz through Spark's SplatMesh (`@sparkjsdev/spark` on three.js).
// The page and the files are served by this script on 127.0.0.1; the browser asks for nothing
// else. Prints one JSON line (the splat count the viewer loaded, requests, errors, the
// screenshot's path); exits non-zero on failure.
//
//   node interop/render.mjs --viewer babylon|spark --map FILE --out DIR --pinhole FX,FY,CX,CY,W,H
import { chromium } from 'playwright-core';
import { createServer } from 'node:http';
import { readFileSync, mkdirSync, existsSync } from 'node:fs';
import { join, dirname, normalize, extname, sep } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromiumArgs } from '../scripts/chromium_args.mjs';

const arg = (name, fallback) => {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 ? process.argv[i + 1] : fallback;
};
const viewer = arg('viewer', 'babylon');
const map = arg('map');
const out = arg('out');
const [fx, fy, cx, cy, width, height] = (arg('pinhole') ?? '').split(',').map(Number);
const executablePath = arg('chromium', '/usr/bin/chromium');
if (!map || !out || !['babylon', 'spark'].includes(viewer) || !(width > 0 && height > 0 && fx > 0 && fy > 0)) {
  console.error('usage: render.mjs --viewer babylon|spark --map FILE --out DIR --pinhole FX,FY,CX,CY,W,H');
  process.exit(2);
}
// The pinhole's projection as Babylon's (row vectors, left-handed camera space x right,
// y up, z forward; WebGL's depth range -1..1), pixel centres at integers as the project's
// rasterizer has them: x_ndc = (2 fx / W) x / z + 2 (cx + 0.5) / W - 1, and y likewise
// with y up.
const near = 0.01;
const far = 1000;
const projection = [
  2 * fx / width, 0, 0, 0,
  0, 2 * fy / height, 0, 0,
  2 * (cx + 0.5) / width - 1, 1 - 2 * (cy + 0.5) / height, (far + near) / (far - near), 1,
  0, 0, -2 * far * near / (far - near), 0,
];
mkdirSync(out, { recursive: true });
const here = dirname(fileURLToPath(import.meta.url));
const modules = join(here, 'node_modules');

// The camera: Babylon is left-handed and its glTF loader turns the asset's right-handed
// frame into it (x negated); a camera at the origin turned half a turn about +Y then looks
// down the asset's -Z with +Y up. Its projection is the pinhole's, frozen.
const babylonPage = `<!doctype html><html><head><style>html,body{margin:0;background:#000}</style>
<script src="/babylon.js"></script><script src="/babylonjs.loaders.min.js"></script></head>
<body><canvas id="c" width="${width}" height="${height}" style="width:${width}px;height:${height}px;display:block"></canvas>
<script>
window.__result = null;
(async () => {
  try {
    const canvas = document.getElementById('c');
    const engine = new BABYLON.Engine(canvas, false, { preserveDrawingBuffer: true, antialias: false }, false);
    engine.setHardwareScalingLevel(1);
    const scene = new BABYLON.Scene(engine);
    scene.clearColor = new BABYLON.Color4(0, 0, 0, 1);
    const camera = new BABYLON.FreeCamera('pinhole', BABYLON.Vector3.Zero(), scene);
    camera.rotation = new BABYLON.Vector3(0, Math.PI, 0);
    camera.minZ = ${near};
    camera.maxZ = ${far};
    camera.freezeProjectionMatrix(BABYLON.Matrix.FromArray(${JSON.stringify(projection)}));
    const result = await BABYLON.SceneLoader.ImportMeshAsync('', '/', 'map.glb', scene);
    const splats = result.meshes.filter((m) => m.getClassName() === 'GaussianSplattingMesh');
    const mesh = splats[0];
    const count = mesh ? (mesh.splatCount ?? mesh._vertexCount ?? 0) : 0;
    let frames = 0;
    engine.runRenderLoop(() => { scene.render(); frames++; });
    // Splats are sorted in a worker; render until the sort has settled.
    await new Promise((r) => setTimeout(r, 4000));
    window.__result = { ok: true, meshes: splats.length, count, frames };
  } catch (e) {
    window.__result = { ok: false, error: String(e && e.stack || e) };
  }
})();
</script></body></html>`;

// Spark: three.js's camera looks down -Z with +Y up, the pinhole's projection set directly
// (column-major, pixel centres at integers). SPZ holds the 3DGS PLY axes (y down, z
// forward), so the mesh is turned half a turn about X, as Spark's own examples do for PLY
// and SPZ captures.
const threeProjection = [
  2 * fx / width, 0, 0, 0,
  0, 2 * fy / height, 0, 0,
  1 - 2 * (cx + 0.5) / width, 2 * (cy + 0.5) / height - 1, -(far + near) / (far - near), -1,
  0, 0, -2 * far * near / (far - near), 0,
];
const sparkPage = `<!doctype html><html><head><style>html,body{margin:0;background:#000}</style>
<script type="importmap">{"imports":{"three":"/modules/three/build/three.module.js","three/addons/":"/modules/three/examples/jsm/","@sparkjsdev/spark":"/modules/@sparkjsdev/spark/dist/spark.module.js"}}</script>
</head><body><canvas id="c" width="${width}" height="${height}" style="width:${width}px;height:${height}px;display:block"></canvas>
<script type="module">
window.__result = null;
try {
  const THREE = await import('three');
  const { SparkRenderer, SplatMesh } = await import('@sparkjsdev/spark');
  const canvas = document.getElementById('c');
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(${width}, ${height}, false);
  renderer.setClearColor(0x000000, 1);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(60, ${width} / ${height}, ${near}, ${far});
  const m = new THREE.Matrix4().fromArray(${JSON.stringify(threeProjection)});
  camera.updateProjectionMatrix = () => {
    camera.projectionMatrix.copy(m);
    camera.projectionMatrixInverse.copy(m).invert();
  };
  camera.updateProjectionMatrix();
  scene.add(new SparkRenderer({ renderer }));
  const mesh = new SplatMesh({ url: '/map.spz' });
  await mesh.initialized;
  mesh.quaternion.set(1, 0, 0, 0);
  scene.add(mesh);
  let frames = 0;
  renderer.setAnimationLoop(() => { renderer.render(scene, camera); frames++; });
  await new Promise((r) => setTimeout(r, 5000));
  window.__result = { ok: true, meshes: 1, count: mesh.numSplats ?? mesh.packedSplats?.numSplats ?? 0, frames };
} catch (e) {
  window.__result = { ok: false, error: String(e && e.stack || e) };
}
</script></body></html>`;

const files = viewer === 'babylon' ? {
  '/': ['text/html', Buffer.from(babylonPage)],
  '/babylon.js': ['text/javascript', readFileSync(join(modules, 'babylonjs', 'babylon.js'))],
  '/babylonjs.loaders.min.js': ['text/javascript', readFileSync(join(modules, 'babylonjs-loaders', 'babylonjs.loaders.min.js'))],
  '/map.glb': ['model/gltf-binary', readFileSync(map)],
} : {
  '/': ['text/html', Buffer.from(sparkPage)],
  '/map.spz': ['application/octet-stream', readFileSync(map)],
};
// Spark's and three.js's modules (and what they fetch: Spark's wasm) from node_modules.
const types = { js: 'text/javascript', mjs: 'text/javascript', wasm: 'application/wasm', json: 'application/json' };
const moduleFile = (path) => {
  if (!path.startsWith('/modules/')) return null;
  const file = normalize(join(modules, decodeURIComponent(path.slice('/modules/'.length))));
  if (!file.startsWith(modules + sep) || !existsSync(file)) return null;
  return [types[extname(file).slice(1)] ?? 'application/octet-stream', readFileSync(file)];
};
const requests = [];
const server = createServer((req, res) => {
  const path = new URL(req.url, 'http://127.0.0.1').pathname;
  requests.push(path);
  const file = files[path] ?? moduleFile(path);
  if (path === '/favicon.ico') { res.writeHead(204); res.end(); return; }
  if (!file) { res.writeHead(404); res.end(); return; }
  res.writeHead(200, { 'Content-Type': file[0] });
  res.end(file[1]);
});
await new Promise((r) => server.listen(0, '127.0.0.1', r));
const base = `http://127.0.0.1:${server.address().port}`;

const browser = await chromium.launch({
  executablePath,
  headless: true,
  args: chromiumArgs,
});
const errors = [];
const outside = [];
const context = await browser.newContext({ viewport: { width, height }, deviceScaleFactor: 1 });
context.on('request', (r) => { if (!r.url().startsWith(base) && !r.url().startsWith('data:') && !r.url().startsWith('blob:')) outside.push(r.url()); });
const tab = await context.newPage();
tab.on('pageerror', (e) => errors.push(String(e)));
tab.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
let result;
try {
  await tab.goto(base + '/', { waitUntil: 'load' });
  await tab.waitForFunction(() => window.__result !== null, null, { timeout: 120000 });
  result = await tab.evaluate(() => window.__result);
  if (result.ok) await tab.locator('#c').screenshot({ path: join(out, `${viewer}.png`) });
} catch (e) {
  result = { ok: false, error: String(e) };
}
await browser.close();
server.close();
console.log(JSON.stringify({ ...result, png: join(out, `${viewer}.png`), requests, outside, errors }));
process.exit(result.ok ? 0 : 1);
