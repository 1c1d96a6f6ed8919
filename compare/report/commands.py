"""CLI subcommands of the report layer (registered by :mod:`pbrcheck_cli`): ``report``, ``sweep``,
``demo`` (the main job) and ``bench report``. Library errors propagate; only :mod:`pbrcheck_cli` maps them to exit codes."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from pathlib import Path

from pbrcheck.args import split_list
from pbrcheck.atomic import check_output_path, staged_folder
from pbrcheck.export import keeping_unmodelled
from pbrcheck.gltf_objects import asset_options_of
from pbrcheck.scene import DEFAULT_SCENE
from realtime.presets import SHADER_SEP

from .. import renderers

from . import demo
from ..corpus.scheduler import SCHEDULER_HELP
from .build import ReportConfig, build_report
from .corpus_section import corpus_section
from .runlog import RUN_FILE, bench_report, bench_report_asset, summary_line
from .sweep import parse_vary, run_sweep


#: The stderr line of ``report --keep-unmodelled``.
KEEP_NOTICE = ("report: --keep-unmodelled: the external engines get the material extensions pbrcheck does not "
               "model kept (their own forms are measured; the page's 'not modelled' banner still marks them and "
               "the gate does not judge them); their render cache is bypassed")


def _cmd_report(args) -> int:
    presets = split_list(args.presets)
    if args.also:  # further renderers (ext:NAME, PRESET+FILE.glsl) after the presets
        presets = (presets or renderers.preset_names()) + split_list(args.also)
    if args.shader:  # each hook file as one more renderer: the default preset with the hooks
        presets = (presets or renderers.preset_names()) + [f"default{SHADER_SEP}{f}" for f in args.shader]
    check_output_path(args.out, folder=True)  # before any render
    # Sections of finished corpora (read before anything is written); images linked relative to OUT.
    extras = [corpus_section(d, prefix=os.path.relpath(Path(d).resolve(), Path(args.out).resolve()) + "/")
              for d in args.corpus or []]
    config = ReportConfig(presets=presets, spp=args.spp, spp_cap=args.spp_cap, vary=args.vary or None,
                          convergence=not args.no_convergence, sweep=not args.no_sweep,
                          approximations=not args.no_approximations, furnace=not args.no_furnace,
                          hardcases=args.hardcases, research=args.research, scheduler=args.scheduler,
                          cache=not args.no_cache, progress=not args.quiet, assets=asset_options_of(args),
                          reference_mode=args.reference_mode)
    # The page and its files are written into a sibling temporary folder (same depth: the corpus
    # links stay right) and moved into OUT when complete: an error or Ctrl-C leaves OUT as it was.
    keep = keeping_unmodelled() if args.keep_unmodelled else contextlib.nullcontext()
    if args.keep_unmodelled:  # said once, before any render (never silent: docs/renderers.md, Transmission)
        print(KEEP_NOTICE, file=sys.stderr)
    with staged_folder(args.out) as stage, keep:
        built = build_report(args.scenes or [DEFAULT_SCENE], stage, config, extras=extras)
    out = Path(args.out) / Path(built).relative_to(stage)
    print(f"report: {out}")
    run = Path(out).parent / RUN_FILE
    if run.is_file():  # where the time went (also the page's last section)
        print(f"report: {summary_line(json.loads(run.read_text()))}; stages in {run}")
    return 0


def _cmd_sweep(args) -> int:
    vary = parse_vary(args.vary) if args.vary or not (args.approximations or args.lobes) else None
    check_output_path(args.out, folder=True)  # before any render
    with staged_folder(args.out) as stage:  # all of its files, or none
        staged = run_sweep(args.scene, vary, preset=args.preset, out_dir=stage, spp=args.spp,
                           progress=not args.quiet, also=split_list(args.also), scheduler=args.scheduler,
                           mode=args.mode, approximations=args.approximations, assets=asset_options_of(args),
                           lobes=args.lobes)
    paths = {k: Path(args.out) / Path(p).relative_to(stage) for k, p in staged.items()}
    for k, p in paths.items():
        print(f"{k}: {p}")
    return 0


def _cmd_demo(args) -> int:
    return demo.run(args)


def _report_args(args) -> list[str] | None:
    """The report arguments after ``--`` (None: the bench's defaults)."""
    rargs = list(args.report_args or [])
    if rargs and rargs[0] == "--":
        rargs = rargs[1:]
    return rargs or None


def _cmd_bench_report(args) -> int:
    print(json.dumps(bench_report(_report_args(args), fresh_home=not args.keep_home), indent=2))
    return 0


def _cmd_bench_report_asset(args) -> int:
    print(json.dumps(bench_report_asset(_report_args(args)), indent=2))
    return 0


def register(sub, bench_sub) -> None:
    """Add ``report``, ``sweep`` and ``demo`` to the ``pbrcheck`` parser."""
    s = sub.add_parser("report", help="render, compare and write a static HTML accuracy report")
    s.add_argument("scenes", nargs="*", metavar="SCENE", help="built-in scene names or TOML paths (default: spheres)")
    s.add_argument("--presets", metavar="P,...", help="real-time presets (default: all); PRESET+FILE.glsl adds "
                   "a shader hook file, ext:NAME an external renderer")
    s.add_argument("--shader", action="append", metavar="FILE.glsl",
                   help="also measure the default preset with this shader hook file (repeatable; docs/hooks.md)")
    s.add_argument("--with", dest="also", metavar="R,...",
                   help="further renderers measured after the presets, e.g. ext:threejs,ext:sample-viewer")
    s.add_argument("--out", default="out/report", metavar="DIR", help="output directory (default out/report)")
    s.add_argument("--spp", type=int, default=64, help="least reference samples per pixel (default 64); more "
                   "are rendered until the reference's noise floor is 10x below the smallest error reported")
    s.add_argument("--spp-cap", type=int, default=None, metavar="N",
                   help="most reference samples per pixel (default: as many as render in 15 s per scene); "
                        "at the cap a verdict is flagged noise-limited")
    s.add_argument("--reference-mode", choices=("local", "path"), default="local",
                   help="the reference every renderer is set against (default local: first hit, no shadows; path: "
                        "visibility and interreflection); with path the both-references section's second truth is "
                        "model-matched (random walk and visibility) and gives the share of each engine's error per "
                        "material")
    s.add_argument("--vary", action="append", metavar="KEY=V1,V2",
                   help="sweep these real-time options (repeatable, every combination); default: the main cost "
                        "knobs one at a time")
    s.add_argument("--no-convergence", action="store_true", help="skip the reference convergence study")
    s.add_argument("--no-sweep", action="store_true", help="skip the default sweep over the cost knobs")
    s.add_argument("--no-approximations", action="store_true",
                   help="asset scenes: skip the approximation options against their truths (a path reference)")
    s.add_argument("--no-furnace", action="store_true", help="skip the white furnace per renderer")
    s.add_argument("--hardcases", action="store_true", help="add the hard-case section (pbrcheck hardcases, small)")
    s.add_argument("--research", action="store_true", help="add the LOD fit (before / after), error "
                   "decomposition and apparent-roughness sections for the first scene (a few minutes)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.add_argument("--keep-unmodelled", action="store_true",
                   help="the external engines (--with ext:NAME) get the material extensions pbrcheck does not "
                        "model kept (default: removed; the modelled ones, transmission and the lobes included, "
                        "they always get); their render cache is bypassed")
    s.add_argument("--no-cache", action="store_true",
                   help="render every real-time image and compute every FLIP map (default: reuse a cached "
                        "render whose scene, options, shader and code are unchanged, its timings those measured "
                        "when it was rendered, and a FLIP map whose two images are unchanged)")
    s.add_argument("--scheduler", metavar="SPEC", help=SCHEDULER_HELP + " (default: this process)")
    s.add_argument("--corpus", action="append", metavar="DIR", help="add the section of a finished corpus "
                   "(the --out folder of pbrcheck corpus; repeatable)")
    s.set_defaults(func=_cmd_report)

    s = sub.add_parser("sweep", help="speed against error over real-time option combinations")
    s.add_argument("scene", help="built-in scene name or TOML path")
    s.add_argument("--vary", action="append", metavar="KEY=V1,V2",
                   help="real-time option and its values (repeatable; every combination is rendered)")
    s.add_argument("--approximations", action="store_true",
                   help="asset scenes: sweep the approximation options (specular_aa, msaa, occlusion), "
                        "each against the reference mode that is its truth (local or path)")
    s.add_argument("--lobes", action="store_true",
                   help="also every other real-time form of the lobes the scene's objects carry (clearcoat, sheen, "
                        "...: each member of each lobe family the renderer takes as an option), one at a time")
    s.add_argument("--mode", choices=("local", "path"), default="local",
                   help="reference mode of the --vary rows (default local)")
    s.add_argument("--preset", default="default", help="preset the variations start from")
    s.add_argument("--with", dest="also", metavar="P,...",
                   help="further renderers measured as they are on the same plot (presets or ext:NAME)")
    s.add_argument("--out", default="out/sweep", metavar="DIR")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.add_argument("--scheduler", metavar="SPEC", help=SCHEDULER_HELP + " (default: this process)")
    s.set_defaults(func=_cmd_sweep)


    b = bench_sub.add_parser("report", help="the report's wall time, first run (empty caches) and again, with "
                             "where it went and the goal (JSON)")
    b.add_argument("--keep-home", action="store_true", help="keep HOME (Dr.Jit's kernel cache and Mesa's shader "
                   "cache warm); default: a temporary HOME, as on a fresh machine")
    b.add_argument("report_args", nargs=argparse.REMAINDER, metavar="-- REPORT ARGS",
                   help="arguments of pbrcheck report (default: those of `make report`)")
    b.set_defaults(func=_cmd_bench_report)

    b = bench_sub.add_parser("report-asset", help="the report of a glTF asset scene beside the spheres scene's: "
                             "wall times, their ratio and the goal (JSON)")
    b.add_argument("report_args", nargs=argparse.REMAINDER, metavar="-- REPORT ARGS",
                   help="arguments of pbrcheck report after the scene (default: --presets default --spp 256 "
                        "--no-furnace)")
    b.set_defaults(func=_cmd_bench_report_asset)

    s = sub.add_parser("demo", help="the main job on the default scene (what `make demo` runs)")
    s.add_argument("--scene", default=DEFAULT_SCENE)
    s.add_argument("--out", default="out/demo", help="output directory (default out/demo)")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.set_defaults(func=_cmd_demo)
