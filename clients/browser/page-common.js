// pbrcheck's browser clients, the page side of the harness (headless.mjs serves this folder under
// /browser/): the protocol's POSTs, console forwarding and error reporting, the supersampling box
// filter and the GL renderer's name. Imported by clients/threejs/page.js and
// clients/gltf-sample-viewer/page.js.

/** POST ``body`` to the runner (``/result``, ``/error`` or ``/log``). */
export async function post(path, body, headers = {}) {
  await fetch(path, { method: 'POST', body, headers });
}

/** Copy console warnings and errors to the runner's stderr, and run ``main`` with every failure
 * (a rejection, an uncaught error) sent as ``/error``. */
export function runMain(main) {
  for (const k of ['error', 'warn']) {
    const f = console[k];
    console[k] = (...a) => { post('/log', `${k}: ${a.map(String).join(' ')}`); f(...a); };
  }
  window.addEventListener('error', (e) => post('/error', String(e.message)));
  window.addEventListener('unhandledrejection', (e) => post('/error', String(e.reason)));
  main().catch((e) => post('/error', String((e && e.stack) || e)));
}

/** The supersampling factor of the page's URL (``?ss=N``, default 2). */
export function supersampling() {
  return Math.max(1, parseInt(new URLSearchParams(location.search).get('ss') || '2', 10));
}

/** RGBA float pixels of (ss W) x (ss H) box-filtered to W x H RGB: ss x ss samples a pixel (the
 * reference's pixels are box-filtered too). Row order is kept (GL's: bottom-up, PFM's). */
export function boxFilter(px, W, H, ss) {
  const SW = W * ss;
  const out = new Float32Array(W * H * 3);
  const inv = 1 / (ss * ss);
  for (let y = 0; y < H; y++) {
    for (let x = 0; x < W; x++) {
      let r = 0, g = 0, b = 0;
      for (let j = 0; j < ss; j++) {
        const row = (y * ss + j) * SW;
        for (let i = 0; i < ss; i++) {
          const k = (row + x * ss + i) * 4;
          r += px[k]; g += px[k + 1]; b += px[k + 2];
        }
      }
      const o = (y * W + x) * 3;
      out[o] = r * inv; out[o + 1] = g * inv; out[o + 2] = b * inv;
    }
  }
  return out;
}

/** The GL renderer's name (unmasked where the browser allows), printable ASCII for a header. */
export function glRendererName(gl) {
  const dbg = gl.getExtension('WEBGL_debug_renderer_info');
  const name = dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  return String(name).replace(/[^\x20-\x7e]/g, '?');
}
