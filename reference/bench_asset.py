"""``pbrcheck bench reference``'s asset row: a textured glTF asset of ~50k triangles against the spheres
scene, same camera, environment, size and spp.

The asset is made here (a fresh clone has no shared assets): a UV sphere of :data:`ASSET_SEGMENTS`
segments and half as many rings (~50k triangles, normals, tangents, UVs) with
:data:`ASSET_TEXTURE_SIZE`-square base-colour, metallic-roughness and normal PNG textures (a
checker, a gradient, a bumpy normal map), written to a temporary ``.glb``-free ``.gltf`` with data
URIs (:class:`pbrcheck.gltf_build.Doc`), lit by the spheres scene's own environment (every field, the
same ``EnvMap``) and lights. Both rows, the asset and ``spheres``, are rendered in this one run, alternately (so that the
machine's load, ``machine_load`` before and after, hits both alike), ``local``, same spp and
sampler (:data:`BENCH_SAMPLER`), after a compile render each, median of repeats. Figures:
``load_seconds`` (:func:`pbrcheck.gltf.load_asset`: parse, decode, tangents) and ``build_seconds``
(the Mitsuba scene: meshes, textures, BVH), apart from the render; ``msamples_per_s`` and
``spheres_msamples_per_s`` (render seconds: ``mi.render`` alone) and ``vs_spheres`` = their ratio
(goal >= :data:`ASSET_THROUGHPUT_GOAL`), ``vs_spheres_cpu_seconds`` the same from the process's CPU
seconds; ``vs_spheres_per_covered_pixel`` divides each render's time by the fraction of pixels that
see geometry (the asset covers more of the image than the spheres); ``kernel_ops`` and
``spheres_kernel_ops``: operations of each render's largest kernel (Dr.Jit's kernel history:
load-independent).

API: :func:`make_asset`, :func:`asset_scene`, :func:`bench_asset`, :data:`ASSET_THROUGHPUT_GOAL`, :data:`BENCH_SAMPLER`.
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pbrcheck.environment import load_environment
from pbrcheck.gltf import load_asset
from pbrcheck.gltf_build import Doc
from pbrcheck.scene import scene_from_dict

#: Segments around the bench sphere (rings: half): 2 x 224 x 112 = 50176 triangles, less the poles'.
ASSET_SEGMENTS = 224
ASSET_TEXTURE_SIZE = 1024
#: The same under ``--quick`` (tests).
ASSET_SEGMENTS_QUICK, ASSET_TEXTURE_QUICK = 64, 128
#: The asset's local samples/s over the spheres scene's (the issue's goal).
ASSET_THROUGHPUT_GOAL = 0.7
#: Both rows' sampler: the spheres row's (``local_msamples_per_s``).
BENCH_SAMPLER = "independent"


def make_asset(path: Path, segments: int = ASSET_SEGMENTS, tex: int = ASSET_TEXTURE_SIZE,
               normal_map: np.ndarray | None = None) -> Path:
    """Write the bench asset (module docstring) to ``path`` (.gltf); returns it. ``normal_map``
    (uint8 (h, w, 3), tangent space): replaces the bumpy normal map (tools/approximation_errors.py)."""
    rings = segments // 2
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    pos = np.stack([np.sin(T) * np.sin(P), np.cos(T), np.sin(T) * np.cos(P)], -1).reshape(-1, 3)
    uv = np.stack([P / (2 * np.pi), T / np.pi], -1).reshape(-1, 2)
    tan = np.stack([np.cos(P), np.zeros_like(P), -np.sin(P), np.ones_like(P)], -1).reshape(-1, 4)
    idx = []
    for r in range(rings):
        for s in range(segments):
            a, b = r * (segments + 1) + s, (r + 1) * (segments + 1) + s
            idx += [[a, b, a + 1], [a + 1, b, b + 1]]
    idx = np.asarray(idx, np.uint32)
    y, x = np.mgrid[0:tex, 0:tex] / tex
    checker = ((np.floor(x * 16) + np.floor(y * 16)) % 2)[..., None]
    bc = (np.where(checker > 0, [200, 60, 40], [230, 220, 200])).astype(np.uint8)
    mr = np.stack([np.zeros_like(x), 40 + 200 * x, (y > 0.5) * 255.0], -1).astype(np.uint8)
    bump = np.sin(x * 2 * np.pi * 32) * 0.4
    n = np.stack([bump, np.zeros_like(bump), np.ones_like(bump)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    nm = ((n * 0.5 + 0.5) * 255).astype(np.uint8) if normal_map is None else normal_map
    doc = Doc()
    textures = [doc.image(px) for px in (bc, mr, nm)]
    attrs = {"POSITION": doc.accessor(pos.astype(np.float32), "VEC3", minmax=True),
             "NORMAL": doc.accessor(pos.astype(np.float32), "VEC3"),
             "TANGENT": doc.accessor(tan.astype(np.float32), "VEC4"),
             "TEXCOORD_0": doc.accessor(uv.astype(np.float32), "VEC2")}
    doc.d["materials"] = [{"name": "textured", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": textures[0]}, "metallicRoughnessTexture": {"index": textures[1]}},
        "normalTexture": {"index": textures[2]}}]
    m = doc.mesh(attrs, doc.accessor(idx.reshape(-1), "SCALAR"), 0)
    doc.d["meshes"][m]["name"] = "sphere"
    doc.node(m, name="bench")
    return doc.write(path)


def asset_scene(spheres_scene, path: Path):
    """The bench asset at ``path`` (:func:`make_asset`) as a scene: ``spheres_scene``'s camera fov and
    size (the asset filling the image's centre, 3.2 units away), its environment (every field: a
    sky's sun, raster size) and its lights; the asset's own name ``bench-asset``."""
    cam = spheres_scene.camera
    data = {"name": "bench-asset", "objects": [{"type": "gltf", "path": str(path)}],
            "camera": {"origin": [0.0, 0.0, 3.2], "target": [0.0, 0.0, 0.0], "fov": cam.fov,
                       "width": cam.width, "height": cam.height},
            "environment": {"type": "constant", "radiance": [1.0, 1.0, 1.0]}}
    return replace(scene_from_dict(data, file=str(path), base_dir=Path(path).parent),
                   environment=spheres_scene.environment, lights=spheres_scene.own_lights())


def _largest_kernel_ops(dr, fn) -> int | None:
    """Operations of the largest kernel ``fn`` launches (Dr.Jit's kernel history; load-independent)."""
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history()
        fn()
        ops = [h.get("operation_count") or 0 for h in dr.kernel_history()]
    return max(ops) if ops else None


def bench_asset(spheres_scene, spp: int, repeats: int, quick: bool = False) -> dict:
    """The asset row (module docstring): the asset and ``spheres_scene`` rendered alternately in one
    run (same load, same sampler, same spp)."""
    from .render import _mi, load_mitsuba_scene, render_uncached

    mi, dr = _mi()
    with tempfile.TemporaryDirectory(prefix="pbrcheck-bench-asset-") as tmp:
        path = make_asset(Path(tmp) / "bench.gltf", segments=ASSET_SEGMENTS_QUICK if quick else ASSET_SEGMENTS,
                          tex=ASSET_TEXTURE_QUICK if quick else ASSET_TEXTURE_SIZE)
        t0 = time.perf_counter()
        asset = load_asset(path)
        load_s = time.perf_counter() - t0
        cam = spheres_scene.camera
        scene = asset_scene(spheres_scene, path)
        envmap = load_environment(spheres_scene)
        t0 = time.perf_counter()
        mscene = load_mitsuba_scene(scene, envmap)
        build_s = time.perf_counter() - t0
        smscene = load_mitsuba_scene(spheres_scene, envmap)
        rows = {"asset": (scene, envmap, mscene), "spheres": (spheres_scene, envmap, smscene)}

        def render(name, seed):
            sc, e, ms = rows[name]
            return render_uncached(sc, spp=spp, progress=False, env=e, mscene=ms, seed=seed, sampler=BENCH_SAMPLER)

        ops = {name: _largest_kernel_ops(dr, lambda: render(name, 0)) for name in rows}  # compiles
        runs = {name: [] for name in rows}
        load0 = _load()
        for k in range(repeats):
            for name in rows:  # alternating: other processes' load hits both alike
                img = render(name, k + 1)
                runs[name].append((float(img.meta["render_seconds"]), float(img.meta["render_cpu_seconds"]),
                                   float((img.channels["coverage"] > 0).mean())))
        load1 = _load()
    med = {name: [statistics.median(r[i] for r in runs[name]) for i in range(3)] for name in rows}
    (t_a, c_a, cov_a), (t_s, c_s, cov_s) = med["asset"], med["spheres"]
    samples = cam.width * cam.height * spp
    return {"triangles": asset.triangles, "texture_size": ASSET_TEXTURE_QUICK if quick else ASSET_TEXTURE_SIZE,
            "load_seconds": load_s, "build_seconds": build_s,
            "render_seconds": t_a, "render_cpu_seconds": c_a,
            "spheres_render_seconds": t_s, "spheres_render_cpu_seconds": c_s,
            "msamples_per_s": samples / t_a / 1e6, "spheres_msamples_per_s": samples / t_s / 1e6,
            "vs_spheres": t_s / t_a, "vs_spheres_cpu_seconds": c_s / c_a,
            "vs_spheres_goal": ASSET_THROUGHPUT_GOAL, "goal_met": t_s / t_a >= ASSET_THROUGHPUT_GOAL,
            "coverage": cov_a, "spheres_coverage": cov_s,
            "vs_spheres_per_covered_pixel": (t_s / cov_s) / (t_a / cov_a),
            "kernel_ops": ops["asset"], "spheres_kernel_ops": ops["spheres"],
            "machine_load": [load0, load1], "repeats": repeats, "sampler": BENCH_SAMPLER,
            "timed": "both rows rendered alternately in this run after a compile render each, median of "
                     "repeats; render seconds: mi.render alone (no scene load, no AOV pass); CPU seconds: "
                     "this process's threads over the render",
            "note": "same camera fov, size, environment (spheres' own, every field), lights, spp and sampler as spheres; the sphere asset fills "
                    "the image's centre (its frame: 3.2 units away); load_seconds (parse, decode, tangents) "
                    "and build_seconds (Mitsuba scene: meshes, textures, BVH) are apart from the render"}


def _load() -> float | None:
    """The machine's 1-minute load average (None where the platform has none)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        return None
