"""Blender Cycles client (``ext:cycles``): render a ``pbrcheck export`` folder with Blender's own glTF
importer and CPU Cycles, writing linear float radiance (docs/renderers.md section 10).

Usage (run by ``clients/cycles/.venv/bin/python``, the environment ``tools/ensure-cycles.sh`` makes
with the ``bpy`` wheel pinned in ``requirements.txt``)::

    render.py SCENARIO.json OUT.exr [--spp N] [--threads N] [--seed N] [--single-scatter]
    render.py --version

What it does, and why (the output contract, docs/renderers.md section 2):

- ``bpy.ops.wm.read_factory_settings(use_empty=True)`` then ``bpy.ops.import_scene.gltf`` on
  ``scene.gltf``, as the Khronos Render Fidelity generator's blender-cycles renderer does
  (KhronosGroup/glTF-Render-Fidelity-Generator ``test/renderers/blender-cycles/render.py``), except
  the light mode: ``export_import_convert_lighting_mode = "COMPAT"`` (a point light of I cd becomes
  4 pi I "W", which Cycles emits as I W/sr: pbrcheck's 1 cd = 1 W/sr). The importer's default,
  ``SPEC``, divides by 683 lm/W (the lights 683x too dark against pbrcheck's radiometric units).
  Lights are made punctual (``shadow_soft_size = 0``, a sun's ``angle = 0``): glTF lights are points.
- The world: an Environment Texture of ``environment.exr`` into a Background of strength 1, with no
  rotation. Blender's equirectangular lookup is ``u = -atan2(y, x) / 2 pi + 0.5`` and
  ``v = atan2(z, hypot(x, y)) / pi + 0.5`` (Z up, v up the image); the importer maps glTF
  ``(x, y, z)`` to Blender ``(x, -z, y)``, so ``u = atan2(d.z, d.x) / 2 pi + 0.5`` and
  ``v = asin(d.y) / pi + 0.5`` in glTF's frame: the export's orientation. Measured by the orientation
  probe (tests/test_cycles.py), not only derived.
- The camera: the glTF's ``camera`` node (the importer converts ``yfov`` and ``aspectRatio``).
- CPU Cycles, ``--spp`` samples a pixel (default ``DEFAULT_SPP``; ``scenario.json``'s ``samples``
  when present), a fixed seed, no adaptive sampling, no denoising, no clamps (direct and indirect
  0: Blender's indirect default is 10), no filter glossy (its default 1.0 blurs glossy paths), a
  box pixel filter 1 px wide (the reference box-filters each pixel), the Standard view transform,
  exposure 0, gamma 1, no look; bounces ``MAX_BOUNCES`` for every kind.
- The importer's Principled BSDF keeps its default Multiscatter GGX (energy-compensated, like the
  web engines); ``--single-scatter`` switches it to GGX to measure that difference apart from the
  metallic blend (docs/renderers.md section 10).
- Output: Blender writes a 32-bit float OpenEXR (R, G, B; EXR output is scene-linear, the view
  transform is not applied to it) into a temporary file beside ``OUT``, renamed over ``OUT`` when
  complete (atomic).

Exit status: 0 done, 1 usage or render error (one line on stderr).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile

#: Samples a pixel when neither ``--spp`` nor ``scenario.json``'s ``samples`` says.
DEFAULT_SPP = 64
#: Path depth for every kind of bounce (diffuse, glossy, transmission, volume, transparent): deep
#: enough that the spheres' interreflections are not cut (the `path` reference's own depth is larger
#: still; a sphere scene's energy after 16 bounces is far below the noise).
MAX_BOUNCES = 16
#: glTF light mode of Blender's importer: COMPAT = Blender "watts" with 1 cd -> 4 pi W (see above).
LIGHT_MODE = "COMPAT"


def version() -> str:
    import bpy
    return f"bpy {bpy.app.version_string}, Cycles (CPU), glTF importer {_importer_version()}"


def _importer_version() -> str:
    try:
        import addon_utils
        for mod in addon_utils.modules():
            if mod.__name__ == "io_scene_gltf2":
                return ".".join(str(v) for v in mod.bl_info.get("version", ()))
    except Exception:                                  # the version line is informative only
        pass
    return "unknown"


def _parse(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="render.py", description="Render a pbrcheck export with Blender Cycles (CPU).")
    p.add_argument("scenario")
    p.add_argument("out")
    p.add_argument("--spp", type=int, default=None, help=f"samples a pixel (default: scenario's samples, else {DEFAULT_SPP})")
    p.add_argument("--threads", type=int, default=0, help="CPU threads (0: Blender's automatic count)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--single-scatter", action="store_true",
                   help="set every Principled BSDF's distribution to GGX (single scattering) instead of the "
                        "importer's Multiscatter GGX: to measure the two model differences apart")
    a = p.parse_args(argv)
    if a.spp is not None and a.spp < 1:
        p.error("--spp must be >= 1")
    if a.threads < 0:
        p.error("--threads must be >= 0")
    return a


def _world(bpy, exr_path: str) -> None:
    world = bpy.data.worlds.new("pbrcheck_environment")
    bpy.context.scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    for node in list(nt.nodes):
        nt.nodes.remove(node)
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(exr_path)
    tex.image.colorspace_settings.name = "Linear Rec.709"      # the export's primaries, no transfer
    tex.interpolation = "Linear"
    tex.projection = "EQUIRECTANGULAR"
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 1.0
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])


def _settings(bpy, width: int, height: int, spp: int, threads: int, seed: int) -> None:
    s = bpy.context.scene
    r = s.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.film_transparent = False                  # the background is the environment
    r.filter_size = 1.0                         # Eevee's; Cycles' own below
    r.threads_mode = "FIXED" if threads else "AUTO"
    if threads:
        r.threads = threads
    c = s.cycles
    c.device = "CPU"
    c.samples = spp
    c.seed = seed
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = c.caustics_refractive = True
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = MAX_BOUNCES
    c.transmission_bounces = c.volume_bounces = c.transparent_max_bounces = MAX_BOUNCES
    vs = s.view_settings
    vs.view_transform = "Standard"
    vs.look = "None"
    vs.exposure = 0.0
    vs.gamma = 1.0
    s.display_settings.display_device = "sRGB"
    im = r.image_settings
    im.file_format = "OPEN_EXR"
    im.color_mode = "RGB"
    im.color_depth = "32"
    im.exr_codec = "ZIP"
    r.use_file_extension = False


def _single_scatter(bpy) -> int:
    """Every Principled BSDF's microfacet distribution set to single-scattering GGX; returns how many."""
    n = 0
    for mat in bpy.data.materials:
        for node in (mat.node_tree.nodes if mat.use_nodes and mat.node_tree else ()):
            if node.type == "BSDF_PRINCIPLED":
                node.distribution = "GGX"
                n += 1
    return n


def render(scenario_path: str, out: str, spp: int | None, threads: int, seed: int,
           single_scatter: bool = False) -> None:
    with open(scenario_path, encoding="utf-8") as f:   # before Blender starts: a bad path fails fast
        sc = json.load(f)
    import bpy
    folder = os.path.dirname(os.path.abspath(scenario_path))
    width, height = int(sc["size"]["width"]), int(sc["size"]["height"])
    spp = spp or int(sc.get("samples", DEFAULT_SPP))

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=os.path.join(folder, sc["gltf"]),
                              export_import_convert_lighting_mode=LIGHT_MODE)
    for obj in bpy.context.scene.objects:
        if obj.type == "LIGHT":                 # glTF lights are punctual: no soft shadows or discs
            obj.data.shadow_soft_size = 0.0
            if obj.data.type == "SUN":
                obj.data.angle = 0.0
    if single_scatter:
        _single_scatter(bpy)
    cams = [o for o in bpy.context.scene.objects if o.type == "CAMERA"]
    node = sc["camera"].get("gltf_node", "camera")
    cam = next((o for o in cams if o.name == node or o.data.name == node), cams[0] if cams else None)
    if cam is None:
        raise RuntimeError(f"{scenario_path}: no camera in {sc['gltf']}")
    bpy.context.scene.camera = cam
    _world(bpy, os.path.join(folder, sc["environment"]["exr"]))
    _settings(bpy, width, height, spp, threads, seed)

    out = os.path.abspath(out)
    fd, tmp = tempfile.mkstemp(prefix=".cycles-", suffix=".exr", dir=os.path.dirname(out))
    os.close(fd)
    try:
        bpy.context.scene.render.filepath = tmp
        bpy.ops.render.render(write_still=True)
        if os.path.getsize(tmp) == 0:
            raise RuntimeError("Cycles wrote no image")
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--version"]:
        print(version())
        return 0
    a = _parse(argv)
    try:
        render(a.scenario, a.out, a.spp, a.threads, a.seed, a.single_scatter)
    except Exception as e:                      # one line for the runner (clients/run.py shows stderr)
        print(f"cycles client: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
