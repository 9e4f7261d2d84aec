// The command-line switches every headless Chromium test here starts Debian's Chromium with:
// no sandbox (root in CI), no GPU (SwiftShader draws WebGL in software), and none of the
// browser's own network traffic (background updates, sync, QUIC), which this machine's closed
// network refuses many at a time. Imported by view/check.mjs and interop/render.mjs.
export const chromiumArgs = [
  '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
  '--disable-background-networking', '--disable-component-update', '--disable-sync',
  '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
];
