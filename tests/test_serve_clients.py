"""Serve mode (issue 39): inside ``clients.run.serve_clients`` a renderer with a ``serve_command``
renders every scene through one long-lived process (the browser clients: one Chromium for a whole
run); a failed render leaves it serving, a timeout kills it and its descendants (one that left the
session included), the block's end and a signal leave no process. A fake serve renderer in Python
(known answers, fast); the real three.js client's serve mode against its one-render mode (bit for
bit; skipped without node, Chromium or three)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import sys
import textwrap
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from clients import config as C
from clients import run as R
from pbrcheck.scene import scene_from_dict
from tests.test_faults import SCENE, _assert_clean, _run_and_signal

ROOT = Path(__file__).resolve().parents[1]

#: One script, both modes: `fake.py one MODE OUT W H PIDS` renders once; `fake.py --serve PIDS`
#: serves JSON command lines. On start it records its pid and that of a grandchild that left the
#: session (setsid), which every kill must reach. MODE: "ok" (radiance 0.25), "fail" (an error
#: answer), "sleep" (never answers).
FAKE_SERVE = textwrap.dedent('''
    import json, os, subprocess, sys, time
    import numpy as np

    def start(pids):
        escaped = subprocess.Popen(["sleep", "300"], start_new_session=True)
        with open(pids, "a") as f:
            f.write(f"{os.getpid()} {escaped.pid}\\n")

    def render(mode, out, w, h):
        if mode == "sleep":
            time.sleep(300)
        if mode == "fail":
            raise RuntimeError("fake client: page error: no mesh")
        with open(out, "wb") as f:   # a PFM: bottom row first
            f.write(b"PF\\n%d %d\\n-1.0\\n" % (w, h))
            f.write(np.full((h, w, 3), 0.25, "<f4").tobytes())
        return json.dumps({"pid": os.getpid()})

    if sys.argv[1] == "--serve":
        start(sys.argv[2])
        for line in sys.stdin:
            argv = json.loads(line)
            try:
                reply = {"ok": True, "stdout": render(argv[3], argv[4], int(argv[5]), int(argv[6]))}
            except RuntimeError as e:
                reply = {"ok": False, "error": str(e)}
            print(json.dumps(reply), flush=True)
    else:
        start(sys.argv[6])
        try:
            print(render(sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5])))
        except RuntimeError as e:
            sys.exit(str(e))
''')


@pytest.fixture
def fake(tmp_path, monkeypatch):
    """The fake serve renderers ``ok``, ``fail`` and ``sleep`` (timeout 2 s) and their pid file."""
    monkeypatch.setenv("PBRCHECK_CACHE", str(tmp_path / "cache"))
    (tmp_path / "fake.py").write_text(FAKE_SERVE)
    pids = tmp_path / "pids"
    toml = ""
    for mode in ("ok", "fail", "sleep"):
        toml += textwrap.dedent(f"""
            [renderer.{mode}]
            command = ["{sys.executable}", "fake.py", "one", "{mode}", "{{out}}", "{{width}}", "{{height}}", "{pids}"]
            serve_command = ["{sys.executable}", "fake.py", "--serve", "{pids}"]
            output = "pfm"
            timeout = {2 if mode == "sleep" else 30}
        """)
    (tmp_path / "renderers.toml").write_text(toml)
    prev = C.user_renderers_file()
    C.set_renderers_file(tmp_path / "renderers.toml")
    yield pids
    C.set_renderers_file(prev)


def _scene():
    return scene_from_dict({"camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "fov": 40, "width": 6, "height": 4},
                            "environment": {"type": "constant", "radiance": [1.0, 1.0, 1.0]},
                            "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0}]})


def _started(pids: Path) -> list[tuple[int, int]]:
    """(process, escaped grandchild) of every fake renderer process started so far."""
    return [tuple(map(int, l.split())) for l in pids.read_text().splitlines()] if pids.exists() else []


def _gone(pid: int, wait: float = 5.0) -> bool:
    deadline = time.time() + wait
    while time.time() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            return True
        if state == "Z":
            return True
        time.sleep(0.05)
    return False


def _server_pid(img) -> int:
    return json.loads(img.meta["renderer_stdout"])["pid"]


def test_one_process_serves_every_render_of_the_block_and_is_gone_after(fake):
    scene = _scene()
    with R.serve_clients():
        imgs = [R.render_external(scene, "ok", use_cache=False) for _ in range(3)]
        assert len(_started(fake)) == 1                      # one process for three renders
        assert {_server_pid(i) for i in imgs} == {_started(fake)[0][0]}
    np.testing.assert_array_equal(imgs[2].channels["R"], np.full((4, 6), 0.25, np.float32))
    assert all(_gone(p) for p in _started(fake)[0])        # the server and the grandchild that left its session


def test_without_the_block_each_render_is_its_own_process(fake):
    scene = _scene()
    imgs = [R.render_external(scene, "ok", use_cache=False) for _ in range(2)]
    assert len(_started(fake)) == 2 and _server_pid(imgs[0]) != _server_pid(imgs[1])
    assert all(_gone(p) for pair in _started(fake) for p in pair)


def test_a_failed_render_is_its_error_and_the_server_serves_on(fake):
    scene = _scene()
    with R.serve_clients():
        with pytest.raises(R.RendererError, match="exited with status 1; stderr: .*fake client: page error: no mesh"):
            R.render_external(scene, "fail", use_cache=False)
        first = _started(fake)[0][0]
        # "fail" and "ok" share the serve command: the same process renders the next scene
        assert _server_pid(R.render_external(scene, "ok", use_cache=False)) == first
        assert len(_started(fake)) == 1


def test_a_timeout_kills_the_server_and_the_next_render_starts_another(fake):
    scene = _scene()
    with R.serve_clients():
        with pytest.raises(R.RendererError, match="timed out after 2 s"):
            R.render_external(scene, "sleep", use_cache=False)
        assert all(_gone(p) for p in _started(fake)[0])
        img = R.render_external(scene, "ok", use_cache=False)
        assert len(_started(fake)) == 2 and _server_pid(img) == _started(fake)[1][0]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_during_a_served_render_leaves_no_process(fake, tmp_path, sig):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    marker = uuid.uuid4().hex
    (tmp_path / "tiny.toml").write_text(SCENE)
    toml = (tmp_path / "renderers.toml").read_text().replace("timeout = 2\n", "timeout = 60\n")
    (tmp_path / "renderers.toml").write_text(toml)
    argv = ["--renderers", str(tmp_path / "renderers.toml"), "render", str(tmp_path / "tiny.toml"),
            "--renderer", "ext:sleep", "--no-cache", "--out", str(tmp_path / "out.exr")]
    rc, err = _run_and_signal(argv, sig, lambda: bool(_started(fake)), tmp, marker)
    _assert_clean(rc, err, sig, tmp, marker)
    assert all(_gone(p) for p in _started(fake)[0])


THREE = ROOT / "clients" / "threejs" / "node_modules" / "three" / "package.json"


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("node") is None or not THREE.is_file()
                    or not any(shutil.which(c) for c in ("chromium", "chromium-browser")),
                    reason="node, Chromium or the three.js client (npm ci in clients/threejs) is absent")
def test_threejs_served_renders_equal_its_one_render_runs(tmp_path, monkeypatch):
    monkeypatch.setenv("PBRCHECK_CACHE", str(tmp_path / "cache"))
    scene = _scene()
    one = R.render_external(scene, "ext:threejs", use_cache=False)
    with R.serve_clients():
        served = [R.render_external(scene, "ext:threejs", use_cache=False) for _ in range(2)]
        servers = R._servers.all
        assert len(servers) == 1 and servers[0].alive    # one node process, one browser
    for img in served:
        for c in "RGB":
            np.testing.assert_array_equal(img.channels[c], one.channels[c])
    assert not servers[0].alive


def test_bench_serve_counts_the_processes_of_both_modes(fake, tmp_path):
    from compare.serve_bench import bench_serve

    (tmp_path / "tiny.toml").write_text(SCENE)
    r = bench_serve((str(tmp_path / "tiny.toml"),) * 2, ("ok",))
    before, after = r["one_browser_per_render"], r["one_browser_per_client"]
    assert before["renders"] == after["renders"] == 2 and r["same_pixels"] is True
    assert before["chromium_starts"] == 2 and after["chromium_starts"] == 1
    # per render: a warm-up and two renders, each its own process; served: one process for all three
    assert len(_started(fake)) == 3 + 1


def test_an_idle_serve_process_tree_is_no_renders_memory(fake):
    # compare.fidelity's usage sums the resident memory of the rendering process's descendants: the
    # other clients' served browsers, idle, are left out (their pids and their descendants')
    from compare.fidelity import idle_serve_processes

    with R.serve_clients():
        assert idle_serve_processes() == set()
        R.render_external(_scene(), "ok", use_cache=False)
        server, escaped = _started(fake)[0]
        assert {server, escaped} <= idle_serve_processes()
    assert idle_serve_processes() == set()


def _served_pid(scene, name, renderers_file):
    """A Dask task: one uncached render of ``name``; the pid of the process that rendered it."""
    from clients import run

    img = run.render_external(scene, name, renderers_file=renderers_file, use_cache=False)
    return json.loads(img.meta["renderer_stdout"])["pid"]


def test_a_dask_worker_keeps_one_process_per_client_and_closes_it_with_the_worker(fake, tmp_path):
    """`local:1`: three renders on the one worker go to one serve process (before the plugin, each
    render started its own: three pids), which is gone once the executor closes."""
    from compare.corpus.scheduler import Task, open_executor

    scene = _scene()
    got = {}
    tasks = [Task(f"render-{k}", _served_pid, (scene, "ok", str(tmp_path / "renderers.toml")), "render", True)
             for k in range(3)]
    with open_executor("local:1") as ex:
        ex.run(tasks, lambda t, v: got.__setitem__(t.key, v))
        started = _started(fake)
        assert len(started) == 1                                  # one process for the worker's three renders
        assert set(got.values()) == {started[0][0]}
    assert all(_gone(p, wait=15.0) for p in started[0])           # closed with the worker (teardown)
