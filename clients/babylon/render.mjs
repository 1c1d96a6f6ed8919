// pbrcheck's Babylon.js client, the runner (docs/renderers.md).
//
//   node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout SECONDS]
//   node render.mjs --version
//
// Serves page.html/page.js, the installed @babylonjs/core and @babylonjs/loaders (their ES
// modules, as they are) and the exported scene folder through ../browser/runner.mjs and
// headless.mjs: headless Chromium, WebGL2 on SwiftShader; the page POSTs linear radiance, written
// here as a little-endian colour PFM. Exit 0 on success; 1 with one line on stderr otherwise.
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { runClient } from '../browser/runner.mjs';

runClient({
  label: 'babylon client',
  here: path.dirname(fileURLToPath(import.meta.url)),
  packages: [['@babylonjs/core', 'node_modules/@babylonjs/core'], ['@babylonjs/loaders', 'node_modules/@babylonjs/loaders']],
  roots: [['/core/', 'node_modules/@babylonjs/core'], ['/loaders/', 'node_modules/@babylonjs/loaders']],
  describe: (h) => ({ environment_size: parseInt(h['x-environment-size'], 10) }),
});
