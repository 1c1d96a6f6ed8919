"""CLI subcommands of this package (registered by pbrcheck.cli): ``export``, ``render``,
``import-scenario``, ``renderers`` and ``bench client``. Library errors propagate; only pbrcheck.cli maps them to exit
codes."""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

from pbrcheck.atomic import check_output_path
from pbrcheck.export import OUTPUT_FORMATS, export_scene
from pbrcheck.atomic import write_text_atomic
from pbrcheck.exr import write_exr
from pbrcheck.fmt import file_name_part, terminal_safe
from pbrcheck.scenario_import import INDEX, import_scenario, import_to_folder
from pbrcheck.scene import load_scene

from .config import load_renderers, set_renderers_file
from .run import render_external


def _cmd_export(args) -> int:
    scene = load_scene(args.scene)
    check_output_path(args.out, folder=True)
    exp = export_scene(scene, Path(args.out), output=args.output, keep_unmodelled=args.keep_unmodelled)
    for feature, materials in exp.unmodelled:
        what = "kept (--keep-unmodelled)" if exp.kept_unmodelled else "removed (--keep-unmodelled keeps it)"
        print(f"pbrcheck: export: {terminal_safe(feature)} {what}: materials {', '.join(map(terminal_safe, materials))}",
              file=sys.stderr)
    segs = sorted(set(exp.segments.values()))
    print(terminal_safe(f"{exp.out_dir}: {', '.join(exp.files)} ({len(scene.objects)} object(s), {exp.triangles} triangles"
                        + (f", sphere segments {segs[0]}-{segs[-1]}" if segs else "") + ")"))
    return 0


def _cmd_render(args) -> int:
    if args.renderers_file:
        set_renderers_file(args.renderers_file)
    scene = load_scene(args.scene)
    out = Path(args.out or f"out/render/{file_name_part(scene.name)}_{file_name_part(args.renderer)}.exr")
    check_output_path(out)  # before the render
    img = render_external(scene, args.renderer, use_cache=not args.no_cache, progress=True)
    write_exr(out, img)
    print(f"{terminal_safe(out)}: {scene.camera.width}x{scene.camera.height}, {img.meta['renderer']} "
          f"({img.meta['version']}), {float(img.meta['seconds']):.2f}s")
    return 0


def _cmd_import_scenario(args) -> int:
    if args.out is not None and (Path(args.out).is_dir() or not Path(args.out).suffix):  # a folder: every scenario
        files = import_to_folder(args.scenario, args.out)
        print(f"{args.out}: {len(files)} scene(s) of {args.scenario} and {INDEX}")
        return 0
    text = import_scenario(args.scenario)
    if args.out is None:
        print(text, end="")
    else:
        write_text_atomic(args.out, text)
        print(f"{args.out}: scene of {args.scenario}")
    return 0


def _cmd_renderers(args) -> int:
    if args.renderers_file:
        set_renderers_file(args.renderers_file)
    for name, cfg in sorted(load_renderers().items()):
        origin = "built in" if cfg.builtin else cfg.source
        print(f"ext:{name:<12} {cfg.output:<8} {origin}: {cfg.description or ' '.join(cfg.command)}")
    return 0


def bench(renderer: str = "threejs", scene_name: str = "spheres", runs: int = 2) -> dict:
    """Wall time of the export and of ``runs`` uncached runs of an external renderer (JSON figures)."""
    scene = load_scene(scene_name)
    with tempfile.TemporaryDirectory(prefix="pbrcheck-bench-") as tmp:
        t0 = time.perf_counter()
        export_scene(scene, Path(tmp))
        export_s = time.perf_counter() - t0
    seconds, meta = [], {}
    for _ in range(runs):
        img = render_external(scene, renderer, use_cache=False, progress=False)
        seconds.append(float(img.meta["seconds"]))
        meta = img.meta
    return {"renderer": meta.get("renderer"), "version": meta.get("version"), "scene": scene_name,
            "size": [scene.camera.width, scene.camera.height], "export_s": round(export_s, 3),
            "run_s": [round(x, 3) for x in seconds], "run_median_s": round(statistics.median(seconds), 3),
            "renderer_report": meta.get("renderer_stdout"), "timed_on": meta.get("timed_on")}


def _cmd_bench(args) -> int:
    print(json.dumps(bench(args.renderer, args.scene, args.runs), indent=2))
    return 0


def register(sub, bench_sub) -> None:
    """Add this package's subcommands to the ``pbrcheck`` parser."""
    s = sub.add_parser("export", help="export a scene for any renderer: glTF 2.0, environment, scenario.json")
    s.add_argument("scene", help="built-in scene name or path to a TOML scene file")
    s.add_argument("--out", required=True, help="output folder")
    s.add_argument("--output", default="exr", choices=OUTPUT_FORMATS,
                   help="the output format the renderer will write, stated in scenario.json (default exr)")
    s.add_argument("--keep-unmodelled", action="store_true",
                   help="keep the asset's material extensions pbrcheck does not model (default: removed, so "
                        "that an engine is measured on what the reference models)")
    s.set_defaults(func=_cmd_export)

    s = sub.add_parser("render", help="render a scene with an external renderer (renderers.toml) to an EXR")
    s.add_argument("scene", help="built-in scene name or path to a TOML scene file")
    s.add_argument("--renderer", required=True, metavar="NAME", help="an external renderer (e.g. threejs)")
    s.add_argument("--renderers", dest="renderers_file", default=None, metavar="FILE",
                   help="renderers file (default ./renderers.toml when present, plus the built-in clients)")
    s.add_argument("--out", default=None, help="output EXR (default out/render/SCENE_NAME.exr)")
    s.add_argument("--no-cache", action="store_true", help="render even when a cached image exists")
    s.set_defaults(func=_cmd_render)

    s = sub.add_parser("import-scenario", help="a Khronos Render Fidelity / model-viewer scenario (JSON) as a "
                       "pbrcheck scene (TOML)")
    s.add_argument("scenario", help="a Render Fidelity config.json (every scenario; with --out DIR), one scenario "
                   "JSON (model, lighting, dimensions, target, orbit, verticalFoV, renderSkybox, exclude), or the "
                   "scenario.json of pbrcheck export")
    s.add_argument("--out", default=None, help="the scene TOML to write (default: print it), or a folder (an "
                   "existing one, or a path without a suffix): one scene TOML per scenario and scenarios.json")
    s.set_defaults(func=_cmd_import_scenario)

    s = sub.add_parser("renderers", help="list the external renderers (built-in clients and renderers.toml)")
    s.add_argument("--renderers", dest="renderers_file", default=None, metavar="FILE", help="renderers file")
    s.set_defaults(func=_cmd_renderers)

    b = bench_sub.add_parser("client", help="JSON: export time and uncached run times of an external renderer")
    b.add_argument("--renderer", default="threejs")
    b.add_argument("--scene", default="spheres")
    b.add_argument("--runs", type=int, default=2)
    b.set_defaults(func=_cmd_bench)
