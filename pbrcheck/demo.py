"""``pbrcheck demo`` / ``make demo``: the main job on the default scene."""

from __future__ import annotations

from .environment import load_environment
from .scene import dump_toml, load_scene, scene_hash


def run(args) -> int:
    scene = load_scene(args.scene)
    env = load_environment(scene)
    print(f"pbrcheck demo: scene {scene.name!r}: {scene.description}")
    print(f"  {len(scene.objects)} objects, {len(scene.lights)} point lights, environment "
          f"{env.width}x{env.height}, hash {scene_hash(scene, env.content_hash)[:16]}")
    print(dump_toml(scene.to_dict()), end="")
    return 0
