// pbrcheck's browser clients, the runner's shared half (docs/renderers.md): argument parsing, the
// version line and the call to headless.mjs's runPage, for the clients whose runner is only
// "serve these packages and the page" (Babylon.js, PlayCanvas, Filament).
//
//   import { runClient } from '../browser/runner.mjs';
//   runClient({ label, here, packages: [['playcanvas', 'node_modules/playcanvas']], roots, ... });
//
// The command line: `node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout SECONDS]` or
// `node render.mjs --version` (one line: each package and its version; Chromium's; node's).
// Exit 0 on success; 1 with one line on stderr otherwise (usage, a package not installed, an
// unreadable scenario, then whatever runPage reports). `node render.mjs --serve`: headless.mjs's
// serve mode (one browser for many renders).
import path from 'node:path';
import { clientMain, runPage, sceneJob, chromiumVersion, packageVersion, fail } from './headless.mjs';

/**
 * @param {object} o
 * @param {string} o.label      the client's name in every message ('babylon client')
 * @param {string} o.here       the client's folder (page.html, page.js, node_modules)
 * @param {Array<[string,string]>} o.packages  [npm name, folder relative to here]: the version line, and the
 *                              check that they are installed
 * @param {Array<[string,string]>} o.roots     [URL prefix, folder relative to here] served besides the page
 * @param {number} [o.timeoutS] default seconds before giving up (--timeout overrides)
 * @param {function(object): object} [o.describe]  request headers -> extra fields of the JSON line
 */
export function runClient(o) {
  clientMain((args) => {
    const versions = () => o.packages.map(([name, dir]) => [name, packageVersion(path.join(o.here, dir, 'package.json'))]);
    const missing = () => versions().filter(([, v]) => !v).map(([n]) => n);
    if (args[0] === '--version') {
      if (missing().length) fail(o.label, `${missing().join(', ')} not installed: run npm ci in ${o.here}`);
      process.stdout.write(`${versions().map(([n, v]) => `${n} ${v}`).join(', ')}; ${chromiumVersion()}; node ${process.version}\n`);
      process.exit(0);
    }
    let ss = 2, timeoutS = o.timeoutS ?? 380;
    const pos = [];
    for (let i = 0; i < args.length; i++) {
      if (args[i] === '--ss') ss = parseInt(args[++i], 10);
      else if (args[i] === '--timeout') timeoutS = parseFloat(args[++i]);
      else pos.push(args[i]);
    }
    if (pos.length !== 2 || !(ss >= 1) || !(timeoutS > 0)) fail(o.label, 'usage: node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout S]');
    const [scenarioPath, outPath] = pos;
    if (missing().length) fail(o.label, `${missing().join(', ')} not installed: run npm ci in ${o.here}`);
    const job = sceneJob(o.label, o.here, scenarioPath, outPath, timeoutS);
    return runPage({
      ...job,
      roots: [...o.roots.map(([p, d]) => [p, path.join(o.here, d)]), job.sceneRoot],
      page: `/page.html?ss=${ss}`,
      describe: (h) => ({
        ...Object.fromEntries(versions()), gl_renderer: h['x-gl-renderer'], supersample: ss,
        page_seconds: parseFloat(h['x-page-seconds']), ...(o.describe ? o.describe(h) : {}),
      }),
    });
  });
}
