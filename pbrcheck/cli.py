"""The ``pbrcheck`` command line.

Library code raises :class:`~pbrcheck.errors.PbrcheckError`; this module alone maps errors to exit
codes: 0 success, 1 a check failed (``gate``), 2 bad input (one line on stderr, no traceback,
nothing written), 3 a backend is unavailable, 130 interrupted.

Subcommands of the renderers and the comparator live with them (``reference/commands.py``,
``realtime/commands.py``, ``compare/commands.py``), each with ``register(subparsers)``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys

from . import __version__
from .errors import PbrcheckError

# Packages that contribute subcommands, in help order.
COMMAND_MODULES = ("reference.commands", "realtime.commands", "compare.commands")


def _cmd_scenes(args) -> int:
    from .scene import builtin_scene_names, load_scene

    names = builtin_scene_names()
    width = max(len(n) for n in names)
    for n in names:
        s = load_scene(n)
        mark = " (default)" if n == DEFAULT_SCENE else ""
        print(f"{n:<{width}}  {s.description}{mark}")
    return 0


def _cmd_check_scene(args) -> int:
    from .environment import load_environment
    from .scene import dump_toml, load_scene, scene_hash

    scene = load_scene(args.scene)
    env = load_environment(scene)  # validates the environment's pixels too
    if args.json:
        print(json.dumps(scene.to_dict(), indent=2))
        return 0
    print(f"# {scene.source}: valid")
    print(f"# {len(scene.objects)} object(s), {len(scene.lights)} light(s), environment "
          f"{env.width}x{env.height} (max radiance {env.max_radiance:.4g})")
    print(f"# scene hash {scene_hash(scene, env.content_hash)}")
    print(dump_toml(scene.to_dict()), end="")
    return 0


def _cmd_demo(args) -> int:
    """The main job: grows with the product (see README)."""
    from . import demo

    return demo.run(args)


DEFAULT_SCENE = "spheres"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pbrcheck",
        description="Reference (Mitsuba 3) vs real-time (GLSL split-sum) validation of physically based shading.",
    )
    p.add_argument("--version", action="version", version=f"pbrcheck {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    s = sub.add_parser("scenes", help="list the built-in scenes")
    s.set_defaults(func=_cmd_scenes)

    s = sub.add_parser("check-scene", help="validate a scene and print it resolved")
    s.add_argument("scene", help="built-in scene name or path to a TOML scene file")
    s.add_argument("--json", action="store_true", help="print the resolved scene as JSON")
    s.set_defaults(func=_cmd_check_scene)

    s = sub.add_parser("demo", help="the main job on the default scene (what `make demo` runs)")
    s.add_argument("--scene", default=DEFAULT_SCENE)
    s.add_argument("--out", default="out/demo", help="output directory (default out/demo)")
    s.add_argument("--spp", type=int, default=64, help="reference samples per pixel (default 64)")
    s.set_defaults(func=_cmd_demo)

    bench = sub.add_parser("bench", help="benchmarks that print JSON figures")
    bench_sub = bench.add_subparsers(dest="bench_target", metavar="TARGET")
    bench_sub.required = True
    p.set_defaults(_bench_sub=bench_sub)

    for mod in COMMAND_MODULES:
        importlib.import_module(mod).register(sub, bench_sub)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except PbrcheckError as e:
        print(f"pbrcheck: error: {e}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print("pbrcheck: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
