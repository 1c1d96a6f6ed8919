"""The local estimator's alpha layers on a scene mixing a MASK material with opaque ones: the symbolic
loop (``reference.integrator.ReferenceIntegrator._first_opaque_hit``) against the unrolled layers it
replaced (every lane through all 8 layers, every BSDF called), same process, renders alternated.

``python tools/alpha_layers.py [SIZE] [SPP] [ROUNDS]`` (default 256 64 4) builds, in a temporary
folder, a MASK checker quad (half its texels cut out) in front of an OPAQUE single-sided quad seen
from its culled back, six opaque quads of distinct materials and an analytic sphere, under a sky;
renders its ``local`` reference (SIZE x 3/4 SIZE, SPP, cache off) with each sampler (``independent``
and the default ``qmc``) through both implementations, checks that every channel is bit-identical,
and prints each implementation's wall seconds per render: the first (trace, kernel compile or load)
and the least of the repeats. Wall clock: inflated by other processes' load (the load average is
printed). docs/reference.md has the output.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pbrcheck.gltf_build import Doc  # noqa: E402
from pbrcheck.scene import load_scene  # noqa: E402

QUAD_POS = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
QUAD_UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)


def quad(path: Path, material: dict, texture: np.ndarray | None = None) -> None:
    """A one-quad asset facing +Z (as tests/gltf_build.py's quad_asset), ``texture`` as texture 0."""
    doc = Doc()
    if texture is not None:
        doc.image(texture, {"magFilter": 9728})
    attrs = {"POSITION": doc.accessor(QUAD_POS, "VEC3", minmax=True),
             "NORMAL": doc.accessor(np.array([[0, 0, 1]] * 4, np.float32), "VEC3"),
             "TEXCOORD_0": doc.accessor(QUAD_UV, "VEC2")}
    doc.d["materials"] = [material]
    doc.node(doc.mesh(attrs, doc.accessor(np.array([0, 1, 2, 0, 2, 3], np.uint16), "SCALAR"), 0))
    doc.write(path)


def mixed_scene(d: Path, size: int) -> Path:
    chk = np.zeros((8, 8, 4), np.uint8)
    chk[..., :3] = (200, 120, 60)
    chk[..., 3] = np.where(np.indices((8, 8)).sum(0) % 2 == 0, 255, 0)
    quad(d / "mask.gltf", {"alphaMode": "MASK", "doubleSided": True, "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 0.5}}, chk)
    for k in range(6):
        quad(d / f"opaque{k}.gltf", {"pbrMetallicRoughness": {
            "baseColorFactor": [0.1 + 0.15 * k, 0.5, 0.8 - 0.1 * k, 1.0], "metallicFactor": k / 5,
            "roughnessFactor": 0.2 + 0.1 * k}})

    def g(p, t, r=0.0, s=1.0):
        return f'[[objects]]\ntype = "gltf"\npath = "{p}"\ntranslation = {list(t)}\nrotation = [0.0, {r}, 0.0]\nscale = {s}\n'
    text = (f'[camera]\norigin = [0.0, 0.3, 5.0]\nfov = 50.0\nwidth = {size}\nheight = {size * 3 // 4}\n'
            '[environment]\ntype = "sky"\n'
            '[[lights]]\nposition = [-2.0, 2.0, 3.0]\nintensity = [6.0, 6.0, 6.0]\n'
            + g("mask.gltf", (0.0, 0.0, 0.8), s=0.9) + g("opaque0.gltf", (0.3, 0.0, 0.4), 180.0, 0.5)
            + "".join(g(f"opaque{k}.gltf", ((k % 3) - 1.0, (k // 3) - 0.5, -1.0 - 0.2 * k), 25.0 * (k - 2.5), 0.6)
                      for k in range(1, 6))
            + '[[objects]]\ntype = "sphere"\ncenter = [1.6, -0.6, 0.3]\nradius = 0.4\n')
    (d / "mixed.toml").write_text(text)
    return d / "mixed.toml"


def unrolled(self, scene, sampler, ray, si, hit):
    """The layers before the symbolic loop: the bit-identity reference of tests/test_gltf.py too."""
    import drjit as dr
    import mitsuba as mi

    from reference.bsdf import SceneCalls
    from reference.integrator import LOCAL_RAY_FLAGS
    going = mi.Bool(hit)
    for _ in range(self.MAX_NULL_LAYERS):
        t = mi.Float(SceneCalls(self._dispatch(scene), si, going).eval_null_transmission(si, going).x)
        u = sampler.next_1d(going)
        through = going & (u < t)
        going = through
        ray = dr.select(through, si.spawn_ray(ray.d), ray)
        si2 = scene.ray_intersect(ray, LOCAL_RAY_FLAGS, mi.Bool(True), through)
        si = dr.select(through, si2, si)
        hit = dr.select(through, si2.is_valid(), hit)
        going &= hit
    return si, hit


def main(argv: list[str]) -> int:
    size, spp, rounds = (int(a) for a in (argv + ["256", "64", "4"][len(argv):])[:3])
    from reference.variant import ensure_variant
    ensure_variant()
    from reference.integrator import ReferenceIntegrator
    from reference.render import render_reference
    loop = ReferenceIntegrator._first_opaque_hit
    impls = {"unrolled": unrolled, "loop": loop}
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        scene = load_scene(mixed_scene(Path(tmp), size))
        for sampler in ("independent", "qmc"):
            walls: dict = {k: [] for k in impls}
            images = {}
            for _ in range(rounds):
                for name, fn in impls.items():
                    ReferenceIntegrator._first_opaque_hit = fn
                    t0 = time.perf_counter()
                    images[name] = render_reference(scene, spp=spp, use_cache=False, progress=False,
                                                    sampler=sampler)
                    walls[name].append(time.perf_counter() - t0)
            ReferenceIntegrator._first_opaque_hit = loop
            same = all(np.array_equal(images["loop"].channels[c], images["unrolled"].channels[c], equal_nan=True)
                       for c in images["loop"].channels)
            failed += not same
            print(f"{sampler}: {'bit-identical' if same else 'DIFFERENT'}; " + "; ".join(
                f"{k} first {w[0]:.3f} s, least of {len(w) - 1} repeats {min(w[1:]):.3f} s"
                for k, w in walls.items() if len(w) > 1) + f" ({size}x{size * 3 // 4}, {spp} spp, local)")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
