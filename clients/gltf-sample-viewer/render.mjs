// pbrcheck's Khronos glTF Sample Viewer client, the runner (docs/renderers.md).
//
//   node render.mjs SCENARIO.json OUT.pfm [--ss N] [--ibl fast|full] [--timeout SECONDS]
//   node render.mjs --version
//
// Serves page.html/page.js, the installed @khronosgroup/gltf-viewer package (node_modules) and the
// exported scene folder (the scenario's folder) through ../browser/headless.mjs: headless Chromium,
// WebGL2 on SwiftShader; the page renders with the Sample Viewer's own engine (its GGX
// prefiltering, its DFG LUT, its shaders) into a float target and POSTs linear radiance, written
// here as a little-endian colour PFM. Exit 0 on success; 1 with one line on stderr otherwise.
//
// --ibl: the quality of the Sample Viewer's environment prefiltering (its iblSampler, run once per
// environment on the GPU; here on SwiftShader, the CPU). `full` is the package's own settings; on
// software WebGL they cost about 2.5e9 shader samples (minutes on a loaded 2-core machine), so
// `fast` (the default) sets the same algorithm's constants lower: see IBL_PROFILES. The module is
// served with those constructor constants replaced (each must be found exactly once, else the run
// fails: a new package version must be looked at again); nothing else in the engine changes.
import path from 'node:path';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';
import { clientMain, runPage, sceneJob, chromiumVersion, packageVersion, fail } from '../browser/headless.mjs';

const LABEL = 'gltf-sample-viewer client';
const HERE = path.dirname(fileURLToPath(import.meta.url));
const VIEWER_DIR = path.join(HERE, 'node_modules', '@khronosgroup', 'gltf-viewer');
const viewerVersion = () => packageVersion(path.join(VIEWER_DIR, 'package.json'));
const MODULE = path.join(VIEWER_DIR, 'dist', 'gltf-viewer.module.js');
// Google's Draco decoder (glTF branch, asm.js), as vendored by the three.js client's package: served
// as /draco/draco_decoder.js for Draco-compressed assets (page.js), absent when that client is not installed.
const DRACO_DIR = path.join(HERE, '..', 'threejs', 'node_modules', 'three', 'examples', 'jsm', 'libs', 'draco', 'gltf');

// iblSampler's constructor constants (package values in `full`). textureSize: the prefiltered cube
// maps' face size (its GGX mip chain runs from it down to 16 x 16, roughness = level / (levels - 1),
// read back at lod = roughness (levels - 1)); ggx / lambertian / sheen: importance samples per
// texel (filtered importance sampling: fewer samples read a blurrier source level); lut: the DFG
// LUT's resolution (512 samples a texel, bilinear lookups of a smooth function). No exported
// material has sheen, so its samples only cost time.
const IBL_PROFILES = {
  full: { textureSize: 256, ggxSampleCount: 1024, lambertianSampleCount: 2048, sheenSamplCount: 64, lutResolution: 1024 },
  fast: { textureSize: 128, ggxSampleCount: 256, lambertianSampleCount: 256, sheenSamplCount: 1, lutResolution: 128 },
};
const PACKAGE_IBL = IBL_PROFILES.full;

function viewerModule(profile) {
  let text = readFileSync(MODULE, 'utf8');
  for (const [k, v] of Object.entries(IBL_PROFILES[profile])) {
    const from = `this.${k} = ${PACKAGE_IBL[k]};`;
    const n = text.split(from).length - 1;
    if (n !== 1) fail(LABEL, `${MODULE}: expected one '${from}' (the iblSampler constant), found ${n}; is the package version the pinned one?`);
    text = text.replace(from, `this.${k} = ${v};`);
  }
  return text;
}

clientMain((args) => {
  if (args[0] === '--version') {
    const v = viewerVersion();
    if (!v) fail(LABEL, `@khronosgroup/gltf-viewer is not installed: run npm ci in ${HERE}`);
    process.stdout.write(`@khronosgroup/gltf-viewer ${v}; ${chromiumVersion()}; node ${process.version}\n`);
    process.exit(0);
  }
  let ss = 2, timeoutS = 280, ibl = 'fast';
  const pos = [];
  for (let i = 0; i < args.length; i++) {
    if (args[i] === '--ss') ss = parseInt(args[++i], 10);
    else if (args[i] === '--timeout') timeoutS = parseFloat(args[++i]);
    else if (args[i] === '--ibl') ibl = args[++i];
    else pos.push(args[i]);
  }
  if (pos.length !== 2 || !(ss >= 1) || !(timeoutS > 0) || !Object.hasOwn(IBL_PROFILES, ibl)) {
    fail(LABEL, 'usage: node render.mjs SCENARIO.json OUT.pfm [--ss N] [--ibl fast|full] [--timeout S]');
  }
  const [scenarioPath, outPath] = pos;
  if (!viewerVersion()) fail(LABEL, `@khronosgroup/gltf-viewer is not installed: run npm ci in ${HERE}`);
  const job = sceneJob(LABEL, HERE, scenarioPath, outPath, timeoutS);
  const { scenario } = job;
  if (!scenario?.environment?.hdr) fail(LABEL, `${scenarioPath}: environment.hdr missing (the Sample Viewer reads Radiance .hdr only)`);

  return runPage({
    ...job,
    contents: { '/viewer/gltf-viewer.module.js': viewerModule(ibl) },
    roots: [['/viewer/', path.join(VIEWER_DIR, 'dist')], job.sceneRoot,
            ['/draco/', DRACO_DIR]],
    page: `/page.html?ss=${ss}`,
    describe: (h) => ({
      viewer: viewerVersion(), gl_renderer: h['x-gl-renderer'], ibl_format: h['x-ibl-format'],
      supersample: ss, ibl: { profile: ibl, ...IBL_PROFILES[ibl] }, page_seconds: parseFloat(h['x-page-seconds']),
      gpu_seconds: parseFloat(h['x-gpu-seconds']),
    }),
  });
});
