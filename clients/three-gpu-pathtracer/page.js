// pbrcheck's three-gpu-pathtracer client, the page: loads the exported scene with three.js's
// loaders and path traces it with three-gpu-pathtracer's WebGLPathTracer (WebGL2; the package's
// WebGPU tracer needs WebGPU, which headless Chromium on SwiftShader does not offer), then POSTs
// the accumulated linear radiance to the runner (render.mjs). See docs/renderers.md, "three-gpu-pathtracer".
//
// - GLTFLoader (+ DRACOLoader): the materials three.js makes from the file (MeshStandardMaterial /
//   MeshPhysicalMaterial): what the tracer supports. KHR_lights_punctual lights go to the tracer
//   (it samples them only with multiple importance sampling, its default).
// - EXRLoader (float32) equirectangular: scene.environment (importance sampled by the tracer) and
//   scene.background.
// - The tracer's own defaults but for: renderDelay 0, minSamples 0 and no fade (no raster preview is
//   ever blended in), tiles 1 x 1 (one full-frame sample per update), renderToCanvas off (the
//   accumulation target is read directly), bounces from ?bounces= (default 8, the package's
//   default 10 clipped for speed on software WebGL; stated in the metadata), filterGlossyFactor 0
//   (no path-space roughening: that biases the estimate), stableNoise on (a run's samples are
//   the same every run: its image is repeatable, its noise that of one fixed estimate). Its accumulation target is a FloatType
//   running mean of `samples` frames (sample k blended with opacity 1/(k+1)); its camera rays are
//   jittered within the pixel, so no supersampling is used. Stops after ?spp= samples. WebGL work
//   is asynchronous: the tracing's time shows in page_seconds (the read-back waits for it), not in
//   setup_seconds (loading and the BVH build).
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';
import { WebGLPathTracer } from 'three-gpu-pathtracer';
import { glRendererName, post, runMain } from '/browser/page-common.js';

const q = new URLSearchParams(location.search);
const SPP = Math.max(1, parseInt(q.get('spp') || '64', 10));
const BOUNCES = Math.max(1, parseInt(q.get('bounces') || '8', 10));
const frame = () => new Promise((r) => setTimeout(r, 0));

async function main() {
  const t0 = performance.now();
  const scenario = await (await fetch('/scene/scenario.json')).json();
  const W = scenario.size.width, H = scenario.size.height;

  const canvas = document.createElement('canvas');
  canvas.width = W; canvas.height = H;
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, alpha: false, preserveDrawingBuffer: true });
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
  renderer.setPixelRatio(1);
  renderer.setSize(W, H, false);

  const draco = new DRACOLoader().setDecoderPath('/three/examples/jsm/libs/draco/');
  const gltf = await new GLTFLoader().setDRACOLoader(draco).loadAsync('/scene/' + scenario.gltf);
  const envTex = await new EXRLoader().setDataType(THREE.FloatType).loadAsync('/scene/' + scenario.environment.exr);
  envTex.mapping = THREE.EquirectangularReflectionMapping;
  envTex.colorSpace = THREE.LinearSRGBColorSpace;

  const scene = new THREE.Scene();
  scene.add(gltf.scene);
  scene.environment = envTex;
  scene.background = envTex;
  const camera = gltf.cameras[0];
  camera.aspect = W / H;
  camera.updateProjectionMatrix();
  scene.updateMatrixWorld(true);

  const tracer = new WebGLPathTracer(renderer);
  tracer.renderDelay = 0;
  tracer.minSamples = 0;
  tracer.fadeDuration = 0;
  tracer.renderToCanvas = false;
  tracer.rasterizeScene = false;
  tracer.tiles.set(1, 1);
  tracer.bounces = BOUNCES;
  tracer.filterGlossyFactor = 0;
  tracer.stableNoise = true;  // the same random sequence every run: a repeatable image
  tracer.setScene(scene, camera);
  const tSetup = performance.now();
  while (tracer.isCompiling) await frame();
  while (tracer.samples < SPP) {
    tracer.renderSample();
    await frame();
  }

  const rt = tracer.target;
  const px = new Float32Array(W * H * 4);
  renderer.readRenderTargetPixels(rt, 0, 0, W, H, px);
  const out = new Float32Array(W * H * 3);
  for (let i = 0; i < W * H; i++) {
    out[3 * i] = px[4 * i]; out[3 * i + 1] = px[4 * i + 1]; out[3 * i + 2] = px[4 * i + 2];
  }
  await post('/result', out, {
    'X-Width': String(W), 'X-Height': String(H), 'X-Samples': String(tracer.samples),
    'X-Bounces': String(BOUNCES), 'X-Three-Revision': THREE.REVISION,
    'X-GL-Renderer': glRendererName(renderer.getContext()),
    'X-Setup-Seconds': String((tSetup - t0) / 1000),
    'X-Page-Seconds': String((performance.now() - t0) / 1000),
  });
}

runMain(main);
