// pbrcheck's headless-browser harness for WebGL clients (docs/renderers.md).
//
//   import { runPage, chromiumPath, chromiumVersion, packageVersion } from '../browser/headless.mjs';
//
// runPage serves a client's page and its files (and this folder under /browser/) on a loopback HTTP server, starts Debian's headless
// Chromium with WebGL2 on SwiftShader (--use-angle=swiftshader --enable-unsafe-swiftshader), waits
// for the page to POST the linear float pixels, writes them as a little-endian colour PFM and stops
// the browser and the server. The page protocol:
//   POST /result  body: W*H*3 float32 RGB, rows bottom-up (GL's order, which is PFM's), headers
//                 X-Width and X-Height, and any X-* the client describes in its stdout JSON line;
//   POST /error   body: a message (the run fails with its first lines);
//   POST /log     body: a line copied to stderr (console warnings and errors).
// Exit 0 on success; 1 with one line on stderr otherwise. $PBRCHECK_CHROMIUM names another
// Chromium binary.
import { spawn, execFileSync } from 'node:child_process';
import { createServer } from 'node:http';
import { mkdtempSync, readFileSync, rmSync, writeFileSync, renameSync, existsSync, statSync } from 'node:fs';
import { tmpdir } from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

/** This folder, served under /browser/ (page-common.js: the pages' shared half). */
const BROWSER_DIR = path.dirname(fileURLToPath(import.meta.url));

const TYPES = {
  '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript', '.json': 'application/json',
  '.gltf': 'model/gltf+json', '.bin': 'application/octet-stream', '.exr': 'image/x-exr',
  '.hdr': 'image/vnd.radiance', '.wasm': 'application/wasm', '.png': 'image/png',
};

/** The Chromium binary: $PBRCHECK_CHROMIUM, else Debian's. */
export function chromiumPath() {
  const c = process.env.PBRCHECK_CHROMIUM;
  if (c) return c;
  for (const p of ['/usr/bin/chromium', '/usr/bin/chromium-browser']) if (existsSync(p)) return p;
  return 'chromium';
}

/** `chromium --version`'s line, or 'chromium ?' when it cannot run. */
export function chromiumVersion() {
  try {
    return execFileSync(chromiumPath(), ['--version'], { encoding: 'utf8', timeout: 20000 }).trim();
  } catch {
    return 'chromium ?';
  }
}

/** The version in a package.json, or null when it is absent (the package is not installed). */
export function packageVersion(packageJson) {
  try {
    return JSON.parse(readFileSync(packageJson, 'utf8')).version;
  } catch {
    return null;
  }
}

/** Print `${label}: ${msg}` on stderr and exit 1. */
export function fail(label, msg) {
  process.stderr.write(`${label}: ${msg}\n`);
  process.exit(1);
}

/**
 * Serve and run one page, write the PFM.
 * @param {object} o
 * @param {string} o.label    the client's name in every message
 * @param {Object<string,string>} o.files   URL path -> file (the page and its scripts)
 * @param {Object<string,string>} [o.contents]  URL path -> text served as it is (checked first)
 * @param {Array<[string,string]>} o.roots  [URL prefix ending in '/', folder] served below it
 * @param {string} o.page     the URL path (with query) Chromium opens
 * @param {number} o.width    expected image width
 * @param {number} o.height   expected image height
 * @param {string} o.outPath  the PFM to write (atomically)
 * @param {number} o.timeoutS seconds before giving up
 * @param {function(object): object} o.describe  request headers -> the JSON line printed on success
 */
/** Chromium starts at most this many times for one page (a browser that dies before the page ran). */
const CHROMIUM_LAUNCHES = 2;

export function runPage(o) {
  const bad = (msg) => fail(o.label, msg);
  const roots = [...o.roots, ['/browser/', BROWSER_DIR]].map(([prefix, dir]) => [prefix, path.resolve(dir)]);
  function resolveUrl(urlPath) {
    const p = decodeURIComponent(urlPath.split('?')[0]);
    if (Object.hasOwn(o.files, p)) return o.files[p];
    for (const [prefix, root] of roots) {
      if (p.startsWith(prefix)) {
        const f = path.resolve(root, '.' + p.slice(prefix.length - 1));
        return f.startsWith(root + path.sep) ? f : null;
      }
    }
    return null;
  }

  let chrome = null, userDir = null, timer = null;
  function cleanup() {
    if (timer) clearTimeout(timer);
    if (chrome && chrome.exitCode === null) {
      try { chrome.kill('SIGKILL'); } catch { /* gone */ }
    }
    if (userDir) {
      try { rmSync(userDir, { recursive: true, force: true }); } catch { /* best effort */ }
    }
  }
  process.on('exit', cleanup);
  for (const sig of ['SIGINT', 'SIGTERM']) process.on(sig, () => { cleanup(); process.exit(1); });

  const W = o.width, H = o.height;
  const contents = o.contents || {};
  const server = createServer((req, res) => {
    const urlPath = decodeURIComponent(req.url.split('?')[0]);
    if (req.method === 'GET' && Object.hasOwn(contents, urlPath)) {
      res.writeHead(200, { 'Content-Type': TYPES[path.extname(urlPath)] || 'application/octet-stream', 'Cache-Control': 'no-store' });
      res.end(contents[urlPath]);
      return;
    }
    if (req.method === 'POST') {
      const chunks = [];
      req.on('data', (c) => chunks.push(c));
      req.on('end', () => {
        res.end('ok');
        const body = Buffer.concat(chunks);
        if (req.url === '/error') bad(`page error: ${body.toString('utf8').split('\n').slice(0, 4).join(' | ')}`);
        if (req.url === '/log') process.stderr.write(body.toString() + '\n');
        if (req.url !== '/result') return;
        const w = parseInt(req.headers['x-width'], 10), h = parseInt(req.headers['x-height'], 10);
        if (w !== W || h !== H || body.length !== W * H * 12) {
          bad(`page returned ${w}x${h} (${body.length} bytes), expected ${W}x${H}`);
        }
        const head = Buffer.from(`PF\n${W} ${H}\n-1.0\n`, 'ascii');
        const tmp = `${o.outPath}.tmp-${process.pid}`;
        writeFileSync(tmp, Buffer.concat([head, body]));   // GL rows are bottom-up: PFM's order
        renameSync(tmp, o.outPath);
        process.stdout.write(JSON.stringify(o.describe(req.headers)) + '\n');
        cleanup();
        process.exit(0);
      });
      return;
    }
    const f = resolveUrl(req.url);
    if (!f || !existsSync(f) || !statSync(f).isFile()) {
      res.writeHead(404);
      res.end('not found');
      return;
    }
    res.writeHead(200, { 'Content-Type': TYPES[path.extname(f)] || 'application/octet-stream', 'Cache-Control': 'no-store' });
    res.end(readFileSync(f));
  });

  server.listen(0, '127.0.0.1', () => {
    const port = server.address().port;
    userDir = mkdtempSync(path.join(tmpdir(), 'pbrcheck-chromium-'));
    const flags = [
      '--headless', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
      '--no-first-run', '--no-default-browser-check', '--disable-extensions', '--disable-dev-shm-usage',
      '--mute-audio', `--user-data-dir=${userDir}`, '--remote-debugging-port=0',
    ];
    if (process.getuid && process.getuid() === 0) flags.push('--no-sandbox');
    // Chromium on SwiftShader now and then exits within its first seconds, before the page runs
    // (seen once in ~40 gate renders, the same render passing 6 times after): the browser, not the
    // page, failed, so it is started once more with a fresh profile before that is an error. A page
    // error (POST /error), a wrong size and the timeout are never retried.
    let launches = 0;
    function launch() {
      launches += 1;
      let stderrTail = '';
      if (launches > 1) {  // a fresh profile: the dead browser's may hold its lock
        try { rmSync(userDir, { recursive: true, force: true }); } catch { /* best effort */ }
        userDir = mkdtempSync(path.join(tmpdir(), 'pbrcheck-chromium-'));
      }
      const args = [...flags.filter((f) => !f.startsWith('--user-data-dir=')), `--user-data-dir=${userDir}`];
      chrome = spawn(chromiumPath(), [...args, `http://127.0.0.1:${port}${o.page}`],
        { stdio: ['ignore', 'ignore', 'pipe'] });
      chrome.stderr.on('data', (d) => { stderrTail = (stderrTail + d.toString()).slice(-2000); });
      chrome.on('error', (e) => bad(`cannot start Chromium (${chromiumPath()}): ${e.message}`));
      chrome.on('exit', (code) => {
        const why = `Chromium exited (${code}) before the page returned pixels`;
        if (launches < CHROMIUM_LAUNCHES) {
          process.stderr.write(`${o.label}: ${why}; starting it once more\n`);
          launch();
          return;
        }
        bad(`${why} (${launches} launches): ${stderrTail.trim().split('\n').slice(-3).join(' | ')}`);
      });
    }
    launch();
    timer = setTimeout(() => bad(`no pixels after ${o.timeoutS} s`), o.timeoutS * 1000);
  });
}
