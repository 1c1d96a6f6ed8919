"""CLI subcommands of the comparator (registered by :mod:`pbrcheck_cli`): ``compare`` and ``gate``.
Library errors propagate; only :mod:`pbrcheck_cli` maps them to exit codes."""

from __future__ import annotations

import tempfile
from pathlib import Path

from pbrcheck.atomic import check_output_path
from pbrcheck.errors import ImageIOError
from pbrcheck.exr import exr_size, read_exr, write_exr
from pbrcheck.fmt import format_value
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.gltf_objects import asset_options_of
from pbrcheck.scene import load_scene

from . import renderers
from .gate import BudgetError, run_gate
from .maps import write_maps
from .metrics import compare_images
from .probe import probe_markdown, run_probe


#: The largest image ``compare`` reads (pixels): a comparison holds ~400 bytes per pixel at its peak
#: (the maps of every metric, FLIP and Delta E_ITP; 566 MB peak RSS for 1000 x 1000, 170 MB of it
#: the imports), so 2048 x 2048 stays under 2 GB. Larger images are refused before their pixels are
#: read; ``--max-pixels`` raises the limit knowingly.
MAX_COMPARE_PIXELS = 2048 * 2048


#: ``compare``'s line on the colour space of the comparison (compare.metrics' ``summary["space"]``).
SPACE_TEXT = {"linear": "linear (scene-referred radiance)",
              "display-referred": "display-referred (an 8-bit png-srgb image: both images clamped to [0, 1] and "
                                  "sRGB-encoded, no noise floor)"}
#: Why ``compare``'s relmse differs from ``diagnose``'s for the same pair.
RAW_NOTE = ("not noise-corrected but for a test's own variance; pbrcheck diagnose's relmse is over all pixels, "
            "background included, less the noise")


def _check_size(path: str, limit: int) -> None:
    w, h = exr_size(path)
    if w * h > limit:
        raise ImageIOError(path, f"{w}x{h} = {w * h:,} pixels is above compare's limit of "
                                 f"{limit:,} (~{w * h * 400 / 1e9:.1f} GB of memory needed; "
                                 "raise it with --max-pixels, or crop or scale the images)")


def _cmd_compare(args) -> int:
    # Everything is read and validated before anything is written; the output paths are checked
    # and the images' sizes read from their headers before any pixel is read.
    for out, folder in ((args.json, False), (args.maps, True)):
        if out:
            check_output_path(out, folder=folder)
    scene = None
    if args.scene:
        scene = load_scene(args.scene, asset_options_of(args))
    for p in (args.reference, args.test):
        _check_size(p, args.max_pixels)
    ref = read_exr(args.reference)
    test = read_exr(args.test)
    cmp = compare_images(ref, test, scene=scene, ref_name=args.reference, test_name=args.test)
    summary = {"reference": str(args.reference), "test": str(args.test), **cmp.summary}
    if args.maps:
        summary["maps"] = {k: str(p) for k, p in write_maps(Path(args.maps), cmp).items()}
    if args.json:
        write_json_atomic(args.json, summary)
    px = cmp.summary["pixels"]
    noise = cmp.summary["noise"]
    print(f"colour space: {SPACE_TEXT[cmp.summary['space']]}")
    print(f"pixels: {px['valid']} valid, {px['edge']} edge, {px['background']} background "
          f"(the metrics: over the valid pixels, {RAW_NOTE})")
    for k, v in cmp.metrics.items():
        flag = ""
        if noise is not None and noise["within_noise"].get(k):
            flag = "  (within reference noise)"
        print(f"{k:<18} {format_value(v)}{flag}")
    if noise is not None:
        print(f"noise floor (mean variance) {format_value(noise['mean_variance'])}, "
              f"noise-corrected MSE {format_value(noise['mse_corrected'])}")
    tn = cmp.summary.get("test_noise")
    if tn is not None:
        print(f"the test's own noise ({test.meta.get('engine_variance', 'its variance channels')}): mean variance "
              f"{format_value(tn['mean_variance'])}, relmse {format_value(tn['relmse'])}, subtracted from "
              f"{', '.join(tn['corrected'])} (raw relmse {format_value(tn['metrics_raw']['relmse'])})")
    return 0


def _cmd_probe(args) -> int:
    if args.out:
        check_output_path(args.out, folder=True)
    with tempfile.TemporaryDirectory(prefix="pbrcheck-probe-") as tmp:
        res, img, ref = run_probe(renderers.RendererSpec.parse(args.renderer), Path(tmp), spp=args.spp)
    print(probe_markdown(res), end="")
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        write_exr(out / "engine.exr", img)
        write_exr(out / "reference.exr", ref)
        write_json_atomic(out / "probe.json", res.to_json())
        print(f"probe: {out}/engine.exr, reference.exr, probe.json")
    return 0


def _cmd_gate(args) -> int:
    if args.accept and not (args.reason or "").strip():
        raise BudgetError(f"{args.budget}: --accept needs --reason \"...\" (it goes into the budget's history)")
    if args.reason is not None and not args.accept:
        raise BudgetError(f"{args.budget}: --reason only together with --accept")
    return run_gate(args.budget, junit=args.junit, summary=args.summary, maps_dir=args.maps, html=args.html,
                    accept_reason=args.reason if args.accept else None, progress=not args.quiet,
                    only=args.checks)


def register(sub, bench_sub) -> None:
    """Add ``compare`` and ``gate`` to the ``pbrcheck`` parser."""
    s = sub.add_parser("compare", help="compare a test EXR against a reference EXR (metrics, error maps)")
    s.add_argument("reference", help="reference EXR")
    s.add_argument("test", help="test EXR")
    s.add_argument("--json", metavar="FILE", help="write every metric, per object and per NdotV bin, as JSON")
    s.add_argument("--maps", metavar="DIR", help="write rel_error.png, flip.png and diff.exr into DIR")
    s.add_argument("--scene", metavar="SCENE", help="scene the images show: names objects and their materials")
    s.add_argument("--max-pixels", type=int, default=MAX_COMPARE_PIXELS, metavar="N",
                   help=f"refuse images above N pixels before reading them (default {MAX_COMPARE_PIXELS}: "
                        "about 400 bytes of memory per pixel)")
    s.set_defaults(func=_cmd_compare)

    s = sub.add_parser("probe", help="an engine's environment orientation, exposure and colour space from one "
                       "render of the probe scene (docs/renderers.md)")
    s.add_argument("renderer", help="ext:NAME (renderers.toml) or a real-time preset")
    s.add_argument("--spp", type=int, default=16, help="reference samples per pixel (default 16)")
    s.add_argument("--out", metavar="DIR", help="also write engine.exr, reference.exr and probe.json into DIR")
    s.set_defaults(func=_cmd_probe)

    s = sub.add_parser("gate", help="CI error budget: exit 1 when a metric exceeds its budget")
    s.add_argument("budget", help="budget TOML file")
    s.add_argument("--junit", metavar="FILE", help="write JUnit XML")
    s.add_argument("--summary", metavar="FILE.md", help="write a Markdown summary")
    s.add_argument("--maps", metavar="DIR", default="out/gate",
                   help="error maps of checks that are not pass go to DIR/<check> (default out/gate)")
    s.add_argument("--html", metavar="DIR", help="write DIR/index.html: a baseline / current slider for every "
                   "check that is not pass")
    s.add_argument("--accept", action="store_true", help="accept the current renders as the baselines "
                   "(baselines/ beside the budget; needs --reason)")
    s.add_argument("--reason", metavar="TEXT", help="why the baselines change (appended to the budget's [[history]])")
    s.add_argument("--check", metavar="NAME", action="append", dest="checks",
                   help="run only this check (repeatable); with --accept only its baseline is rewritten")
    s.add_argument("--quiet", action="store_true", help="no progress output")
    s.set_defaults(func=_cmd_gate)
