"""CLI subcommands of the research layer (registered by :mod:`pbrcheck_cli`): ``hardcases``,
``fit-lod``, ``fit-normal-roughness``, ``explain``, ``fit-roughness``, ``diagnose``, ``energy``, ``layered-coat``, ``fit-lobes`` and ``bench fit-roughness``. Library errors propagate;
only :mod:`pbrcheck_cli` maps them to exit codes."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

from pbrcheck.errors import PbrcheckError
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.args import split_list
from pbrcheck.gltf_objects import asset_options_of
from pbrcheck.scene import load_scene
from realtime.presets import overrides_from_args

from pbrcheck.environment import read_image_file
from pbrcheck.exr import Image, read_exr

from ..verdict_spp import DEFAULT_SPP_CAP
from . import diagnose, energy, explain, fit_lod, fit_normal_roughness, fit_roughness, fit_lobes, hardcases, layered_coat


def _cmd_hardcases(args) -> int:
    settings = {"size": args.size, "spp": args.spp, "presets": split_list(args.presets),
                "cases": split_list(args.cases), "cube_size": args.cube_size}
    rows = hardcases.run_hardcases(size=args.size, spp=args.spp, presets=settings["presets"], cases=settings["cases"],
                         cube_size=args.cube_size, spp_cap=args.spp_cap, progress=not args.quiet)
    paths = hardcases.write_hardcases(rows, Path(args.out), settings)
    print(hardcases.table_markdown(rows), end="")
    for k, p in paths.items():
        print(f"{k}: {p}")
    bad = [r for r in rows if not r.finite]
    if bad:
        print(f"hardcases: {len(bad)} render(s) non-finite or failed: "
              + ", ".join(f"{r.case}/{r.preset or 'reference'}" for r in bad))
        return 1
    return 0


def _cmd_fit_lod(args) -> int:
    scene = load_scene(args.scene, asset_options_of(args))
    rough = None
    if args.roughness:
        try:
            rough = [float(x) for x in split_list(args.roughness)]
        except ValueError:
            raise PbrcheckError(f"fit-lod: --roughness: expected numbers separated by commas, found {args.roughness!r}")
    chains = split_list(args.chains) if args.chains else None
    res = fit_lod.run_fit_lod(scene, roughness=rough, preset=args.preset, options=overrides_from_args(args.set, args.shader), spp=args.spp,
                      size=args.size, out=Path(args.out), spp_cap=args.spp_cap, progress=not args.quiet,
                      **({"chains": chains} if chains else {}))
    print(fit_lod.table_markdown(res), end="")
    print(f"json: {args.out}\nglsl: {res.glsl}")
    return 0


def _cmd_fit_normal_roughness(args) -> int:
    res = fit_normal_roughness.run_fit_normal_roughness(
        load_scene(args.scene, asset_options_of(args)), method=args.method, preset=args.preset,
        options=overrides_from_args(args.set, args.shader), spp=args.spp, size=args.size, out=Path(args.out),
        iterations=args.iterations, fit_spp=args.fit_spp, spp_cap=args.spp_cap, progress=not args.quiet)
    print(fit_normal_roughness.table_markdown(res), end="")
    print(f"json: {args.out}\nglsl: {res.glsl}")
    return 0


def _cmd_explain(args) -> int:
    res = explain.run_explain(
        load_scene(args.scene, asset_options_of(args)), preset=args.preset,
        options=overrides_from_args(args.set, args.shader), spp=args.spp, size=args.size or None, fitted=args.fitted,
        spp_cap=args.spp_cap, only=tuple(split_list(args.sources)) if args.sources else None, progress=not args.quiet)
    out = explain.write_explain(res, Path(args.out))
    print(explain.table_markdown(res), end="")
    print(f"json: {out}\ntable: {out.with_suffix('.md')}")
    return 0


def _cmd_fit_roughness(args) -> int:
    res = fit_roughness.run_fit_roughness(
        load_scene(args.scene, asset_options_of(args)), preset=args.preset,
        options=overrides_from_args(args.set, args.shader), size=args.size or None, iterations=args.iterations,
        spp=args.spp, scan=not args.no_scan)
    out = write_json_atomic(args.out, res)
    print(fit_roughness.table_markdown(res), end="")
    print(f"json: {out}")
    return 0


def _read_image(path: str) -> Image:
    """An EXR as pbrcheck writes it (AOVs and metadata kept), or any .exr/.hdr as plain RGB."""
    p = Path(path)
    if p.suffix.lower() == ".exr":
        img = read_exr(p)
        if img.has("R", "G", "B"):
            return img
    return Image.from_rgb(read_image_file(p)[..., :3])


def _cmd_diagnose(args) -> int:
    ref, test = _read_image(args.reference), _read_image(args.test)
    scene = load_scene(args.scene, asset_options_of(args)) if args.scene else None
    res = diagnose.diagnose(ref, test, scene, spp=args.spp, progress=not args.quiet, mode=args.reference_mode)
    print(diagnose.table_markdown(res), end="")
    if args.json:
        print(f"json: {write_json_atomic(args.json, res)}")
    return 0


def _cmd_bench_fit_roughness(args) -> int:
    rough = fit_roughness.SELF_CHECK_ROUGHNESS if not args.roughness else [float(x) for x in args.roughness.split(",")]
    print(json.dumps(fit_roughness.self_check(size=args.size, sun_deg=args.sun, sun_radiance=args.sun_radiance,
                                metallic=args.metallic, roughness=rough, target_spp=args.target_spp), indent=2))
    return 0


def _cmd_energy(args) -> int:
    scenes = split_list(args.scenes) if args.scenes else list(energy.DEFAULT_SCENES)
    out = Path(args.out)
    res = energy.run_energy(samples=args.samples, seed=args.seed, images=not args.no_images, scenes=scenes,
                            preset=args.preset, options=overrides_from_args(args.set, args.shader), spp=args.spp, size=args.size or None,
                            out_dir=out, progress=not args.quiet)
    paths = energy.write_energy(res, out)
    print(energy.table_markdown(res), end="")
    for k, p in paths.items():
        print(f"{k}: {p}")
    return 0


def _cmd_layered_coat(args) -> int:
    rows = layered_coat.run_layered_coat(samples=args.samples, seed=args.seed)
    print(layered_coat.table_markdown(rows), end="")
    if args.json:
        print(f"json: {write_json_atomic(args.json, [asdict(r) for r in rows])}")
    return 0


def _cmd_fit_lobes(args) -> int:
    from pbrcheck.atomic import write_text_atomic
    errors, table = fit_lobes.sheen_report(baked32=not args.no_baked32)
    print(fit_lobes.sheen_table_markdown(errors))
    print(fit_lobes.sheen_check_line(table))
    aniso, aniso_losses = fit_lobes.fit_aniso_table(return_losses=True)
    aniso_errors = fit_lobes.aniso_report(aniso)
    print(fit_lobes.aniso_table_markdown(aniso_errors, aniso), end="")
    print(fit_lobes.aniso_fit_line(aniso_losses, aniso if args.check_scan else None))
    if args.module:
        print(f"module: {write_text_atomic(args.module, fit_lobes.module_text(table, aniso))}")
    if args.json:
        print(f"json: {write_json_atomic(args.json, {'sheen_albedo': errors, 'table': table.tolist(), 'aniso_bend': aniso_errors, 'aniso_table': aniso.tolist(), 'aniso_ad_losses': aniso_losses})}")
    return 0


def _spp_cap_arg(s, cap: int) -> None:
    s.add_argument("--spp-cap", type=int, default=cap, metavar="N",
                   help=f"most reference samples per pixel (default {cap}): --spp is the least, more are rendered "
                        f"until the reference's noise floor is 10x below the error; at the cap: noise-limited")


def _renderer_args(s, *, spp: int, size: int | None, size_help: str) -> None:
    """The arguments every research command shares: the scene, the renderer under test and its
    overrides, the reference spp and the image height."""
    s.add_argument("scene", help="built-in scene name or TOML path")
    s.add_argument("--preset", default="default", help="real-time preset (default: default)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="real-time option override (repeatable)")
    s.add_argument("--shader", metavar="FILE.glsl", help="shader hook file for the real-time renderer (docs/hooks.md)")
    s.add_argument("--spp", type=int, default=spp, help=f"samples per pixel (default {spp})")
    s.add_argument("--size", type=int, default=size, help=size_help)


def register(sub, bench_sub) -> None:
    """Add the research subcommands to the ``pbrcheck`` parser."""
    s = sub.add_parser("hardcases", help="hard-case scenes through the reference and every preset: "
                                         "NaN/Inf check and error table (exit 1 on a non-finite output)")
    s.add_argument("--out", default="out/hardcases", metavar="DIR", help="output directory (default out/hardcases)")
    s.add_argument("--spp", type=int, default=16, help="least reference samples per pixel (default 16); more "
                   "are rendered until the reference's noise floor is 10x below the presets' smallest error")
    _spp_cap_arg(s, hardcases.SPP_CAP)
    s.add_argument("--size", type=int, default=48, help="image height in pixels (default 48)")
    s.add_argument("--presets", metavar="P,...", help="real-time presets (default: all)")
    s.add_argument("--cases", metavar="C,...", help="only these cases (default: all)")
    s.add_argument("--cube-size", type=int, default=None, metavar="N",
                   help="bake N^2 cubes instead of each preset's own (faster; mip count capped to fit)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_hardcases)

    s = sub.add_parser("fit-lod", help="per-roughness optimal prefiltered LOD, a fitted monotone mapping, "
                                       "and every mapping's error")
    _renderer_args(s, spp=64, size=None, size_help="image height (default: 96 for the probe grid, the scene's "
                   "own otherwise); a sphere grid in the scene is used as is")
    _spp_cap_arg(s, DEFAULT_SPP_CAP)
    s.add_argument("--roughness", metavar="R1,R2,...", help="roughness values (default: 16 in [0, 1]); "
                   "they are rendered as metal spheres under the scene's environment")
    s.add_argument("--out", default="out/fit_lod.json", metavar="FILE.json", help="JSON (the GLSL goes next to it)")
    s.add_argument("--chains", metavar="C1,C2,...", help="prefiltered chains to scan and fit on (built-in "
                   "mappings; default: linear,quadratic,log2; the best-predicting one is kept)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_fit_lod)

    s = sub.add_parser("fit-normal-roughness", help="the GGX alpha^2 added per normal-map mip level that makes the "
                                                    "filtered image match the reference, against Toksvig's closed form "
                                                    "(ad: an inverse fit by AD in the reference, normal filtering "
                                                    "alone; scan: raster renders scanned); written as a "
                                                    "hook_specular_aa GLSL file")
    s.add_argument("--method", choices=fit_normal_roughness.METHODS, default=fit_normal_roughness.METHODS[0],
                   help="ad: the reference with the raster's filtered normal lookup, the table fitted by Adam "
                        "(default); scan: fit-lod's scan of raster renders")
    s.add_argument("--iterations", type=int, default=fit_normal_roughness.ITERATIONS, help="ad: Adam steps")
    s.add_argument("--fit-spp", type=int, default=fit_normal_roughness.FIT_SPP,
                   help="ad: samples per pixel of each step's renders")
    _renderer_args(s, spp=64, size=None, size_help="image height (default: the scene's own)")
    _spp_cap_arg(s, DEFAULT_SPP_CAP)
    s.add_argument("--out", default="out/fit_normal_roughness.json", metavar="FILE.json",
                   help="JSON (the GLSL hook goes next to it)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_fit_normal_roughness)

    s = sub.add_parser("explain", help="error decomposition: make one approximation exact at a time and "
                                       "measure the error it contributes")
    _renderer_args(s, spp=64, size=64, size_help="image height (default 64; 0: the scene's own)")
    _spp_cap_arg(s, DEFAULT_SPP_CAP)
    s.add_argument("--fitted", metavar="FILE.json", help="also try this fitted LOD mapping (pbrcheck fit-lod)")
    s.add_argument("--sources", metavar="S,...", help="measure these sources only (default: every one; glTF "
                   "asset scenes add texture_filtering, normal_filtering, occlusion)")
    s.add_argument("--out", default="out/explain.json", metavar="FILE.json", help="JSON (a .md table next to it)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_explain)

    s = sub.add_parser("fit-roughness", help="apparent roughness: fit the differentiable reference's roughness "
                                             "per object to the real-time image")
    _renderer_args(s, spp=16, size=64, size_help="image height (default 64; 0: the scene's own)")
    s.add_argument("--iterations", type=int, default=40, help="Adam steps (default 40)")
    s.add_argument("--no-scan", action="store_true",
                   help="start Adam at each object's own roughness, without the starting scan (and no range)")
    s.add_argument("--out", default="out/fit_roughness.json", metavar="FILE.json")
    s.set_defaults(func=_cmd_fit_roughness)

    s = sub.add_parser("diagnose", help="why do two images differ? rank known convention mismatches (flips, "
                                        "sRGB, exposure, clamp, channel order, alpha; with --scene also the "
                                        "environment's orientation, roughness, diffuse and light units)")
    s.add_argument("reference", help="reference image (.exr, ideally pbrcheck's with variance and coverage)")
    s.add_argument("test", help="image under test (.exr or .hdr, linear radiance)")
    s.add_argument("--scene", help="the scene both show (enables the scene-space hypotheses)")
    s.add_argument("--spp", type=int, default=None,
                   help="spp of the re-rendered references (default: the reference's own)")
    s.add_argument("--json", metavar="FILE.json", help="also write the result as JSON")
    s.add_argument("--reference-mode", choices=("local", "path"), default=None,
                   help="reference mode of the scene-space re-renders: the truth the engine is set against "
                        "(default: the reference image's own mode, else local)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_diagnose)

    s = sub.add_parser("energy", help="multiple-scattering energy compensations against the reference's random "
                                      "walk: directional albedo over roughness x F0 x n.v, furnace and spheres images")
    s.add_argument("--samples", type=int, default=energy.DEFAULT_SAMPLES, help="walks per grid point (default 65536)")
    s.add_argument("--seed", type=int, default=0, help="the walks' hash seed (default 0)")
    s.add_argument("--scenes", metavar="S,...", help="scenes of the image comparison (default furnace,spheres)")
    s.add_argument("--no-images", action="store_true", help="the albedo grid only")
    s.add_argument("--preset", default="default", help="real-time preset of the images (default: default)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="real-time option override (repeatable)")
    s.add_argument("--shader", metavar="FILE.glsl", help="shader hook file for the real-time renderer (docs/hooks.md)")
    s.add_argument("--spp", type=int, default=128, help="reference samples per pixel (default 128)")
    s.add_argument("--size", type=int, default=64, help="image height (default 64; 0: the scene's own)")
    s.add_argument("--out", default="out/energy", metavar="DIR", help="output directory (default out/energy)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_energy)

    s = sub.add_parser("layered-coat", help="the spec's clearcoat layering (albedo scaling) against a physically "
                                            "layered coat (a position-free random walk through a dielectric slab "
                                            "over the base): albedo and BRDF per coat roughness and n.v")
    s.add_argument("--samples", type=int, default=layered_coat.DEFAULT_SAMPLES,
                   help=f"walks per estimate (default {layered_coat.DEFAULT_SAMPLES})")
    s.add_argument("--seed", type=int, default=0, help="the walks' seed (default 0)")
    s.add_argument("--json", metavar="FILE.json", help="also write the rows as JSON")
    s.set_defaults(func=_cmd_layered_coat)

    s = sub.add_parser("fit-lobes", help="inverse fits of the lobes' real-time forms against the truth: a sheen "
                                         "albedo table fitted to the spec's quadrature, the anisotropic bent normal's "
                                         "blend weight fitted to the spec's GGX under test environments; before/after errors")
    s.add_argument("--module", metavar="FILE.py", help="write the fitted table as a module (realtime/fitted_lobes.py)")
    s.add_argument("--json", metavar="FILE.json", help="also write the errors and the table as JSON")
    s.add_argument("--no-baked32", action="store_true", help="skip the 32 x 32 bake's row (1024 quadratures)")
    s.add_argument("--check-scan", action="store_true", help="also check the AD bend weights against a dense scan "
                                                            "of each node's objective (~10-30 s more)")
    s.set_defaults(func=_cmd_fit_lobes)

    b = bench_sub.add_parser("fit-roughness", help="fit-roughness against the reference itself: r* error per "
                                                   "roughness on one sphere under a sun (JSON)")
    b.add_argument("--size", type=int, default=48, help="image size (default 48)")
    b.add_argument("--sun", type=float, default=8.0, help="sun angular diameter in degrees (default 8)")
    b.add_argument("--sun-radiance", type=float, default=60.0, help="sun radiance (default 60)")
    b.add_argument("--metallic", type=float, default=1.0, help="the sphere's metallic (default 1)")
    b.add_argument("--roughness", metavar="r1,r2,...", help="target roughness values (default 0.03 ... 0.8)")
    b.add_argument("--target-spp", type=int, default=1024, help="samples per pixel of the targets (default 1024)")
    b.set_defaults(func=_cmd_bench_fit_roughness)
