"""External renderers (clients/): renderers.toml, the runner's failure modes, caching, metadata,
``ext:NAME`` through the seam, the CLI and the gate. A fake engine (a Python script) plays the
renderer, so these run without node or Chromium."""

from __future__ import annotations

import json
import os
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import compare.renderers as renderers
from clients import config as C
from clients import run as R
from compare.gate import run_gate
from pbrcheck_cli import main
from pbrcheck.exr import read_exr
from pbrcheck.hdrimage import write_hdr, write_pfm
from pbrcheck.scene import scene_from_dict

FAKE = textwrap.dedent('''
    import json, os, subprocess, sys, time
    mode, scenario, out = sys.argv[1], sys.argv[2], sys.argv[3]
    here = os.path.dirname(os.path.abspath(__file__))
    if mode == "sleep":   # before the slow imports: the child must exist when the timeout strikes
        child = subprocess.Popen(["sleep", "60"])
        open(os.path.join(here, "child.pid.tmp"), "w").write(str(child.pid))
        os.replace(os.path.join(here, "child.pid.tmp"), os.path.join(here, "child.pid"))
        time.sleep(60)
    import numpy as np
    with open(os.path.join(here, "runs.txt"), "a") as f:
        f.write(mode + "\\n")
    sc = json.load(open(scenario))
    W, H = sc["size"]["width"], sc["size"]["height"]
    sys.path.insert(0, os.environ["PBRCHECK_ROOT"])
    from pbrcheck.hdrimage import write_pfm, write_hdr
    from pbrcheck.exr import Image, write_exr
    img = np.full((H, W, 3), 0.5, np.float32)
    img[0, 0] = (1.0, 0.0, 0.0)
    if mode == "pfm":
        write_pfm(out, img)
    elif mode == "exr":
        write_exr(out, Image.from_rgb(img))
    elif mode == "hdr":
        write_hdr(out, img)
    elif mode == "png":
        from PIL import Image as P
        P.fromarray((img * 255).astype(np.uint8)).save(out)
    elif mode == "nonzero":
        print("line one", file=sys.stderr); print("engine exploded: boom", file=sys.stderr); sys.exit(3)
    elif mode == "nofile":
        pass
    elif mode == "wrongsize":
        write_pfm(out, np.zeros((H + 1, W, 3), np.float32))
    elif mode == "nan":
        img[1, 1, 1] = float("nan"); img[2, 2, 0] = float("inf"); write_pfm(out, img)
    elif mode == "garbage":
        open(out, "wb").write(b"this is not an image")
''')

SCENE = {
    "name": "tiny", "camera": {"origin": [0, 0, 4], "fov": 40.0, "width": 16, "height": 8},
    "environment": {"type": "constant", "radiance": [1, 1, 1]},
    "objects": [{"type": "sphere", "radius": 1.0, "material": {"metallic": 1.0, "roughness": 0.5}}],
}


@pytest.fixture
def scene():
    return scene_from_dict(SCENE)


@pytest.fixture
def fake(tmp_path, monkeypatch, tmp_cache):
    """A renderers.toml whose renderers are modes of the fake engine; returns its folder."""
    d = tmp_path / "engine"
    d.mkdir()
    (d / "fake.py").write_text(FAKE)
    monkeypatch.setenv("PBRCHECK_ROOT", str(Path(__file__).resolve().parents[1]))
    modes = {"pfm": "pfm", "exr": "exr", "hdr": "hdr", "png": "png-srgb", "nonzero": "pfm", "sleep": "pfm",
             "nofile": "pfm", "wrongsize": "pfm", "nan": "pfm", "garbage": "pfm"}
    lines = []
    for m, fmt in modes.items():
        lines += [f"[renderer.{m}]", f'command = [{json.dumps(sys.executable)}, "fake.py", "{m}", "{{scenario}}", "{{out}}"]',
                  f'output = "{fmt}"', "timeout = " + ("3" if m == "sleep" else "60"),
                  f'version_command = [{json.dumps(sys.executable)}, "-c", "print(\'fake 1.2\')"]',
                  'lockfile = "fake.py"', ""]
    lines += ["[renderer.missing]", 'command = ["/nonexistent/engine-xyz", "{out}"]']
    (d / "renderers.toml").write_text("\n".join(lines) + "\n")
    C.set_renderers_file(d / "renderers.toml")
    yield d
    C.set_renderers_file(None)


def runs(d: Path) -> list[str]:
    p = d / "runs.txt"
    return p.read_text().split() if p.exists() else []


# --- success, formats, metadata, cache --------------------------------------------------------

@pytest.mark.parametrize("mode", ["pfm", "exr", "hdr"])
def test_float_outputs_come_back_row_0_at_the_top_with_metadata(fake, scene, mode):
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse(f"ext:{mode}"))
    assert img.shape == (8, 16)
    assert np.allclose(img.rgb[0, 0], (1.0, 0.0, 0.0), atol=0.01)     # row 0 is the top
    assert np.allclose(img.rgb[4, 8], 0.5, atol=0.01)
    m = img.meta
    assert m["renderer"] == f"ext:{mode}" and m["version"] == "fake 1.2" and m["display_referred"] == "0"
    assert json.loads(m["command"])[1:3] == ["fake.py", mode]
    assert float(m["seconds"]) > 0 and json.loads(m["timings"])["frame"] > 0
    # the object AOV (pixel centres): the sphere in the middle, background in the corner
    assert img.channels["object"][4, 8] == 0 and img.channels["object"][0, 0] == -1


def test_png_srgb_is_display_referred(fake, scene):
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:png"))
    assert img.meta["display_referred"] == "1"
    assert np.allclose(img.rgb[4, 8], 127 / 255, atol=1e-6)


def test_cached_by_scene_and_renderer_config_and_lockfile(fake, scene):
    renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:pfm"))
    renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:pfm"))
    assert runs(fake) == ["pfm"]                       # the second came from the cache
    renderers.render_under_test(scene.with_camera(width=18), renderers.RendererSpec.parse("ext:pfm"))
    assert runs(fake) == ["pfm", "pfm"]                # another scene hash
    (fake / "fake.py").write_text(FAKE + "\n# changed\n")
    renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:pfm"))
    assert runs(fake) == ["pfm", "pfm", "pfm"]         # the lockfile changed


# --- failure modes: one line, RendererError (exit 2), nothing half-written ---------------------

@pytest.mark.parametrize("mode,msg", [
    ("missing", "executable not found: '/nonexistent/engine-xyz'"),
    ("nonzero", "exited with status 3; stderr: line one | engine exploded: boom"),
    ("nofile", "wrote no output file"),
    ("wrongsize", "output is 16x9, expected 16x8"),
    ("nan", "output has 2 pixel(s) with NaN/Inf"),
    ("garbage", "unreadable output"),
])
def test_failure_modes(fake, scene, mode, msg):
    with pytest.raises(R.RendererError) as e:
        renderers.render_under_test(scene, renderers.RendererSpec.parse(f"ext:{mode}"))
    assert msg in str(e.value) and str(e.value).startswith(f"ext:{mode}: ")
    assert "\n" not in str(e.value) and e.value.exit_code == 2


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.split(")")[-1].split()[0] != "Z"


def test_timeout_kills_the_renderer_and_its_children(fake, scene):
    t0 = time.perf_counter()
    with pytest.raises(R.RendererError, match=r"timed out after 3 s \(killed with its children: its session"):
        renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:sleep"))
    assert time.perf_counter() - t0 < 20
    pid = int((fake / "child.pid").read_text())
    deadline = time.time() + 5
    while _alive(pid) and time.time() < deadline:
        time.sleep(0.05)
    assert not _alive(pid), "the renderer's child survived the timeout"


def test_cli_render_failure_is_one_line_exit_2_and_writes_nothing(fake, tmp_path, capsys):
    out = tmp_path / "o" / "x.exr"
    scene_file = tmp_path / "tiny.toml"
    from pbrcheck.scene import dump_toml
    scene_file.write_text(dump_toml(SCENE))
    rc = main(["render", str(scene_file), "--renderer", "nonzero", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "boom" in err[0]
    assert not out.exists() and not out.parent.exists()
    rc = main(["render", str(scene_file), "--renderer", "exr", "--out", str(out)])
    assert rc == 0
    img = read_exr(out)
    assert img.meta["renderer"] == "ext:exr" and img.shape == (8, 16)


def test_gate_reports_error_never_pass(fake, tmp_path, scene, capsys):
    from pbrcheck.exr import Image, write_exr
    from pbrcheck.scene import dump_toml
    (tmp_path / "tiny.toml").write_text(dump_toml(SCENE))
    ref = Image.from_rgb(np.full((8, 16, 3), 0.5, np.float32))
    write_exr(tmp_path / "ref.exr", ref)
    budget = tmp_path / "b.toml"
    budget.write_text(textwrap.dedent('''
        [[check]]
        name = "ok"
        scene = "tiny.toml"
        preset = "ext:pfm"
        reference = "ref.exr"
        [check.max]
        relmse = 1.0
        [[check]]
        name = "broken"
        scene = "tiny.toml"
        preset = "ext:nan"
        reference = "ref.exr"
        [check.max]
        relmse = 1.0
    '''))
    rc = run_gate(budget)
    out = capsys.readouterr()
    assert rc == 2
    assert "ERROR broken: ext:nan: output has 2 pixel(s) with NaN/Inf" in out.out + out.err


# --- renderers.toml ---------------------------------------------------------------------------

@pytest.mark.parametrize("body,msg", [
    ("[renderer.a]\noutput = 'exr'\n", "renderer.a.command: required"),
    ("[renderer.a]\ncommand = ['x', '{scene}', '{out}']\n", "unknown placeholder(s) scene"),
    ("[renderer.a]\ncommand = ['x']\n", "must name the output file with {out}"),
    ("[renderer.a]\ncommand = ['x', '{out}']\noutput = 'jpg'\n", "renderer.a.output: expected one of exr, hdr, pfm, png-srgb"),
    ("[renderer.a]\ncommand = ['x', '{out}']\ntimeout = -1\n", "renderer.a.timeout: expected a number of seconds > 0"),
    ("[renderer.a]\ncommand = ['x', '{out}']\ncolour = 1\n", "unknown key(s) colour"),
    ("[renderer.a]\ncommand = 'x {out}'\n", "renderer.a.command: expected a non-empty array"),
    ("[renderer.a\n", "not valid TOML"),
])
def test_malformed_renderers_file_names_file_and_field(tmp_path, body, msg):
    p = tmp_path / "renderers.toml"
    p.write_text(body)
    with pytest.raises(C.RendererConfigError) as e:
        C.load_renderers(p)
    assert str(p) in str(e.value) and msg in str(e.value)


def test_unknown_renderer_lists_the_known_ones(tmp_path):
    with pytest.raises(C.RendererConfigError, match="unknown external renderer 'ext:nope'; known: ext:babylon, ext:cycles, ext:filament, ext:playcanvas, ext:sample-viewer, .*ext:threejs"):
        renderers.RendererSpec.parse("ext:nope")
    spec = renderers.RendererSpec.parse("ext:threejs")
    assert spec.external and spec.options is None and spec.name == "ext:threejs" and spec.overrides == ()
    with pytest.raises(Exception, match="takes no options"):
        renderers.RendererSpec.parse("ext:threejs", {"supersample": 2})


def test_builtin_threejs_config_and_user_override(tmp_path):
    cfg = C.get_renderer("ext:threejs")
    assert cfg.builtin and cfg.output == "pfm" and cfg.lockfile_path().name == "package-lock.json"
    assert cfg.lockfile_hash() not in (None, "missing")
    assert cfg.inputs_hash() is not None and cfg.cache_dict()["inputs"] == cfg.inputs_hash()
    argv = C.expand(cfg, cfg.command, scenario="/s/scenario.json", out="/o/x.pfm", dir="/s", width=1, height=1)
    assert argv[0] == "node" and Path(argv[1]).is_file() and argv[2:4] == ["/s/scenario.json", "/o/x.pfm"]
    p = tmp_path / "renderers.toml"
    p.write_text("[renderer.threejs]\ncommand = ['my-three', '{out}']\n")
    assert C.load_renderers(p)["threejs"].command == ("my-three", "{out}")


def test_object_ids_match_the_scene(scene):
    ids = R.object_ids(scene)
    assert ids.shape == (8, 16) and set(np.unique(ids)) == {-1.0, 0.0}


def test_committed_clients_budget_is_well_formed():
    from compare.gate import load_budget, scene_arg

    budget = load_budget(Path(__file__).resolve().parents[1] / "compare" / "budgets" / "clients.toml")
    checks, base = budget.checks, budget.base
    # Every built-in client is gated on both CI scenes (sample-viewer-full: the same client as
    # sample-viewer with slower settings, minutes per run; cycles: a CPU path tracer in an optional
    # 950 MB environment, measured in docs/renderers.md section 10; three-gpu-pathtracer: a path
    # tracer, ~2 minutes a run on SwiftShader with a noisy image, measured by `pbrcheck fidelity`;
    # neither gated).
    clients = {f"ext:{n}" for n, cfg in C.load_renderers().items() if cfg.builtin} - {
        "ext:sample-viewer-full", "ext:cycles", "ext:three-gpu-pathtracer"}
    assert clients >= {"ext:threejs", "ext:sample-viewer", "ext:babylon", "ext:playcanvas", "ext:filament"}
    # and on the five lobe CI scenes (issue 36) where the engine renders the lobe (Filament 1.53.4's web
    # build renders anisotropy and iridescence as the bare material: no check of them)
    assert {(c.preset, c.scene) for c in checks} == {(p, s) for p in clients for s in (
        "spheres_ci.toml", "furnace_ci.toml", "clearcoat_ci.toml", "sheen_ci.toml", "specular_ci.toml",
        "anisotropy_ci.toml", "iridescence_ci.toml")} - {("ext:filament", "anisotropy_ci.toml"),
                                                         ("ext:filament", "iridescence_ci.toml")}
    for c in checks:
        assert c.max and (base / c.reference).is_file()
        scene = scene_arg(base, c.scene)
        assert scene.camera.width * scene.camera.height <= 200 * 200  # CI size


def test_report_summary_and_furnace_call_a_compensating_renderer_a_model_difference(fake, tmp_path, monkeypatch):
    """An external renderer that keeps a white furnace at 1.0 where the (here: faked) single-scattering
    reference loses energy is named a model difference in the report, and appears in the summary."""
    from compare.report.build import ReportConfig, build_report
    from tests.test_compare_report import fake_reference

    (fake / "fake.py").write_text(FAKE.replace("img = np.full((H, W, 3), 0.5, np.float32)",
                                               "img = np.full((H, W, 3), 1.0, np.float32)"))

    def lossy_reference(scene, **kw):
        img = fake_reference(scene, **kw)
        ids = np.rint(img.channels["object"])
        for c in "RGB":   # roughness k/4 keeps 1 - 0.15 k of the energy
            img.channels[c] = np.where(ids >= 0, 1.0 - 0.15 * ids, 1.0).astype(np.float32)
        return img

    monkeypatch.setattr(renderers, "render_reference", lossy_reference)
    (tmp_path / "tiny.toml").write_text(__import__("pbrcheck.scene", fromlist=["dump_toml"]).dump_toml(SCENE))
    index = build_report([str(tmp_path / "tiny.toml")], tmp_path / "r",
                         ReportConfig(presets=["ext:pfm"], spp=4, convergence=False, sweep=False, progress=False))
    html = index.read_text()
    assert "ext:pfm keeps the energy at every roughness" in html and "model difference" in html
    summary = html[html.index('id="summary"'):html.index('id="furnace-per-renderer"')]
    assert "ext:pfm" in summary and "unstated" in summary
    # The report runs diagnose on every external renderer's image and shows its verdict line.
    assert "Convention check (<code>pbrcheck diagnose</code>): no convention mismatch found" in html \
        or "Convention check (<code>pbrcheck diagnose</code>): likely cause:" in html
    assert (tmp_path / "r" / "tiny" / "diagnose_ext_pfm.json").is_file()


def test_png_srgb_is_compared_in_display_space(fake, scene):
    from compare.metrics import compare_images
    from pbrcheck.exr import Image

    test = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:png"))           # code values 127/255 (0.5 * 255 floored)
    lin = (127 / 255 + 0.055) / 1.055
    lin = lin ** 2.4                                                 # the linear radiance sRGB 127 encodes
    ref = Image.from_rgb(np.full((8, 16, 3), lin, np.float32), variance_R=np.zeros((8, 16), np.float32))
    c = compare_images(ref, test)
    assert c.summary["space"] == "display-referred" and c.summary["noise"] is None
    assert c.metrics["mean_abs"] < 1e-3                             # same display values
    hot = Image.from_rgb(np.full((8, 16, 3), 5.0, np.float32))      # clamped to 1 before the transfer
    assert compare_images(hot, test).metrics["mean_abs"] == pytest.approx(1 - 127 / 255, abs=0.02)
    assert compare_images(ref, renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:pfm"))).summary["space"] == "linear"


def test_ext_names_a_renderer_in_explain_and_sweep(fake, scene, tmp_path, monkeypatch):
    from compare.report.sweep import run_sweep
    from compare.research.explain import run_explain
    from pbrcheck.scene import dump_toml
    from tests.test_compare_report import fake_reference

    monkeypatch.setattr(renderers, "render_reference", fake_reference)
    res = run_explain(scene, preset="ext:pfm", spp=4)
    assert res.preset == "ext:pfm" and res.sources == [] and res.baseline["relmse"] > 0
    (tmp_path / "tiny.toml").write_text(dump_toml(SCENE))
    paths = run_sweep(str(tmp_path / "tiny.toml"), {}, preset="ext:exr", out_dir=tmp_path / "sw", spp=4,
                      progress=False, also=["ext:pfm"])
    rows = json.loads(paths["json"].read_text())
    assert [r["preset"] for r in rows] == ["ext:exr", "ext:pfm"] and paths["plot"].is_file()
    with pytest.raises(Exception, match="takes no options"):
        run_sweep(str(tmp_path / "tiny.toml"), {"cube_size": [64]}, preset="ext:exr", out_dir=tmp_path / "x",
                  spp=4, progress=False)
    assert not (tmp_path / "x").exists()


def test_threejs_client_without_a_browser_fails_in_one_line(scene, monkeypatch, tmp_cache):
    """The real three.js client, with Chromium missing: exit 1, the runner's one line in the error."""
    import shutil
    threejs = Path(__file__).resolve().parents[1] / "clients" / "threejs"
    if shutil.which("node") is None or not (threejs / "node_modules" / "three").is_dir():
        pytest.skip("node or clients/threejs/node_modules absent (make setup)")
    monkeypatch.setenv("PBRCHECK_CHROMIUM", "/nonexistent/chromium")
    with pytest.raises(R.RendererError, match=r"ext:threejs: exited with status 1; stderr: .*cannot start Chromium "
                                              r"\(/nonexistent/chromium\)"):
        renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:threejs"))


def test_renderers_option_does_not_outlive_its_call(tmp_path):
    """``--renderers FILE`` names the file of one ``main()`` call: a later in-process call (a test, a
    script) must not read it (it once leaked a broken file into every later external render)."""
    from clients.config import user_renderers_file
    from pbrcheck_cli import main

    bad = tmp_path / "renderers.toml"
    bad.write_bytes(b"[renderer.x]\ncommand = '\xe9'\n")
    assert user_renderers_file() is None
    assert main(["--renderers", str(bad), "renderers"]) == 2
    assert user_renderers_file() is None
