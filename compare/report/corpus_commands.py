"""CLI subcommands of corpus studies (registered by :mod:`pbrcheck_cli`): ``corpus`` and
``bench corpus``. They live in the report layer because ``corpus`` writes the report page of the
corpus (:mod:`compare.report.corpus_section`). Library errors propagate; only :mod:`pbrcheck_cli`
maps them to exit codes."""

from __future__ import annotations

import json
from pathlib import Path

from pbrcheck.args import positive_int, split_list
from pbrcheck.atomic import check_output_path
from pbrcheck.gltf_objects import asset_options_of
from pbrcheck.scene import DEFAULT_SCENE, load_scene
from realtime.presets import parse_sets

from .. import renderers
from ..corpus.bench import run_bench
from ..corpus.scheduler import SCHEDULER_HELP, parse_scheduler
from ..corpus.study import CorpusSettings, run_corpus
from ..renderers import RendererSpec
from .corpus_section import write_corpus_page


def _cmd_corpus(args) -> int:
    scene = load_scene(args.scene, asset_options_of(args))
    names = split_list(args.presets) or renderers.preset_names()
    options = parse_sets(args.set)
    # --set is for the real-time presets; external renderers take their options from renderers.toml.
    settings = CorpusSettings(scene, tuple(RendererSpec.parse(n, None if renderers.is_external(n) else options)
                                           for n in names), spp=args.spp,
                              seed=args.seed, rank_metric=args.rank_metric)
    spec = parse_scheduler(args.scheduler, default="local")
    check_output_path(args.out, folder=True)  # before any render
    res = run_corpus(args.corpus, settings, Path(args.out), scheduler=spec, resume=args.resume,
                     progress=not args.quiet)
    page = write_corpus_page(res)
    errors = sum(r["status"] != "ok" for r in res.rows)
    print(f"corpus: {len(res.rows)} row(s), {errors} error row(s), {res.computed} computed now "
          f"({res.tasks} task(s) on {spec})")
    for k, p in {**res.files, "html": page}.items():
        print(f"{k}: {p}")
    return 0


def _cmd_bench_corpus(args) -> int:
    print(json.dumps(run_bench(envs=args.envs, presets=tuple(split_list(args.presets)), spp=args.spp,
                               workers=args.workers), indent=2))
    return 0


def register(sub, bench_sub) -> None:
    """Add ``corpus`` and ``bench corpus`` to the ``pbrcheck`` parser."""
    s = sub.add_parser("corpus", help="every renderer against the reference under every environment of a corpus "
                                      "(serially or on Dask): corpus.csv, corpus.json, plots, index.html")
    s.add_argument("corpus", metavar="DIR_OR_LIST", help="folder of .exr/.hdr environments (searched recursively) "
                   "or a text file listing them, one path a line")
    s.add_argument("--scene", default=DEFAULT_SCENE, help=f"scene lit by each environment (default {DEFAULT_SCENE})")
    s.add_argument("--presets", metavar="P,...", help="renderers under test: real-time presets or ext:NAME "
                   "(default: every preset)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="option override for every renderer (repeatable)")
    s.add_argument("--spp", type=positive_int(2), default=64, help="reference samples per pixel (default 64)")
    s.add_argument("--seed", type=int, default=0, help="reference seed (default 0)")
    s.add_argument("--out", default="out/corpus", metavar="DIR", help="output folder (default out/corpus)")
    s.add_argument("--scheduler", default="local", metavar="SPEC", help=SCHEDULER_HELP + " (default local)")
    s.add_argument("--resume", action="store_true", help="keep the rows already in DIR/rows and compute only "
                   "the missing ones")
    s.add_argument("--rank-metric", default="relmse", metavar="METRIC",
                   help="metric that ranks the worst environments (default relmse)")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_corpus)

    b = bench_sub.add_parser("corpus", help="a generated corpus serially and on local:N: wall times and Dask's "
                                            "overhead per task (JSON)")
    b.add_argument("--envs", type=positive_int(1), default=6, help="generated environments (default 6)")
    b.add_argument("--presets", default="default,runtime_is20", metavar="P,...",
                   help="renderers (default default,runtime_is20)")
    b.add_argument("--spp", type=positive_int(2), default=16, help="reference samples per pixel (default 16)")
    b.add_argument("--workers", type=positive_int(1), default=2, help="LocalCluster worker processes (default 2)")
    b.set_defaults(func=_cmd_bench_corpus)
