// pbrcheck's Filament client, the page: Filament's web build renders the exported scene with its
// own glTF loader (gltfio: its lit materials from glTF's metallic-roughness, KHR_lights_punctual
// point lights) and its own shading (its DFG LUT, multiple-scattering compensation, specular
// occlusion, its LOD mapping of the reflections cube), post-processing off (no tone mapping, no
// colour grading), exposure 1 (setExposureDirect), into a float target; then POSTs linear radiance
// to the runner (render.mjs). See docs/renderers.md.
//
// The image-based lighting. Filament's web build has no runtime prefilter (its IBLPrefilterContext
// is not in the JavaScript bindings) and reads prefiltered environments only as cmgen's KTX files
// (createIblFromKtx1); cmgen is a native tool, not in the npm package. So this page prefilters the
// exported panorama the way cmgen does and hands the result to IndirectLight.Builder:
//  - reflections: a cube of FACE_SIZE with LEVELS levels, level l holding the GGX lobe of
//    perceptual roughness r = 1 - sqrt(1 - l / (LEVELS - 1)) (cmgen's lodToPerceptualRoughness, the
//    inverse of Filament's lod = iblRoughnessOneLevel r (2 - r)), importance-sampled with N = V = R,
//    weighted by n.l, each sample read from the panorama's box-filtered mip chain at the level
//    matching its solid angle (filtered importance sampling); level 0 is the panorama resampled;
//  - irradiance: 3-band spherical harmonics of the panorama convolved with the clamped cosine and
//    divided by pi, each coefficient pre-multiplied by its basis constant, in the order and the
//    polynomials of Filament's Irradiance_SphericalHarmonics (cmgen's output);
//  - the skybox: the same cube (Skybox.Builder().environment), read at level 0.
// So what this client measures is Filament's shading of a cmgen-style cube, not Filament's own
// prefilter (docs/renderers.md says so).
import { boxFilter, floatCanvas, glRendererName, post, runMain, supersampling } from '/browser/page-common.js';

let F;   // window.Filament: the module object once Filament.init has run
const ss = supersampling();
/** cmgen's defaults: a 256 face, levels down to 16 x 16 (5 levels); samples per texel (cmgen: 1024). */
const IBL = { faceSize: 256, levels: 5, samples: 256 };

/** Radiance .hdr (RGBE, -Y H +X W, flat or new-style RLE scanlines) -> {w, h, rgb Float32Array}. */
function parseHdr(buf) {
  const b = new Uint8Array(buf);
  let p = 0;
  const line = () => { let s = ''; while (b[p] !== 10) s += String.fromCharCode(b[p++]); p++; return s; };
  if (!line().startsWith('#?')) throw new Error('environment.hdr: not a Radiance file');
  while (line() !== '');
  const m = /^-Y (\d+) \+X (\d+)$/.exec(line());
  if (!m) throw new Error('environment.hdr: only -Y H +X W is read');
  const h = +m[1], w = +m[2];
  const rgb = new Float32Array(w * h * 3), scan = new Uint8Array(w * 4);
  for (let y = 0; y < h; y++) {
    if (b[p] === 2 && b[p + 1] === 2 && ((b[p + 2] << 8) | b[p + 3]) === w) {
      p += 4;
      for (let c = 0; c < 4; c++) {
        for (let x = 0; x < w;) {
          let n = b[p++];
          if (n > 128) { n -= 128; const v = b[p++]; while (n--) scan[(x++) * 4 + c] = v; }
          else while (n--) scan[(x++) * 4 + c] = b[p++];
        }
      }
    } else {
      scan.set(b.subarray(p, p + w * 4)); p += w * 4;
    }
    for (let x = 0; x < w; x++) {
      const e = scan[x * 4 + 3], f = e ? Math.pow(2, e - 136) : 0, o = (y * w + x) * 3;
      rgb[o] = scan[x * 4] * f; rgb[o + 1] = scan[x * 4 + 1] * f; rgb[o + 2] = scan[x * 4 + 2] * f;
    }
  }
  return { w, h, rgb };
}

/** The panorama's box-filtered mip chain (2 x 2 averages down to 8 x 4). */
function mipChain(pano) {
  const chain = [pano];
  while (chain[chain.length - 1].h > 4) {
    const s = chain[chain.length - 1], w = s.w >> 1, h = s.h >> 1, rgb = new Float32Array(w * h * 3);
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) for (let c = 0; c < 3; c++) {
      const a = (i, j) => s.rgb[((2 * y + j) * s.w + 2 * x + i) * 3 + c];
      rgb[(y * w + x) * 3 + c] = 0.25 * (a(0, 0) + a(1, 0) + a(0, 1) + a(1, 1));
    }
    chain.push({ w, h, rgb });
  }
  return chain;
}

/** Bilinear radiance of the export's panorama in direction (x, y, z) (docs/renderers.md, section 1:
 * u = atan2(z, x) / 2pi + 0.5, v = asin(y) / pi + 0.5 up, row 0 at the top), added into out. */
function lookup(img, x, y, z, out, wgt) {
  const u = Math.atan2(z, x) / (2 * Math.PI) + 0.5;
  const v = Math.asin(Math.max(-1, Math.min(1, y))) / Math.PI + 0.5;
  const fx = u * img.w - 0.5, fy = (1 - v) * img.h - 0.5;
  const x0 = Math.floor(fx), y0 = Math.floor(fy), tx = fx - x0, ty = fy - y0;
  for (let j = 0; j < 2; j++) {
    const yy = Math.min(img.h - 1, Math.max(0, y0 + j)), wy = j ? ty : 1 - ty;
    for (let i = 0; i < 2; i++) {
      const xx = ((x0 + i) % img.w + img.w) % img.w, k = (yy * img.w + xx) * 3, ww = wgt * wy * (i ? tx : 1 - tx);
      out[0] += img.rgb[k] * ww; out[1] += img.rgb[k + 1] * ww; out[2] += img.rgb[k + 2] * ww;
    }
  }
}

/** GL's cube map convention: face f (+X, -X, +Y, -Y, +Z, -Z), texel coordinates (s, t) in [0, 1]
 * (t = 0 is the first row uploaded) -> direction (not normalised). */
function faceDir(f, s, t) {
  const sc = 2 * s - 1, tc = 2 * t - 1;
  switch (f) {
    case 0: return [1, -tc, -sc];
    case 1: return [-1, -tc, sc];
    case 2: return [sc, 1, tc];
    case 3: return [sc, -1, -tc];
    case 4: return [sc, -tc, 1];
    default: return [-sc, -tc, -1];
  }
}

function radicalInverse(i) {
  let b = i;
  b = ((b << 16) | (b >>> 16)) >>> 0;
  b = (((b & 0x55555555) << 1) | ((b & 0xAAAAAAAA) >>> 1)) >>> 0;
  b = (((b & 0x33333333) << 2) | ((b & 0xCCCCCCCC) >>> 2)) >>> 0;
  b = (((b & 0x0F0F0F0F) << 4) | ((b & 0xF0F0F0F0) >>> 4)) >>> 0;
  b = (((b & 0x00FF00FF) << 8) | ((b & 0xFF00FF00) >>> 8)) >>> 0;
  return b / 4294967296;
}

/** One level of the reflections cube: RGBA float, 6 faces, GGX lobe of perceptual roughness r. */
function prefilterLevel(chain, size, r, samples) {
  const data = new Float32Array(6 * size * size * 4), acc = [0, 0, 0];
  const a = r * r, a2 = a * a;
  // Sample directions in the tangent frame of n = (0, 0, 1) with N = V: l = 2 (n.h) h - n.
  const smp = [];
  if (r > 0) {
    for (let i = 0; i < samples; i++) {
      const e1 = (i + 0.5) / samples, e2 = radicalInverse(i), phi = 2 * Math.PI * e2;
      const cosT = Math.sqrt((1 - e1) / (1 + (a2 - 1) * e1)), sinT = Math.sqrt(1 - cosT * cosT);
      const h = [sinT * Math.cos(phi), sinT * Math.sin(phi), cosT];
      const l = [2 * cosT * h[0], 2 * cosT * h[1], 2 * cosT * h[2] - 1];
      if (l[2] <= 0) continue;
      const d = cosT * cosT * (a2 - 1) + 1, D = a2 / (Math.PI * d * d), pdf = D / 4;
      const omegaS = 1 / (samples * pdf), omegaP = 4 * Math.PI / (chain[0].w * chain[0].h);
      const lod = Math.max(0, 0.5 * Math.log2(omegaS / omegaP) + 1);
      smp.push([l, l[2], Math.min(chain.length - 1, Math.round(lod))]);
    }
  }
  for (let f = 0; f < 6; f++) for (let j = 0; j < size; j++) for (let i = 0; i < size; i++) {
    let [x, y, z] = faceDir(f, (i + 0.5) / size, (j + 0.5) / size);
    const inv = 1 / Math.hypot(x, y, z); x *= inv; y *= inv; z *= inv;
    acc[0] = acc[1] = acc[2] = 0;
    if (r === 0) {
      lookup(chain[0], x, y, z, acc, 1);
    } else {
      // A frame around n = (x, y, z).
      const up = Math.abs(z) < 0.999 ? [0, 0, 1] : [1, 0, 0];
      let tx = [up[1] * z - up[2] * y, up[2] * x - up[0] * z, up[0] * y - up[1] * x];
      const tl = 1 / Math.hypot(...tx); tx = tx.map((c) => c * tl);
      const ty = [y * tx[2] - z * tx[1], z * tx[0] - x * tx[2], x * tx[1] - y * tx[0]];
      let wsum = 0;
      for (const [l, nl, lev] of smp) {
        const dx = tx[0] * l[0] + ty[0] * l[1] + x * l[2], dy = tx[1] * l[0] + ty[1] * l[1] + y * l[2], dz = tx[2] * l[0] + ty[2] * l[1] + z * l[2];
        lookup(chain[lev], dx, dy, dz, acc, nl);
        wsum += nl;
      }
      acc[0] /= wsum; acc[1] /= wsum; acc[2] /= wsum;
    }
    const o = ((f * size + j) * size + i) * 4;
    data[o] = acc[0]; data[o + 1] = acc[1]; data[o + 2] = acc[2]; data[o + 3] = 1;
  }
  return data;
}

/** Filament's 9 irradiance coefficients (E(n) / pi in its polynomial basis), from a small mip. */
function irradianceSH(img) {
  const K = [0.282095, 0.488603, 0.488603, 0.488603, 1.092548, 1.092548, 0.315392, 1.092548, 0.546274];
  const A = [Math.PI, 2 * Math.PI / 3, 2 * Math.PI / 3, 2 * Math.PI / 3, Math.PI / 4, Math.PI / 4, Math.PI / 4, Math.PI / 4, Math.PI / 4];
  const sh = new Float32Array(27);
  for (let k = 0; k < img.h; k++) {
    const e = Math.PI * (0.5 - (k + 0.5) / img.h), dw = (2 * Math.PI / img.w) * (Math.PI / img.h) * Math.cos(e);
    for (let c = 0; c < img.w; c++) {
      const a = 2 * Math.PI * ((c + 0.5) / img.w - 0.5);
      const x = Math.cos(a) * Math.cos(e), y = Math.sin(e), z = Math.sin(a) * Math.cos(e);
      const poly = [1, y, z, x, y * x, y * z, 3 * z * z - 1, z * x, x * x - y * y];
      const o = (k * img.w + c) * 3;
      for (let i = 0; i < 9; i++) {
        const w = poly[i] * dw * K[i] * K[i] * A[i] / Math.PI;
        sh[i * 3] += img.rgb[o] * w; sh[i * 3 + 1] += img.rgb[o + 1] * w; sh[i * 3 + 2] += img.rgb[o + 2] * w;
      }
    }
  }
  return sh;
}

async function main() {
  const t0 = performance.now();
  await new Promise((resolve) => window.Filament.init([], resolve));
  F = window.Filament;
  const scenario = await (await fetch('/scene/scenario.json')).json();
  const W = scenario.size.width, H = scenario.size.height;
  const SW = W * ss, SH = H * ss;

  const canvas = document.createElement('canvas');
  canvas.width = SW; canvas.height = SH;
  // The context first, with the float target bound as "the default framebuffer" (Filament caches
  // GL state: it never binds 0 while it believes 0 is bound); Engine.create finds this context.
  const gl = canvas.getContext('webgl2', { antialias: false, alpha: false, depth: true, stencil: true });
  const target = floatCanvas(gl, SW, SH);
  const engine = F.Engine.create(canvas, { antialias: false, alpha: false });
  const scene = engine.createScene();
  const swapChain = engine.createSwapChain();
  const renderer = engine.createRenderer();
  const camera = engine.createCamera(F.EntityManager.get().create());
  const view = engine.createView();
  view.setCamera(camera);
  view.setScene(scene);
  view.setViewport([0, 0, SW, SH]);
  view.setPostProcessingEnabled(false);   // no tone mapping, colour grading, dithering, AA
  renderer.setClearOptions({ clearColor: [0, 0, 0, 1], clear: true });

  const c = scenario.camera;
  camera.lookAt(c.origin, c.target, c.up);
  camera.setProjectionFov(c.yfov_rad * 180 / Math.PI, SW / SH, 0.05, 1000, F.Camera$Fov.VERTICAL);
  camera.setExposureDirect(1.0);

  const loader = engine.createAssetLoader();
  const gltf = new Uint8Array(await (await fetch('/scene/' + scenario.gltf)).arrayBuffer());
  const asset = loader.createAsset(gltf);
  if (!asset) throw new Error('gltfio could not parse scene.gltf');
  await new Promise((resolve) => asset.loadResources(resolve, null, new URL('/scene/', location.href).href));
  scene.addEntities(asset.getEntities());

  const tIbl = performance.now();
  const pano = parseHdr(await (await fetch('/scene/' + scenario.environment.hdr)).arrayBuffer());
  const chain = mipChain(pano);
  const cube = F.Texture.Builder().width(IBL.faceSize).height(IBL.faceSize).levels(IBL.levels)
    .sampler(F.Texture$Sampler.SAMPLER_CUBEMAP).format(F.Texture$InternalFormat.RGBA16F).build(engine);
  for (let l = 0; l < IBL.levels; l++) {
    const r = 1 - Math.sqrt(1 - l / (IBL.levels - 1));
    const data = prefilterLevel(chain, IBL.faceSize >> l, r, IBL.samples);
    cube.setImageCube(engine, l, F.PixelBuffer(data, F.PixelDataFormat.RGBA, F.PixelDataType.FLOAT));
  }
  const small = chain.find((m) => m.w <= 128) || chain[chain.length - 1];
  const ibl = F.IndirectLight.Builder().reflections(cube).irradianceSh(3, irradianceSH(small)).intensity(1.0).build(engine);
  scene.setIndirectLight(ibl);
  scene.setSkybox(F.Skybox.Builder().environment(cube).build(engine));
  const iblSeconds = (performance.now() - tIbl) / 1000;

  let rendered = 0;
  for (let i = 0; i < 20 && rendered < 2; i++) {
    await new Promise((resolve) => requestAnimationFrame(resolve));
    if (renderer.beginFrame(swapChain)) {
      renderer.renderView(view);
      renderer.endFrame();
      rendered++;
    }
    engine.execute();
  }
  if (rendered < 2) throw new Error(`Filament rendered ${rendered} frame(s) in 20 animation frames`);
  gl.finish();
  const px = target.read();
  target.restore();

  const out = boxFilter(px, W, H, ss);
  await post('/result', out, {
    'X-Width': String(W), 'X-Height': String(H), 'X-GL-Renderer': glRendererName(gl),
    'X-IBL': JSON.stringify({ ...IBL, prefilter: 'cmgen-style, in the page', seconds: iblSeconds }),
    'X-Page-Seconds': String((performance.now() - t0) / 1000),
  });
}

runMain(main);
