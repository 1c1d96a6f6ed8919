// pbrcheck's three.js client, the runner (docs/renderers.md).
//
//   node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout SECONDS]
//   node render.mjs --version
//
// Serves page.html/page.js, node_modules/three and the exported scene folder (the scenario's
// folder) through ../browser/headless.mjs: a loopback HTTP server, Debian's headless Chromium with
// WebGL2 on SwiftShader (--use-angle=swiftshader --enable-unsafe-swiftshader); the page POSTs the
// linear float pixels (or an error), written here as a little-endian colour PFM, then the browser
// and the server stop. Exit 0 on success; 1 with one line on stderr otherwise. $PBRCHECK_CHROMIUM
// names another Chromium binary.
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { clientMain, runPage, sceneJob, chromiumVersion, packageVersion, fail } from '../browser/headless.mjs';

const LABEL = 'threejs client';
const HERE = path.dirname(fileURLToPath(import.meta.url));
const THREE_DIR = path.join(HERE, 'node_modules', 'three');
const threeVersion = () => packageVersion(path.join(THREE_DIR, 'package.json'));

clientMain((args) => {
  if (args[0] === '--version') {
    const v = threeVersion();
    if (!v) fail(LABEL, `three is not installed: run npm ci in ${HERE}`);
    process.stdout.write(`three ${v} (r${v.split('.')[1]}); ${chromiumVersion()}; node ${process.version}\n`);
    process.exit(0);
  }
  let ss = 2, timeoutS = 240;
  const pos = [];
  for (let i = 0; i < args.length; i++) {
    if (args[i] === '--ss') ss = parseInt(args[++i], 10);
    else if (args[i] === '--timeout') timeoutS = parseFloat(args[++i]);
    else pos.push(args[i]);
  }
  if (pos.length !== 2 || !(ss >= 1)) fail(LABEL, 'usage: node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout S]');
  const [scenarioPath, outPath] = pos;
  if (!threeVersion()) fail(LABEL, `three is not installed: run npm ci in ${HERE}`);
  const job = sceneJob(LABEL, HERE, scenarioPath, outPath, timeoutS);

  return runPage({
    ...job,
    roots: [['/three/', THREE_DIR], job.sceneRoot],
    page: `/page.html?ss=${ss}`,
    describe: (h) => ({
      three: h['x-three-revision'], gl_renderer: h['x-gl-renderer'], supersample: ss,
      page_seconds: parseFloat(h['x-page-seconds']),
    }),
  });
});
