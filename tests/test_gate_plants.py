"""The gate's own test suite: planted regressions (tests/gate_plants.py) on the CI scenes are
``regressed`` or ``changed``, a real improvement ``improved``, and 20 reruns of the unchanged tree
(environments baked afresh each time) all ``pass``. Slow: every plant renders both CI scenes."""

from __future__ import annotations

import dataclasses
import io
import shutil
from pathlib import Path

import pytest

from compare import renderers
from compare.gate import load_budget, run_check, run_gate
from gate_plants import CLIENT_PLANTS, FITTED_LOD, IMPROVEMENT, PLANTS, accept_baselines, plant_budget

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
    checks, base = load_budget(budget)
    return {c.name: run_check(c, base, progress=False) for c in checks}


@pytest.mark.parametrize("plant", PLANTS + [IMPROVEMENT, FITTED_LOD], ids=lambda p: p.name)
def test_planted_change_is_caught(accepted, plant):
    results = verdicts(plant_budget(accepted, plant))
    got = {name: r.change.verdict for name, r in results.items()}
    assert all(r.status != "error" for r in results.values()), {n: r.error for n, r in results.items()}
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


@pytest.fixture(scope="module")
def accepted_threejs(tmp_path_factory):
    if shutil.which("node") is None or not (THREEJS / "node_modules" / "three").is_dir() \
            or not any(shutil.which(c) for c in ("chromium", "chromium-browser")):
        pytest.skip("three.js client not installed (node, clients/threejs/node_modules, Chromium; make setup)")
    d = tmp_path_factory.mktemp("plants-threejs")
    accept_baselines(d, "ext:threejs")
    return d


@pytest.mark.parametrize("plant", CLIENT_PLANTS, ids=lambda p: p.name)
def test_planted_change_is_caught_for_threejs(accepted_threejs, plant):
    results = verdicts(plant_budget(accepted_threejs, dataclasses.replace(plant, preset="ext:threejs")))
    assert all(r.status != "error" for r in results.values()), {n: r.error for n, r in results.items()}
    got = {name: r.change.verdict for name, r in results.items()}
    assert any(v in plant.caught for v in got.values()), got
