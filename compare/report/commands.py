"""CLI subcommands of the report layer (registered by :mod:`pbrcheck.cli`): ``report``, ``sweep`` and
``demo`` (the main job). Library errors propagate; only :mod:`pbrcheck.cli` maps them to exit codes."""

from __future__ import annotations

from pathlib import Path

from pbrcheck.args import split_list
from pbrcheck.scene import DEFAULT_SCENE

from . import demo
from .build import build_report
from .sweep import parse_vary, run_sweep


def _cmd_report(args) -> int:
    out = build_report(args.scenes or [DEFAULT_SCENE], presets=split_list(args.presets), out_dir=Path(args.out),
                       spp=args.spp, vary=args.vary or None, convergence=not args.no_convergence,
                       sweep=not args.no_sweep, progress=not args.quiet,
                       hardcases=args.hardcases, research=args.research, furnace=not args.no_furnace)
    print(f"report: {out}")
    return 0


def _cmd_sweep(args) -> int:
    vary = parse_vary(args.vary)
    paths = run_sweep(args.scene, vary, preset=args.preset, out_dir=Path(args.out), spp=args.spp,
                      progress=not args.quiet, also=split_list(args.also))
    for k, p in paths.items():
        print(f"{k}: {p}")
    return 0


def _cmd_demo(args) -> int:
    return demo.run(args)


def register(sub, bench_sub) -> None:
    """Add ``report``, ``sweep`` and ``demo`` to the ``pbrcheck`` parser."""
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
    s.add_argument("--no-furnace", action="store_true", help="skip the white furnace per renderer")
    s.add_argument("--hardcases", action="store_true", help="add the hard-case section (pbrcheck hardcases, small)")
    s.add_argument("--research", action="store_true", help="add the LOD fit (before / after), error "
                   "decomposition and apparent-roughness sections for the first scene (a few minutes)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_report)

    s = sub.add_parser("sweep", help="speed against error over real-time option combinations")
    s.add_argument("scene", help="built-in scene name or TOML path")
    s.add_argument("--vary", action="append", required=True, metavar="KEY=V1,V2",
                   help="real-time option and its values (repeatable; every combination is rendered)")
    s.add_argument("--preset", default="default", help="preset the variations start from")
    s.add_argument("--with", dest="also", metavar="P,...",
                   help="further renderers measured as they are on the same plot (presets or ext:NAME)")
    s.add_argument("--out", default="out/sweep", metavar="DIR")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_sweep)


    s = sub.add_parser("demo", help="the main job on the default scene (what `make demo` runs)")
    s.add_argument("--scene", default=DEFAULT_SCENE)
    s.add_argument("--out", default="out/demo", help="output directory (default out/demo)")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.set_defaults(func=_cmd_demo)
