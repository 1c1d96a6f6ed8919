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

/** A float stand-in for the canvas: an RGBA32F colour texture with a depth-stencil buffer of
 * SW x SH, bound wherever the engine binds the default framebuffer (``null``) until ``restore()``.
 * For engines whose last pass draws into the canvas (8 bit): with their tone mapping and output
 * encoding off, the shading result lands here untouched. ``read()`` returns the RGBA float pixels
 * (GL's rows, bottom-up) and throws on a GL error of the read. Call it before the engine makes its first
 * draw (for Filament: before Engine.create, on the context the engine will find). Used by the Babylon.js, PlayCanvas and
 * Filament pages (the Sample Viewer page has its own copy of the same hook). */
export function floatCanvas(gl, SW, SH) {
  if (!gl.getExtension('EXT_color_buffer_float')) throw new Error('EXT_color_buffer_float missing: no float render target');
  const bind = gl.bindFramebuffer.bind(gl);
  const fbo = gl.createFramebuffer();
  const color = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, color);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, SW, SH, 0, gl.RGBA, gl.FLOAT, null);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.bindTexture(gl.TEXTURE_2D, null);
  const depth = gl.createRenderbuffer();
  gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
  gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH24_STENCIL8, SW, SH);
  gl.bindRenderbuffer(gl.RENDERBUFFER, null);
  bind(gl.FRAMEBUFFER, fbo);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, color, 0);
  gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_STENCIL_ATTACHMENT, gl.RENDERBUFFER, depth);
  const status = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
  if (status !== gl.FRAMEBUFFER_COMPLETE) throw new Error(`float framebuffer incomplete (0x${status.toString(16)})`);
  gl.clearColor(0, 0, 0, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT | gl.STENCIL_BUFFER_BIT);
  // Left bound: an engine that caches GL state and never binds "0" because it thinks it is bound
  // already (Filament) draws here too.
  gl.bindFramebuffer = (target, fb) => bind(target, fb == null ? fbo : fb);   // null, or undefined (emscripten's id 0)
  return {
    restore() { gl.bindFramebuffer = bind; },
    read() {
      while (gl.getError() !== gl.NO_ERROR) { /* an engine's earlier error is not the read's */ }
      bind(gl.READ_FRAMEBUFFER, fbo);
      const px = new Float32Array(SW * SH * 4);
      gl.readPixels(0, 0, SW, SH, gl.RGBA, gl.FLOAT, px);
      const err = gl.getError();
      if (err !== gl.NO_ERROR) throw new Error(`WebGL error 0x${err.toString(16)} reading the float target`);
      return px;
    },
  };
}
