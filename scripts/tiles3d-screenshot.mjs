// Driver of scripts/tiles3d-screenshot: serves the viewer page, its node modules and the
// tileset's folder on a local port, opens the page in headless Chromium (playwright-core,
// Debian's /usr/bin/chromium), waits until every tile the view needs is loaded, and writes
// the screenshot. Arguments: VIEWER_DIR TILESET.json OUT.png WIDTH HEIGHT ELEV AZIM ZOOM ERROR
// TIMEOUT_S. Prints what the renderer loaded and a building's metadata read back through
// EXT_mesh_features / EXT_structural_metadata.
import http from 'node:http';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { pathToFileURL, fileURLToPath } from 'node:url';

const [viewerDir, tileset, out, width, height, elev, azim, zoom, error, timeout] = process.argv.slice(2);
const here = path.dirname(fileURLToPath(import.meta.url));
const { chromium } = await import(pathToFileURL(path.join(viewerDir, 'node_modules/playwright-core/index.mjs')));

const roots = {
  '/node_modules/': path.join(viewerDir, 'node_modules'),
  '/tiles/': path.dirname(path.resolve(tileset)),
};
const types = { '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript',
  '.json': 'application/json', '.glb': 'model/gltf-binary', '.map': 'application/json' };
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(new URL(req.url, 'http://x').pathname);
  let file = null;
  if (url === '/favicon.ico') {
    res.writeHead(204);
    res.end();
    return;
  }
  if (url === '/' || url === '/index.html') file = path.join(here, 'tiles3d-viewer.html');
  for (const [prefix, root] of Object.entries(roots)) {
    if (url.startsWith(prefix)) {
      const f = path.resolve(root, url.slice(prefix.length));
      // Nothing outside the served folders.
      if (f === root || f.startsWith(root + path.sep)) file = f;
    }
  }
  fs.readFile(file ?? '', (err, data) => {
    if (err || !file) {
      res.writeHead(404);
      res.end();
      return;
    }
    res.writeHead(200, { 'content-type': types[path.extname(file)] ?? 'application/octet-stream' });
    res.end(data);
  });
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const port = server.address().port;

const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'tiles3d-chromium-'));
const context = await chromium.launchPersistentContext(profile, {
  executablePath: '/usr/bin/chromium',
  headless: true,
  viewport: { width: Number(width), height: Number(height) },
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    // WebGL without a GPU: the SwiftShader software renderer.
    '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
let code = 0;
try {
  const page = context.pages()[0] ?? await context.newPage();
  const logs = [];
  // (SwiftShader's notes on reading pixels back are noise.)
  page.on('console', (m) => { if (!m.text().includes('GL Driver Message')) logs.push(`${m.type()}: ${m.text()}`); });
  page.on('pageerror', (e) => logs.push(`page error: ${e.message}`));
  page.on('response', (r) => { if (r.status() >= 400) logs.push(`HTTP ${r.status()}: ${r.url()}`); });
  const name = encodeURIComponent(path.basename(tileset));
  const q = `tileset=/tiles/${name}&elev=${elev}&azim=${azim}&zoom=${zoom}&error=${error}`;
  await page.goto(`http://127.0.0.1:${port}/?${q}`);
  const deadline = Date.now() + Number(timeout) * 1000;
  let state = null;
  for (;;) {
    state = await page.evaluate(() => window.__state ?? null);
    if (state?.ready || state?.error || Date.now() > deadline) break;
    await page.waitForTimeout(250);
  }
  if (state?.error) throw new Error(`the page failed: ${state.error}\n${logs.join('\n')}`);
  if (!state?.ready) throw new Error(`tiles not loaded after ${timeout} s (state ${JSON.stringify(state)})\n${logs.join('\n')}`);
  await page.screenshot({ path: out });
  console.log(`wrote ${out}: ${state.tiles} tiles visible after ${state.frames} frames; ` +
    `${state.features.withFeatures} of ${state.features.meshes} meshes with features; ` +
    `a building: ${JSON.stringify(state.features.sample)}`);
  if (state.failed) console.log(`${state.failed} tiles failed to load`);
  if (logs.length) console.log(logs.join('\n'));
} catch (e) {
  console.error(`tiles3d-screenshot: ${e.message}`);
  code = 1;
} finally {
  await context.close();
  server.close();
  fs.rmSync(profile, { recursive: true, force: true });
}
process.exit(code);
