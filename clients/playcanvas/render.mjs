// pbrcheck's PlayCanvas client, the runner (docs/renderers.md).
//
//   node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout SECONDS]
//   node render.mjs --version
//
// Serves page.html/page.js, the installed playcanvas engine (its ES module build) and the exported
// scene folder through ../browser/runner.mjs and headless.mjs: headless Chromium, WebGL2 on
// SwiftShader; the page POSTs linear radiance, written here as a little-endian colour PFM. Exit 0
// on success; 1 with one line on stderr otherwise.
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { runClient } from '../browser/runner.mjs';

runClient({
  label: 'playcanvas client',
  here: path.dirname(fileURLToPath(import.meta.url)),
  packages: [['playcanvas', 'node_modules/playcanvas'], ['draco3d', 'node_modules/draco3d']],
  roots: [['/playcanvas/', 'node_modules/playcanvas'], ['/draco3d/', 'node_modules/draco3d']],
  describe: (h) => ({ atlas: JSON.parse(h['x-atlas'] || 'null') }),
});
