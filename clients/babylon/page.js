// pbrcheck's Babylon.js client, the page: loads the exported scene with Babylon.js's own glTF
// loader (@babylonjs/loaders: PBRMaterial, KHR_lights_punctual point lights, the glTF camera) and
// the Radiance .hdr environment with HDRCubeTexture (its panorama-to-cube conversion, its
// spherical polynomial for the diffuse, its GPU GGX prefiltering on load: prefilterOnLoad), the
// same texture as the skybox (createDefaultSkybox, PBR, blur 0: level 0 of the cube), renders one
// frame with image processing off (applied by a post-process that is never attached: no exposure,
// tone mapping, contrast or gamma) into a float
// target and POSTs linear radiance to the runner (render.mjs). See docs/renderers.md.
//
// - Orientation: Babylon's default left-handed scene (the glTF loader adds its root node that
//   mirrors z); the panorama-to-cube conversion then reads the export's panorama turned a quarter
//   turn about +Y, undone by rotationY = pi/2 on the environment and on the skybox's clone of it
//   (measured with the orientation probe: background within 0.7 px, mirror sphere within 2.1 px).
// - The float target: ../browser/page-common.js's floatCanvas stands in for the canvas (the last
//   pass draws into the default framebuffer); (ss W) x (ss H), box-filtered to W x H.
import { Engine } from '@babylonjs/core/Engines/engine.js';
import { Scene } from '@babylonjs/core/scene.js';
import { AppendSceneAsync } from '@babylonjs/core/Loading/sceneLoader.js';
import { HDRCubeTexture } from '@babylonjs/core/Materials/Textures/hdrCubeTexture.js';
import '@babylonjs/core/Helpers/sceneHelpers.js';
import '@babylonjs/core/Loading/loadingScreen.js';
import '@babylonjs/core/Materials/PBR/pbrMaterial.js';
import '@babylonjs/loaders/glTF/index.js';
import { DracoDecoder } from '@babylonjs/core/Meshes/Compression/dracoDecoder.js';
import { boxFilter, floatCanvas, glRendererName, post, runMain, supersampling } from '/browser/page-common.js';

const ss = supersampling();
// KHR_draco_mesh_compression: the decoder @babylonjs/core ships (assets/Draco, Google's Draco glTF
// build), served under /core/ (the default configuration fetches it from Babylon's CDN, which fails
// offline). Absolute URLs: the decoder runs in workers made from blobs.
const DRACO = (f) => new URL(`/core/assets/Draco/${f}`, location.href).href;
DracoDecoder.DefaultConfiguration = {
  wasmUrl: DRACO('draco_wasm_wrapper_gltf.js'), wasmBinaryUrl: DRACO('draco_decoder_gltf.wasm'),
  fallbackUrl: DRACO('draco_decoder_gltf.js'),
};
/** HDRCubeTexture's face size: the prefiltered cube's level 0 (Babylon's examples use 256 to 512). */
const CUBE_SIZE = 256;
/** The texture rotation that makes Babylon's lookup of the panorama the export's (section 1 of
 * docs/renderers.md): measured with the orientation probe (tests/test_engines.py). */
const ENV_ROTATION_Y = Math.PI / 2;

async function main() {
  const t0 = performance.now();
  const scenario = await (await fetch('/scene/scenario.json')).json();
  const W = scenario.size.width, H = scenario.size.height;
  const SW = W * ss, SH = H * ss;

  const canvas = document.createElement('canvas');
  canvas.width = SW; canvas.height = SH;
  const engine = new Engine(canvas, false, { preserveDrawingBuffer: true, stencil: true, adaptToDeviceRatio: false });
  engine.setHardwareScalingLevel(1);
  const gl = engine._gl;
  const target = floatCanvas(gl, SW, SH);

  const scene = new Scene(engine);
  // Linear output. applyImageProcessing() (exposure, tone map, contrast, toGammaSpace, saturate)
  // ends every material's shader, with isEnabled false too, unless the configuration is enabled
  // and applied by a post-process (IMAGEPROCESSINGPOSTPROCESS): then the materials write linear
  // radiance (skipFinalColorClamp: not clamped to [0, 30]). No such post-process is attached
  // (that is DefaultRenderingPipeline's), so nothing applies it.
  const ipc = scene.imageProcessingConfiguration;
  ipc.isEnabled = true;
  ipc.applyByPostProcess = true;
  ipc.skipFinalColorClamp = true;
  ipc.toneMappingEnabled = false;
  ipc.exposure = 1.0;
  scene.environmentIntensity = 1.0;
  await AppendSceneAsync('/scene/' + scenario.gltf, scene);

  const env = await new Promise((resolve, reject) => {
    const t = new HDRCubeTexture('/scene/' + scenario.environment.hdr, scene, CUBE_SIZE,
      false /* mipmaps */, true /* harmonics */, false /* linear */, true /* prefilterOnLoad */,
      () => resolve(t), (msg, e) => reject(new Error(`HDRCubeTexture: ${msg || e}`)));
  });
  env.rotationY = ENV_ROTATION_Y;
  scene.environmentTexture = env;
  const sky = scene.createDefaultSkybox(env, true /* PBR */, 1000, 0.0 /* blur: level 0 */);
  sky.material.reflectionTexture.rotationY = ENV_ROTATION_Y;   // a clone of env
  if (!scene.activeCamera) scene.activeCamera = scene.cameras[0];
  if (!scene.activeCamera) throw new Error('the glTF loader made no camera');
  await scene.whenReadyAsync();

  scene.render();
  scene.render();   // a second frame: anything that became ready during the first is in
  const px = target.read();
  target.restore();

  const out = boxFilter(px, W, H, ss);
  await post('/result', out, {
    'X-Width': String(W), 'X-Height': String(H), 'X-GL-Renderer': glRendererName(gl),
    'X-Environment-Size': String(CUBE_SIZE), 'X-Page-Seconds': String((performance.now() - t0) / 1000),
  });
}

runMain(main);
