"""Fault injection (issue 26): every command that writes, against every class of bad output path,
fails with one line on stderr, exit 2, no traceback and nothing half-written; signals during an
external render, a report and a corpus leave no process and no temporary folder; a closed stdout
is not an error; bad numbers and bad encodings in user files are one line.

Bad output paths (:data:`CLASSES`): an existing file where a folder is expected (or a folder where
a file is), a path under a file, a read-only folder as a non-root user (``setpriv`` to ``nobody``:
skipped, with the reason, when the tests do not run as root or ``setpriv`` is missing), a full disk
(a small tmpfs, mounted when the tests run as root; skipped, with the reason, where mounting is not
allowed). The disk is full in three ways: no block left (caught before the work), no inode left
(the free-space check passes; the first file or folder created fails: after the work for a single
file, before it for a staged folder), and 8 KiB left with larger outputs (a write fails half-way:
export's five files and compare's three maps, the cases that used to leave part of a folder).

Small on purpose: a 16 x 8 scene, 4 spp, the real-time renderer at its smallest sizes.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from pbrcheck_cli import main
from pbrcheck.exr import Image, write_exr
from pbrcheck.hdrimage import write_hdr

ROOT = Path(__file__).resolve().parents[1]

SCENE = textwrap.dedent("""
    name = "tiny"
    [camera]
    origin = [0, 0, 4]
    fov = 40.0
    width = 16
    height = 8
    [environment]
    type = "constant"
    radiance = [1, 1, 1]
    [[objects]]
    type = "sphere"
    radius = 1.0
    [objects.material]
    metallic = 1.0
    roughness = 0.5
""")

#: The real-time renderer at its smallest (a constant environment needs no resolution).
RT_FAST = ["--set", "cube_size=16", "--set", "prefilter_samples=16", "--set", "irradiance=sh9",
           "--set", "prefilter_levels=4", "--set", "lut_size=16", "--set", "lut_samples=16",
           "--set", "irradiance_source_size=8"]

FAKE = textwrap.dedent('''
    import os, subprocess, sys, time
    mode, out, pids = sys.argv[1], sys.argv[2], sys.argv[3]
    if mode == "sleep":   # a child in the session, and a grandchild that left it (setsid)
        child = subprocess.Popen(["sleep", "60"])
        escaped = subprocess.Popen(["sleep", "61"], start_new_session=True)
        with open(pids + ".tmp", "w") as f:
            f.write(f"{child.pid} {escaped.pid}")
        os.replace(pids + ".tmp", pids)
        time.sleep(60)
    import numpy as np
    w, h = 16, 8
    with open(out, "wb") as f:   # a PFM: bottom row first
        f.write(b"PF\\n%d %d\\n-1.0\\n" % (w, h))
        f.write(np.full((h, w, 3), 0.5, "<f4").tobytes())
''')

BUDGET = textwrap.dedent("""
    [[check]]
    name = "too bright/1"
    test = "test.exr"
    reference = "ref.exr"
    [check.max]
    relmse = 0.001
""")


def _tree(root: Path) -> dict:
    """Every path under ``root`` with its size (a folder: -1); the state of the outputs' area."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for d in dirnames:
            out[os.path.join(dirpath, d)] = -1
        for f in filenames:
            p = os.path.join(dirpath, f)
            out[p] = os.lstat(p).st_size
    return out


@pytest.fixture(scope="module")
def work():
    """Inputs in a world-readable folder (the read-only class runs as ``nobody``): the scene, two
    EXRs, a budget with a failing check, a fake external renderer, a corpus of one environment, and
    a cache folder anyone may write."""
    d = Path(tempfile.mkdtemp(prefix="pbrcheck-faults-"))
    os.chmod(d, 0o755)
    try:
        (d / "tiny.toml").write_text(SCENE)
        rng = np.random.default_rng(0)
        ref = rng.uniform(0.2, 1.0, (8, 16, 3)).astype(np.float32)
        write_exr(d / "ref.exr", Image.from_rgb(ref))
        write_exr(d / "test.exr", Image.from_rgb(ref * 1.5))
        (d / "budget.toml").write_text(BUDGET)
        (d / "fake.py").write_text(FAKE)
        (d / "renderers.toml").write_text(textwrap.dedent(f"""
            [renderer.fake]
            command = ["{sys.executable}", "fake.py", "pfm", "{{out}}", "pids"]
            output = "pfm"
            timeout = 60
            [renderer.sleep]
            command = ["{sys.executable}", "fake.py", "sleep", "{{out}}", "{{dir}}/../pids"]
            output = "pfm"
            timeout = 60
        """))
        (d / "envs").mkdir()
        write_hdr(d / "envs" / "grey.hdr", np.full((8, 16, 3), 0.5, np.float32))
        (d / "cache").mkdir(mode=0o777)
        os.chmod(d / "cache", 0o777)
        for p in d.rglob("*"):
            os.chmod(p, 0o777 if p.is_dir() else 0o644)
        yield d
    finally:
        shutil.rmtree(d, ignore_errors=True)


def writers(w: Path) -> dict:
    """command name -> (argv with OUT for the output path, whether OUT is a folder)."""
    s = str(w / "tiny.toml")
    return {
        "export": (["export", s, "--out", "OUT"], True),
        "reference": (["reference", s, "--spp", "4", "--out", "OUT"], False),
        "realtime": (["realtime", s, *RT_FAST, "--out", "OUT"], False),
        "lut": (["lut", "--size", "8", "--samples", "16", "--out", "OUT"], False),
        "render": (["--renderers", str(w / "renderers.toml"), "render", s, "--renderer", "ext:fake", "--no-cache", "--out", "OUT"],
                   False),
        "compare --json": (["compare", str(w / "ref.exr"), str(w / "test.exr"), "--json", "OUT"], False),
        "compare --maps": (["compare", str(w / "ref.exr"), str(w / "test.exr"), "--maps", "OUT"], True),
        "gate --junit": (["gate", str(w / "budget.toml"), "--quiet", "--maps", str(w / "gate-maps"), "--junit", "OUT"],
                         False),
        "gate --summary": (["gate", str(w / "budget.toml"), "--quiet", "--maps", str(w / "gate-maps"),
                            "--summary", "OUT"], False),
        "gate --maps": (["gate", str(w / "budget.toml"), "--quiet", "--maps", "OUT"], True),
        "corpus": (["corpus", str(w / "envs"), "--scene", s, "--presets", "default", *RT_FAST, "--spp", "4",
                    "--scheduler", "serial", "--quiet", "--out", "OUT"], True),
        "report": (["report", s, "--presets", "default", "--spp", "4", "--spp-cap", "4", "--no-convergence",
                    "--no-sweep", "--no-furnace", "--quiet", "--out", "OUT"], True),
        "sweep": (["sweep", s, "--vary", "cube_size=16,32", "--spp", "4", "--quiet", "--out", "OUT"], True),
    }


def _argv(argv: list[str], out: Path) -> list[str]:
    return [str(out) if a == "OUT" else a for a in argv]


def _assert_one_line(rc: int, err: str, out_path: Path, *, allow_progress: bool = False):
    lines = [l for l in err.splitlines() if l.strip()]
    assert "Traceback" not in err, err
    assert rc == 2, (rc, err)
    errors = [l for l in lines if l.startswith("pbrcheck: error: ")]
    assert len(errors) == 1 and lines[-1] == errors[0], err
    if not allow_progress:
        assert len(lines) == 1, err
    else:  # only progress lines of the work before the failing write
        assert all("%" in l for l in lines[:-1]), err
    name = out_path.name
    assert name in errors[0] or str(out_path.parent) in errors[0], (out_path, errors[0])


# --- bad output paths --------------------------------------------------------------------------

def _in_the_way(base: Path, folder: bool) -> Path:
    """A folder where a file is expected, or a file where a folder is."""
    out = base / "out"
    if folder:
        out.write_text("I am a file\n")
    else:
        out.mkdir()
        (out / "keep.txt").write_text("keep\n")
    return out


def _under_a_file(base: Path, folder: bool) -> Path:
    (base / "plain").write_text("a file\n")
    return base / "plain" / "sub" / ("out" if folder else "out.x")


@pytest.mark.parametrize("make", [_in_the_way, _under_a_file], ids=["in-the-way", "under-a-file"])
@pytest.mark.parametrize("cmd", list(writers(Path("/w"))))
def test_bad_output_path_is_one_line_exit_2_nothing_written(work, tmp_path, capfd, monkeypatch, cmd, make):
    monkeypatch.setenv("PBRCHECK_CACHE", str(tmp_path / "cache"))
    argv, folder = writers(work)[cmd]
    area = tmp_path / "area"
    area.mkdir()
    out = make(area, folder)
    before = _tree(area)
    inputs = _tree(work)
    rc = main(_argv(argv, out))
    err = capfd.readouterr().err
    _assert_one_line(rc, err, out)
    assert _tree(area) == before
    assert _tree(work) == inputs


# --- full disk (tmpfs) ---------------------------------------------------------------------------

@pytest.fixture
def full_disk(tmp_path):
    """A tmpfs factory: ``full_disk("blocks")`` no block free, ``full_disk("inodes")`` no inode free
    (files cannot be created; the free blocks let a check of the free space pass). Root only."""
    mounts = []
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")

    def make(kind: str, left: int = 0) -> Path:
        m = tmp_path / f"tmpfs-{len(mounts)}"
        m.mkdir()
        opts = "size=256k,nr_inodes=3" if kind == "inodes" else "size=256k"
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(m)], capture_output=True, text=True)
        if r.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
        mounts.append(m)
        (m / "outputs").mkdir()
        if kind == "blocks":
            fd = os.open(m / "filler", os.O_WRONLY | os.O_CREAT)
            try:
                while True:
                    os.write(fd, b"\0" * 4096)
            except OSError:
                pass
            finally:
                os.close(fd)
            if left:
                os.truncate(m / "filler", os.path.getsize(m / "filler") - left)
        else:
            n = 0
            while True:  # the inodes left
                try:
                    (m / f"f{n}").touch()
                    n += 1
                except OSError:
                    break
        return m / "outputs"

    yield make
    for m in mounts:
        subprocess.run(["umount", "-l", str(m)], capture_output=True)


@pytest.mark.parametrize("kind", ["blocks", "inodes"])
@pytest.mark.parametrize("cmd", list(writers(Path("/w"))))
def test_full_disk_is_one_line_exit_2_nothing_written(work, tmp_path, capfd, monkeypatch, full_disk, cmd, kind):
    monkeypatch.setenv("PBRCHECK_CACHE", str(tmp_path / "cache"))
    argv, folder = writers(work)[cmd]
    area = full_disk(kind)
    out = area / ("out" if folder else "out.x")
    before = _tree(area.parent)
    rc = main(_argv(argv, out))
    err = capfd.readouterr().err
    _assert_one_line(rc, err, out, allow_progress=True)
    if kind == "blocks":  # caught before the work (the free space is checked first)
        assert "no space left on device" in err.lower(), err
    else:  # the work ran; the write failed (the system's reason, not the check's)
        assert "No space left on device" in err, err
    assert _tree(area.parent) == before


def test_disk_full_half_way_leaves_no_part(work, tmp_path, capfd, monkeypatch, full_disk):
    monkeypatch.setenv("PBRCHECK_CACHE", str(tmp_path / "cache"))
    big = np.random.default_rng(2).uniform(0.2, 1.0, (64, 128, 3)).astype(np.float32)
    write_hdr(tmp_path / "env.hdr", big)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.replace('type = "constant"\nradiance = [1, 1, 1]', f'type = "file"\npath = "{tmp_path / "env.hdr"}"'))
    write_exr(tmp_path / "r.exr", Image.from_rgb(big))
    write_exr(tmp_path / "t.exr", Image.from_rgb(big * 1.2))
    for argv in (["export", str(scene), "--out", "OUT"],
                 ["compare", str(tmp_path / "r.exr"), str(tmp_path / "t.exr"), "--maps", "OUT"]):
        area = full_disk("blocks", left=8192)
        (area / "out").mkdir()
        (area / "out" / "keep.txt").write_text("an older file\n")
        before = _tree(area.parent)
        rc = main(_argv(argv, area / "out"))
        err = capfd.readouterr().err
        _assert_one_line(rc, err, area / "out", allow_progress=True)
        assert "No space left on device" in err, err
        assert _tree(area.parent) == before, argv


# --- read-only folder, as a user who is not root ------------------------------------------------

DRIVER = textwrap.dedent('''
    import json, os, sys, tempfile
    from pbrcheck_cli import main
    results = {}
    for name, argv in json.loads(sys.argv[1]).items():
        with tempfile.TemporaryFile() as cap:
            saved = os.dup(2)
            os.dup2(cap.fileno(), 2)
            try:
                rc = main(argv)
            except BaseException as e:
                import traceback; traceback.print_exc()
                rc = -1
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            cap.seek(0)
            results[name] = [rc, cap.read().decode("utf-8", "replace")]
    print(json.dumps(results))
''')


def test_read_only_folder_as_nobody_is_one_line_exit_2(work):
    if os.geteuid() != 0:
        pytest.skip("dropping to the user nobody needs root (and as a plain user the read-only case "
                    "is the same as root's: the tests run as that user)")
    if shutil.which("setpriv") is None:
        pytest.skip("setpriv (util-linux) is missing: cannot drop privileges")
    ro = work / f"ro-{uuid.uuid4().hex[:8]}"
    ro.mkdir()
    os.chmod(ro, 0o555)
    cases = {}
    for cmd, (argv, folder) in writers(work).items():
        target = ro / ("out" if folder else "out.x")
        cases[cmd] = _argv(argv, target)
    cases["export into a read-only sub-folder"] = _argv(writers(work)["export"][0], ro / "a" / "b")
    before = _tree(ro)
    env = {**os.environ, "PBRCHECK_CACHE": str(work / "cache"), "HOME": str(work / "cache"),
           "MPLCONFIGDIR": str(work / "cache"), "PYTHONPATH": str(ROOT)}
    r = subprocess.run(["setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups",
                        sys.executable, "-c", DRIVER, json.dumps(cases)],
                       cwd=work, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    results = json.loads(r.stdout.strip().splitlines()[-1])
    for cmd, (rc, err) in results.items():
        assert "Traceback" not in err, (cmd, err)
        lines = [l for l in err.splitlines() if l.strip()]
        assert rc == 2 and len(lines) == 1 and lines[0].startswith("pbrcheck: error: "), (cmd, rc, err)
        assert str(ro) in lines[0] and ("not writable" in lines[0] or "Permission denied" in lines[0]), (cmd, err)
    assert _tree(ro) == before


# --- signals: no process, no temporary folder ---------------------------------------------------

def _marked(marker: str) -> list[int]:
    """Processes whose environment carries ``PBRCHECK_FAULT_TEST=marker``."""
    out = []
    tag = f"PBRCHECK_FAULT_TEST={marker}".encode()
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            env = Path(f"/proc/{d}/environ").read_bytes().split(b"\0")
            stat = Path(f"/proc/{d}/stat").read_text()
        except OSError:
            continue
        if tag in env and stat.rsplit(")", 1)[1].split()[0] != "Z":
            out.append(int(d))
    return out


def _run_and_signal(argv: list[str], sig: int, ready, tmp: Path, marker: str, timeout: float = 120):
    env = {**os.environ, "PBRCHECK_FAULT_TEST": marker, "TMPDIR": str(tmp), "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen([sys.executable, "-m", "pbrcheck_cli", *argv], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    deadline = time.time() + timeout
    try:
        while not ready() and p.poll() is None and time.time() < deadline:
            time.sleep(0.1)
        assert p.poll() is None, f"finished before the signal: {p.communicate()}"
        p.send_signal(sig)
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    return p.returncode, err


def _assert_clean(rc, err, sig, tmp: Path, marker: str):
    assert rc == 128 + sig, (rc, err)
    assert "Traceback" not in err and "CommClosedError" not in err, err
    lines = [l for l in err.splitlines() if l.strip()]
    assert lines and lines[-1] == ("pbrcheck: interrupted" if sig == signal.SIGINT else "pbrcheck: terminated"), err
    deadline = time.time() + 10
    while _marked(marker) and time.time() < deadline:
        time.sleep(0.1)
    assert not _marked(marker), f"processes left: {_marked(marker)}"
    assert not [p.name for p in tmp.iterdir()], f"temporary files left: {list(tmp.iterdir())}"


SIGNALS = [pytest.param(signal.SIGINT, id="SIGINT"), pytest.param(signal.SIGTERM, id="SIGTERM")]


@pytest.mark.parametrize("sig", SIGNALS)
def test_signal_during_external_render_kills_the_whole_run(work, tmp_path, sig):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    marker = uuid.uuid4().hex
    pids = tmp_path / "pids"  # {dir}/../pids: beside the export folder in TMPDIR; moved here
    argv = ["--renderers", str(work / "renderers.toml"), "render", str(work / "tiny.toml"), "--renderer", "ext:sleep",
            "--no-cache", "--out", str(tmp_path / "out.exr")]

    def ready():
        found = list(tmp.glob("pbrcheck-ext-*/pids"))
        if found:
            pids.write_text(found[0].read_text())
        return bool(found)

    rc, err = _run_and_signal(argv, sig, ready, tmp, marker)
    _assert_clean(rc, err, sig, tmp, marker)
    child, escaped = (int(x) for x in pids.read_text().split())
    for pid in (child, escaped):
        assert not Path(f"/proc/{pid}").exists() or "Z" == Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    assert not (tmp_path / "out.exr").exists()


def test_timeout_kills_a_grandchild_that_left_the_session(work, tmp_path, monkeypatch):
    from clients import run as R

    monkeypatch.setenv("PBRCHECK_CACHE", str(tmp_path / "cache"))
    pids = tmp_path / "pids"
    with pytest.raises(R.RendererError, match="timed out after 2 s"):
        R.run_process([sys.executable, str(work / "fake.py"), "sleep", "x", str(pids)], cwd=tmp_path,
                      timeout=2, label="ext:sleep")
    for pid in (int(x) for x in pids.read_text().split()):
        deadline = time.time() + 5
        while Path(f"/proc/{pid}").exists() and time.time() < deadline:
            time.sleep(0.05)
        assert not Path(f"/proc/{pid}").exists(), f"process {pid} survived the timeout"


@pytest.mark.parametrize("sig", SIGNALS)
def test_signal_during_report_leaves_nothing(work, tmp_path, sig):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    marker = uuid.uuid4().hex
    out = tmp_path / "report"
    argv = ["report", str(work / "tiny.toml"), "--presets", "default", "--spp", "4", "--spp-cap", "4",
            "--no-convergence", "--no-sweep", "--no-furnace", "--no-cache", "--out", str(out)]
    seen = []

    # 1 s into its work (its staged folder exists, the handler is set): a signal may land in an import of
    # Mitsuba (handled: the CLI finds the interrupt in the SystemError's context); --no-cache: a warm
    # cache finished the whole report in 1.1 s, before the signal.
    def ready():
        if not seen and list(tmp_path.glob(".report.*")):
            seen.append(time.time())
        return bool(seen) and time.time() - seen[0] > 1

    rc, err = _run_and_signal(argv, sig, ready, tmp, marker)
    _assert_clean(rc, err, sig, tmp, marker)
    assert not out.exists() and not list(tmp_path.glob(".report.*")), list(tmp_path.iterdir())


#: Environments of the interrupted corpus (each a reference and a real-time render on one worker).
CORPUS_SIGNAL_ENVS = 16


@pytest.mark.parametrize("sig", SIGNALS)
def test_signal_during_corpus_leaves_nothing(work, tmp_path, sig):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    marker = uuid.uuid4().hex
    out = tmp_path / "corpus"
    # Enough work that the run is still going when the worker is up and the signal comes (one
    # environment at 4 spp once finished before the signal; CORPUS_SIGNAL_ENVS of them at 1024 spp).
    envs = tmp_path / "envs"
    envs.mkdir()
    for i in range(CORPUS_SIGNAL_ENVS):
        write_hdr(envs / f"grey{i:02d}.hdr", np.full((8, 16, 3), 0.1 + 0.05 * i, np.float32))
    argv = ["corpus", str(envs), "--scene", str(work / "tiny.toml"), "--presets", "default",
            *RT_FAST, "--spp", "1024", "--scheduler", "local:1", "--out", str(out)]

    def ready():  # the Dask worker runs (a process of the run besides pbrcheck itself)
        return len(_marked(marker)) >= 2 and time.time() - t0 > 1

    t0 = time.time()
    rc, err = _run_and_signal(argv, sig, ready, tmp, marker)
    _assert_clean(rc, err, sig, tmp, marker)
    assert not (out / "corpus.csv").exists()


# --- a closed stdout ------------------------------------------------------------------------------

@pytest.mark.parametrize("argv", [["scenes"], ["check-scene", "spheres"], ["renderers"], ["cache", "info"],
                                  ["compare", "ref.exr", "test.exr"], ["gate", "budget.toml", "--quiet"]],
                         ids=lambda a: a[0])
def test_closed_stdout_is_not_an_error(work, tmp_path, argv):
    r, w = os.pipe()
    os.close(r)  # the reader is gone before the first line (`| head -0`): every write meets EPIPE
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PBRCHECK_CACHE": str(tmp_path / "cache")}
    p = subprocess.run([sys.executable, "-m", "pbrcheck_cli", *argv, *(["--maps", str(tmp_path / "m")]
                                                                        if argv[0] == "gate" else [])],
                       cwd=work, env=env, stdout=w, stderr=subprocess.PIPE, text=True, timeout=120)
    os.close(w)
    assert "Traceback" not in p.stderr and "BrokenPipe" not in p.stderr, p.stderr
    assert p.returncode == (1 if argv[0] == "gate" else 0), p.stderr


# --- numbers and encodings of user files ----------------------------------------------------------

@pytest.mark.parametrize("value", ["0.0", "-1.0", "inf", "nan"])
def test_gate_budget_numbers(work, tmp_path, capfd, monkeypatch, value):
    monkeypatch.setenv("PBRCHECK_CACHE", str(tmp_path / "cache"))
    b = tmp_path / "b.toml"
    b.write_text(f'[[check]]\nname = "same"\ntest = "{work / "ref.exr"}"\nreference = "{work / "ref.exr"}"\n'
                 f'[check.max]\nrelmse = {value}\n')
    rc = main(["gate", str(b), "--quiet", "--maps", str(tmp_path / "maps"), "--junit", str(tmp_path / "j.xml"),
               "--summary", str(tmp_path / "s.md")])
    err = capfd.readouterr().err
    assert "Traceback" not in err
    if value == "0.0":  # identical images pass a budget of 0; nothing divides by it
        assert rc == 0, err
        assert (tmp_path / "j.xml").is_file() and (tmp_path / "s.md").is_file()
    else:
        assert rc == 2 and "relmse: expected a finite number >= 0" in err, err
        assert not (tmp_path / "j.xml").exists()


def test_gate_budget_of_zero_with_a_noisy_reference(tmp_path):
    from compare.gate import Check, CheckResult, Verdict, budget_noise, noise_note

    c = Check(name="x", max={"relmse": 0.0}, min={}, reference="ref.exr")
    r = CheckResult(c, Verdict.PASS, budget_noise=budget_noise(c, {"simulated": {"relmse": 1e-3}}, 64))
    assert "a budget of 0" in noise_note(r)


@pytest.mark.parametrize("value", ["1e9", "1e12", "inf", "nan", "0", "-5"])
def test_renderers_timeout_bounded(tmp_path, capfd, value):
    f = tmp_path / "renderers.toml"
    f.write_text(f'[renderer.a]\ncommand = ["x", "{{out}}"]\ntimeout = {value}\n')
    rc = main(["--renderers", str(f), "renderers"])
    err = capfd.readouterr().err
    assert rc == 2 and "renderer.a.timeout: expected a number of seconds > 0 and <= 86400" in err, err
    assert len(err.strip().splitlines()) == 1


def test_version_command_errors_name_it(tmp_path):
    from clients import config as C
    from clients import run as R

    f = tmp_path / "renderers.toml"
    f.write_text('[renderer.a]\ncommand = ["x", "{out}"]\nversion_command = ["/nonexistent/v", "--version"]\n')
    cfg = C.load_renderers(f)["a"]
    assert "version_command" in R.renderer_version(cfg)


def test_binary_and_non_utf8_user_files(work, tmp_path, capfd):
    glb = tmp_path / "model.glb"
    glb.write_bytes(b"glTF\x02\x00\x00\x00\xff\xfe\x00binary")
    toml = tmp_path / "renderers.toml"
    toml.write_bytes(b"[renderer.a]\ncommand = [\"x\", \"{out}\"]\ndescription = \"caf\xe9\"\n")
    hook = tmp_path / "hook.glsl"
    hook.write_bytes(b"vec3 hook_F(float VoH, vec3 F0) { return F0; } // caf\xe9\n")
    binary_scene = tmp_path / "scene.toml"
    binary_scene.write_bytes(glb.read_bytes())
    # a .glb is a glTF asset scene (pbrcheck.gltf): its reader names the problem
    for argv, what, why in ((["check-scene", str(glb)], glb, "not a valid glTF 2.0 file"),
                            (["check-scene", str(binary_scene)], binary_scene, "not UTF-8"),
                            (["--renderers", str(toml), "renderers"], toml, "not UTF-8"),
                            (["realtime", str(work / "tiny.toml"), "--shader", str(hook), "--out",
                              str(tmp_path / "o.exr")], hook, "not UTF-8")):
        rc = main(argv)
        err = capfd.readouterr().err
        assert rc == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, (argv, err)
        assert str(what) in err and why in err, err


def test_hook_compile_error_is_exit_2_naming_the_line(work, tmp_path, capfd):
    pytest.importorskip("moderngl")
    from pbrcheck.errors import BackendError
    from realtime.gl import get_context

    try:  # skip only where there is no GL at all: an exit 3 of a working GL is a failure, not a skip
        get_context()
    except BackendError as e:
        pytest.skip(f"no GL backend here: {e}")
    hook = tmp_path / "broken.glsl"
    hook.write_text("vec3 hook_F(float VoH, vec3 F0) {\n    return F0 * undefined_thing;\n}\n")
    rc = main(["realtime", str(work / "tiny.toml"), *RT_FAST, "--shader", str(hook), "--out", str(tmp_path / "o.exr")])
    err = capfd.readouterr().err
    assert rc == 2, err
    assert f"{hook}:2" in err.strip().splitlines()[-1], err
    assert not (tmp_path / "o.exr").exists()


def test_compare_refuses_a_large_image_before_reading_it(work, capfd):
    rc = main(["compare", str(work / "ref.exr"), str(work / "test.exr"), "--max-pixels", "100"])
    err = capfd.readouterr().err
    assert rc == 2 and "16x8 = 128 pixels is above compare's limit of 100" in err, err


def test_gate_check_names_that_would_share_a_maps_folder(work, tmp_path, capfd):
    b = tmp_path / "b.toml"
    b.write_text(BUDGET.replace('"test.exr"', f'"{work / "test.exr"}"').replace('"ref.exr"', f'"{work / "ref.exr"}"')
                 + BUDGET.replace("too bright/1", "too bright_1")
                 .replace('"test.exr"', f'"{work / "test.exr"}"').replace('"ref.exr"', f'"{work / "ref.exr"}"'))
    rc = main(["gate", str(b), "--quiet", "--maps", str(tmp_path / "m")])
    err = capfd.readouterr().err
    assert rc == 2 and "maps folder" in err and "too bright/1" in err, err
    assert not (tmp_path / "m").exists()


def test_corrupt_exr_is_one_line_without_the_library_messages(work, tmp_path, capfd):
    big = np.random.default_rng(1).uniform(0, 1, (256, 256, 3)).astype(np.float32)
    write_exr(tmp_path / "big.exr", Image.from_rgb(big))
    data = (tmp_path / "big.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) * 2 // 3])
    rc = main(["compare", str(tmp_path / "cut.exr"), str(tmp_path / "big.exr")])
    cap = capfd.readouterr()
    assert rc == 2 and cap.out == "", cap
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"pbrcheck: error: {tmp_path / 'cut.exr'}: not a readable EXR"), cap.err


def test_refused_tcp_scheduler_fails_at_once(monkeypatch):
    import socket

    import compare.corpus.scheduler as S
    from compare.corpus.scheduler import SchedulerUnavailable, open_executor

    monkeypatch.setattr(S, "PROBE_TIMEOUT_S", 2.0)  # its port is tried this long, not CONNECT_TIMEOUT_S

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there now
    t0 = time.perf_counter()
    with pytest.raises(SchedulerUnavailable, match="cannot connect"):
        with open_executor(f"tcp://127.0.0.1:{port}"):
            pass
    assert time.perf_counter() - t0 < 10


def test_bounded_renderer_output(tmp_path):
    from clients import run as R

    script = "import sys\nfor i in range(40):\n    sys.stdout.write('x' * (1 << 20))\nsys.stdout.write('END')\n"
    r = R.run_process([sys.executable, "-c", script], cwd=tmp_path, timeout=60, label="ext:loud")
    assert r.returncode == 0 and r.stdout.endswith("END") and len(r.stdout) <= R.OUTPUT_TAIL_BYTES


def test_interrupted_rerun_leaves_no_stale_table(work, tmp_path, monkeypatch):
    from compare.corpus.study import CorpusSettings, run_corpus
    from compare.renderers import RendererSpec
    from pbrcheck.scene import load_scene
    from realtime.presets import parse_sets

    monkeypatch.setenv("PBRCHECK_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "corpus"
    out.mkdir()
    (out / "corpus.csv").write_text("environment,renderer\nold,run\n")  # a previous run's table
    (out / "corpus.json").write_text("{}\n")

    def stop(row):
        raise KeyboardInterrupt

    settings = CorpusSettings(load_scene(work / "tiny.toml"),
                              (RendererSpec.parse("default", parse_sets(RT_FAST[1::2])),),
                              spp=4)
    with pytest.raises(KeyboardInterrupt):
        run_corpus(work / "envs", settings, out, scheduler="serial", progress=False, on_row=stop)
    assert not (out / "corpus.csv").exists() and not (out / "corpus.json").exists()


def test_an_interrupt_inside_an_extension_import_is_an_interrupt(monkeypatch, capsys):
    """Ctrl-C while a C extension imports (Mitsuba's set_variant) arrives as a SystemError whose
    context is the KeyboardInterrupt: exit 130 and one line, no traceback."""
    import pbrcheck_cli as cli

    def boom(args):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("<built-in function __import__> returned a result with an exception set")

    ns = type("A", (), {"func": staticmethod(boom)})()
    assert cli._run(ns) == 130
    assert capsys.readouterr().err.strip() == "pbrcheck: interrupted"


# --- an interrupt that Python or C++ swallowed is still an interrupt ----------------------------------

_SWALLOWED = r'''
import gc, os, signal, sys, time
import pbrcheck_cli as cli

def swallowed_in_gc(args):
    # The signal lands in a gc callback (as in Dask's GCDiagnosis): Python can only print it there.
    def cb(phase, info):
        if phase == "start":
            gc.callbacks.remove(cb)
            os.kill(os.getpid(), signal.SIGNUM)
            time.sleep(0.05)  # the handler runs here, inside the callback
    gc.callbacks.append(cb)
    gc.collect()
    for _ in range(200):  # the command's own work goes on: the re-delivered interrupt must land here
        time.sleep(0.01)
    print("finished", flush=True)
    return 0

def swallowed_at_the_end(args):
    # What Python does with an interrupt raised where it cannot propagate (a gc callback, a __del__):
    # hand it to sys.unraisablehook. Here at the command's very end, which it reaches before the
    # re-delivery (20 ms later) would land.
    import types
    from pbrcheck.errors import Terminated
    exc = KeyboardInterrupt() if signal.SIGNUM == signal.SIGINT else Terminated(signal.SIGNUM)
    sys.unraisablehook(types.SimpleNamespace(exc_type=type(exc), exc_value=exc, exc_traceback=None,
                                             err_msg=None, object=None))
    print("finished", flush=True)
    return 0

def swallowed_by_cpp(args):
    # What mi.load_dict gives back when the signal lands in a Python plugin's constructor: a
    # RuntimeError whose text (not chain) holds the interrupt.
    try:
        os.kill(os.getpid(), signal.SIGNUM)
        time.sleep(1)
    except KeyboardInterrupt:
        pass  # C++ caught it ...
    raise RuntimeError("[PluginManager] Traceback ...\nKeyboardInterrupt: ")  # ... and raised this

cli._cmd_scenes = WHICH
sys.exit(cli.main(["scenes"]))
'''


@pytest.mark.parametrize("which", ["swallowed_in_gc", "swallowed_at_the_end", "swallowed_by_cpp"])
@pytest.mark.parametrize("sig", SIGNALS)
def test_swallowed_interrupt_still_interrupts(which, sig):
    code = _SWALLOWED.replace("SIGNUM", sig.name).replace("WHICH", which)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       env={**os.environ, "PYTHONPATH": str(ROOT)}, cwd=ROOT)
    assert r.returncode == 128 + sig, (r.returncode, r.stdout, r.stderr)
    assert ("finished" in r.stdout) == (which == "swallowed_at_the_end")  # the work ran on only there
    assert "Traceback" not in r.stderr, r.stderr
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    assert lines[-1] == ("pbrcheck: interrupted" if sig == signal.SIGINT else "pbrcheck: terminated"), r.stderr
