// pbrcheck's three-gpu-pathtracer client, the runner (docs/renderers.md, "three-gpu-pathtracer").
//
//   node render.mjs SCENARIO.json OUT.pfm [--spp N] [--bounces N] [--timeout SECONDS]
//   node render.mjs --version
//
// Serves page.html/page.js, node_modules/{three,three-mesh-bvh,three-gpu-pathtracer} and the
// exported scene folder through ../browser/headless.mjs (loopback HTTP server, Debian's headless
// Chromium, WebGL2 on SwiftShader); the page path traces N samples per pixel and POSTs the linear
// float mean, written as a little-endian colour PFM. Exit 0 on success; 1 with one line on stderr.
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { clientMain, runPage, sceneJob, chromiumVersion, packageVersion, fail } from '../browser/headless.mjs';

const LABEL = 'three-gpu-pathtracer client';
const HERE = path.dirname(fileURLToPath(import.meta.url));
const MODULES = path.join(HERE, 'node_modules');
const version = (name) => packageVersion(path.join(MODULES, name, 'package.json'));
const missing = () => ['three', 'three-mesh-bvh', 'three-gpu-pathtracer'].filter((n) => !version(n));

clientMain((args) => {
  if (args[0] === '--version') {
    if (missing().length) fail(LABEL, `${missing().join(', ')} not installed: run npm ci in ${HERE}`);
    process.stdout.write(`three-gpu-pathtracer ${version('three-gpu-pathtracer')}; three-mesh-bvh ${version('three-mesh-bvh')}; `
      + `three ${version('three')}; ${chromiumVersion()}; node ${process.version}\n`);
    process.exit(0);
  }
  let spp = 64, bounces = 8, timeoutS = 600;
  const pos = [];
  for (let i = 0; i < args.length; i++) {
    if (args[i] === '--spp') spp = parseInt(args[++i], 10);
    else if (args[i] === '--bounces') bounces = parseInt(args[++i], 10);
    else if (args[i] === '--timeout') timeoutS = parseFloat(args[++i]);
    else pos.push(args[i]);
  }
  if (pos.length !== 2 || !(spp >= 1) || !(bounces >= 1)) {
    fail(LABEL, 'usage: node render.mjs SCENARIO.json OUT.pfm [--spp N] [--bounces N] [--timeout S]');
  }
  const [scenarioPath, outPath] = pos;
  if (missing().length) fail(LABEL, `${missing().join(', ')} not installed: run npm ci in ${HERE}`);
  const job = sceneJob(LABEL, HERE, scenarioPath, outPath, timeoutS);

  return runPage({
    ...job,
    roots: [['/three/', path.join(MODULES, 'three')], ['/bvh/', path.join(MODULES, 'three-mesh-bvh')],
      ['/gpt/', path.join(MODULES, 'three-gpu-pathtracer')], job.sceneRoot],
    page: `/page.html?spp=${spp}&bounces=${bounces}`,
    describe: (h) => ({
      three: h['x-three-revision'], gl_renderer: h['x-gl-renderer'], samples: parseInt(h['x-samples'], 10),
      bounces: parseInt(h['x-bounces'], 10), setup_seconds: parseFloat(h['x-setup-seconds']),
      page_seconds: parseFloat(h['x-page-seconds']),
    }),
  });
});
