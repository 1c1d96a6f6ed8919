"""CLI subcommands of this package (registered by pbrcheck.cli): ``realtime``, ``lut``, ``shaders``
and ``bench realtime``. Library errors propagate; only pbrcheck.cli maps them to exit codes."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from pbrcheck.atomic import check_output_path
from pbrcheck.fmt import file_name_part, terminal_safe
from pbrcheck.exr import Image, write_exr
from pbrcheck.scene import load_scene

from . import render as R
from .gl import dump_sources, renderer_name, timing_clock
from .hooks import load_hook_file
from .presets import PRESETS, overrides_from_args, parse_value, resolve_options
from .render import dfg_lut, read_lut, render_realtime


def _cmd_realtime(args) -> int:
    overrides = overrides_from_args(args.set, args.shader)
    resolve_options(args.preset, overrides)  # validate before any GL work
    if args.shader:
        load_hook_file(args.shader)  # a hook file that cannot be read or parsed: before any work
    scene = load_scene(args.scene)
    out = Path(args.out or f"out/realtime/{file_name_part(scene.name)}_{args.preset}.exr")
    check_output_path(out)  # before the render
    img = render_realtime(scene, args.preset, overrides, progress=True)
    write_exr(out, img)
    t = json.loads(img.meta["timings"])
    print(f"{terminal_safe(out)}: {scene.camera.width}x{scene.camera.height}, preset {args.preset}, "
          f"frame {t['frame']:.3f}s, passes " + ", ".join(f"{k} {v:.3f}s" for k, v in sorted(t.items())
                                                         if k != "frame"))
    for w in json.loads(img.meta["warnings"]):
        print(terminal_safe(f"warning: {w}"))
    return 0


def _cmd_lut(args) -> int:
    size = parse_value("lut_size", args.size)
    samples = parse_value("lut_samples", args.samples)
    fmt = parse_value("lut_format", args.format)
    geometry = parse_value("lut_geometry", args.geometry)
    if geometry == "scene":
        geometry = "smith_ggx_correlated"
    sampling = parse_value("lut_sampling", args.sampling)
    check_output_path(args.out)
    t0 = time.perf_counter()
    lut = read_lut(dfg_lut(size, samples, fmt, geometry, args.ndf, sampling))
    dt = time.perf_counter() - t0
    meta = {"kind": "dfg_lut", "size": size, "samples": samples, "format": fmt, "geometry": geometry,
            "ndf": args.ndf, "sampling": sampling, "seconds": dt,
            "convention": "pixel (row j, col i): n.v=(i+0.5)/N, roughness=(j+0.5)/N (alpha=roughness^2), "
                          "row 0 smoothest; A scales F0, B is the bias"}
    write_exr(args.out, Image({"A": lut[..., 0], "B": lut[..., 1]}, meta))
    print(f"{args.out}: {size}x{size} DFG LUT ({geometry}, {samples} samples, {fmt}) in {dt:.3f}s; "
          f"A in [{np.min(lut[..., 0]):.4f}, {np.max(lut[..., 0]):.4f}]")
    return 0


def _cmd_shaders(args) -> int:
    check_output_path(args.dump, folder=True)
    names = dump_sources(args.dump)
    print(f"{args.dump}: {len(names)} files (README.txt says how they compile)")
    return 0


def bench(size: int = 512, scene_name: str = "spheres", presets=None, env: str | None = None) -> dict:
    """Wall time of each precompute pass and of one frame, per preset, after a warm-up render
    (shader compilation and llvmpipe's JIT), with ctx.finish() around each pass. ``scene_name`` may
    be a glTF asset (``env`` its environment file): the raster pipeline then also reports its
    ``texture_upload`` and ``texture_mips`` (upload and mip generation apart, re-done warm) and
    ``geometry`` passes."""
    from pbrcheck.gltf_objects import is_asset_path, set_asset_options
    from . import raster
    if is_asset_path(scene_name):
        set_asset_options(env=env, size=(size, size))
    scene = load_scene(scene_name).with_camera(width=size, height=size)
    out = {"scene": scene_name, "size": [size, size], "gl_renderer": renderer_name(), "clock": timing_clock(),
           "clock_note": "frame_s: GL timer query (GPU time of the frame's commands) on a GPU, the wall clock "
                         "to glFinish on llvmpipe; raster frames time the colour pass's draws", "presets": {}}
    for p in presets or PRESETS:
        R.render_realtime(scene, p, progress=False)            # warm-up: compile, JIT, load env
        for k in [k for k in R._cache if isinstance(k, tuple) and k[0] in ("env_cube", "irr", "sh9", "pre", "lut", "kd")]:
            R._cache.pop(k)                                     # re-bake every pass, now warm
        for k in [k for k in raster._textures if k != ("white",)]:
            raster._textures.pop(k)[1].release()               # re-upload the material textures
        t0 = time.perf_counter()
        img = R.render_realtime(scene, p, progress=False)
        total = time.perf_counter() - t0
        t = json.loads(img.meta["timings"])
        t.pop("compile_frame", None)
        frame_total = t.pop("frame_total", None)  # raster: the draws' call with its read-back and AOV pass
        out["presets"][p] = {"passes_s": {k: round(v, 4) for k, v in t.items() if k != "frame"},
                             "frame_s": round(t["frame"], 4), "total_s": round(total, 4),
                             **({"frame_with_readback_s": round(frame_total, 4)} if frame_total is not None else {}),
                             "supersample": json.loads(img.meta["options"])["supersample"],
                             "pipeline": img.meta.get("pipeline", "raycast")}
    return out


def _cmd_bench(args) -> int:
    presets = [x for x in (args.presets or "").split(",") if x] or None
    print(json.dumps(bench(args.size, args.scene, presets=presets, env=args.env), indent=2))
    return 0


def register(sub, bench_sub) -> None:
    """Add this package's subcommands to the ``pbrcheck`` parser."""
    s = sub.add_parser("realtime", help="render a scene with the real-time GLSL split-sum renderer")
    s.add_argument("scene", help="built-in scene name or path to a TOML scene file")
    s.add_argument("--preset", default="default", choices=list(PRESETS))
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override one option (repeatable); see docs/realtime.md")
    s.add_argument("--shader", metavar="FILE.glsl",
                   help="shader hook file: its hook_* functions replace built-in pieces (docs/hooks.md)")
    s.add_argument("--out", default=None, help="output EXR (default out/realtime/SCENE_PRESET.exr)")
    s.set_defaults(func=_cmd_realtime)

    s = sub.add_parser("lut", help="bake the split-sum DFG LUT (channels A and B) to an EXR")
    s.add_argument("--size", required=True, help="N: the LUT is N x N")
    s.add_argument("--samples", default="4096")
    s.add_argument("--geometry", default="smith_ggx_correlated")
    s.add_argument("--format", default="f32", help="f16 | f32")
    s.add_argument("--sampling", default="vndf", help="vndf | ndf")
    s.add_argument("--ndf", default="ggx", choices=("ggx", "beckmann", "blinn_phong"))
    s.add_argument("--out", required=True)
    s.set_defaults(func=_cmd_lut)

    s = sub.add_parser("shaders", help="write the GLSL the real-time programs compile (generated includes too)")
    s.add_argument("--dump", required=True, metavar="DIR", help="folder to write (created; files replaced)")
    s.set_defaults(func=_cmd_shaders)

    b = bench_sub.add_parser("realtime", help="JSON: wall time of each precompute pass and one frame per preset")
    b.add_argument("--size", type=int, default=512)
    b.add_argument("--scene", default="spheres", help="built-in scene, TOML file or glTF asset")
    b.add_argument("--env", default=None, help="environment file of a glTF asset scene")
    b.add_argument("--presets", default=None, metavar="P,...", help="presets to time (default: every preset)")
    b.set_defaults(func=_cmd_bench)
