// pbrcheck's three.js client, the runner (docs/renderers.md).
//
//   node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout SECONDS]
//   node render.mjs --version
//
// Serves page.html/page.js, node_modules/three and the exported scene folder (the scenario's
// folder) on a loopback HTTP server, starts Debian's headless Chromium with WebGL2 on SwiftShader
// (--use-angle=swiftshader --enable-unsafe-swiftshader), waits for the page to POST the linear
// float pixels (or an error), writes OUT as a little-endian colour PFM and stops the browser and
// the server. Exit 0 on success; 1 with one line on stderr otherwise. $PBRCHECK_CHROMIUM names
// another Chromium binary.
import { spawn, execFileSync } from 'node:child_process';
import { createServer } from 'node:http';
import { mkdtempSync, readFileSync, rmSync, writeFileSync, renameSync, existsSync, statSync } from 'node:fs';
import { tmpdir } from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const THREE_DIR = path.join(HERE, 'node_modules', 'three');
const TYPES = {
  '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript', '.json': 'application/json',
  '.gltf': 'model/gltf+json', '.bin': 'application/octet-stream', '.exr': 'image/x-exr',
  '.hdr': 'image/vnd.radiance',
};

function fail(msg) {
  process.stderr.write(`threejs client: ${msg}\n`);
  process.exit(1);
}

function chromiumPath() {
  const c = process.env.PBRCHECK_CHROMIUM;
  if (c) return c;
  for (const p of ['/usr/bin/chromium', '/usr/bin/chromium-browser']) if (existsSync(p)) return p;
  return 'chromium';
}

function threeVersion() {
  try {
    return JSON.parse(readFileSync(path.join(THREE_DIR, 'package.json'), 'utf8')).version;
  } catch {
    return null;
  }
}

const args = process.argv.slice(2);
if (args[0] === '--version') {
  const v = threeVersion();
  if (!v) fail(`three is not installed: run npm ci in ${HERE}`);
  let chrome = 'chromium ?';
  try {
    chrome = execFileSync(chromiumPath(), ['--version'], { encoding: 'utf8', timeout: 20000 }).trim();
  } catch { /* reported at render time */ }
  process.stdout.write(`three ${v} (r${v.split('.')[1]}); ${chrome}; node ${process.version}\n`);
  process.exit(0);
}
let ss = 2, timeoutS = 240;
const pos = [];
for (let i = 0; i < args.length; i++) {
  if (args[i] === '--ss') ss = parseInt(args[++i], 10);
  else if (args[i] === '--timeout') timeoutS = parseFloat(args[++i]);
  else pos.push(args[i]);
}
if (pos.length !== 2 || !(ss >= 1)) fail('usage: node render.mjs SCENARIO.json OUT.pfm [--ss N] [--timeout S]');
const [scenarioPath, outPath] = pos;
if (!threeVersion()) fail(`three is not installed: run npm ci in ${HERE}`);
let scenario;
try {
  scenario = JSON.parse(readFileSync(scenarioPath, 'utf8'));
} catch (e) {
  fail(`cannot read the scenario ${scenarioPath}: ${e.message}`);
}
const sceneDir = path.dirname(path.resolve(scenarioPath));
const W = scenario.size.width, H = scenario.size.height;

function resolveUrl(urlPath) {
  const p = decodeURIComponent(urlPath.split('?')[0]);
  const roots = [['/three/', THREE_DIR], ['/scene/', sceneDir]];
  for (const [prefix, root] of roots) {
    if (p.startsWith(prefix)) {
      const f = path.resolve(root, '.' + p.slice(prefix.length - 1));
      return f.startsWith(root + path.sep) ? f : null;
    }
  }
  if (p === '/page.html' || p === '/page.js') return path.join(HERE, p.slice(1));
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

const server = createServer((req, res) => {
  if (req.method === 'POST') {
    const chunks = [];
    req.on('data', (c) => chunks.push(c));
    req.on('end', () => {
      res.end('ok');
      const body = Buffer.concat(chunks);
      if (req.url === '/error') fail(`page error: ${body.toString('utf8').split('\n').slice(0, 4).join(' | ')}`);
      if (req.url === '/log') process.stderr.write(body.toString() + '\n');
      if (req.url !== '/result') return;
      const w = parseInt(req.headers['x-width'], 10), h = parseInt(req.headers['x-height'], 10);
      if (w !== W || h !== H || body.length !== W * H * 12) {
        fail(`page returned ${w}x${h} (${body.length} bytes), expected ${W}x${H}`);
      }
      const head = Buffer.from(`PF\n${W} ${H}\n-1.0\n`, 'ascii');
      const tmp = `${outPath}.tmp-${process.pid}`;
      writeFileSync(tmp, Buffer.concat([head, body]));   // GL rows are bottom-up: PFM's order
      renameSync(tmp, outPath);
      process.stdout.write(JSON.stringify({
        three: req.headers['x-three-revision'], gl_renderer: req.headers['x-gl-renderer'],
        supersample: ss, page_seconds: parseFloat(req.headers['x-page-seconds']),
      }) + '\n');
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
  chrome = spawn(chromiumPath(), [...flags, `http://127.0.0.1:${port}/page.html?ss=${ss}`],
    { stdio: ['ignore', 'ignore', 'pipe'] });
  let stderrTail = '';
  chrome.stderr.on('data', (d) => { stderrTail = (stderrTail + d.toString()).slice(-2000); });
  chrome.on('error', (e) => fail(`cannot start Chromium (${chromiumPath()}): ${e.message}`));
  chrome.on('exit', (code) => fail(`Chromium exited (${code}) before the page returned pixels: ${stderrTail.trim().split('\n').slice(-3).join(' | ')}`));
  timer = setTimeout(() => fail(`no pixels after ${timeoutS} s`), timeoutS * 1000);
});
