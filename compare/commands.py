"""CLI subcommands of this package (registered by pbrcheck.cli): compare, report, gate, sweep."""

from __future__ import annotations

import json
import math
from pathlib import Path

from pbrcheck.atomic import write_text_atomic

from .metrics import format_value


def _jsonable(x):
    """JSON without NaN/Infinity (not valid JSON): non-finite floats become null."""
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def dump_json(obj) -> str:
    return json.dumps(_jsonable(obj), indent=2, allow_nan=False)




def _cmd_compare(args) -> int:
    from pbrcheck.exr import read_exr

    from .maps import write_maps
    from .metrics import compare_images

    # Everything is read and validated before anything is written.
    scene = None
    if args.scene:
        from pbrcheck.scene import load_scene

        scene = load_scene(args.scene)
    ref = read_exr(args.reference)
    test = read_exr(args.test)
    cmp = compare_images(ref, test, scene=scene, ref_name=args.reference, test_name=args.test)
    summary = {"reference": str(args.reference), "test": str(args.test), **cmp.summary}
    if args.maps:
        summary["maps"] = {k: str(p) for k, p in write_maps(Path(args.maps), cmp).items()}
    if args.json:
        p = Path(args.json)
        p.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(p, dump_json(summary) + "\n")
    px = cmp.summary["pixels"]
    noise = cmp.summary["noise"]
    print(f"pixels: {px['valid']} valid, {px['edge']} edge, {px['background']} background")
    for k, v in cmp.metrics.items():
        flag = ""
        if noise is not None and noise["within_noise"].get(k):
            flag = "  (within reference noise)"
        print(f"{k:<18} {format_value(v)}{flag}")
    if noise is not None:
        print(f"noise floor (mean variance) {format_value(noise['mean_variance'])}, "
              f"noise-corrected MSE {format_value(noise['mse_corrected'])}")
    return 0


def _cmd_gate(args) -> int:
    from .gate import run_gate

    return run_gate(args.budget, junit=args.junit, summary=args.summary, maps_dir=args.maps,
                    progress=not args.quiet)


def _split_list(s: str | None) -> list[str] | None:
    if s is None:
        return None
    return [x.strip() for x in s.split(",") if x.strip()]


def _cmd_report(args) -> int:
    from pbrcheck.cli import DEFAULT_SCENE

    from .report import build_report

    out = build_report(args.scenes or [DEFAULT_SCENE], presets=_split_list(args.presets), out_dir=Path(args.out),
                       spp=args.spp, vary=args.vary or None, convergence=not args.no_convergence,
                       sweep=not args.no_sweep, progress=not args.quiet,
                       hardcases=args.hardcases, research=args.research)
    print(f"report: {out}")
    return 0


def _cmd_sweep(args) -> int:
    from .sweep import parse_vary, run_sweep

    vary = parse_vary(args.vary)
    paths = run_sweep(args.scene, vary, preset=args.preset, out_dir=Path(args.out), spp=args.spp,
                      progress=not args.quiet)
    for k, p in paths.items():
        print(f"{k}: {p}")
    return 0


def _cmd_hardcases(args) -> int:
    from .hardcases import run_hardcases, table_markdown, write_hardcases

    settings = {"size": args.size, "spp": args.spp, "presets": _split_list(args.presets),
                "cases": _split_list(args.cases), "cube_size": args.cube_size}
    rows = run_hardcases(size=args.size, spp=args.spp, presets=settings["presets"], cases=settings["cases"],
                         cube_size=args.cube_size, progress=not args.quiet)
    paths = write_hardcases(rows, Path(args.out), settings)
    print(table_markdown(rows), end="")
    for k, p in paths.items():
        print(f"{k}: {p}")
    bad = [r for r in rows if not r["finite"]]
    if bad:
        print(f"hardcases: {len(bad)} render(s) non-finite or failed: "
              + ", ".join(f"{r['case']}/{r['preset'] or 'reference'}" for r in bad))
        return 1
    return 0


def _cmd_fit_lod(args) -> int:
    from pbrcheck.scene import load_scene
    from realtime.presets import parse_sets

    from .fitlod import run_fit_lod, table_markdown

    scene = load_scene(args.scene)
    rough = None
    if args.roughness:
        try:
            rough = [float(x) for x in _split_list(args.roughness)]
        except ValueError:
            from pbrcheck.errors import PbrcheckError

            raise PbrcheckError(f"fit-lod: --roughness: expected numbers separated by commas, found {args.roughness!r}")
    chains = _split_list(args.chains) if args.chains else None
    res = run_fit_lod(scene, roughness=rough, preset=args.preset, options=parse_sets(args.set), spp=args.spp,
                      size=args.size, out=Path(args.out), progress=not args.quiet,
                      **({"chains": chains} if chains else {}))
    print(table_markdown(res), end="")
    print(f"json: {args.out}\nglsl: {res['glsl']}")
    return 0


def _cmd_explain(args) -> int:
    from pbrcheck.scene import load_scene
    from realtime.presets import parse_sets

    from .explain import run_explain, table_markdown, write_explain

    res = run_explain(load_scene(args.scene), preset=args.preset, options=parse_sets(args.set), spp=args.spp,
                      size=args.size or None, fitted=args.fitted, progress=not args.quiet)
    out = write_explain(res, Path(args.out))
    print(table_markdown(res), end="")
    print(f"json: {out}\ntable: {out.with_suffix('.md')}")
    return 0


def _cmd_fit_roughness(args) -> int:
    from pbrcheck.scene import load_scene
    from realtime.presets import parse_sets

    from .fitrough import run_fit_roughness, table_markdown

    res = run_fit_roughness(load_scene(args.scene), preset=args.preset, options=parse_sets(args.set),
                            size=args.size or None, iterations=args.iterations, spp=args.spp,
                            scan=not args.no_scan)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, dump_json(res) + "\n")
    print(table_markdown(res), end="")
    print(f"json: {out}")
    return 0


def _cmd_bench_fit_roughness(args) -> int:
    from .fitrough import SELF_CHECK_ROUGHNESS, self_check

    rough = SELF_CHECK_ROUGHNESS if not args.roughness else [float(x) for x in args.roughness.split(",")]
    print(json.dumps(self_check(size=args.size, sun_deg=args.sun, sun_radiance=args.sun_radiance,
                                metallic=args.metallic, roughness=rough, target_spp=args.target_spp), indent=2))
    return 0


def register(sub, bench_sub) -> None:
    """Add this package's subcommands to the ``pbrcheck`` parser."""
    s = sub.add_parser("compare", help="compare a test EXR against a reference EXR (metrics, error maps)")
    s.add_argument("reference", help="reference EXR")
    s.add_argument("test", help="test EXR")
    s.add_argument("--json", metavar="FILE", help="write every metric, per object and per NdotV bin, as JSON")
    s.add_argument("--maps", metavar="DIR", help="write rel_error.png, flip.png and diff.exr into DIR")
    s.add_argument("--scene", metavar="SCENE", help="scene the images show: names objects and their materials")
    s.set_defaults(func=_cmd_compare)

    s = sub.add_parser("report", help="render, compare and write a static HTML accuracy report")
    s.add_argument("scenes", nargs="*", metavar="SCENE", help="built-in scene names or TOML paths (default: spheres)")
    s.add_argument("--presets", metavar="P,...", help="real-time presets (default: all)")
    s.add_argument("--out", default="out/report", metavar="DIR", help="output directory (default out/report)")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.add_argument("--vary", action="append", metavar="KEY=V1,V2",
                   help="sweep these real-time options (repeatable, every combination); default: the main cost "
                        "knobs one at a time")
    s.add_argument("--no-convergence", action="store_true", help="skip the reference convergence study")
    s.add_argument("--no-sweep", action="store_true", help="skip the default sweep over the cost knobs")
    s.add_argument("--hardcases", action="store_true", help="add the hard-case section (pbrcheck hardcases, small)")
    s.add_argument("--research", action="store_true", help="add the LOD fit (before / after), error "
                   "decomposition and apparent-roughness sections for the first scene (a few minutes)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_report)

    s = sub.add_parser("gate", help="CI error budget: exit 1 when a metric exceeds its budget")
    s.add_argument("budget", help="budget TOML file")
    s.add_argument("--junit", metavar="FILE", help="write JUnit XML")
    s.add_argument("--summary", metavar="FILE.md", help="write a Markdown summary")
    s.add_argument("--maps", metavar="DIR", default="out/gate",
                   help="error maps of failing checks go to DIR/<check> (default out/gate)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_gate)

    s = sub.add_parser("sweep", help="speed against error over real-time option combinations")
    s.add_argument("scene", help="built-in scene name or TOML path")
    s.add_argument("--vary", action="append", required=True, metavar="KEY=V1,V2",
                   help="real-time option and its values (repeatable; every combination is rendered)")
    s.add_argument("--preset", default="default", help="preset the variations start from")
    s.add_argument("--out", default="out/sweep", metavar="DIR")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_sweep)

    s = sub.add_parser("hardcases", help="hard-case scenes through the reference and every preset: "
                                         "NaN/Inf check and error table (exit 1 on a non-finite output)")
    s.add_argument("--out", default="out/hardcases", metavar="DIR", help="output directory (default out/hardcases)")
    s.add_argument("--spp", type=int, default=16, help="reference samples per pixel (default 16)")
    s.add_argument("--size", type=int, default=48, help="image height in pixels (default 48)")
    s.add_argument("--presets", metavar="P,...", help="real-time presets (default: all)")
    s.add_argument("--cases", metavar="C,...", help="only these cases (default: all)")
    s.add_argument("--cube-size", type=int, default=None, metavar="N",
                   help="bake N^2 cubes instead of each preset's own (faster; mip count capped to fit)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_hardcases)

    s = sub.add_parser("fit-lod", help="per-roughness optimal prefiltered LOD, a fitted monotone mapping, "
                                       "and every mapping's error")
    s.add_argument("scene", help="built-in scene name or TOML path (a sphere grid is used as is)")
    s.add_argument("--roughness", metavar="R1,R2,...", help="roughness values (default: 16 in [0, 1]); "
                   "they are rendered as metal spheres under the scene's environment")
    s.add_argument("--out", default="out/fit_lod.json", metavar="FILE.json", help="JSON (the GLSL goes next to it)")
    s.add_argument("--preset", default="default", help="real-time preset (its chain and cube are fitted)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="real-time option override (repeatable)")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.add_argument("--size", type=int, default=None, help="image height (default: 96 for the probe grid, "
                   "the scene's own otherwise)")
    s.add_argument("--chains", metavar="C1,C2,...", help="prefiltered chains to scan and fit on (built-in "
                   "mappings; default: linear,quadratic,log2; the best-predicting one is kept)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_fit_lod)

    s = sub.add_parser("explain", help="error decomposition: make one approximation exact at a time and "
                                       "measure the error it contributes")
    s.add_argument("scene", help="built-in scene name or TOML path")
    s.add_argument("--preset", default="default", help="real-time preset (default: default)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="real-time option override (repeatable)")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.add_argument("--size", type=int, default=64, help="image height (default 64; 0: the scene's own)")
    s.add_argument("--fitted", metavar="FILE.json", help="also try this fitted LOD mapping (pbrcheck fit-lod)")
    s.add_argument("--out", default="out/explain.json", metavar="FILE.json", help="JSON (a .md table next to it)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_explain)

    s = sub.add_parser("fit-roughness", help="apparent roughness: fit the differentiable reference's roughness "
                                             "per object to the real-time image")
    s.add_argument("scene", help="built-in scene name or TOML path")
    s.add_argument("--preset", default="default", help="real-time preset (default: default)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="real-time option override (repeatable)")
    s.add_argument("--size", type=int, default=64, help="image height (default 64; 0: the scene's own)")
    s.add_argument("--iterations", type=int, default=40, help="Adam steps (default 40)")
    s.add_argument("--spp", type=int, default=16, help="samples per pixel per step (default 16)")
    s.add_argument("--no-scan", action="store_true",
                   help="start Adam at each object's own roughness, without the starting scan (and no range)")
    s.add_argument("--out", default="out/fit_roughness.json", metavar="FILE.json")
    s.set_defaults(func=_cmd_fit_roughness)

    b = bench_sub.add_parser("fit-roughness", help="fit-roughness against the reference itself: r* error per "
                                                   "roughness on one sphere under a sun (JSON)")
    b.add_argument("--size", type=int, default=48, help="image size (default 48)")
    b.add_argument("--sun", type=float, default=8.0, help="sun angular diameter in degrees (default 8)")
    b.add_argument("--sun-radiance", type=float, default=60.0, help="sun radiance (default 60)")
    b.add_argument("--metallic", type=float, default=1.0, help="the sphere's metallic (default 1)")
    b.add_argument("--roughness", metavar="r1,r2,...", help="target roughness values (default 0.03 ... 0.8)")
    b.add_argument("--target-spp", type=int, default=1024, help="samples per pixel of the targets (default 1024)")
    b.set_defaults(func=_cmd_bench_fit_roughness)
