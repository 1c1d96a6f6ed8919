// pbrcheck's three.js client, the page: loads the exported scene with three.js's own loaders,
// renders linear radiance into a float render target and POSTs the pixels to the runner
// (render.mjs), which writes the PFM. See docs/renderers.md.
//
// - GLTFLoader (+ DRACOLoader for Draco-compressed assets): meshes, MeshStandardMaterial (MeshPhysicalMaterial where KHR_materials_ior is
//   used), KHR_lights_punctual point lights (decay 2, no range), the glTF camera.
// - EXRLoader (float32) + PMREMGenerator: the image-based lighting; the equirectangular texture
//   itself is the background.
// - NoToneMapping, linear output; a FloatType render target of (ss W) x (ss H), read back with
//   readRenderTargetPixels and box-filtered to W x H (ss x ss samples per pixel: the reference's
//   pixels are box-filtered too). GL's rows start at the bottom, which is PFM's order.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';
import { boxFilter, glRendererName, post, runMain, supersampling } from '/browser/page-common.js';

const ss = supersampling();

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

  // KHR_draco_mesh_compression (users' assets): three.js's own Draco decoder, shipped in the package
  const draco = new DRACOLoader().setDecoderPath('/three/examples/jsm/libs/draco/');
  const gltf = await new GLTFLoader().setDRACOLoader(draco).loadAsync('/scene/' + scenario.gltf);
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

  const out = boxFilter(px, W, H, ss);
  await post('/result', out, {
    'X-Width': String(W), 'X-Height': String(H), 'X-Supersample': String(ss),
    'X-Three-Revision': THREE.REVISION, 'X-GL-Renderer': glRendererName(renderer.getContext()),
    'X-Page-Seconds': String((performance.now() - t0) / 1000),
  });
}

runMain(main);
