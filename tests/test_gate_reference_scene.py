"""A gate check's ``reference_scene``: the model-matched reference (the check's scene but for
``[brdf]``: multiscatter, roughness_floor) that an external engine is gated against."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from compare.gate import BudgetError, Verdict, load_budget, run_check
from pbrcheck.environment import scene_hash
from pbrcheck.exr import Image, write_exr
from pbrcheck.scene import load_scene

SCENE = """name = "{name}"
[camera]
origin = [0.0, 0.0, 5.0]
target = [0.0, 0.0, 0.0]
width = {width}
height = 8
[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]
{brdf}
[[objects]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
"""

BUDGET = """[[check]]
name = "model-matched"
scene = "s.toml"
test = "test.exr"
reference = "ref.exr"
reference_scene = "{ref_scene}"
[check.max]
relmse = 1
"""


def _write(d: Path, ref_scene_text: str, hash_of: str) -> Path:
    (d / "s.toml").write_text(SCENE.format(name="s", width=8, brdf=""))
    (d / "s_ms.toml").write_text(ref_scene_text)
    h = scene_hash(load_scene(d / hash_of))
    rgb = np.full((8, 8, 3), 0.5, np.float32)
    write_exr(d / "ref.exr", Image.from_rgb(rgb, meta={"scene_hash": h}))
    write_exr(d / "test.exr", Image.from_rgb(rgb * 1.01))
    (d / "b.toml").write_text(BUDGET.format(ref_scene="s_ms.toml"))
    return d / "b.toml"


MS = SCENE.format(name="s_ms", width=8, brdf='[brdf]\nmultiscatter = "random_walk"\nroughness_floor = 0.045\n')


def test_the_reference_is_checked_against_the_reference_scene(tmp_path):
    budget = load_budget(_write(tmp_path, MS, "s_ms.toml"))
    checks, base = budget.checks, budget.base
    assert checks[0].reference_scene == "s_ms.toml"
    r = run_check(checks[0], base, progress=False)
    assert r.verdict is Verdict.PASS, r.error


def test_a_reference_of_the_checks_own_scene_is_refused(tmp_path):
    budget = load_budget(_write(tmp_path, MS, "s.toml"))  # a single-scattering EXR
    checks, base = budget.checks, budget.base
    r = run_check(checks[0], base, progress=False)
    assert r.verdict is Verdict.ERROR and "s_ms.toml hashes to" in r.error


def test_a_reference_scene_that_differs_outside_brdf_is_refused(tmp_path):
    other = SCENE.format(name="s_ms", width=9, brdf='[brdf]\nmultiscatter = "random_walk"\n')
    budget = load_budget(_write(tmp_path, other, "s_ms.toml"))
    checks, base = budget.checks, budget.base
    r = run_check(checks[0], base, progress=False)
    assert r.verdict is Verdict.ERROR and "only [brdf] may differ" in r.error and "camera" in r.error


def test_reference_scene_needs_scene(tmp_path):
    (tmp_path / "b.toml").write_text('[[check]]\nname = "x"\ntest = "t.exr"\nreference = "r.exr"\n'
                                     'reference_scene = "s.toml"\n[check.max]\nrelmse = 1\n')
    with pytest.raises(BudgetError, match="reference_scene"):
        load_budget(tmp_path / "b.toml")


def test_shipped_client_checks_name_model_matched_references():
    """clients.toml gates every client on both CI scenes against the random-walk reference (three.js's
    with its roughness floor and geometric roughness, the others with neither), each stored EXR of its
    reference_scene (the lobe scenes: ci.toml's single-scattering reference of the scene itself). Every
    check is asserted on (no check is skipped): the expected checks exist."""
    from pbrcheck.exr import read_exr

    path = Path(__file__).resolve().parents[1] / "compare" / "budgets" / "clients.toml"
    budget = load_budget(path)
    checks, base = budget.checks, budget.base
    clients = ("ext:threejs", "ext:sample-viewer", "ext:babylon", "ext:playcanvas", "ext:filament")
    lobes = ("clearcoat_ci.toml", "sheen_ci.toml", "specular_ci.toml", "anisotropy_ci.toml", "iridescence_ci.toml")
    not_rendered = {("ext:filament", "anisotropy_ci.toml"), ("ext:filament", "iridescence_ci.toml")}
    assert sorted((c.preset, c.scene) for c in checks) == sorted(
        (p, s) for p in clients for s in ("spheres_ci.toml", "furnace_ci.toml") + lobes if (p, s) not in not_rendered)
    for c in checks:
        if c.scene in lobes:  # the reference's lobes are single-scattering: ci.toml's reference, no reference_scene
            assert c.reference_scene is None and c.reference == "refs/" + c.scene.replace(".toml", ".exr"), c.name
            assert read_exr(base / c.reference).meta["scene_hash"] == scene_hash(load_scene(base / c.scene)), c.name
            continue
        assert c.reference_scene, c.name
        s = load_scene(base / c.reference_scene)
        assert s.brdf.multiscatter == "random_walk", c.name
        assert read_exr(base / c.reference).meta["scene_hash"] == scene_hash(s), c.name
        three = c.preset == "ext:threejs"  # its floor and screen-space geometric roughness at its 2 x 2 samples
        assert s.brdf.roughness_floor == (0.045 if three else 0.0), c.name
        assert (s.brdf.geometric_roughness, s.brdf.geometric_roughness_supersample) == \
            (("threejs", 2) if three else ("none", 1)), c.name


def test_ci_filament_preset_gated_against_the_random_walk():
    """ci.toml's filament preset compensates energy: its checks name the random-walk reference."""
    from pbrcheck.exr import read_exr

    budget = load_budget(Path(__file__).resolve().parents[1] / "compare" / "budgets" / "ci.toml")
    checks, base = budget.checks, budget.base
    fil = [c for c in checks if c.preset == "filament"]
    assert len(fil) == 2
    for c in fil:
        s = load_scene(base / c.reference_scene)
        assert s.brdf.multiscatter == "random_walk" and s.brdf.roughness_floor == 0.0, c.name
        assert read_exr(base / c.reference).meta["scene_hash"] == scene_hash(s), c.name
