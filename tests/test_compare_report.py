"""``pbrcheck report`` and ``pbrcheck sweep`` on a tiny scene, and gate with reference = "auto".

The renderers are replaced by small numpy ray casters (:func:`fake_reference`, :func:`fake_realtime`)
so that these tests check the comparator's plumbing quickly and independently of Mitsuba/GL; the
real renderers are exercised in ``test_compare_real.py``.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from pbrcheck.camera import primary_rays
from pbrcheck_cli import main
from pbrcheck.exr import Image

SCENE = """
name = "tiny"
description = "2 x 3 sphere grid, 24 x 24"
[camera]
origin = [0.0, 0.0, 8.0]
fov = 30.0
width = 24
height = 24
[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]
[[objects]]
type = "sphere_grid"
rows = 2
columns = 3
radius = 0.6
spacing = 1.4
[objects.material]
base_color = [0.8, 0.5, 0.3]
"""


def raycast(scene):
    """(rgb, aovs) of a simple analytic shading of the scene's spheres (centre ray, 4 coverage samples)."""
    cam = scene.camera
    h, w = cam.height, cam.width

    def hit(offsets):
        o, d = primary_rays(cam, offsets)
        best_t = np.full((h, w), np.inf)
        best = np.full((h, w), -1)
        for ob in scene.objects:
            oc = o - np.asarray(ob.center)
            b = d @ oc
            c = oc @ oc - ob.radius ** 2
            disc = b * b - c
            t = -b - np.sqrt(np.maximum(disc, 0))
            m = (disc > 0) & (t > 0) & (t < best_t)
            best_t[m], best[m] = t[m], ob.id
        return o, d, best_t, best

    o, d, t, ids = hit((0.5, 0.5))
    cov = np.mean([hit(off)[3] >= 0 for off in ((0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75))], axis=0)
    rgb = np.zeros((h, w, 3))
    n = np.zeros((h, w, 3))
    ndv = np.zeros((h, w))
    for ob in scene.objects:
        m = ids == ob.id
        p = o + d[m] * t[m][:, None]
        nn = (p - np.asarray(ob.center)) / ob.radius
        n[m] = nn
        ndv[m] = np.clip(-(nn * d[m]).sum(-1), 0, 1)
        mat = ob.material
        rgb[m] = np.asarray(mat.base_color) * (0.3 + 0.7 * ndv[m][:, None]) * (1 - 0.5 * mat.metallic) \
            + 0.1 * (1 - mat.roughness)
    aovs = {"N.X": n[..., 0], "N.Y": n[..., 1], "N.Z": n[..., 2], "NdotV": ndv,
            "object": ids.astype(np.float32), "coverage": cov}
    return rgb, aovs


CALLS = {"reference": [], "realtime": [], "cached": []}


def fake_reference(scene, *, spp=64, mode="local", seed=0, use_cache=True, progress=True):
    CALLS["reference"].append(spp)
    rgb, aovs = raycast(scene)
    sigma2 = 0.01 / spp
    rng = np.random.default_rng(seed * 1000 + spp)
    noisy = rgb + rng.standard_normal(rgb.shape) * np.sqrt(sigma2)
    var = {f"variance.{c}": np.full(rgb.shape[:2], sigma2, np.float32) for c in "RGB"}
    return Image.from_rgb(noisy.astype(np.float32), {"scene_hash": "f" * 64, "spp": str(spp), "mode": mode,
                                                     "seed": str(seed), "variant": "fake", "versions": "{}"},
                          **var, **aovs)


def fake_realtime(scene, spec, *, progress=True, context=None, use_cache=True):
    preset, options = spec.text, dict(spec.overrides)
    CALLS["realtime"].append((preset, dict(options or {})))
    CALLS["cached"].append(bool(context and context.cache))
    rgb, aovs = raycast(scene)
    opts = dict(options or {})
    n = opts.get("prefilter_samples", 64)
    bias = {"default": 1.01, "cheap": 1.2}.get(preset, 1.05) + 1.0 / n
    timings = {"prefilter": 0.001 * n, "lut": 0.01, "frame": 0.002 if preset == "cheap" else 0.004}
    return Image.from_rgb((rgb * bias).astype(np.float32), {"preset": preset, "options": json.dumps(opts),
                                                            "timings": json.dumps(timings)}, **aovs)


@pytest.fixture
def fakes(monkeypatch):
    import compare.renderers as renderers

    presets = {"default": {}, "cheap": {}}

    def resolve_options(preset, overrides=None):
        from pbrcheck.errors import PbrcheckError

        if preset not in presets:
            raise PbrcheckError(f"unknown preset {preset!r}")
        for k in overrides or {}:
            if k not in ("prefilter_samples", "lut_size"):
                raise PbrcheckError(f"unknown option {k!r}")
        return {"prefilter_samples": 64, "lut_size": 32, **(overrides or {})}

    # The renderer seam: every compare, report and research module renders through it.
    monkeypatch.setattr(renderers, "render_reference", fake_reference)
    monkeypatch.setattr(renderers, "render_under_test", fake_realtime)
    monkeypatch.setattr(renderers, "preset_names", lambda: list(presets))
    monkeypatch.setattr(renderers, "resolve_options", resolve_options)
    for v in CALLS.values():
        v.clear()
    return CALLS


@pytest.fixture
def scene_file(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(SCENE)
    return p


class Refs(HTMLParser):
    def __init__(self):
        super().__init__()
        self.refs = []

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            if k in ("src", "href") and v:
                self.refs.append(v)


def check_offline_html(index: Path):
    html = index.read_text()
    assert not re.search(r"(https?:)?//[a-z0-9]", html, re.I), "external URL in the report"
    p = Refs()
    p.feed(html)
    assert p.refs
    for r in p.refs:
        assert not r.startswith(("/", "http", "data:")) and ".." not in r, r
        assert (index.parent / r).is_file(), f"{r} referenced but missing"
    return p.refs


def test_report_for_a_small_scene(fakes, scene_file, tmp_path, tmp_cache, monkeypatch, capsys):
    out = tmp_path / "report"
    rc = main(["report", str(scene_file), "--out", str(out), "--spp", "16", "--quiet"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert f"stages in {out / 'run.json'}" in printed and "s CPU on" in printed and "FLIP maps" in printed
    index = out / "index.html"
    refs = check_offline_html(index)
    names = {Path(r).name for r in refs}
    assert {"reference.png", "rt_default.png", "rt_cheap.png", "flip_default.png", "rel_cheap.png",
            "materials.png", "ndotv.png", "speed.png", "convergence.png", "sweep.csv"} <= names
    # issue 39's plot pruning: every figure written is one the page shows (none rendered for nothing)
    written = {p.relative_to(out).as_posix() for p in out.rglob("*.png")}
    assert written and written <= {r.split("#")[0] for r in refs}, sorted(written - set(refs))
    html = index.read_text()
    assert "flip_mean" in html and "relmse" in html and 'type="range"' in html
    assert "f" * 64 in html  # provenance: the reference's scene hash
    # all presets by default, the default sweep (here: prefilter_samples and lut_size, one at a time)
    assert {p for p, _ in fakes["realtime"]} == {"default", "cheap"}
    swept = [o for _, o in fakes["realtime"] if o]
    assert {"prefilter_samples": 256} in swept and {"lut_size": 16} in swept
    data = json.loads((out / "tiny" / "metrics.json").read_text())
    # the reference's spp: from 16 up (powers of two) until its noise floor is 10x below the
    # smallest error (or the cap); the convergence study renders fractions of the chosen spp
    rule = data["reference_spp"]
    chosen = rule["spp"]
    assert fakes["reference"][0] == 16 and chosen >= 16 and chosen & (chosen - 1) == 0
    if rule["smallest_error"] is not None:  # an error resolved above the noise sets the spp
        assert rule["ratio"] >= 10 or rule["noise_limited"], rule
    else:  # every preset within the noise: the least spp stands
        assert chosen == 16
    conv = sorted(c["spp"] for c in data["convergence"])
    assert conv and conv[-1] < chosen and set(conv) <= set(fakes["reference"])
    assert f"{chosen} spp: noise floor" in html
    assert data["presets"]["cheap"]["metrics"]["relmse"] > data["presets"]["default"]["metrics"]["relmse"]
    # the page opens with the summary (one row per renderer and scene), then the furnace per renderer
    assert html.index('id="summary"') < html.index('id="furnace-per-renderer"') < html.index('id="tiny"')
    summary = html[html.index('id="summary"'):html.index('id="furnace-per-renderer"')]
    assert summary.count("<tr>") == 1 + 2 and "delta_e_itp_mean" in summary and "timed on" in summary
    # every real-time render of the report may come from the content-addressed cache...
    assert fakes["cached"] and all(fakes["cached"])
    fakes["cached"].clear()
    # ... and --no-cache renders them all (and computes every FLIP map: no per-process memo either)
    import compare.metrics

    monkeypatch.setattr(compare.metrics, "_map_memo", {})
    assert main(["report", str(scene_file), "--out", str(tmp_path / "r2"), "--spp", "16", "--quiet",
                 "--no-cache", "--no-sweep", "--no-convergence"]) == 0
    assert fakes["cached"] and not any(fakes["cached"])
    # where the time went: run.json and the page's last section (stages, the caches' counts)
    run = json.loads((out / "run.json").read_text())
    names = [x["name"] for x in run["stages"]]
    for stage in ("tiny: renderers under test", "tiny: reference", "tiny: comparisons and diagnose", "tiny: sweep",
                  "tiny: convergence", "summary and furnace", "both references"):
        assert stage in names, stage
    assert run["wall_s"] >= sum(x["wall_s"] for x in run["stages"]) > 0 and run["cores"] >= 1
    assert {x["name"]: x["calls"] for x in run["stages"]}["tiny: comparisons and diagnose"] == 2  # one per renderer
    assert run["caches"].get("flip_miss", 0) > 0 and not run["caches"].get("flip_hit")
    assert 'id="run"' in html and "Where this report" in html and html.index('id="tiny"') < html.index('id="run"')
    r2 = json.loads((tmp_path / "r2" / "run.json").read_text())
    assert r2["caches"].get("flip_off", 0) > 0 and not r2["caches"].get("flip_miss")
    assert "tiny: convergence" not in [x["name"] for x in r2["stages"]] and "tiny: sweep" not in [x["name"] for x in r2["stages"]]
    # again with the cache, in a "new process" (no per-process memo): unchanged pairs' FLIP maps are read back
    monkeypatch.setattr(compare.metrics, "_map_memo", {})
    assert main(["report", str(scene_file), "--out", str(tmp_path / "r3"), "--spp", "16", "--quiet"]) == 0
    r3 = json.loads((tmp_path / "r3" / "run.json").read_text())
    assert r3["caches"].get("flip_hit", 0) > 0 and not r3["caches"].get("flip_miss")


def test_sweep_writes_table_and_pareto_plot(fakes, scene_file, tmp_path, capsys):
    out = tmp_path / "sweep"
    rc = main(["sweep", str(scene_file), "--vary", "prefilter_samples=4,64", "--vary", "lut_size=16,32",
               "--out", str(out), "--spp", "4", "--quiet"])
    assert rc == 0
    rows = json.loads((out / "sweep.json").read_text())
    assert len(rows) == 4
    assert all(r["precompute_s"] is not None and r["frame_s"] is not None and "flip_mean" in r for r in rows)
    csv = (out / "sweep.csv").read_text().splitlines()
    assert csv[0].startswith("preset,lut_size,prefilter_samples,precompute_s,frame_s,mean_abs") or \
        csv[0].startswith("preset,prefilter_samples,lut_size,precompute_s,frame_s,mean_abs")
    assert len(csv) == 5 and (out / "pareto.png").stat().st_size > 0


@pytest.mark.parametrize("vary, msg", [("prefilter_samples", "KEY=V1"), ("bogus=1,2", "unknown option")])
def test_sweep_bad_vary_exits_2(fakes, scene_file, tmp_path, capsys, vary, msg):
    assert main(["sweep", str(scene_file), "--vary", vary, "--out", str(tmp_path / "s"), "--quiet"]) == 2
    assert msg in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_sweep_refuses_msaa_above_this_gl_before_any_render(fakes, scene_file, tmp_path, monkeypatch, capsys):
    """A --vary value this GL cannot render (msaa above GL_MAX_SAMPLES, lowered to 2 here) stops the
    sweep in its preflight: exit 3 (a backend limit) naming the option, no render, no output."""
    import compare.renderers as renderers
    from realtime import raster
    from types import SimpleNamespace  # resolved options: attribute access
    monkeypatch.setattr(renderers, "resolve_options",
                        lambda preset, overrides=None: SimpleNamespace(**{"msaa": 1, **(overrides or {})}))
    monkeypatch.setattr(raster, "max_msaa", lambda: 2)
    assert main(["sweep", str(scene_file), "--vary", "msaa=1,4", "--out", str(tmp_path / "s"), "--quiet"]) == 3
    assert "option msaa: 4 samples asked" in capsys.readouterr().err
    assert not any(fakes.values()) and not (tmp_path / "s").exists()


def test_pareto_front():
    from compare.report.sweep import pareto_front, split_timings

    pts = [(1, 5), (2, 3), (3, 4), (4, 1), (2, 3.5), (None, 1)]
    assert pareto_front(pts) == [0, 1, 3]
    assert split_timings({"prefilter": 1.0, "lut": 0.5, "frame": 0.01, "total": 2}) == (1.5, 0.01)
    assert split_timings({"prefilter_s": 1.0, "draw_s": 0.25}) == (1.0, 0.25)


def test_gate_auto_reference_and_rendered_test(fakes, scene_file, tmp_path, tmp_cache, capsys):
    budget = tmp_path / "budget.toml"
    budget.write_text(f"""
[[check]]
name = "tiny-default"
scene = "{scene_file.name}"
preset = "default"
reference = "auto"
spp = 8
[check.max]
relmse = 0.05
[[check]]
name = "tiny-cheap"
scene = "{scene_file.name}"
preset = "cheap"
reference = "auto"
spp = 8
[check.max]
relmse = 0.01
""")
    rc = main(["gate", str(budget), "--quiet", "--maps", str(tmp_path / "maps")])
    out = capsys.readouterr().out
    assert rc == 1, out
    assert "pass tiny-default" in out and "FAIL tiny-cheap: relmse" in out and "worst objects: grid[r" in out


CHROMIUM = Path("/usr/bin/chromium")


@pytest.mark.slow
def test_report_opens_in_headless_chromium(fakes, scene_file, tmp_path, tmp_cache):
    if not CHROMIUM.exists():
        pytest.skip("/usr/bin/chromium is absent (Debian package 'chromium', installed by the set-up for this test)")
    out = tmp_path / "report"
    assert main(["report", str(scene_file), "--out", str(out), "--spp", "4", "--quiet", "--no-convergence",
                 "--presets", "default"]) == 0
    profile = tmp_path / "chromium-profile"
    cmd = [str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
           "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={profile}",
           "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000", "--dump-dom",
           (out / "index.html").as_uri()]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr[-2000:]
    dom = p.stdout
    assert "pbrcheck accuracy report" in dom
    m = re.search(r'data-images-ok="([^"]*)"', dom)
    assert m and m.group(1) == "yes", (m and m.group(1), p.stderr[-2000:])
    count = int(re.search(r'data-image-count="(\d+)"', dom).group(1))
    assert count >= 6
    assert re.search(r'data-js-errors="0"', dom), p.stderr[-2000:]
    console_errors = [l for l in p.stderr.splitlines() if "CONSOLE" in l and ("rror" in l or "Uncaught" in l)]
    assert not console_errors, console_errors


@pytest.mark.parametrize("args, msg", [(["--presets", "nope"], "nope"), (["--vary", "bogus=1"], "unknown option"),
                                       (["--spp", "1"], "--spp")])
def test_report_bad_arguments_exit_2_writing_nothing(fakes, scene_file, tmp_path, capsys, args, msg):
    out = tmp_path / "report"
    assert main(["report", str(scene_file), "--out", str(out), "--quiet", *args]) == 2
    assert msg in capsys.readouterr().err
    assert not out.exists()


def test_gate_renderer_crash_is_an_error_not_a_failure(fakes, scene_file, tmp_path, monkeypatch, capsys):
    def boom(*a, **k):
        raise RuntimeError("GL context lost")

    import compare.renderers as renderers

    monkeypatch.setattr(renderers, "render_under_test", boom)
    budget = tmp_path / "budget.toml"
    budget.write_text(f'[[check]]\nname = "x"\nscene = "{scene_file.name}"\nreference = "auto"\nspp = 4\n'
                      '[check.max]\nrelmse = 1\n')
    assert main(["gate", str(budget), "--quiet"]) == 2
    assert "GL context lost" in capsys.readouterr().out


def test_report_cli_with_and_shader_add_renderers_after_the_presets(monkeypatch, tmp_path):
    """`--with R,...` and `--shader FILE` append renderers to the presets (all of them by default)."""
    import compare.report.commands as rc
    from pbrcheck_cli import main

    seen = {}

    def fake_build(scenes, out_dir, config, **kw):
        seen["presets"] = config.presets
        return out_dir / "index.html"

    monkeypatch.setattr(rc, "build_report", fake_build)
    hook = tmp_path / "h.glsl"
    hook.write_text("vec3 hook_diffuse_ibl(vec3 n) { return vec3(0.0); }\n")
    assert main(["report", "--presets", "default", "--with", "ext:threejs,ext:sample-viewer",
                 "--shader", str(hook), "--out", str(tmp_path / "r")]) == 0
    assert seen["presets"] == ["default", "ext:threejs", "ext:sample-viewer", f"default+{hook}"]
    assert main(["report", "--with", "ext:threejs", "--out", str(tmp_path / "r")]) == 0
    assert seen["presets"][-1] == "ext:threejs" and "filament" in seen["presets"]


def test_the_stage_list_sizes_the_progress_bar_and_each_stage_advances_its_steps(monkeypatch):
    """One list of stages runs the work and drives the bar: the total is the stages' steps; a stage
    that reports more than its steps is held to them, one that reports fewer is completed."""
    import compare.report.stages as stages

    seen = {}

    class Bar:
        def __init__(self, label, total, **kw):
            seen["total"], seen["updates"] = total, []

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def update(self, n=1.0, note=""):
            seen["updates"].append((n, note))

    monkeypatch.setattr(stages, "Progress", Bar)
    ran = []
    work = [stages.ReportStage("a", 2, lambda p: [p.update(1, "a") for _ in range(5)] and ran.append("a")),
            stages.ReportStage("b", 3, lambda p: (p.update(1, "b"), ran.append("b"))),
            stages.ReportStage("c", 0, lambda p: ran.append("c"), record=False)]
    stages.run_stages(work, "t")
    assert ran == ["a", "b", "c"] and seen["total"] == stages.total_steps(work) == 5
    assert sum(n for n, _ in seen["updates"]) == 5
    assert seen["updates"] == [(1, "a"), (1, "a"), (1, "b"), (2, "b")]


def test_report_config_replaces_the_keywords_and_its_stages_match_the_run_log(fakes, scene_file, tmp_path, tmp_cache):
    from compare.report import build

    cfg = build.ReportConfig(presets=["default"], spp=4, convergence=False, sweep=False, furnace=False,
                             progress=False)
    index = build.build_report([str(scene_file)], tmp_path / "r", cfg)
    run = json.loads((tmp_path / "r" / "run.json").read_text())
    assert [s["name"] for s in run["stages"]] == ["tiny: renderers under test", "tiny: reference",
                                                  "tiny: comparisons and diagnose", "summary and furnace",
                                                  "both references"]
    assert 'id="tiny"' in index.read_text()


def test_report_of_an_asset_scene_shows_the_approximations_against_both_truths(tmp_path, tmp_cache):
    # a built quad with a tilted normal map and an occlusion texture: the asset section lists every
    # option of compare.approximations, the shading ones against local, the occlusion ones against path
    from compare.approximations import LOCAL_ROWS, PATH_ROWS
    from compare.report import build
    from gltf_build import quad_asset, quad_scene

    nm = np.zeros((4, 4, 3), np.uint8)
    nm[...] = (128, 128, 255)
    nm[::2, ::2] = (200, 128, 230)
    ao = np.full((4, 4, 3), 128, np.uint8)
    asset = quad_asset(tmp_path / "q.gltf", {"normalTexture": {"index": 0}, "occlusionTexture": {"index": 1},
                                            "pbrMetallicRoughness": {"metallicFactor": 1.0, "roughnessFactor": 0.3}},
                       [(nm, None), (ao, None)])
    scene = quad_scene(tmp_path, asset, size=(10, 10))
    cfg = build.ReportConfig(presets=["default"], spp=4, convergence=False, sweep=False, furnace=False,
                             progress=False)
    index = build.build_report([str(scene)], tmp_path / "r", cfg)
    m = json.loads(next((tmp_path / "r").glob("*/metrics.json")).read_text())["asset_approximations"]
    assert m["preset"] == "default"
    rows = m["rows"]
    assert [(r["truth"], r["option"]) for r in rows] == (
        [("local", label) for label, _ in LOCAL_ROWS] + [("path", label) for label, _ in PATH_ROWS])
    for r in rows:
        assert np.isfinite(r["relmse"]) and np.isfinite(r["smape"]), r
        assert [x["material"] for x in r["materials"]] and all(x["pixels"] > 0 for x in r["materials"]), r
    # the occlusion texture (0.5) darkens the diffuse-free metal's specular only with specular occlusion
    by = {r["option"]: r for r in rows}
    assert by["+ specular_occlusion=lagarde"]["relmse"] != by["occlusion_texture (diffuse)"]["relmse"]
    html = index.read_text()
    assert "Asset approximations" in html and "<td class=\"l\">path</td>" in html and "<td class=\"l\">local</td>" in html


def test_sweep_over_the_asset_approximations_against_their_truths(tmp_path, tmp_cache, capsys):
    # pbrcheck sweep --approximations on a built quad: every option of compare.approximations, each
    # against its truth's reference (a truth column), one speed-against-error plot per truth
    from compare.approximations import LOCAL_ROWS, PATH_ROWS
    from gltf_build import quad_asset, quad_scene

    nm = np.full((4, 4, 3), (128, 128, 255), np.uint8)
    nm[::2, ::2] = (200, 128, 230)
    asset = quad_asset(tmp_path / "q.gltf", {"normalTexture": {"index": 0}, "occlusionTexture": {"index": 1},
                                            "pbrMetallicRoughness": {"roughnessFactor": 0.3}},
                       [(nm, None), (np.full((4, 4, 3), 128, np.uint8), None)])
    out = tmp_path / "sweep"
    assert main(["sweep", str(quad_scene(tmp_path, asset, size=(8, 8))), "--approximations", "--out", str(out),
                 "--spp", "4", "--quiet"]) == 0
    rows = json.loads((out / "sweep.json").read_text())
    assert [r["truth"] for r in rows] == ["local"] * len(LOCAL_ROWS) + ["path"] * len(PATH_ROWS)
    assert all(r["options"]["pipeline"] == "raster" and r["frame_s"] is not None and np.isfinite(r["relmse"])
               for r in rows)
    assert all(r["options"]["occlusion_texture"] is False for r in rows[:len(LOCAL_ROWS)])
    assert (out / "sweep.csv").read_text().startswith("preset,truth,")
    assert (out / "pareto_local.png").stat().st_size > 0 and (out / "pareto_path.png").stat().st_size > 0
