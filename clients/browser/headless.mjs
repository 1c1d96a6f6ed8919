// pbrcheck's headless-browser harness for WebGL clients (docs/renderers.md).
//
//   import { clientMain, runPage, chromiumPath, chromiumVersion, packageVersion, fail } from '../browser/headless.mjs';
//   clientMain((args) => { ...parse args...; return runPage({...}); });
//
// runPage serves a client's page and its files (and this folder under /browser/) on a loopback HTTP
// server, has headless Chromium (WebGL2 on SwiftShader: --use-angle=swiftshader
// --enable-unsafe-swiftshader) open the page, waits for it to POST the linear float pixels and writes
// them as a little-endian colour PFM. The page protocol:
//   POST /result  body: W*H*3 float32 RGB, rows bottom-up (GL's order, which is PFM's), headers
//                 X-Width and X-Height, and any X-* the client describes in its stdout JSON line;
//   POST /error   body: a message (the render fails with its first lines);
//   POST /log     body: a line copied to stderr (console warnings and errors).
// $PBRCHECK_CHROMIUM names another Chromium binary.
//
// Two modes (clientMain):
// - one render: `node render.mjs ARGS...`: the server and Chromium start, the page renders, the JSON
//   line describing it goes to stdout, both stop; exit 0, or 1 with one line on stderr.
// - serve: `node render.mjs --serve`: one server and ONE Chromium (one tab) for every render of the
//   process. Each stdin line is a JSON array, the render's whole command line ([node, render.mjs,
//   ARGS...]); each render answers one stdout line, {"ok": true, "stdout": the one-render JSON line}
//   or {"ok": false, "error": the one-render stderr line}. The tab navigates to each render's page
//   (a fresh document: nothing of the previous render's JavaScript or WebGL state survives); a
//   POST from an earlier render's page (its Referer names another job) is ignored. Chromium is
//   driven over its DevTools pipe (--remote-debugging-pipe: fd 3 in, fd 4 out, NUL-terminated JSON);
//   it is started on the first render, started again after it died or after a render timed out
//   (the runaway page is killed with it), and stopped when stdin closes, on SIGINT / SIGTERM, or
//   at exit. pbrcheck's clients/run.py starts one such process per client for a whole run.
import { spawn, execFileSync } from 'node:child_process';
import { createServer } from 'node:http';
import { createInterface } from 'node:readline';
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

/** Chromium starts at most this many times for one render (a browser that dies before the page ran). */
const CHROMIUM_LAUNCHES = 2;
/** Milliseconds to wait for Chromium's first tab to appear on the DevTools pipe. */
const TAB_WAIT_MS = 20000;

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

/** A render's failure: its one line (`label: message`). */
class ClientFailure extends Error {}

/** True in serve mode: a failure fails one render, not the process. */
let serving = false;

/** One render: print `${label}: ${msg}` on stderr and exit 1; in serve mode, throw it (that render fails). */
export function fail(label, msg) {
  if (serving) throw new ClientFailure(`${label}: ${msg}`);
  process.stderr.write(`${label}: ${msg}\n`);
  process.exit(1);
}

/** The DevTools protocol over Chromium's pipe (fd 3: commands in, fd 4: replies and events out). */
class Cdp {
  constructor(chrome) {
    this.out = chrome.stdio[3];
    this.pending = new Map();
    this.next = 1;
    let buf = '';
    chrome.stdio[4].on('data', (d) => {
      buf += d.toString('utf8');
      let k;
      while ((k = buf.indexOf('\0')) >= 0) {
        const msg = JSON.parse(buf.slice(0, k));
        buf = buf.slice(k + 1);
        const p = msg.id && this.pending.get(msg.id);
        if (!p) continue;
        this.pending.delete(msg.id);
        if (msg.error) p.reject(new Error(`${p.method}: ${msg.error.message}`));
        else p.resolve(msg.result);
      }
    });
    this.out.on('error', () => { /* the browser is gone: its exit handler reports it */ });
  }

  send(method, params = {}, sessionId = undefined) {
    const id = this.next++;
    return new Promise((resolve, reject) => {
      this.pending.set(id, { resolve, reject, method });
      this.out.write(JSON.stringify({ id, method, params, ...(sessionId ? { sessionId } : {}) }) + '\0');
    });
  }

  close(why) {
    for (const p of this.pending.values()) p.reject(new Error(why));
    this.pending.clear();
  }
}

/** One headless Chromium with one tab, driven over the DevTools pipe. */
class Browser {
  constructor(onExit) {
    this.userDir = mkdtempSync(path.join(tmpdir(), 'pbrcheck-chromium-'));
    const flags = [
      '--headless', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
      '--no-first-run', '--no-default-browser-check', '--disable-extensions', '--disable-dev-shm-usage',
      '--mute-audio', `--user-data-dir=${this.userDir}`, '--remote-debugging-pipe',
    ];
    if (process.getuid && process.getuid() === 0) flags.push('--no-sandbox');
    this.stderrTail = '';
    this.chrome = spawn(chromiumPath(), [...flags, 'about:blank'], { stdio: ['ignore', 'ignore', 'pipe', 'pipe', 'pipe'] });
    this.chrome.stderr.on('data', (d) => { this.stderrTail = (this.stderrTail + d.toString()).slice(-2000); });
    this.cdp = new Cdp(this.chrome);
    this.exited = false;
    const gone = (why) => {
      if (this.exited) return;
      this.exited = true;
      this.cdp.close(why);
      this.removeProfile();
      onExit(this, why);
    };
    this.chrome.on('error', (e) => gone(`cannot start Chromium (${chromiumPath()}): ${e.message}`));
    this.chrome.on('exit', (code) => gone(`Chromium exited (${code}) before the page returned pixels`));
    this.session = this.attach();
    this.session.catch(() => { /* reported by the navigation that awaits it */ });
  }

  /** The DevTools session of Chromium's first tab. */
  async attach() {
    const t0 = Date.now();
    for (;;) {
      const { targetInfos } = await this.cdp.send('Target.getTargets');
      const tab = targetInfos.find((t) => t.type === 'page');
      if (tab) return (await this.cdp.send('Target.attachToTarget', { targetId: tab.targetId, flatten: true })).sessionId;
      if (Date.now() - t0 > TAB_WAIT_MS) throw new Error(`Chromium opened no tab in ${TAB_WAIT_MS / 1000} s`);
      await new Promise((r) => setTimeout(r, 50));
    }
  }

  async navigate(url) {
    const r = await this.cdp.send('Page.navigate', { url }, await this.session);
    if (r.errorText) throw new Error(`navigation to ${url} failed: ${r.errorText}`);
  }

  removeProfile() {
    try { rmSync(this.userDir, { recursive: true, force: true }); } catch { /* best effort */ }
  }

  kill() {
    if (this.chrome.exitCode === null && this.chrome.signalCode === null) {
      try { this.chrome.kill('SIGKILL'); } catch { /* gone */ }
    }
    this.removeProfile();
  }
}

/** The loopback server and the browser shared by every render of the process; one render at a time. */
class Session {
  constructor() {
    this.job = null;
    this.browser = null;
    this.jobs = 0;
    this.listening = new Promise((resolve) => {
      this.server = createServer((req, res) => this.handle(req, res));
      this.server.listen(0, '127.0.0.1', () => resolve(this.server.address().port));
    });
  }

  /** The job a request belongs to: the current one, unless the request's page is an earlier job's. */
  jobOf(req) {
    const j = this.job;
    if (!j) return null;
    let job = null;
    try { job = new URL(req.headers.referer).searchParams.get('job'); } catch { /* no Referer: the current job */ }
    return job !== null && job !== String(j.id) ? null : j;
  }

  handle(req, res) {
    const j = this.jobOf(req);
    const urlPath = decodeURIComponent(req.url.split('?')[0]);
    if (req.method === 'POST') {
      const chunks = [];
      req.on('data', (c) => chunks.push(c));
      req.on('end', () => {
        res.end('ok');
        if (j) j.post(urlPath, Buffer.concat(chunks), req.headers);
      });
      return;
    }
    const f = j && j.resolveGet(urlPath);
    if (f && f.text !== undefined) {
      res.writeHead(200, { 'Content-Type': TYPES[path.extname(urlPath)] || 'application/octet-stream', 'Cache-Control': 'no-store' });
      res.end(f.text);
      return;
    }
    if (!f || !existsSync(f.file) || !statSync(f.file).isFile()) {
      res.writeHead(404);
      res.end('not found');
      return;
    }
    res.writeHead(200, { 'Content-Type': TYPES[path.extname(f.file)] || 'application/octet-stream', 'Cache-Control': 'no-store' });
    res.end(readFileSync(f.file));
  }

  /** Chromium died: the render it was running starts it once more, or fails. */
  browserExited(browser, why) {
    if (this.browser === browser) this.browser = null;
    const j = this.job;
    if (!j || j.browser !== browser) return;
    if (j.launches < CHROMIUM_LAUNCHES) {
      // Chromium on SwiftShader now and then exits within its first seconds, before the page runs
      // (seen once in ~40 gate renders, the same render passing 6 times after): the browser, not
      // the page, failed, so it is started once more before that is an error. A page error (POST
      // /error), a wrong size and the timeout are never retried.
      process.stderr.write(`${j.o.label}: ${why}; starting it once more\n`);
      this.open(j);
      return;
    }
    j.finish(new ClientFailure(`${j.o.label}: ${why} (${j.launches} launches): `
      + browser.stderrTail.trim().split('\n').slice(-3).join(' | ')));
  }

  /** Navigate the (started if needed) browser's tab to the job's page. */
  open(j) {
    j.launches += 1;
    if (!this.browser) this.browser = new Browser((b, why) => this.browserExited(b, why));
    j.browser = this.browser;
    const b = this.browser;
    const url = `http://127.0.0.1:${j.port}${j.o.page}${j.o.page.includes('?') ? '&' : '?'}job=${j.id}`;
    b.navigate(url).catch((e) => {
      if (!b.exited) j.finish(new ClientFailure(`${j.o.label}: ${e.message}`));
    });
  }

  /** One render (runPage's options): resolves to its JSON line's object, rejects with a ClientFailure. */
  async render(o) {
    const port = await this.listening;
    const roots = [...o.roots, ['/browser/', BROWSER_DIR]].map(([prefix, dir]) => [prefix, path.resolve(dir)]);
    const contents = o.contents || {};
    return new Promise((resolve, reject) => {
      const j = {
        o, port, id: ++this.jobs, launches: 0, browser: null, done: false,
        resolveGet(p) {
          if (Object.hasOwn(contents, p)) return { text: contents[p] };
          if (Object.hasOwn(o.files, p)) return { file: o.files[p] };
          for (const [prefix, root] of roots) {
            if (p.startsWith(prefix)) {
              const f = path.resolve(root, '.' + p.slice(prefix.length - 1));
              return f.startsWith(root + path.sep) ? { file: f } : null;
            }
          }
          return null;
        },
        post: (p, body, headers) => {
          if (j.done) return;
          if (p === '/log') process.stderr.write(body.toString() + '\n');
          if (p === '/error') j.finish(new ClientFailure(`${o.label}: page error: ${body.toString('utf8').split('\n').slice(0, 4).join(' | ')}`));
          if (p !== '/result') return;
          const W = o.width, H = o.height;
          const w = parseInt(headers['x-width'], 10), h = parseInt(headers['x-height'], 10);
          if (w !== W || h !== H || body.length !== W * H * 12) {
            j.finish(new ClientFailure(`${o.label}: page returned ${w}x${h} (${body.length} bytes), expected ${W}x${H}`));
            return;
          }
          const head = Buffer.from(`PF\n${W} ${H}\n-1.0\n`, 'ascii');
          const tmp = `${o.outPath}.tmp-${process.pid}`;
          try {
            writeFileSync(tmp, Buffer.concat([head, body]));   // GL rows are bottom-up: PFM's order
            renameSync(tmp, o.outPath);
          } catch (e) {
            j.finish(new ClientFailure(`${o.label}: cannot write ${o.outPath}: ${e.message}`));
            return;
          }
          j.finish(null, o.describe(headers));
        },
        finish: (err, value) => {
          if (j.done) return;
          j.done = true;
          clearTimeout(j.timer);
          if (this.job === j) this.job = null;
          // the finished page's engine, textures and WebGL context go now, not at the next render
          // (a run keeps one idle browser per client)
          if (this.browser && this.browser === j.browser) this.browser.navigate('about:blank').catch(() => {});
          if (err) reject(err);
          else resolve(value);
        },
      };
      j.timer = setTimeout(() => {
        j.finish(new ClientFailure(`${o.label}: no pixels after ${o.timeoutS} s`));
        this.dropBrowser();   // the runaway page with it; the next render starts another
      }, o.timeoutS * 1000);
      this.job = j;
      this.open(j);
    });
  }

  /** Kill the browser now; the next render starts another. */
  dropBrowser() {
    const b = this.browser;
    this.browser = null;
    if (b) b.kill();
  }

  close() {
    this.dropBrowser();
    this.server.close();
  }
}

let session = null;
function theSession() {
  if (!session) {
    session = new Session();
    const stop = () => { if (session) session.close(); };
    process.on('exit', stop);
    for (const sig of ['SIGINT', 'SIGTERM']) process.on(sig, () => { stop(); process.exit(1); });
  }
  return session;
}

/**
 * What every client's render shares: the scenario (read here; `fail` names it when unreadable), the
 * page and its script in `here`, the expected size, and `sceneRoot`, the exported scene's folder
 * served under /scene/ (for `roots`). Spread into runPage's options.
 */
export function sceneJob(label, here, scenarioPath, outPath, timeoutS) {
  let scenario;
  try {
    scenario = JSON.parse(readFileSync(scenarioPath, 'utf8'));
  } catch (e) {
    fail(label, `cannot read the scenario ${scenarioPath}: ${e.message}`);
  }
  return {
    label, scenario, outPath, timeoutS, width: scenario.size.width, height: scenario.size.height,
    files: { '/page.html': path.join(here, 'page.html'), '/page.js': path.join(here, 'page.js') },
    sceneRoot: ['/scene/', path.dirname(path.resolve(scenarioPath))],
  };
}

/**
 * Serve and run one page, write the PFM. One render: prints the JSON line and exits (0, or 1 with
 * one line on stderr). Serve mode: returns a promise of the JSON line's object.
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
export function runPage(o) {
  const p = theSession().render(o);
  if (serving) return p;
  p.then((line) => {
    process.stdout.write(JSON.stringify(line) + '\n');
    process.exit(0);
  }, (e) => {
    process.stderr.write(`${e.message}\n`);
    process.exit(1);
  });
  return p;
}

/**
 * A client's entry point: `main(args)` parses one render's arguments and returns runPage's result.
 * `node render.mjs --serve` runs it once per stdin line (module comment); otherwise once on argv.
 */
export function clientMain(main) {
  if (process.argv[2] !== '--serve') {
    main(process.argv.slice(2));
    return;
  }
  serving = true;
  theSession();
  const lines = createInterface({ input: process.stdin, terminal: false });
  let queue = Promise.resolve();
  lines.on('line', (line) => {
    queue = queue.then(async () => {
      let reply;
      try {
        const argv = JSON.parse(line);
        if (!Array.isArray(argv) || argv.length < 2) throw new ClientFailure('serve: expected a JSON array, the render command line');
        reply = { ok: true, stdout: JSON.stringify(await main(argv.slice(2).map(String))) };
      } catch (e) {
        reply = { ok: false, error: e instanceof ClientFailure ? e.message : String((e && e.stack) || e) };
      }
      process.stdout.write(JSON.stringify(reply) + '\n');
    });
  });
  lines.on('close', () => { queue.then(() => process.exit(0)); });
}
