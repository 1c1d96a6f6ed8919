"""The gate's lobe checks (issue 36): ci.toml gates the default preset on one CI-size scene per glTF
lobe (compare/budgets/<lobe>_ci.toml, 3 x 3 spheres of the built-in lobe scene's upper rows) against
its committed reference; a planted change of the lobe's parameter that only the renderer under test
sees (a scene edit, as tests/gate_plants.py's client plants) is caught by the committed baseline.
clients.toml gates each web engine on the same scenes where it renders the lobe (Filament 1.53.4's web
build renders anisotropy and iridescence as the bare material: not gated); one representative engine
per lobe of the second lobe wave (:data:`ENGINE_PLANTED`) sees the same plant ``regressed`` against
clients.toml's committed baseline and its unchanged render, made afresh, ``pass``."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from compare.baseline import BASELINE_DIR
from compare.gate import load_budget, run_check
from pbrcheck.exr import read_exr
from pbrcheck.environment import scene_hash
from pbrcheck.exr import write_exr
from pbrcheck.lobe_params import SCENE_DEFAULTS, SCENE_FIELD_EXTENSION, scene_features
from pbrcheck.scene import load_scene, scene_from_dict

ROOT = Path(__file__).resolve().parents[1]
BUDGETS = ROOT / "compare" / "budgets"
#: lobe -> the material field a plant edits and the edit (each a change of a few percent of the lobe's
#: own contribution: well under 1 % of most pixels).
LOBE_PLANTS = {
    "clearcoat": ("clearcoat", lambda v: v * 0.95),
    "sheen": ("sheen_color", lambda c: [0.95 * x for x in c]),
    "specular": ("specular_factor", lambda v: v * 0.95),
    "anisotropy": ("anisotropy_strength", lambda v: v * 0.95),
    "iridescence": ("iridescence_thickness", lambda v: v + 10.0),
}
LOBES = tuple(LOBE_PLANTS)


def _ci_checks():
    budget = load_budget(BUDGETS / "ci.toml")
    return budget, {c.name: c for c in budget.checks}


@pytest.mark.parametrize("lobe", LOBES)
def test_ci_gates_the_default_preset_on_each_lobe_scene(lobe):
    """One default-preset check per lobe, on its CI scene (every object carries the lobe's extension),
    against a committed reference of exactly that scene."""
    budget, checks = _ci_checks()
    c = checks[f"{lobe}-default"]
    assert (c.scene, c.preset, c.reference) == (f"{lobe}_ci.toml", "default", f"refs/{lobe}_ci.exr")
    scene = load_scene(budget.base / c.scene)
    ext = SCENE_FIELD_EXTENSION[LOBE_PLANTS[lobe][0]]
    assert len(scene.objects) == 9
    feats = [scene_features(o.material) for o in scene.objects]
    # specular's r4,c2 (factor 1, colour white) is the extension's neutral value: the core material
    neutral = ["specular[r4,c2]"] if lobe == "specular" else []
    assert [o.name for o, f in zip(scene.objects, feats) if f != (ext,)] == neutral
    assert all(f in ((ext,), ()) for f in feats)
    assert read_exr(budget.base / c.reference).meta["scene_hash"] == scene_hash(scene)


def _lobe_check(lobe: str, preset: str):
    """The shipped check of ``preset`` on the lobe's CI scene: ci.toml's for a real-time preset,
    clients.toml's for an ``ext:`` engine."""
    budget = load_budget(BUDGETS / ("clients.toml" if preset.startswith("ext:") else "ci.toml"))
    (c,) = [c for c in budget.checks if c.scene == f"{lobe}_ci.toml" and c.preset == preset]
    return c


def _planted_budget(folder: Path, lobe: str, preset: str = "default", planted: bool = True) -> Path:
    """The shipped check of ``preset`` on the lobe scene (its reference, budgets and committed baseline,
    copied to ``folder``) gating ``preset``'s render of the lobe scene, with the lobe's plant applied
    where ``planted`` (else the unchanged scene, rendered afresh)."""
    from compare import renderers

    c = _lobe_check(lobe, preset)
    key, edit = LOBE_PLANTS[lobe]
    d = json.loads(json.dumps(load_scene(BUDGETS / c.scene).to_dict()))
    for o in d["objects"] if planted else ():
        m = o["material"]
        m[key] = edit(m.get(key, SCENE_DEFAULTS[key]))
    img = renderers.render_under_test(scene_from_dict(d), renderers.RendererSpec.parse(preset, None))
    test = write_exr(folder / f"{lobe}-planted.exr", img)
    (folder / BASELINE_DIR).mkdir(exist_ok=True)
    for ext in (".exr", ".json"):
        shutil.copyfile(BUDGETS / BASELINE_DIR / (c.name + ext), folder / BASELINE_DIR / (c.name + ext))
    mx = "\n".join(f"{k} = {v}" for k, v in c.max.items())
    p = folder / "planted.toml"
    p.write_text(f'[[check]]\nname = "{c.name}"\nscene = "{BUDGETS / c.scene}"\nreference = "{BUDGETS / c.reference}"\n'
                 f'test = "{test}"\n[check.max]\n{mx}\n')
    return p


@pytest.mark.slow
@pytest.mark.parametrize("lobe", LOBES)
def test_a_planted_change_of_the_lobe_is_caught(tmp_path, lobe):
    budget = load_budget(_planted_budget(tmp_path, lobe))
    (r,) = [run_check(c, budget.base, progress=False) for c in budget.checks]
    assert r.verdict.judged, r.error
    assert r.change.verdict in ("regressed", "changed"), r.change.verdict


#: The engine each lobe's planted change is rendered by on clients.toml's checks (one per lobe gated
#: there since the second lobe wave; a different engine each, among the faster clients): specular on
#: Filament, anisotropy on three.js, iridescence on the Sample Viewer (Filament's web build renders
#: neither anisotropy nor iridescence: docs/renderers.md section 11).
ENGINE_PLANTED = {"specular": "ext:filament", "anisotropy": "ext:threejs", "iridescence": "ext:sample-viewer"}


def _engine_installed(preset: str) -> None:
    from tests.test_lobe_clients import ENGINES

    folder, pkg = ENGINES[preset.removeprefix("ext:")]
    if shutil.which("node") is None or not any(shutil.which(c) for c in ("chromium", "chromium-browser")) \
            or not (ROOT / "clients" / folder / "node_modules" / pkg).is_dir():
        pytest.skip(f"{preset} not installed (node, Chromium, clients/{folder}/node_modules; make setup)")


@pytest.mark.slow
@pytest.mark.parametrize("planted", [True, False], ids=["planted", "unchanged"])
@pytest.mark.parametrize("lobe", tuple(ENGINE_PLANTED))
def test_an_engines_planted_lobe_change_is_caught(tmp_path, tmp_cache, lobe, planted):
    """clients.toml's check of the lobe's engine (its reference, budgets and committed baseline): the
    engine's render of the plant (a fresh cache) is ``regressed`` or ``changed``; its render of the
    unchanged scene, made afresh, ``pass`` (the engines are bit-exact run to run on SwiftShader)."""
    preset = ENGINE_PLANTED[lobe]
    _engine_installed(preset)
    budget = load_budget(_planted_budget(tmp_path, lobe, preset, planted))
    (r,) = [run_check(c, budget.base, progress=False) for c in budget.checks]
    assert r.verdict.judged, r.error
    assert r.change.verdict in (("regressed", "changed") if planted else ("pass",)), r.change.verdict
