"""``pbrcheck demo`` / ``make demo``: the main job on the default scene.

Validates and summarizes the scene, then renders the Mitsuba reference (cached) and every real-time
preset, compares them, and writes the static HTML accuracy report to ``--out`` (default
``out/demo/index.html``).
"""

from __future__ import annotations

from pathlib import Path

from pbrcheck.environment import load_environment, scene_hash
from pbrcheck.gltf_objects import asset_options_of
from pbrcheck.scene import load_scene

from .build import ReportConfig, build_report


def run(args) -> int:
    """Summarize the scene, build the report to ``args.out``; returns 0."""
    scene = load_scene(args.scene, asset_options_of(args))
    env = load_environment(scene)
    print(f"pbrcheck demo: scene {scene.name!r}: {scene.description}")
    print(f"  {len(scene.objects)} objects, {len(scene.lights)} lights, environment "
          f"{env.width}x{env.height} (max radiance {env.max_radiance:.4g}), "
          f"hash {scene_hash(scene, env.content_hash)[:16]}")
    out = build_report([args.scene], Path(args.out), ReportConfig(spp=args.spp, assets=asset_options_of(args)))
    print(f"pbrcheck demo: report written to {out}")
    return 0
