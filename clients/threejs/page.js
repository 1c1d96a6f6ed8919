// pbrcheck's three.js client, the page: loads the exported scene with three.js's own loaders,
// renders linear radiance into a float render target and POSTs the pixels to the runner
// (render.mjs), which writes the PFM. See docs/renderers.md.
//
// - GLTFLoader: meshes, MeshStandardMaterial (MeshPhysicalMaterial where KHR_materials_ior is
//   used), KHR_lights_punctual point lights (decay 2, no range), the glTF camera.
// - EXRLoader (float32) + PMREMGenerator: the image-based lighting; the equirectangular texture
//   itself is the background.
// - NoToneMapping, linear output; a FloatType render target of (ss W) x (ss H), read back with
//   readRenderTargetPixels and box-filtered to W x H (ss x ss samples per pixel: the reference's
//   pixels are box-filtered too). GL's rows start at the bottom, which is PFM's order.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';

const params = new URLSearchParams(location.search);
const ss = Math.max(1, parseInt(params.get('ss') || '2', 10));

// Page warnings and errors go to the runner's stderr (the tail pbrcheck shows on failure).
for (const k of ['error', 'warn']) {
  const f = console[k];
  console[k] = (...a) => { post('/log', `${k}: ${a.map(String).join(' ')}`); f(...a); };
}

async function post(path, body, headers = {}) {
  await fetch(path, { method: 'POST', body, headers });
}

async function main() {
  const t0 = performance.now();
  const scenario = await (await fetch('/scene/scenario.json')).json();
  const W = scenario.size.width, H = scenario.size.height;
  const SW = W * ss, SH = H * ss;

  const canvas = document.createElement('canvas');
  canvas.width = SW; canvas.height = SH;
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, alpha: false });
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
  renderer.setPixelRatio(1);
  renderer.setSize(SW, SH, false);

  const gltf = await new GLTFLoader().loadAsync('/scene/' + scenario.gltf);
  const envTex = await new EXRLoader().setDataType(THREE.FloatType).loadAsync('/scene/' + scenario.environment.exr);
  envTex.mapping = THREE.EquirectangularReflectionMapping;
  envTex.colorSpace = THREE.LinearSRGBColorSpace;

  const pmrem = new THREE.PMREMGenerator(renderer);
  const envRT = pmrem.fromEquirectangular(envTex);
  const scene = new THREE.Scene();   // gltf.scene is a Group: background and environment live on a Scene
  scene.add(gltf.scene);
  scene.environment = envRT.texture;
  scene.background = envTex;

  const camera = gltf.cameras[0];
  camera.aspect = W / H;
  camera.updateProjectionMatrix();
  scene.updateMatrixWorld(true);

  const rt = new THREE.WebGLRenderTarget(SW, SH, {
    type: THREE.FloatType, format: THREE.RGBAFormat, depthBuffer: true,
    minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, colorSpace: THREE.LinearSRGBColorSpace,
  });
  renderer.setRenderTarget(rt);
  renderer.render(scene, camera);
  const px = new Float32Array(SW * SH * 4);
  renderer.readRenderTargetPixels(rt, 0, 0, SW, SH, px);
  renderer.setRenderTarget(null);

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
  const gl = renderer.getContext();
  const dbg = gl.getExtension('WEBGL_debug_renderer_info');
  const glRenderer = dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  await post('/result', out, {
    'X-Width': String(W), 'X-Height': String(H), 'X-Supersample': String(ss),
    'X-Three-Revision': THREE.REVISION, 'X-GL-Renderer': String(glRenderer).replace(/[^\x20-\x7e]/g, '?'),
    'X-Page-Seconds': String((performance.now() - t0) / 1000),
  });
}

main().catch((e) => post('/error', String((e && e.stack) || e)));
window.addEventListener('error', (e) => post('/error', String(e.message)));
window.addEventListener('unhandledrejection', (e) => post('/error', String(e.reason)));
