"""Render the cross product of the real-time renderer's choice and bool options once.

``python tools/option_cross_product.py [--budget SECONDS] [--seed S]`` counts the full cross product
of every choice and bool option of :data:`realtime.presets.OPTIONS` (and ``msaa``'s legal values, 1,
2, 4, 8: an int option with requirements) on the default preset, accepted and refused by
:func:`realtime.presets.resolve_options`, reduces it to the distinct shader programs each pipeline
compiles, renders them at 16 x 16 and reports any combination that neither renders with finite
pixels nor is refused with a one-line OptionError. Exit status 1 if there is one. Progress lines
every 250 programs; each stage's programs run in a random order (``--seed``, default 0), so a stage
stopped by ``--budget`` (seconds for the last stage, the remainder) or by Ctrl-C (which ends the
stage and reports it) has rendered a uniform sample.

Counting: only the options that take part in a requirement (registry members' and options'
``requires``, and resolve_options' raster/shadows check: :func:`coupled`) are enumerated through
resolve_options; the other options multiply the accepted count by their number of values.

Distinct programs: a program is keyed by the ``#define``s its assembled source names
(:func:`read_defines`: a macro the source never names cannot change the program, so e.g. the
raster-only SPECULAR_AA, TEXTURE_LOD0, NORMAL_LOD0 do not split ray-cast programs). Stages:

1. ``raster``: on :func:`mask_panel_scene` (a tiny normal-mapped, textured panel with an occlusion
   texture and a MASK material; pipeline=raster), the full product of the raster options
   (:data:`RASTER_READS` and ``alpha_to_coverage``, ``msaa`` and ``occlusion_texture``, these two
   host state rather than defines: each program renders with one state, drawn with a fixed seed,
   among the msaa values the GL supports; one msaa above GL_MAX_SAMPLES must be a one-line
   BackendError) for every accepted (shading, ibl,
   energy_compensation) triple with the preset's terms, LUT, irradiance and LOD mapping. The
   reduction is sound because those composition-side defines are read only inside shade()
   (shading.glsl and its includes, identical in both pipelines: stages 2 and 3 render them), while
   SPECULAR_AA, TEXTURE_LOD0, NORMAL_LOD0 and ALPHA_TO_COVERAGE act in raster.frag on the Surface
   before shade() is called; SPECULAR_OCCLUSION and HORIZON_OCCLUSION are a scalar factor in the
   material composition's split-sum branch, beside the energy compensation (so crossed with it here).
2. ``raycast``: on the 16 x 16 furnace (pipeline=raycast), every accepted triple x the specular and
   horizon occlusion, plus the bake passes' variants (:data:`BAKES`).
3. ``remainder``: every other distinct ray-cast frame program (:data:`FRAME_READS`: the terms,
   irradiance, DFG, LOD mapping, shadows, runtime sampling switches of each composition), within
   ``--budget`` seconds.
"""

from __future__ import annotations

import itertools
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 16, "lut_size": 8, "lut_samples": 16, "runtime_samples": 4, "supersample": 1}
TERMS = ("ndf", "geometry", "fresnel")
#: Options of the occlusion of the split-sum specular (read in shade_material).
OCCLUSION = ("specular_occlusion", "horizon_occlusion")
#: The frame-pass switches each (shading, ibl) reads besides the energy compensation (ray-cast).
FRAME_READS = {
    ("material", "splitsum"): (*TERMS, "irradiance", "dfg", "lod_mapping", "shadows", *OCCLUSION),
    ("material", "runtime"): (*TERMS, "irradiance", "shadows", "runtime_sampling", "runtime_lod", "runtime_rotate",
                              *OCCLUSION),
    ("article000", "splitsum"): ("irradiance", "dfg", "lod_mapping", "shadows"),
    ("article001", "runtime"): (*TERMS, "irradiance", "shadows", "runtime_sampling", "runtime_lod", "runtime_rotate"),
    ("article002", "splitsum"): ("irradiance", "dfg", "lod_mapping", "shadows", "reflect_bug"),
}
#: The raster stage's product: define-bearing options (with alpha_to_coverage).
RASTER_READS = (*OCCLUSION, "specular_aa", "texture_sampling", "normal_sampling", "alpha_to_coverage")
#: Host state of the raster pass (no define): one drawn per raster program.
RASTER_STATE = ("msaa", "occlusion_texture")
#: The bake passes' own options, crossed with each other (on shading=material, ibl=splitsum).
BAKES = (("lut_geometry", "ndf", "lut_sampling", "lut_format"),
         ("prefilter_filtered", "prefilter_nl_weight", "lod_mapping", "cube_format"),
         ("irradiance", "irradiance_method", "cube_format"))
#: msaa's legal values (power of two in [1, 8]).
MSAA = (1, 2, 4, 8)


def switches() -> dict:
    from realtime.presets import OPTIONS
    sw = {n: (o.choices if o.kind == "choice" else (False, True))
          for n, o in OPTIONS.items() if o.kind in ("choice", "bool")}
    return {**sw, "msaa": MSAA}


def coupled(sw: dict) -> tuple[str, ...]:
    """The options that take part in a requirement: enumerated through resolve_options."""
    from realtime.presets import OPTION_REGISTRIES, OPTIONS
    names = {"pipeline", "shadows"}  # resolve_options: the raster pipeline has no shadow rays
    for name, reg in OPTION_REGISTRIES.items():
        for e in reg:
            if e.requires:
                names |= {name, *e.requires}
    for name, opt in OPTIONS.items():
        if opt.requires:
            names |= {name, *opt.requires}
    return tuple(n for n in sw if n in names)


def full_count(sw: dict) -> tuple[int, int]:
    """(combinations, accepted) of the full cross product of ``sw`` on the default preset."""
    from realtime.presets import OptionError, resolve_options
    cp = coupled(sw)
    accepted = 0
    for values in itertools.product(*(sw[n] for n in cp)):
        try:
            resolve_options("default", {**SMALL, **dict(zip(cp, values))})
            accepted += 1
        except OptionError:
            pass
    rest = math.prod(len(v) for n, v in sw.items() if n not in cp)
    return math.prod(len(v) for v in sw.values()), accepted * rest


_READ: dict = {}


def read_defines(entry: str, defines: dict) -> tuple:
    """``defines`` restricted to the macros ``entry``'s assembled source names, as a sorted key."""
    import re

    from realtime.gl import assemble
    if entry not in _READ:
        _READ[entry] = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", assemble(entry).text))
    return tuple(sorted((k, v) for k, v in defines.items() if k.split("(")[0] in _READ[entry]))


def mask_panel_scene(directory: Path):
    """A 16 x 16 scene of a tiny panel (:func:`pbrcheck.gltf_build.panel_asset`: normal map, base
    colour, occlusion / roughness / metallic textures) with a MASK material, under a constant sky."""
    from pbrcheck.gltf_build import panel_asset
    from pbrcheck.scene import load_scene
    panel_asset(directory / "panel.gltf", segments=8, tex=16, alpha_mode="MASK", alpha=0.6)
    (directory / "scene.toml").write_text(
        'name = "mask_panel"\n[camera]\norigin = [0.0, 0.35, 3.1]\ntarget = [0.0, 0.0, 0.45]\nfov = 44.0\n'
        'width = 16\nheight = 16\n[environment]\ntype = "constant"\nradiance = [0.8, 0.9, 1.0]\n'
        '[[lights]]\ntype = "point"\nposition = [-2.0, 2.0, 3.0]\nintensity = [6.0, 6.0, 6.0]\n'
        '[[objects]]\ntype = "gltf"\npath = "panel.gltf"\n')
    return load_scene(directory / "scene.toml")


def _triples(sw: dict, pipeline: str):
    """The accepted (shading, ibl, energy_compensation) overrides."""
    from realtime.presets import OptionError, resolve_options
    for triple in itertools.product(sw["shading"], sw["ibl"], sw["energy_compensation"]):
        over = dict(zip(("shading", "ibl", "energy_compensation"), triple))
        try:
            resolve_options("default", {**SMALL, **over, "pipeline": pipeline})
        except OptionError:
            continue
        yield over


def _distinct(scene, entry: str, candidates, extra=lambda o: {}):
    """The candidates (overrides) whose program (keyed by :func:`read_defines`) is new."""
    from realtime.presets import OptionError, resolve_options
    from realtime.render import frame_defines, resolved_energy_compensation, resolved_terms
    seen = set()
    for over in candidates:
        try:
            o = resolve_options("default", {**SMALL, **over})
        except OptionError:
            continue
        terms = {**resolved_terms(scene, o), "energy_compensation": resolved_energy_compensation(scene, o)}
        key = read_defines(entry, {**frame_defines(o, terms), **extra(o)})
        if key not in seen:
            seen.add(key)
            yield over


def raster_stage(sw: dict, scene, max_samples: int) -> list[dict]:
    """The raster stage's programs, each with a drawn (msaa, occlusion_texture) state among the msaa
    values this GL supports (``max_samples``: GL_MAX_SAMPLES; llvmpipe has 4, and msaa = 8 is
    refused there with a one-line BackendError, exit 3, checked once by :func:`main`)."""
    cands = ({**t, "pipeline": "raster", **dict(zip(RASTER_READS, v)), "msaa": 2}
             for t in _triples(sw, "raster") for v in itertools.product(*(sw[n] for n in RASTER_READS)))
    out = list(_distinct(scene, "raster.frag", cands, lambda o: {"ALPHA_TO_COVERAGE": int(o.alpha_to_coverage)}))
    msaa = [m for m in MSAA if m <= max_samples]
    a2c_states = list(itertools.product(msaa[1:], (False, True)))
    states = list(itertools.product(msaa, (False, True)))
    pick = np.random.default_rng(0)  # each program one (msaa, occlusion_texture) state, drawn
    for over in out:
        cyc = a2c_states if over["alpha_to_coverage"] else states
        over.update(zip(RASTER_STATE, cyc[pick.integers(len(cyc))]))
    return out


def raycast_stage(sw: dict, scene) -> list[dict]:
    cands = ({**t, "pipeline": "raycast", **dict(zip(OCCLUSION, v))}
             for t in _triples(sw, "raycast") for v in itertools.product(*(sw[n] for n in OCCLUSION)))
    out = list(_distinct(scene, "render.comp", cands))
    for names in BAKES:
        out += [{"pipeline": "raycast", **dict(zip(names, v))} for v in itertools.product(*(sw[n] for n in names))]
    return out


def remainder_stage(sw: dict, scene) -> list[dict]:
    def cands():
        for t in _triples(sw, "raycast"):
            for v in itertools.product(*(sw[n] for n in FRAME_READS[(t["shading"], t["ibl"])])):
                yield {**t, "pipeline": "raycast", **dict(zip(FRAME_READS[(t["shading"], t["ibl"])], v))}
    return list(_distinct(scene, "render.comp", cands()))


def run(name: str, todo: list, scene, seed: int, budget: float | None, failed: list) -> tuple[int, float]:
    """Render ``todo`` on ``scene`` (random order); (rendered, seconds)."""
    from pbrcheck.errors import PbrcheckError
    from realtime.presets import OptionError
    from realtime.render import render_realtime
    todo = [todo[i] for i in np.random.default_rng(seed).permutation(len(todo))]
    t0, done = time.perf_counter(), 0
    for over in todo:
        if budget is not None and time.perf_counter() - t0 > budget:
            break
        try:
            img = render_realtime(scene, "default", {**SMALL, **over}, progress=False)
        except KeyboardInterrupt:  # stopped by hand: report what was rendered
            print(f"{name}: interrupted", flush=True)
            break
        except OptionError as e:
            failed.append(f"{name} {over}: refused only at render time: {e}")
        except (PbrcheckError, KeyError) as e:
            failed.append(f"{name} {over}: {type(e).__name__}: {str(e).splitlines()[0][:160]}")
        else:
            if not all(np.all(np.isfinite(img.channels[c])) for c in ("R", "G", "B")):
                failed.append(f"{name} {over}: non-finite pixels")
        done += 1
        if failed and failed[-1].startswith(f"{name} {over}"):
            print("FAILED", failed[-1], flush=True)
        if done % 250 == 0:
            print(f"  {name}: {done}/{len(todo)} ({time.perf_counter() - t0:.0f} s)", flush=True)
    dt = time.perf_counter() - t0
    print(f"{name}: {done}/{len(todo)} distinct programs rendered in {dt:.0f} s ({len(failed)} failures so far)",
          flush=True)
    return done, dt


def main(argv) -> int:
    from pbrcheck.errors import BackendError
    from pbrcheck.scene import load_scene
    from realtime.gl import get_context
    from realtime.render import render_realtime
    budget = float(argv[argv.index("--budget") + 1]) if "--budget" in argv else None
    seed = int(argv[argv.index("--seed") + 1]) if "--seed" in argv else 0
    sw = switches()
    total, accepted = full_count(sw)
    print(f"full cross product of {len(sw)} choice, bool and msaa options: {total:,} combinations, "
          f"{accepted:,} accepted by resolve_options (enumerated: {', '.join(coupled(sw))})", flush=True)
    failed: list = []
    furnace = load_scene("furnace").with_camera(width=16, height=16)
    with tempfile.TemporaryDirectory() as tmp:
        panel = mask_panel_scene(Path(tmp))
        max_samples = get_context().max_samples
        over = {"pipeline": "raster", "msaa": MSAA[-1]}
        if MSAA[-1] > max_samples:  # a backend limit: refused with a one-line BackendError (exit 3)
            try:
                render_realtime(panel, "default", {**SMALL, **over}, progress=False)
                failed.append(f"{over}: rendered above GL_MAX_SAMPLES {max_samples}")
            except BackendError as e:
                if "\n" in str(e):
                    failed.append(f"{over}: BackendError of several lines: {e}")
                print(f"msaa={MSAA[-1]} above this GL's GL_MAX_SAMPLES {max_samples}: BackendError: {e}", flush=True)
        stages = [("raster", raster_stage(sw, panel, max_samples), panel), ("raycast", raycast_stage(sw, furnace), furnace),
                  ("remainder", remainder_stage(sw, furnace), furnace)]
        print(", ".join(f"{n}: {len(t)} distinct programs" for n, t, _ in stages), flush=True)
        for i, (name, todo, scene) in enumerate(stages):
            run(name, todo, scene, seed, budget if i == len(stages) - 1 else None, failed)
    print(f"{len(failed)} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
