"""The gate's own test suite: planted regressions (tests/gate_plants.py) on the CI scenes are
``regressed`` or ``changed``, real improvements (a finer DFG LUT, a LOD mapping fitted on the CI
scene) ``improved``, and 20 reruns of the unchanged tree (environments baked afresh each time) all
``pass``; for three.js a reduced set of its plants against clients.toml's own checks, and reruns of
its checks with a fresh cache and browser each. Slow: every plant renders."""

from __future__ import annotations

import dataclasses
import io
import shutil
from pathlib import Path

import pytest

from compare import renderers
from compare.gate import load_budget, run_check, run_gate
from gate_plants import (ASSET_PLANTS, CLIENTS, FITTED_LOD, FITTED_LOD_CI, IMPROVEMENT, PLANTS, THREEJS_PLANTS,
                         accept_baselines, client_checks, plant_budget, planted_threejs, rerun_checks)

pytestmark = pytest.mark.slow

THREEJS = Path(__file__).resolve().parents[1] / "clients" / "threejs"
#: Reruns of the unchanged tree that must all pass.
RERUNS = 20


@pytest.fixture(scope="module")
def accepted(tmp_path_factory):
    d = tmp_path_factory.mktemp("plants")
    accept_baselines(d)
    return d


def verdicts(budget):
    b = load_budget(budget)
    return {c.name: run_check(c, b.base, progress=False) for c in b.checks}


@pytest.mark.parametrize("plant", PLANTS + [IMPROVEMENT, FITTED_LOD, FITTED_LOD_CI], ids=lambda p: p.name)
def test_planted_change_is_caught(accepted, plant):
    results = verdicts(plant_budget(accepted, plant))
    got = {name: r.change.verdict for name, r in results.items()}
    assert all(r.verdict.judged for r in results.values()), {n: r.error for n, r in results.items()}
    if plant.caught == ("improved",):
        assert set(got.values()) <= {"improved", "pass"} and "improved" in got.values(), got
    else:
        assert any(v in plant.caught for v in got.values()), got
    rc = run_gate(plant_budget(accepted, plant), progress=False, stream=io.StringIO())
    assert rc == (0 if plant.caught == ("improved",) else 1)


def test_twenty_reruns_of_the_unchanged_tree_pass(tmp_path):
    """Bakes at cube_size 64 (so that 20 fresh bakes of both scenes fit a test's time); every rerun
    frees the process's environment bakes first."""
    opts = {"cube_size": 64}
    budget = accept_baselines(tmp_path, options=opts)
    for i in range(RERUNS):
        renderers.trim_caches(0)
        out = io.StringIO()
        assert run_gate(budget, progress=False, stream=out) == 0, (i, out.getvalue())
        assert out.getvalue().count("\npass ") + out.getvalue().startswith("pass ") == 2, out.getvalue()


@pytest.mark.parametrize("plant", ASSET_PLANTS, ids=lambda p: p.name)
def test_asset_plant_is_caught(tmp_path, plant):
    """On ci.toml's asset check panel-default (its committed reference and baseline): a base colour
    read without sRGB decoding and a normal map with its green channel flipped are regressed."""
    accept_baselines(tmp_path, scenes=("panel",), committed=True)
    results = verdicts(plant_budget(tmp_path, plant))
    assert all(r.verdict.judged for r in results.values()), {n: r.error for n, r in results.items()}
    assert [r.change.verdict for r in results.values()] == ["regressed"], results


def _threejs_installed():
    if shutil.which("node") is None or not (THREEJS / "node_modules" / "three").is_dir() \
            or not any(shutil.which(c) for c in ("chromium", "chromium-browser")):
        pytest.skip("three.js client not installed (node, clients/threejs/node_modules, Chromium; make setup)")


@pytest.fixture(scope="module")
def accepted_threejs(tmp_path_factory):
    """clients.toml's spheres-threejs check (model-matched reference, budgets, committed baseline)."""
    _threejs_installed()
    d = tmp_path_factory.mktemp("plants-threejs")
    accept_baselines(d, "ext:threejs", scenes=("spheres",))
    return d


#: A reduced set of the three.js plants (one render each, spheres only; the full table of
#: docs/compare.md comes from ``python tests/gate_plants.py DIR ext:threejs``): a page edit of the
#: IBL's diffuse term, of its LOD, and a scene edit.
THREEJS_TESTED = ("page: getIBLIrradiance x0.99", "page: roughnessToMip + 0.1", "scene edit: environment.rotation += 1")


@pytest.mark.parametrize("plant", [p for p in THREEJS_PLANTS if p.how in THREEJS_TESTED], ids=lambda p: p.name)
def test_planted_change_is_caught_for_threejs(accepted_threejs, plant):
    """Against clients.toml's own check: the model-matched reference and the committed baseline."""
    results = verdicts(plant_budget(accepted_threejs, dataclasses.replace(plant, preset="ext:threejs"),
                                    scenes=("spheres",)))
    assert all(r.verdict.judged for r in results.values()), {n: r.error for n, r in results.items()}
    got = {name: r.change.verdict for name, r in results.items()}
    assert any(v in plant.caught for v in got.values()), got


def test_planted_threejs_page_edit_must_apply(tmp_path):
    """A page edit whose text is not in the installed three.js is an error, never a silent no-op."""
    _threejs_installed()
    with pytest.raises(ValueError, match="not in"):
        with planted_threejs(tmp_path, (("lights_fragment_begin", "no such GLSL", "x"),)):
            pass


#: Reruns of clients.toml's three.js checks in the test (each a fresh cache, so a fresh export and
#: a fresh browser): 2 x 2 renders fit the test's time; tools/client_reruns.py runs the full 20 for
#: every client (docs/compare.md).
THREEJS_RERUNS = 2


def test_reruns_of_threejs_unchanged_pass(tmp_path):
    """clients.toml's three.js checks, rendered afresh (fresh cache, fresh Chromium) each time,
    all pass against their committed baselines."""
    _threejs_installed()
    names = [c.name for c in client_checks("ext:threejs").values()]
    runs = rerun_checks(CLIENTS, names, THREEJS_RERUNS, tmp_path)
    assert len(runs) == THREEJS_RERUNS and all(len(r["outcomes"]) == 2 for r in runs)
    assert all(set(r["outcomes"].values()) == {"pass"} for r in runs), runs
