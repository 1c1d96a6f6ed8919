// pbrcheck's PlayCanvas client, the page: loads the exported scene with PlayCanvas's own glTF
// container loader (StandardMaterial from glTF's metallic-roughness, KHR_lights_punctual point
// lights), the Radiance .hdr environment through its texture loader (RGBE), which
// EnvLighting prefilters as the engine's viewer does (generateLightingSource, then generateAtlas:
// its GGX-prefiltered reflection levels and its ambient in one atlas), the environment itself as
// the skybox (generateSkyboxCubemap, skyboxMip 0), and renders with tone mapping none and gamma
// none (linear output) into a float target, then POSTs linear radiance to the runner (render.mjs).
// See docs/renderers.md.
//
// - Point lights: left as the loader makes them, disabled (its glTF lights are created with
//   enabled: false and, in its default non-physical units, an intensity clamped to [0, 2] and an
//   inverse-square falloff of 16 / (d^2 + 1): engine issue #3252). Enabled with the glTF
//   intensity, a 10 cd lamp at 4 m renders 49x the reference (measured), so ext:playcanvas
//   measures the image-based lighting only (docs/renderers.md, section 8).
// - Camera: a camera entity made from scenario.json (origin, target, up, vertical fov, near clip);
//   the glTF camera describes the same view.
// - The float target: ../browser/page-common.js's floatCanvas stands in for the canvas (the
//   engine's back buffer is the default framebuffer); (ss W) x (ss H), box-filtered to W x H.
import * as pc from 'playcanvas';
import { boxFilter, floatCanvas, glRendererName, post, runMain, supersampling } from '/browser/page-common.js';

const ss = supersampling();
// KHR_draco_mesh_compression: Google's Draco decoder from the npm package draco3d (its emscripten
// glue runs in a worker as well as in node), served under /draco3d/ (the engine's default looks for
// draco.wasm.js beside the page, which it does not ship).
pc.WasmModule.setConfig('DracoDecoderModule', {
  glueUrl: '/draco3d/draco_decoder_nodejs.js', wasmUrl: '/draco3d/draco_decoder.wasm', numWorkers: 1,
});
/** EnvLighting.generateAtlas's options: the engine's defaults (atlas 512, 1024 reflection samples,
 * 2048 ambient samples). */
const ATLAS = { size: 512, numReflectionSamples: 1024, numAmbientSamples: 2048 };
/** The skybox rotation (degrees about +Y; scene.skyboxRotation turns the skybox and the lighting
 * alike) that makes PlayCanvas's equirect lookup the export's: without it the panorama is read a
 * quarter turn about +Y off. Measured with the orientation probe: background within 0.3 px,
 * mirror sphere within 1.2 px (tests/test_engines.py). */
const SKYBOX_ROTATION_Y = -90;

function loadAsset(app, asset) {
  return new Promise((resolve, reject) => {
    asset.once('load', () => resolve(asset));
    asset.once('error', (e) => reject(new Error(`${asset.name}: ${e}`)));
    app.assets.add(asset);
    app.assets.load(asset);
  });
}

async function main() {
  const t0 = performance.now();
  const scenario = await (await fetch('/scene/scenario.json')).json();
  const W = scenario.size.width, H = scenario.size.height;
  const SW = W * ss, SH = H * ss;

  const canvas = document.createElement('canvas');
  canvas.width = SW; canvas.height = SH;
  document.body.appendChild(canvas);
  const app = new pc.Application(canvas, { graphicsDeviceOptions: { antialias: false, alpha: false, preserveDrawingBuffer: true, deviceTypes: ['webgl2'] } });
  app.setCanvasFillMode(pc.FILLMODE_NONE);
  app.setCanvasResolution(pc.RESOLUTION_FIXED, SW, SH);
  const gl = app.graphicsDevice.gl;
  const target = floatCanvas(gl, SW, SH);

  const container = await loadAsset(app, new pc.Asset('scene', 'container', { url: '/scene/' + scenario.gltf }));
  app.root.addChild(container.resource.instantiateRenderEntity());

  const envAsset = await loadAsset(app, new pc.Asset('environment', 'texture', { url: '/scene/' + scenario.environment.hdr }, { mipmaps: false }));
  const src = envAsset.resource;
  const lighting = pc.EnvLighting.generateLightingSource(src);
  app.scene.envAtlas = pc.EnvLighting.generateAtlas(lighting, ATLAS);
  app.scene.skybox = pc.EnvLighting.generateSkyboxCubemap(src);
  app.scene.skyboxMip = 0;
  app.scene.skyboxIntensity = 1.0;
  app.scene.exposure = 1.0;
  app.scene.skyboxRotation = new pc.Quat().setFromEulerAngles(0, SKYBOX_ROTATION_Y, 0);

  const c = scenario.camera;
  // the near clip: 0.05, or the export's znear (half the nearest object's gap) when the model is closer
  // (RF's MetalRoughSpheresNoTextures: the camera 10 mm from a millimetre-scale grid)
  const NEAR_CLIP = 0.05;
  const camera = new pc.Entity('camera');
  camera.addComponent('camera', {
    fov: c.yfov_rad * 180 / Math.PI, horizontalFov: false, nearClip: Math.min(NEAR_CLIP, c.znear ?? NEAR_CLIP), farClip: 1000,
    toneMapping: pc.TONEMAP_NONE, gammaCorrection: pc.GAMMA_NONE, clearColor: new pc.Color(0, 0, 0, 1),
  });
  camera.setPosition(...c.origin);
  camera.lookAt(new pc.Vec3(...c.target), new pc.Vec3(...c.up));
  // KHR_materials_transmission / _volume: the loader sets useDynamicRefraction, whose shader reads the
  // camera's grab of the opaque pass (uSceneColorMap); the engine grabs it only where the camera asks
  // (as PlayCanvas's own viewer does): asked only for a glTF that uses the extensions, so every other
  // scene renders as before (docs/renderers.md, Transmission)
  const gltfJson = await (await fetch('/scene/' + scenario.gltf)).text().catch(() => '');
  if (gltfJson.includes('"KHR_materials_transmission"') || gltfJson.includes('"KHR_materials_volume"')) {
    camera.camera.requestSceneColorMap(true);
  }
  app.root.addChild(camera);

  let frames = 0;
  await new Promise((resolve) => {
    app.on('frameend', () => { if (++frames === 3) resolve(); });
    app.start();
  });
  app.autoRender = false;
  const px = target.read();
  target.restore();

  const out = boxFilter(px, W, H, ss);
  await post('/result', out, {
    'X-Width': String(W), 'X-Height': String(H), 'X-GL-Renderer': glRendererName(gl),
    'X-Atlas': JSON.stringify(ATLAS), 'X-Page-Seconds': String((performance.now() - t0) / 1000),
  });
}

runMain(main);
