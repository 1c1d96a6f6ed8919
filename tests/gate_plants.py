"""Planted regressions of the gate's own test suite (tests/test_gate_plants.py, docs/compare.md).

Each plant is a change of the real-time default preset of a size users care about, made through a
shader hook (docs/hooks.md), an option, or a scene edit (the renderer under test sees the edited
scene, the reference does not): the gate must call it ``regressed`` or ``changed`` against baselines
accepted from the unchanged tree on the CI scenes (compare/budgets/spheres_ci.toml, furnace_ci.toml
with their committed references), and a real improvement (a DFG LUT of twice the resolution) ``improved``.

An external client's plants (:data:`CLIENT_PLANTS`: scene edits; for three.js also
:data:`THREEJS_PLANTS`: page edits of its shader chunks, :func:`planted_threejs`) are rendered by the
client and gated by clients.toml's own checks (model-matched references, budgets and committed
baselines).

API: :data:`PLANTS`, :data:`CLIENT_PLANTS`, :data:`THREEJS_PLANTS`, :data:`ASSET_PLANTS`, :data:`IMPROVEMENT`,
:data:`FITTED_LOD`, :data:`FITTED_LOD_CI`, :func:`base_budget`, :func:`accept_baselines`, :func:`client_checks`,
:func:`planted_threejs`, :func:`plant_budget`, :func:`detection_table`, :func:`rerun_checks`.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import tempfile
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from compare.baseline import BASELINE_DIR
from pbrcheck.exr import write_exr
from pbrcheck.scene import load_scene, scene_from_dict

ROOT = Path(__file__).resolve().parents[1]
BUDGETS = ROOT / "compare" / "budgets"
#: The CI scenes, their committed references and ci.toml's budgets of the default preset.
#: An external client's plants are gated by clients.toml's own checks (:func:`client_checks`).
CLIENTS = BUDGETS / "clients.toml"
CLIENTS_DIR = ROOT / "clients"
SCENES = {"spheres": ("spheres_ci.toml", "refs/spheres_ci.exr", {"relmse": 0.0023, "flip_mean": 0.074, "delta_e_itp_mean": 3}),
          "furnace": ("furnace_ci.toml", "refs/furnace_ci.exr", {"relmse": 3e-07, "flip_mean": 0.0045, "delta_e_itp_mean": 0.12}),
          "panel": ("panel_ci.toml", "refs/panel_ci.exr", {"relmse": 0.029, "flip_mean": 0.33, "delta_e_itp_mean": 15})}


def _lod(shift: float) -> str:
    return ("float hook_lod(float roughness, float max_lod, float cube_log2) {\n"
            f"    return clamp(lod_from_roughness(roughness, max_lod, cube_log2) + ({shift}), 0.0, max_lod);\n}}\n")


@dataclass
class Plant:
    """One planted change: ``shader`` hook text, ``options`` or a ``scene_edit`` (a function of the
    scene's dict), and the verdicts that count as caught."""
    name: str
    how: str
    shader: str | None = None
    options: dict = field(default_factory=dict)
    scene_edit: object = None
    caught: tuple = ("regressed", "changed")
    preset: str = "default"
    scenes: tuple = ("spheres", "furnace")
    # three.js page edits: (shader chunk, text, replacement) applied to THREE.ShaderChunk before the
    # first compile (:func:`planted_threejs`), the client's equivalent of a shader hook
    page: tuple = ()
    # the panel asset's texture images edited (a function of pbrcheck.gltf_build.panel_arrays' dict):
    # the asset scene renders a planted copy of compare/budgets/assets/panel.glb (:func:`_planted_panel`)
    asset_edit: object = None


def _objects(pred, key, f):
    """A scene edit: ``material[key] = f(value)`` on every object whose material satisfies ``pred``."""
    def edit(d: dict) -> dict:
        d = json.loads(json.dumps(d))
        for o in d["objects"]:
            m = o["material"]
            if pred(m):
                m[key] = f(m[key])
        return d
    return edit


def _env_scale(k: float):
    def edit(d: dict) -> dict:
        d = json.loads(json.dumps(d))
        d["environment"]["scale"] = d["environment"].get("scale", 1.0) * k
        return d
    return edit


def _rotate(d: dict) -> dict:
    d = json.loads(json.dumps(d))
    d["environment"]["rotation"] = d["environment"].get("rotation", 0.0) + 1.0
    return d


PLANTS = [
    Plant("diffuse x0.99", "hook_diffuse_ibl",
          shader="vec3 hook_diffuse_ibl(vec3 n) { return 0.99 * textureLod(irradiance_cube, n, 0.0).rgb; }\n"),
    Plant("diffuse x1.01", "hook_diffuse_ibl",
          shader="vec3 hook_diffuse_ibl(vec3 n) { return 1.01 * textureLod(irradiance_cube, n, 0.0).rgb; }\n"),
    Plant("DFG x0.99", "hook_dfg",
          shader="vec2 hook_dfg(float NoV, float roughness) { return 0.99 * dfg_lookup(dfg_lut, NoV, roughness); }\n"),
    Plant("LOD +0.1 mip", "hook_lod", shader=_lod(0.1)),
    Plant("LOD -0.1 mip", "hook_lod", shader=_lod(-0.1)),
    Plant("prefilter 1024 -> 64 samples", "option prefilter_samples=64", options={"prefilter_samples": 64}),
    Plant("LUT at 8 samples", "option lut_samples=8", options={"lut_samples": 8}),
    Plant("F90 0.97", "hook_dfg (B x 0.97) + hook_F",
          shader="vec2 hook_dfg(float NoV, float roughness) {\n    vec2 ab = dfg_lookup(dfg_lut, NoV, roughness);\n"
                 "    return vec2(ab.x, 0.97 * ab.y);\n}\n"
                 "vec3 hook_F(float VoH, vec3 F0) { return F0 + (vec3(0.97) - F0) * pow(1.0 - VoH, 5.0); }\n"),
    Plant("environment rotated 1 deg", "scene edit: environment.rotation += 1", scene_edit=_rotate),
]
#: Plants of an external engine (no shader hooks, no options): scene edits the reference does not
#: see, each the size of a default-preset plant above. A dielectric's base colour is its diffuse
#: albedo only (its F0 is ``specular``), so x0.99 on the dielectrics is "diffuse x0.99"; a metal's
#: base colour is its F0.
def _dielectric(m):
    return m["metallic"] == 0.0


CLIENT_PLANTS = [
    Plant("diffuse x0.99", "scene edit: dielectrics' base colour x0.99",
          scene_edit=_objects(_dielectric, "base_color", lambda c: [0.99 * x for x in c])),
    Plant("diffuse x1.01", "scene edit: dielectrics' base colour x1.01",
          scene_edit=_objects(_dielectric, "base_color", lambda c: [1.01 * x for x in c])),
    Plant("metals' F0 x0.99", "scene edit: metals' base colour x0.99",
          scene_edit=_objects(lambda m: m["metallic"] == 1.0, "base_color", lambda c: [0.99 * x for x in c])),
    Plant("roughness +0.01", "scene edit: every roughness + 0.01 (clamped to 1)",
          scene_edit=_objects(lambda m: True, "roughness", lambda r: min(r + 0.01, 1.0))),
    Plant("environment x0.99", "scene edit: environment.scale x0.99", scene_edit=_env_scale(0.99)),
    Plant("environment rotated 1 deg", "scene edit: environment.rotation += 1", scene_edit=_rotate),
]
#: three.js's equivalents of the default preset's hook plants, planted as page edits of its shader
#: chunks (three.js r187's ``envmap_physical_pars_fragment``: getIBLIrradiance / getIBLRadiance's
#: PMREM lookup at ``roughnessToMip(roughness)``; ``lights_fragment_begin``: the DFG LUT fetch;
#: ``lights_physical_fragment``: specularF90), and the scene edits of :data:`CLIENT_PLANTS`. Not
#: plantable in three.js: the prefilter's and the LUT's sample counts (PMREMGenerator's fixed
#: blur, a DFG LUT shipped as data).
_IRR = "return PI * envMapColor.rgb * envMapIntensity;"
_MIP = "textureLod( envMap, envMapRotation * reflectVec, roughnessToMip( roughness ) )"
_DFG = "material.dfg = texture2D( dfgLUT, vec2( material.roughness, dotNVms ) ).rg;"


def _tjs_lod(shift: float) -> tuple:
    return (("envmap_physical_pars_fragment", _MIP, _MIP[:-2] + f" + ({shift}) )"),)


THREEJS_PLANTS = [
    Plant("diffuse x0.99", "page: getIBLIrradiance x0.99",
          page=(("envmap_physical_pars_fragment", _IRR, _IRR.replace("return ", "return 0.99 * ")),)),
    Plant("diffuse x1.01", "page: getIBLIrradiance x1.01",
          page=(("envmap_physical_pars_fragment", _IRR, _IRR.replace("return ", "return 1.01 * ")),)),
    Plant("DFG x0.99", "page: DFG LUT fetch x0.99",
          page=(("lights_fragment_begin", _DFG, _DFG.replace("= texture2D", "= 0.99 * texture2D")),)),
    Plant("LOD +0.1 mip", "page: roughnessToMip + 0.1", page=_tjs_lod(0.1)),
    Plant("LOD -0.1 mip", "page: roughnessToMip - 0.1", page=_tjs_lod(-0.1)),
    Plant("F90 0.97", "page: specularF90 0.97",
          page=(("lights_physical_fragment", "material.specularF90 = 1.0;", "material.specularF90 = 0.97;"),
                ("lights_physical_fragment", "mix( specularIntensityFactor, 1.0, metalnessFactor )",
                 "mix( specularIntensityFactor, 0.97, metalnessFactor )"))),
] + CLIENT_PLANTS

def _srgb_encode(p: np.ndarray) -> np.ndarray:
    """uint8 texels read as linear, stored sRGB-encoded: a renderer that decodes them shades the raw
    values, as one that forgot to decode the original would (8-bit rounding aside)."""
    x = p / 255.0
    e = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(e * 255).astype(np.uint8)


def _no_srgb_decode(imgs: dict) -> dict:
    return {**imgs, "base_color": _srgb_encode(imgs["base_color"])}


def _flip_green(imgs: dict) -> dict:
    n = imgs["normal"].copy()
    n[..., 1] = 255 - n[..., 1]
    return {**imgs, "normal": n}


#: Asset plants on ci.toml's asset check (panel-default): asset edits the reference does not see.
ASSET_PLANTS = [
    Plant("base colour not sRGB-decoded", "asset edit: base-colour texels sRGB-encoded (decoded = the raw values)",
          asset_edit=_no_srgb_decode, scenes=("panel",)),
    Plant("normal map green flipped", "asset edit: normal texture G -> 255 - G", asset_edit=_flip_green,
          scenes=("panel",)),
]


def _planted_panel(folder: Path, edit) -> Path:
    """The panel asset (pbrcheck.gltf_build.panel_asset) with its texture images ``edit``-ed, in ``folder``."""
    from unittest import mock

    from pbrcheck import gltf_build

    orig = gltf_build.panel_arrays
    with mock.patch.object(gltf_build, "panel_arrays", lambda tex=gltf_build.PANEL_TEXTURE_SIZE: edit(orig(tex))):
        return gltf_build.panel_asset(Path(tempfile.mkdtemp(prefix="panel-plant-", dir=folder)) / "panel.glb")


#: The unchanged tree rendered afresh (an external client's own render against its committed baseline).
UNCHANGED = Plant("unchanged tree", "nothing", caught=("pass",))

#: A real improvement: a DFG LUT of twice the resolution (less interpolation error; better on
#: spheres_ci's smooth objects, nothing worse). On spheres_ci only: furnace_ci's default preset is
#: already exact within the reference's noise, so there the same change is ``changed``.
IMPROVEMENT = Plant("DFG LUT 64 -> 128", "option lut_size=128", options={"lut_size": 128}, caught=("improved",),
                    scenes=("spheres",))
#: A LOD mapping fitted on the CI scene per object (``python tools/lod_regions.py``, docs/compare.md):
#: per roughness knot (0, 0.2, .., 1) the LOD moves from the default (quadratic) mapping's to the
#: nearest of its objects' own best LODs (all of a column's objects want the same side), so no object
#: passes its optimum; between knots the quadratic mapping plus the linearly interpolated shift.
LOD_CI_SHIFT = (0.29, -0.02, -0.07, -0.14, -0.13, 0.0)


def _lod_knots(shift) -> str:
    n = len(shift) - 1
    body = "".join(f"    if (t <= {k + 1}.0) return {shift[k]!r} + ({shift[k + 1]!r} - {shift[k]!r}) * (t - {k}.0);\n"
                   for k in range(n))
    return ("float lod_ci_shift(float t) {\n" + body + f"    return {shift[n]!r};\n}}\n"
            "float hook_lod(float roughness, float max_lod, float cube_log2) {\n"
            f"    float shift = lod_ci_shift(clamp(roughness, 0.0, 1.0) * {n}.0);\n"
            "    return clamp(lod_from_roughness(roughness, max_lod, cube_log2) + shift, 0.0, max_lod);\n}\n")


FITTED_LOD_CI = Plant("LOD mapping fitted on the CI scene", "hook_lod: quadratic + per-roughness shift (tools/lod_regions.py)",
                      shader=_lod_knots(LOD_CI_SHIFT), caught=("improved",))
#: The fitted LOD mapping: better on 26 regions of spheres_ci, worse on 10 (docs/compare.md): not an
#: improvement by the gate's rule (nothing worse), so it is ``regressed``.
FITTED_LOD = Plant("fitted LOD mapping", "option lod_mapping=fitted:reports/research/fit_lod.json",
                   options={"lod_mapping": "fitted:" + str(ROOT / "reports" / "research" / "fit_lod.json")},
                   caught=("regressed",))


def _check(name, scene, ref, budgets, extra: str) -> str:
    mx = "\n".join(f"{k} = {v}" for k, v in budgets.items())
    return (f'[[check]]\nname = "{name}"\nscene = "{scene}"\nreference = "{ref}"\n{extra}[check.max]\n{mx}\n\n')


def client_checks(preset: str) -> dict:
    """clients.toml's checks of ``preset`` (an ``ext:`` client) per CI scene: ``{"spheres": Check, ...}``
    (model-matched references, budgets and committed baselines of the shipped gate)."""
    from compare.gate import load_budget

    checks = load_budget(CLIENTS).checks
    return {s: c for s in SCENES for c in checks if c.preset == preset and c.scene == SCENES[s][0]}


def _client_check(c, extra: str) -> str:
    """``c`` (a clients.toml check) as a check of a budget elsewhere: absolute paths, ``extra`` keys."""
    extra = f'reference_scene = "{BUDGETS / c.reference_scene}"\n{extra}' if c.reference_scene else extra
    return _check(c.name, BUDGETS / c.scene, BUDGETS / c.reference, c.max, extra)


def _options(options: dict) -> str:
    return ("options = { " + ", ".join(f"{k} = {json.dumps(v)}" for k, v in options.items()) + " }\n") if options else ""


def base_budget(folder: Path, preset: str = "default", scenes=("spheres", "furnace"), options=None) -> Path:
    """The unchanged tree's budget of ``preset`` (with ``options``) on the CI scenes, in ``folder``: for
    a real-time preset ci.toml's references and budgets, for an ``ext:`` client clients.toml's checks."""
    extra = f'preset = "{preset}"\n' + _options(options or {})
    if preset.startswith("ext:"):
        cc = client_checks(preset)
        text = "".join(_client_check(cc[s], extra) for s in scenes)
    else:
        text = "".join(_check(f"{s}-{preset}", BUDGETS / SCENES[s][0], BUDGETS / SCENES[s][1], SCENES[s][2], extra)
                       for s in scenes)
    p = Path(folder) / "base.toml"
    p.write_text(text)
    return p


def accept_baselines(folder: Path, preset: str = "default", scenes=("spheres", "furnace"), options=None,
                     committed: bool = False) -> Path:
    """The unchanged tree's baselines in ``folder/baselines``; returns the budget. A real-time preset's
    are accepted afresh (``committed``: ci.toml's committed ones, copied); an ``ext:`` client's are
    clients.toml's committed ones (copied), so its plants are gated exactly as ``make gate`` gates it."""
    from compare.gate import run_gate

    b = base_budget(folder, preset, scenes, options)
    if preset.startswith("ext:") or committed:
        (Path(folder) / BASELINE_DIR).mkdir(exist_ok=True)
        for s in scenes:
            check = client_checks(preset)[s].name if preset.startswith("ext:") else f"{s}-{preset}"
            for ext in (".exr", ".json"):
                shutil.copyfile(BUDGETS / BASELINE_DIR / (check + ext), Path(folder) / BASELINE_DIR / (check + ext))
        return b
    rc = run_gate(b, accept_reason="unchanged tree", progress=False, stream=io.StringIO())
    assert rc == 0
    return b


@contextlib.contextmanager
def planted_threejs(folder: Path, edits: tuple):
    """A copy of the three.js client (clients/threejs, its node_modules linked) whose page applies
    ``edits`` ((chunk, text, replacement): every occurrence) to ``THREE.ShaderChunk`` before the
    first compile, named ``threejs`` in a renderers file made current for the block. A text absent
    from the installed three.js is a ValueError here, and an error of the page (never a silent no-op)."""
    from clients import config

    build = (CLIENTS_DIR / "threejs" / "node_modules" / "three" / "build" / "three.module.js").read_text(encoding="utf-8")
    for chunk, a, _ in edits:
        if a not in build:
            raise ValueError(f"three.js plant: {a!r} is not in {chunk} of the installed three.js")
    d = Path(tempfile.mkdtemp(prefix="threejs-plant-", dir=folder))
    shutil.copytree(CLIENTS_DIR / "threejs", d / "threejs", ignore=shutil.ignore_patterns("node_modules"))
    (d / "threejs" / "node_modules").symlink_to(CLIENTS_DIR / "threejs" / "node_modules")
    (d / "browser").symlink_to(CLIENTS_DIR / "browser")
    page = d / "threejs" / "page.js"
    anchor = "async function main() {\n"
    patch = (anchor + "  // planted (tests/gate_plants.py): edits of three.js's shader chunks\n"
             f"  for (const [c, a, b] of {json.dumps([list(e) for e in edits])}) {{\n"
             "    if (!THREE.ShaderChunk[c].includes(a)) throw new Error(`plant: ${a} not in ${c}`);\n"
             "    THREE.ShaderChunk[c] = THREE.ShaderChunk[c].split(a).join(b);\n  }\n")
    page.write_text(page.read_text(encoding="utf-8").replace(anchor, patch, 1), encoding="utf-8")
    cfg = tomllib.loads((CLIENTS_DIR / "renderers.toml").read_text(encoding="utf-8"))["renderer"]["threejs"]
    lines = ["[renderer.threejs]"]
    for k, v in cfg.items():
        v = json.loads(json.dumps(v).replace("{clients}", "{config_dir}"))
        lines.append(f"{k} = {json.dumps(v)}")
    toml = d / "renderers.toml"
    toml.write_text("\n".join(lines) + "\n", encoding="utf-8")
    prev = config.user_renderers_file()
    config.set_renderers_file(toml)
    try:
        yield toml
    finally:
        config.set_renderers_file(prev)


def plant_budget(folder: Path, plant: Plant, scenes=None) -> Path:
    """A budget in ``folder`` (beside the accepted baselines) whose checks render with ``plant`` (on
    ``scenes``, default the plant's)."""
    from compare import renderers

    scenes = scenes or plant.scenes
    folder = Path(folder)
    safe = "".join(c if c.isalnum() else "_" for c in plant.name)
    external = plant.preset.startswith("ext:")
    text = ""
    for s in scenes:
        scene_file, ref, budgets = SCENES[s]
        if external or plant.scene_edit is not None or plant.asset_edit is not None:
            d = json.loads(json.dumps(load_scene(BUDGETS / scene_file).to_dict()))
            if plant.asset_edit is not None:
                glb = _planted_panel(folder, plant.asset_edit)
                for o in d["objects"]:
                    o["path"] = str(glb)
                    o.pop("content_hash", None)
            edited = scene_from_dict(plant.scene_edit(d) if plant.scene_edit else d)
            with (planted_threejs(folder, plant.page) if plant.page else contextlib.nullcontext()):
                img = renderers.render_under_test(edited, plant.preset, plant.options or None)
            test = write_exr(folder / f"{safe}-{s}.exr", img)
            if external:
                text += _client_check(client_checks(plant.preset)[s], f'test = "{test}"\n')
            else:
                text += _check(f"{s}-{plant.preset}", BUDGETS / scene_file, BUDGETS / ref, budgets, f'test = "{test}"\n')
            continue
        extra = f'preset = "{plant.preset}"\n'
        if plant.shader:
            hook = folder / f"{safe}.glsl"
            hook.write_text(plant.shader)
            extra += f'shader = "{hook}"\n'
        extra += _options(plant.options)
        text += _check(f"{s}-{plant.preset}", BUDGETS / scene_file, BUDGETS / ref, budgets, extra)
    p = folder / f"{safe}.toml"
    p.write_text(text)
    return p


def rerun_checks(budget: Path, names, runs: int, workdir: Path, stream=None) -> list[dict]:
    """Run the checks ``names`` of ``budget`` ``runs`` times, each time with a fresh, empty
    ``$PBRCHECK_CACHE`` (under ``workdir``, removed after the run) and the process's environment
    bakes freed, so every run exports, bakes and (for a client) starts its browser afresh. Returns
    per run ``{"run", "outcomes": {name: outcome}, "seconds"}``; prints a line per run to ``stream``."""
    import os
    import time

    from compare import renderers
    from compare.gate import load_budget, run_check
    from pbrcheck.cache import CACHE_ENV

    budget_ = load_budget(budget)
    checks, base = budget_.checks, budget_.base
    checks = [c for c in checks if c.name in set(names)]
    old = os.environ.get(CACHE_ENV)
    out = []
    try:
        for i in range(runs):
            cache = Path(workdir) / f"cache-{i}"
            os.environ[CACHE_ENV] = str(cache)
            renderers.trim_caches(0)
            t = time.perf_counter()
            res = {c.name: run_check(c, base, progress=False) for c in checks}
            out.append({"run": i, "outcomes": {n: r.verdict.label for n, r in res.items()},
                        "errors": {n: r.error for n, r in res.items() if r.error},
                        "seconds": time.perf_counter() - t})
            shutil.rmtree(cache, ignore_errors=True)
            if stream is not None:
                print(f"run {i + 1}/{runs}: " + ", ".join(f"{n} {o}" for n, o in out[-1]["outcomes"].items())
                      + f" ({out[-1]['seconds']:.1f} s)", file=stream, flush=True)
    finally:
        if old is None:
            os.environ.pop(CACHE_ENV, None)
        else:
            os.environ[CACHE_ENV] = old
    return out


def detection_table(folder: Path, preset: str = "default", *, plants=None, scenes=("spheres", "furnace")) -> str:
    """The measured detection table of docs/compare.md: every plant (and the improvements), the
    verdict per CI scene and the region that caught it (the most significant one)."""
    import dataclasses

    from compare.gate import Verdict, load_budget, run_check

    accept_baselines(folder, preset, scenes)
    plants = plants or (PLANTS + CLIENT_PLANTS[:4] + [IMPROVEMENT, FITTED_LOD, FITTED_LOD_CI] if preset == "default"
              else [dataclasses.replace(p, preset=preset)
                    for p in [UNCHANGED] + (THREEJS_PLANTS if preset == "ext:threejs" else CLIENT_PLANTS)])
    rows = ["| planted change | made by | " + " | ".join(f"{x}_ci" for x in scenes)
            + " | caught by (most significant region) | likely term |", "|---|---|" + "---|" * len(scenes) + "---|---|"]
    for p in plants:
        budget = load_budget(plant_budget(folder, p))
        checks, base = budget.checks, budget.base
        res = {c.name.split("-")[0]: run_check(c, base, progress=False) for c in checks}
        cells, best, likely = [], "", ""
        for s in scenes:
            r = res.get(s)
            if r is None:
                cells.append("(not run)")
                continue
            if not r.verdict.judged or r.change is None:
                cells.append(f"**error**: {r.error}" if not r.verdict.judged else "(no baseline)")
                continue
            ch = r.change
            n = {k: len(ch.by_state(k)) for k in ("worse", "better", "changed")}
            cells.append(f"**{ch.verdict}** ({n['worse']} worse, {n['better']} better, {n['changed']} changed"
                         f" of {len(ch.regions)})" + (f"; budget fail" if r.verdict is Verdict.OVER_BUDGET else ""))
            state = {"regressed": "worse", "improved": "better", "changed": "changed"}.get(ch.verdict)
            if state and not best:
                x = ch.by_state(state)[0]
                z = x.d_relmse / x.sigma_d if x.sigma_d > 0 else float("inf")
                best = (f"{s}: {x.name}, bias {x.bias:+.2%}, relmse {x.relmse_before:.3g} -> {x.relmse_after:.3g}"
                        f" ({z:+.0f} sigma)")
            likely = likely or (r.likely or "")
        rows.append(f"| {p.name} | {p.how} | " + " | ".join(cells) + f" | {best} | {likely} |")
    return "\n".join(rows)


if __name__ == "__main__":  # python tests/gate_plants.py DIR [PRESET | assets]: print the detection table
    import sys

    if sys.argv[2:3] == ["assets"]:
        print(detection_table(Path(sys.argv[1]), plants=ASSET_PLANTS, scenes=("panel",)))
    else:
        print(detection_table(Path(sys.argv[1]), *sys.argv[2:3]))
