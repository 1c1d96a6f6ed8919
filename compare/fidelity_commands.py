"""CLI subcommand ``pbrcheck fidelity CONFIG.json`` (registered by :mod:`pbrcheck_cli`): every RF
scenario through the truth and the chosen renderers (:mod:`compare.fidelity`; docs/fidelity.md).
Library errors propagate; only :mod:`pbrcheck_cli` maps them to exit codes."""

from __future__ import annotations

from pathlib import Path

from pbrcheck.args import add_limit_flags, positive_int, split_list
from pbrcheck.atomic import check_output_path
from pbrcheck.fmt import terminal_safe

from . import renderers
from .corpus.scheduler import SCHEDULER_HELP, parse_scheduler
from .fidelity import FidelitySettings, run_fidelity
from .fidelity_page import write_outputs
from .renderers import RendererSpec
from .serve_bench import DEFAULT_CLIENTS as SERVE_CLIENTS, DEFAULT_SCENES as SERVE_SCENES

#: The external clients run when ``--renderers`` is not given: RF's engines that pbrcheck has.
DEFAULT_CLIENTS = ("threejs", "filament", "babylon", "sample-viewer", "playcanvas", "three-gpu-pathtracer")
#: The real-time presets run when ``--presets`` is not given.
DEFAULT_PRESETS = ("default",)


def renderer_specs(clients: list[str], presets: list[str]) -> tuple[RendererSpec, ...]:
    """External clients (``NAME`` or ``ext:NAME``) then presets, parsed."""
    names = [c if renderers.is_external(c) else f"ext:{c}" for c in clients] + list(presets)
    return tuple(RendererSpec.parse(n) for n in names)


def _cmd_fidelity(args) -> int:
    clients = split_list(args.fidelity_renderers) if args.fidelity_renderers is not None else list(DEFAULT_CLIENTS)
    presets = split_list(args.presets) if args.presets is not None else list(DEFAULT_PRESETS)
    settings = FidelitySettings(renderer_specs(clients, presets), spp=args.spp, seed=args.seed, size=args.size,
                                scenarios=tuple(split_list(args.scenarios)) if args.scenarios else None)
    settings.validate()
    spec = parse_scheduler(args.scheduler, default="serial")
    check_output_path(args.out, folder=True)
    res = run_fidelity(args.config, settings, Path(args.out), scheduler=spec, resume=args.resume,
                       progress=not args.quiet)
    files = write_outputs(res, args.config)
    errors = sum(r["status"] != "ok" for r in res.rows)
    dis = sum(1 for r in res.rows if r.get("disagree"))
    print(f"fidelity: {len(res.scenarios)} scenario(s), {len(res.rows)} row(s), {errors} error row(s), "
          f"{dis} RF/truth disagreement(s), {res.computed} computed now on {spec}, {res.wall_s:.0f} s")
    for k, p in files.items():
        print(f"{k}: {terminal_safe(str(p))}")
    return 0


def _cmd_bench_serve(args) -> int:
    import json

    from .serve_bench import bench_serve

    print(json.dumps(bench_serve(split_list(args.scenes), split_list(args.clients)), indent=2))
    return 0


def register(sub, bench_sub) -> None:
    """Add ``fidelity`` and ``bench serve``."""
    s = sub.add_parser("fidelity", help="every scenario of a Render Fidelity config.json through the truth and "
                                        "every renderer, with RF's own metric beside the truth's (docs/fidelity.md)")
    s.add_argument("config", metavar="CONFIG.json", help="an RF config.json (its scenarios list)")
    s.add_argument("--renderers", dest="fidelity_renderers", metavar="NAME,...",
                   help=f"external clients (renderers.toml names; default {','.join(DEFAULT_CLIENTS)}); "
                        "'' for none")
    s.add_argument("--presets", metavar="P,...",
                   help=f"real-time presets (default {','.join(DEFAULT_PRESETS)}); '' for none")
    s.add_argument("--scenarios", metavar="NAME,...", help="only these scenarios of the config (default: all)")
    s.add_argument("--size", type=positive_int(1), default=None, metavar="N",
                   help="the images' longer side in pixels, the aspect kept (default: each scenario's own)")
    s.add_argument("--spp", type=positive_int(2), default=64, help="the truth's samples per pixel (default 64)")
    s.add_argument("--seed", type=int, default=0, help="the truth's seed (default 0)")
    s.add_argument("--out", default="out/fidelity", metavar="DIR", help="output folder (default out/fidelity)")
    s.add_argument("--scheduler", default="serial", metavar="SPEC", help=SCHEDULER_HELP + " (default serial)")
    s.add_argument("--resume", action="store_true", help="keep the rows already in DIR/rows, compute the rest")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    add_limit_flags(s)
    s.set_defaults(func=_cmd_fidelity)

    b = bench_sub.add_parser("serve", help="the web clients' renders of a small report: one browser per render "
                                           "against one per client for the run (JSON)")
    b.add_argument("--scenes", default=",".join(SERVE_SCENES), metavar="S,...",
                   help=f"scenes (default {','.join(SERVE_SCENES)}: the committed report's)")
    b.add_argument("--clients", default=",".join(SERVE_CLIENTS), metavar="NAME,...",
                   help=f"web clients (default {','.join(SERVE_CLIENTS)}: the committed report's)")
    b.set_defaults(func=_cmd_bench_serve)
