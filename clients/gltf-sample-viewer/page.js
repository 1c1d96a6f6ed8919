// pbrcheck's Khronos glTF Sample Viewer client, the page: loads the exported scene with the Sample
// Viewer's own ResourceLoader (glTF, KHR_lights_punctual, the Radiance .hdr environment, which its
// iblSampler prefilters into GGX / Lambertian cube maps and its GGX LUT, in float when the context
// has EXT_color_buffer_float + OES_texture_float_linear), renders one frame with GltfView and POSTs
// linear radiance to the runner (render.mjs), which writes the PFM. See docs/renderers.md.
//
// Linear HDR output. GltfView.renderFrame draws into the canvas, and its final pass ends in
// toneMap() (exposure, tone map, pow(1/2.2)) unless the fragment shader is built with the engine's
// own LINEAR_OUTPUT define (which it uses for its transmission pass). Two small hooks, no change
// to the engine's files or shaders:
//  1. while our frame renders, binding the default framebuffer (null) binds our RGBA32F
//     framebuffer of (ss W) x (ss H) (with a depth buffer) instead of the 8-bit canvas;
//  2. the renderer's drawPrimitive and the environment renderer's drawEnvironmentMap are called
//     with linearOutput / "LINEAR_OUTPUT 1", so they write the shading result untouched.
// The result is read back with readPixels (float) and box-filtered to W x H (ss x ss samples per
// pixel, as the reference's pixels are box-filtered). GL's rows start at the bottom: PFM's order.
//
// Settings: the scenario's glTF camera (cameraIndex 0); environmentRotation 0 (the Sample
// Viewer's panorama lookup u = atan2(d.z, d.x)/2pi + 0.5 is the exported orientation; its default
// of 90 degrees would turn the environment); blurEnvironmentMap off (the background is the
// environment itself, from the level-0 cube map); iblIntensity 1; punctual lights on.
import { GltfView, GltfState } from '/viewer/gltf-viewer.module.js';
import { boxFilter, glRendererName, post, runMain, supersampling } from '/browser/page-common.js';

const ss = supersampling();

// The Sample Viewer asks for a Draco decoder and a KTX2 transcoder at start-up (both WASM
// libraries, Draco from a CDN); scenes without Draco meshes (every analytic export) and without KTX2
// textures get stubs that report themselves ready (no network, no WASM start-up). A Draco-compressed
// asset gets Google's Draco decoder (the glTF branch's asm.js build, no WASM file) that the three.js
// package vendors, served by render.mjs under /draco/ from the three.js client's node_modules.
const NO_DRACO = (module) => module.onModuleLoaded({});
const NO_KTX = async () => ({ GL: { createContext: () => 0, makeContextCurrent: () => true } });

async function dracoLib(doc) {
  const ext = [...(doc.extensionsRequired || []), ...(doc.extensionsUsed || [])];
  if (!ext.includes('KHR_draco_mesh_compression')) return NO_DRACO;
  const r = await fetch('/draco/draco_decoder.js');
  if (!r.ok) {
    throw new Error('KHR_draco_mesh_compression: no offline Draco decoder (the three.js client\'s ' +
                    'node_modules/three is not installed: npm ci in clients/threejs)');
  }
  const script = document.createElement('script');
  script.textContent = await r.text();   // defines the global DracoDecoderModule
  document.head.appendChild(script);
  if (typeof globalThis.DracoDecoderModule !== 'function') throw new Error('the Draco decoder did not load');
  return globalThis.DracoDecoderModule;
}

async function main() {
  const t0 = performance.now();
  const scenario = await (await fetch('/scene/scenario.json')).json();
  const W = scenario.size.width, H = scenario.size.height;
  const SW = W * ss, SH = H * ss;
  const draco = await dracoLib(await (await fetch('/scene/' + scenario.gltf)).json());

  const canvas = document.createElement('canvas');
  canvas.width = SW; canvas.height = SH;
  const gl = canvas.getContext('webgl2', { antialias: false, alpha: false });
  if (!gl) throw new Error('no WebGL2 context');
  if (!gl.getExtension('EXT_color_buffer_float')) throw new Error('EXT_color_buffer_float missing: no float render target');

  const view = new GltfView(gl);
  const state = view.createState();
  const loader = view.createResourceLoader(draco, NO_KTX, '/viewer/libs/');
  await loader.initDracoLib(draco);   // createResourceLoader starts it; loadGltf needs it ready
  state.gltf = await loader.loadGltf('/scene/' + scenario.gltf);
  const envHdr = await (await fetch('/scene/' + scenario.environment.hdr)).arrayBuffer();
  // The sheen albedo LUT is a PNG the package does not ship; no exported material has sheen, so a
  // 1 x 1 black image (made here) stands in for it.
  const blank = document.createElement('canvas');
  blank.width = 1; blank.height = 1;
  state.environment = await loader.loadEnvironment(envHdr, { lut_sheen_E_file: blank.toDataURL('image/png') });
  if (!state.environment) throw new Error('the Sample Viewer could not load the environment');
  state.sceneIndex = state.gltf.scene ?? 0;
  state.cameraIndex = 0;
  const rp = state.renderingParameters;
  rp.environmentRotation = 0.0;
  rp.blurEnvironmentMap = false;
  rp.renderEnvironmentMap = true;
  rp.useIBL = true;
  rp.usePunctual = true;
  rp.iblIntensity = 1.0;
  rp.exposure = 1.0;
  rp.toneMap = GltfState.ToneMaps.NONE;    // unused under LINEAR_OUTPUT; stated for the record

  // Hook 2: the engine's LINEAR_OUTPUT switch on every pass of the frame.
  const renderer = view.renderer;
  const drawPrimitive = renderer.drawPrimitive.bind(renderer);
  renderer.drawPrimitive = (st, cfg, ...rest) => drawPrimitive(st, { ...cfg, linearOutput: true }, ...rest);
  const init = renderer.init.bind(renderer);
  renderer.init = (st) => {   // the environment renderer is made by the first init
    init(st);
    const env = renderer.environmentRenderer;
    if (env && !env.pbrcheckLinear) {
      const drawEnv = env.drawEnvironmentMap.bind(env);
      env.drawEnvironmentMap = (webGl, vp, s, cache, defines, ...rest) =>
        drawEnv(webGl, vp, s, cache, [...defines.filter((d) => !d.startsWith('LINEAR_OUTPUT')), 'LINEAR_OUTPUT 1'], ...rest);
      env.pbrcheckLinear = true;
    }
  };

  // Hook 1: our float framebuffer stands in for the canvas while the frame renders.
  const fbo = gl.createFramebuffer();
  const color = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, color);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, SW, SH, 0, gl.RGBA, gl.FLOAT, null);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  const depth = gl.createRenderbuffer();
  gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
  gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, SW, SH);
  gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, color, 0);
  gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
  const status = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
  if (status !== gl.FRAMEBUFFER_COMPLETE) throw new Error(`float framebuffer incomplete (0x${status.toString(16)})`);
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  const bindFramebuffer = gl.bindFramebuffer.bind(gl);
  gl.bindFramebuffer = (target, fb) => bindFramebuffer(target, fb === null ? fbo : fb);

  view.renderFrame(state, SW, SH);

  gl.bindFramebuffer = bindFramebuffer;
  bindFramebuffer(gl.FRAMEBUFFER, fbo);
  const px = new Float32Array(SW * SH * 4);
  const tRead = performance.now();   // readPixels waits for the queued prefiltering and the frame
  gl.readPixels(0, 0, SW, SH, gl.RGBA, gl.FLOAT, px);
  const err = gl.getError();
  if (err !== gl.NO_ERROR) throw new Error(`WebGL error 0x${err.toString(16)} after the frame`);

  const out = boxFilter(px, W, H, ss);
  const iblFloat = gl.getExtension('OES_texture_float_linear') ? 'FLOAT' : 'HALF_FLOAT';
  await post('/result', out, {
    'X-Width': String(W), 'X-Height': String(H), 'X-GL-Renderer': glRendererName(gl),
    'X-IBL-Format': iblFloat, 'X-Page-Seconds': String((performance.now() - t0) / 1000),
    'X-GPU-Seconds': String((performance.now() - tRead) / 1000),
  });
}

runMain(main);
