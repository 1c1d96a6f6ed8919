// pbrcheck's Filament client, the runner (docs/renderers.md).
//
//   node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout SECONDS]
//   node render.mjs --version
//
// Serves page.html/page.js, Filament's web build (npm filament: filament.js + filament.wasm, its
// gltfio included) and the exported scene folder through ../browser/runner.mjs and headless.mjs:
// headless Chromium, WebGL2 on SwiftShader; the page POSTs linear radiance, written here as a
// little-endian colour PFM. Exit 0 on success; 1 with one line on stderr otherwise.
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { runClient } from '../browser/runner.mjs';

runClient({
  label: 'filament client',
  here: path.dirname(fileURLToPath(import.meta.url)),
  packages: [['filament', 'node_modules/filament']],
  roots: [['/filament/', 'node_modules/filament']],
  describe: (h) => ({ ibl: JSON.parse(h['x-ibl'] || 'null') }),
});
