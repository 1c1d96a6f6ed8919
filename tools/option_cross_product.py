"""Render the cross product of the real-time renderer's choice and bool options once.

``python tools/option_cross_product.py [--limit N] [--seed S]`` counts the full cross product of every choice
and bool option of :data:`realtime.presets.OPTIONS` on the default preset (accepted and refused by
:func:`realtime.presets.resolve_options`), then renders an 8 x 8 furnace for every distinct program
that product compiles, and reports any combination that neither renders with finite pixels nor is
refused with an OptionError. Exit status 1 if there is one. The programs run in a random order
(``--seed``, default 0), so that a run stopped early (``--limit``, or interrupted: progress lines
every 250) has rendered a uniform sample of them.

The rendered set: resolve_options couples only ``shading``, ``ibl`` and ``energy_compensation``, so
the count is the accepted (shading, ibl, energy_compensation) triples times the other options'
values. A combination's frame program depends on the switches its composition reads (below,
:data:`FRAME_READS`; ``scene`` values resolve to the furnace's terms and are deduplicated by the
program's ``#define``s), and each bake program on its own options (:data:`BAKES`); ``tonemap`` is
display only. Every distinct frame program and every bake variant is rendered once.
"""

from __future__ import annotations

import itertools
import math
import sys
import time

import numpy as np

SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 16, "lut_size": 8, "lut_samples": 16, "runtime_samples": 4, "supersample": 1}
COUPLED = ("shading", "ibl", "energy_compensation")
TERMS = ("ndf", "geometry", "fresnel")
#: The frame-pass switches each (shading, ibl) reads besides the terms' (shadows: every one).
FRAME_READS = {
    ("material", "splitsum"): (*TERMS, "irradiance", "dfg", "lod_mapping", "shadows"),
    ("material", "runtime"): (*TERMS, "irradiance", "shadows", "runtime_sampling", "runtime_lod", "runtime_rotate"),
    ("article000", "splitsum"): ("irradiance", "dfg", "lod_mapping", "shadows"),
    ("article001", "runtime"): (*TERMS, "irradiance", "shadows", "runtime_sampling", "runtime_lod", "runtime_rotate"),
    ("article002", "splitsum"): ("irradiance", "dfg", "lod_mapping", "shadows", "reflect_bug"),
}
#: The bake passes' own options, crossed with each other (on shading=material, ibl=splitsum).
BAKES = (("lut_geometry", "ndf", "lut_sampling", "lut_format"),
         ("prefilter_filtered", "prefilter_nl_weight", "lod_mapping", "cube_format"),
         ("irradiance", "irradiance_method", "cube_format"))


def switches() -> dict:
    from realtime.presets import OPTIONS
    return {n: (o.choices if o.kind == "choice" else (False, True))
            for n, o in OPTIONS.items() if o.kind in ("choice", "bool")}


def full_count(sw: dict) -> tuple[int, int]:
    """(combinations, accepted) of the full cross product of ``sw`` on the default preset."""
    from realtime.presets import OptionError, resolve_options
    accepted = 0
    for values in itertools.product(*(sw[n] for n in COUPLED)):
        try:
            resolve_options("default", {**SMALL, **dict(zip(COUPLED, values))})
            accepted += 1
        except OptionError:
            pass
    rest = math.prod(len(v) for n, v in sw.items() if n not in COUPLED)
    return math.prod(len(v) for v in sw.values()), accepted * rest


def variants(sw: dict):
    """Option overrides, one per distinct program the cross product compiles."""
    from pbrcheck.scene import load_scene
    from realtime.presets import OptionError, resolve_options
    from realtime.render import frame_defines, resolved_energy_compensation, resolved_terms
    scene = load_scene("furnace")
    seen = set()
    for triple in itertools.product(*(sw[n] for n in COUPLED)):
        base = dict(zip(COUPLED, triple))
        reads = FRAME_READS.get((base["shading"], base["ibl"]))
        if reads is None:
            continue
        for values in itertools.product(*(sw[n] for n in reads)):
            over = {**base, **dict(zip(reads, values))}
            try:
                o = resolve_options("default", {**SMALL, **over})
            except OptionError:
                continue
            terms = {**resolved_terms(scene, o), "energy_compensation": resolved_energy_compensation(scene, o)}
            key = tuple(sorted(frame_defines(o, terms).items()))
            if key not in seen:
                seen.add(key)
                yield over
    for names in BAKES:
        for values in itertools.product(*(sw[n] for n in names)):
            yield dict(zip(names, values))


def main(argv) -> int:
    from pbrcheck.errors import PbrcheckError
    from pbrcheck.scene import load_scene
    from realtime.presets import OptionError
    from realtime.render import render_realtime
    limit = int(argv[argv.index("--limit") + 1]) if "--limit" in argv else None
    sw = switches()
    total, accepted = full_count(sw)
    print(f"full cross product of {len(sw)} choice and bool options: {total} combinations, "
          f"{accepted} accepted by resolve_options", flush=True)
    seed = int(argv[argv.index("--seed") + 1]) if "--seed" in argv else 0
    todo = list(variants(sw))
    print(f"{len(todo)} distinct programs (frame variants and bakes)", flush=True)
    todo = [todo[i] for i in np.random.default_rng(seed).permutation(len(todo))][:limit]
    scene = load_scene("furnace").with_camera(width=8, height=8)
    failed, refused, t0 = [], 0, time.perf_counter()
    for i, over in enumerate(todo):
        try:
            img = render_realtime(scene, "default", {**SMALL, **over}, progress=False)
        except OptionError:
            refused += 1
            continue
        except (PbrcheckError, KeyError) as e:
            failed.append(f"{over}: {type(e).__name__}: {str(e).splitlines()[0][:160]}")
            print("FAILED", failed[-1], flush=True)
            continue
        if not all(np.all(np.isfinite(img.channels[c])) for c in ("R", "G", "B")):
            failed.append(f"{over}: non-finite pixels")
            print("FAILED", failed[-1], flush=True)
        if (i + 1) % 250 == 0:
            print(f"  {i + 1}/{len(todo)} ({time.perf_counter() - t0:.0f} s)", flush=True)
    print(f"{len(todo)} distinct programs rendered in {time.perf_counter() - t0:.0f} s "
          f"({refused} refused, {len(failed)} failed)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
