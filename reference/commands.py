"""CLI subcommands of this package (registered by pbrcheck.cli): ``reference``, ``bench reference``
and ``bench multiscatter``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from pbrcheck.args import positive_int
from pbrcheck.atomic import check_output_path
from pbrcheck.fmt import file_name_part, terminal_safe
from pbrcheck.exr import write_exr
from pbrcheck.scene import load_scene

from .bench import SECTIONS, run_asset_bench, run_bench, run_sections
from .render import DEFAULT_ADAPTIVE, DEFAULT_SAMPLER, SAMPLER_NAMES, render_reference


def _cmd_reference(args) -> int:
    scene = load_scene(args.scene)
    out = Path(args.out) if args.out else Path("out") / f"reference_{file_name_part(scene.name)}_{args.mode}_{args.spp}spp.exr"
    check_output_path(out)  # before the render
    img = render_reference(scene, spp=args.spp, mode=args.mode, seed=args.seed, max_depth=args.max_depth,
                           use_cache=not args.no_cache, progress=True, sampler=args.sampler,
                           adaptive=args.adaptive)
    write_exr(out, img)
    m = img.meta
    print(terminal_safe(f"{out}: {scene.name} {m['mode']} {m['spp']} spp seed {m['seed']}, sampler {m.get('sampler')}"
                        + (f" (adaptive: {m['adaptive']})" if m.get("adaptive", "off") != "off" else "")
                        + f", variant {m['variant']}, {m['seconds']} s render, cache {m.get('cache', 'off')}"))
    return 0


def _cmd_bench(args) -> int:
    if args.asset_only:
        out = run_asset_bench(quick=args.quick)
    elif args.section:
        out = run_sections(tuple(args.section), quick=args.quick, envmap=args.envmap)
    else:
        out = run_bench(quick=args.quick, envmap=args.envmap)
    print(json.dumps(out, indent=2))
    sys.stdout.flush()
    return 0


def _cmd_bench_multiscatter(args) -> int:
    from .multiscatter_measure import bench_multiscatter  # local: loads Mitsuba; only this bench needs it

    print(json.dumps(bench_multiscatter(lanes=args.lanes, roughness=args.roughness, mu=args.nov), indent=2))
    sys.stdout.flush()
    return 0


def register(sub, bench_sub) -> None:
    """Add this package's subcommands to the ``pbrcheck`` parser."""
    s = sub.add_parser("reference", help="render the Mitsuba 3 reference image of a scene (EXR)")
    s.add_argument("scene", help="built-in scene name or path to a TOML scene file")
    s.add_argument("--spp", type=positive_int(2), default=64, help="samples per pixel (>= 2; default 64)")
    s.add_argument("--mode", choices=("local", "path"), default="local",
                   help="local: first hit, MIS, no visibility (default); path: Mitsuba's path tracer")
    s.add_argument("--seed", type=positive_int(0), default=0)
    s.add_argument("--max-depth", type=positive_int(1), default=None,
                   help="path mode: maximum path depth (default 8)")
    s.add_argument("--sampler", choices=SAMPLER_NAMES, default=DEFAULT_SAMPLER,
                   help="qmc: randomized quasi-Monte Carlo (multijitter), variance from 16 replicates "
                        "(default); independent: uniform random numbers, per-sample variance")
    s.add_argument("--adaptive", action=argparse.BooleanOptionalAction, default=DEFAULT_ADAPTIVE,
                   help="qmc at >= 256 spp: a pilot (discarded) sets each pixel's spp, mean = --spp (default on)")
    s.add_argument("--out", default=None, help="output EXR (default out/reference_<scene>_<mode>_<spp>spp.exr)")
    s.add_argument("--no-cache", action="store_true", help="render even if a cached reference exists, store nothing")
    s.set_defaults(func=_cmd_reference)

    b = bench_sub.add_parser("reference", help="reference throughput against Mitsuba's path, integrator efficiency, BSDF speed, seconds to the 10x noise floor (JSON, with goals)")
    b.add_argument("--quick", action="store_true", help="smaller sizes (for tests)")
    b.add_argument("--envmap", default=None,
                   help="HDR environment of the real-HDR figures (default: the first of ../shared/envmaps; "
                        "skipped when absent)")
    b.add_argument("--asset-only", action="store_true",
                   help="only the asset row: the ~50k-triangle textured asset and spheres, rendered alternately")
    b.add_argument("--section", action="append", choices=SECTIONS, default=None,
                   help="only this section's figures (samplers, variance_reduction; repeatable)")
    b.set_defaults(func=_cmd_bench)

    b = bench_sub.add_parser("multiscatter", help="BSDF samples per second: random_walk against single "
                                                  "scattering, in one run (JSON)")
    b.add_argument("--lanes", type=positive_int(1), default=1 << 20, help="samples per launch (default 2^20)")
    b.add_argument("--roughness", type=float, default=0.5, help="roughness (default 0.5)")
    b.add_argument("--nov", type=float, default=0.5, help="n.v of the incident direction (default 0.5)")
    b.set_defaults(func=_cmd_bench_multiscatter)
