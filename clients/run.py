"""Run an external renderer on a pbrcheck scene and bring its image back (docs/renderers.md).

API
---
- :func:`render_external` -- export the scene to a temporary folder, run the renderer's command,
  validate its output against the contract, return a pbrcheck :class:`~pbrcheck.exr.Image`
  (linear ``R G B`` plus an ``object`` AOV, metadata renderer / version / command / seconds);
  cached by scene hash + renderer config + the client's lockfile hash.
- :func:`run_process` -- one command in its own session, killed with all its descendants (its
  session, its process group, every process carrying its :data:`MARKER_VAR`) after the timeout, on
  Ctrl-C or SIGTERM; the tails of stdout and stderr come back (bounded buffers).
- :func:`kill_run`, :func:`run_members` -- that kill, and the /proc walk that finds the run's processes.
- :func:`serve_clients`, :func:`serve_processes_started`, :func:`idle_serve_pids` -- a context in which the renders of every renderer with a ``serve_command``
  (the built-in browser clients) go to one long-lived process per client (one headless Chromium and
  one tab for all of a run's renders, ``clients/browser/headless.mjs``'s serve mode) instead of one
  process (one browser start) per render; the processes are killed like :func:`run_process`'s
  (session, group, marker) when the block ends, on Ctrl-C / SIGTERM, and at exit. Same pixels
  (the same page renders in a fresh document); a render that times out kills its server (the next
  render starts another).
- :func:`read_output` -- a renderer's output file, validated (exists, readable, size, finite).
- :func:`object_ids` -- the ``object`` AOV of a scene at pixel centres (numpy ray casting).
- :func:`ray_distances` -- the distance along rays to a sphere's or rectangle's first hit (object_ids' and compare.transmission_split's).
- :class:`RendererError` -- every failure, one line naming the renderer (exit 2; the gate's
  ``error``).

Failure modes (each a :class:`RendererError`, nothing written outside the temporary folder): the
executable is missing; it exits non-zero (the last lines of its stderr are shown); it runs past
``timeout`` (its whole session and every descendant are killed); it writes no file; the file is unreadable, of the
wrong size, or holds NaN/Inf.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import queue
import signal
import subprocess
import tempfile
import threading
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pbrcheck import __version__
from pbrcheck.cache import Cache, cache_key
from pbrcheck.camera import primary_rays
from pbrcheck.environment import load_environment, scene_hash
from pbrcheck.errors import ImageIOError, PbrcheckError
from pbrcheck.export import EXPORT_FORMAT_VERSION, OUTPUT_SUFFIX, export_scene
from pbrcheck.exr import ENGINE_VARIANCE_META, VARIANCE, Image
from pbrcheck.hdrimage import read_float_image, read_png_srgb
from pbrcheck.progress import Progress
from pbrcheck.scene import Plane, Scene, Sphere, plane_frame

from .config import RendererConfig, expand, get_renderer

#: Lines of a failing renderer's stderr shown in the one-line error.
STDERR_TAIL_LINES = 3
#: Characters of that tail at most.
STDERR_TAIL_CHARS = 400
#: Seconds a version command may take.
VERSION_TIMEOUT_S = 30.0
#: Seconds to wait for a killed process group's pipes to close.
KILL_GRACE_S = 5.0
CACHE_NAMESPACE = "clients"

_versions: dict[tuple, str] = {}


class RendererError(PbrcheckError):
    """An external renderer failed (names the renderer and what went wrong)."""


@dataclass
class ProcessResult:
    """What :func:`run_process` saw: exit status, stdout, stderr and wall seconds."""
    returncode: int
    stdout: str
    stderr: str
    seconds: float


def stderr_tail(text: str) -> str:
    """The last :data:`STDERR_TAIL_LINES` non-empty lines of ``text`` joined by `` | ``."""
    lines = [l.strip() for l in text.splitlines() if l.strip()]
    tail = " | ".join(lines[-STDERR_TAIL_LINES:])
    return tail[-STDERR_TAIL_CHARS:] if tail else "(no stderr)"


#: The environment variable that marks every process of one :func:`run_process` (its value is unique
#: per run): descendants that left the session (``setsid``) still carry it and are found by it.
MARKER_VAR = "PBRCHECK_RUN_MARKER"
#: Bytes of a renderer's stdout and of its stderr kept (the tail; the rest is read and dropped).
OUTPUT_TAIL_BYTES = 1 << 20


class _Tail:
    """The last ``limit`` bytes of a stream, read to its end by a daemon thread."""

    def __init__(self, stream, limit: int = OUTPUT_TAIL_BYTES):
        self.buf = bytearray()
        self.dropped = 0
        self.limit = limit
        self.thread = threading.Thread(target=self._pump, args=(stream,), daemon=True)
        self.thread.start()

    def _pump(self, stream) -> None:
        try:
            while True:
                chunk = stream.read1(1 << 16) if hasattr(stream, "read1") else stream.read(1 << 16)
                if not chunk:
                    break
                self.buf += chunk
                if len(self.buf) > 2 * self.limit:
                    cut = len(self.buf) - self.limit
                    self.dropped += cut
                    del self.buf[:cut]
        except (OSError, ValueError):
            pass
        finally:
            try:
                stream.close()
            except OSError:
                pass

    def text(self, grace: float | None = None) -> str:
        self.thread.join(grace)
        data = bytes(self.buf[-self.limit:])
        return data.decode("utf-8", "replace")

    def seen(self) -> int:
        """Bytes read so far (a mark for :meth:`since`)."""
        return self.dropped + len(self.buf)

    def since(self, mark: int) -> str:
        """What was read after ``mark`` (what is still kept of it)."""
        return bytes(self.buf[max(0, mark - self.dropped):]).decode("utf-8", "replace")


def _proc_ids(pid: int) -> tuple[int, int] | None:
    """(process group, session) of ``pid`` from /proc (None when it is gone)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat = f.read().decode("utf-8", "replace")
    except OSError:
        return None
    fields = stat[stat.rindex(")") + 2:].split()
    return int(fields[2]), int(fields[3])


def _has_marker(pid: int, marker: bytes) -> bool:
    try:
        with open(f"/proc/{pid}/environ", "rb") as f:
            return marker in f.read().split(b"\0")
    except OSError:
        return False


def run_members(leader: int, marker: str) -> list[int]:
    """Every process of one run: in the session or process group of ``leader``, or carrying
    ``MARKER_VAR=marker`` in its environment (a descendant that called ``setsid``); found by walking
    /proc (no cgroup needed). Empty without /proc."""
    me = os.getpid()
    tag = f"{MARKER_VAR}={marker}".encode()
    out = []
    try:
        pids = [int(d) for d in os.listdir("/proc") if d.isdigit()]
    except OSError:
        return out
    for pid in pids:
        if pid == me:
            continue
        ids = _proc_ids(pid)
        if ids is None:
            continue
        if leader in ids or _has_marker(pid, tag):
            out.append(pid)
    return out


def kill_run(proc: subprocess.Popen, marker: str) -> None:
    """SIGKILL the whole run of ``proc``: its process group, its session and every process carrying
    its marker (:func:`run_members`), repeated until none is left (a process forking while it is
    killed) or 20 rounds have passed."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)   # the session leader's pid is the group id
    except (ProcessLookupError, PermissionError):
        pass
    for _ in range(20):
        members = [p for p in run_members(proc.pid, marker) if p != proc.pid or proc.returncode is None]
        alive = []
        for pid in members:
            try:
                os.kill(pid, signal.SIGKILL)
                alive.append(pid)
            except (ProcessLookupError, PermissionError):
                pass
        if proc.returncode is None:
            try:
                proc.wait(timeout=0.05)
            except subprocess.TimeoutExpired:
                pass
        if not alive:
            return
        time.sleep(0.02)


def run_process(argv: list[str], *, cwd: Path, timeout: float, label: str, key: str = "command") -> ProcessResult:
    """Run ``argv`` in ``cwd`` in a new session; on timeout, interrupt or SIGTERM kill the whole run
    (:func:`kill_run`: its session, its process group and every descendant carrying the run's
    marker variable, ``setsid`` grandchildren included), and after a normal exit whatever it left
    running. stdout and stderr are read into bounded buffers (:data:`OUTPUT_TAIL_BYTES`, the tail).

    Raises
    ------
    RendererError
        The executable is missing or not executable, or the command ran past ``timeout``.
    """
    t0 = time.perf_counter()
    who = f"{label}: " if key == "command" else f"{label}: {key}: "
    marker = uuid.uuid4().hex
    env = {**os.environ, MARKER_VAR: marker}
    try:
        proc = subprocess.Popen(argv, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, start_new_session=True, env=env)
    except FileNotFoundError:
        raise RendererError(f"{who}executable not found: {argv[0]!r} (is it installed and on PATH?)") from None
    except PermissionError:
        raise RendererError(f"{who}cannot execute {argv[0]!r} (permission denied)") from None
    except OSError as e:
        raise RendererError(f"{who}cannot start {argv[0]!r}: {e.strerror or e}") from None
    out, err = _Tail(proc.stdout), _Tail(proc.stderr)
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        kill_run(proc, marker)
        raise RendererError(f"{who}timed out after {timeout:g} s (killed with its children: its session, "
                            f"its process group and every descendant carrying {MARKER_VAR}); stderr: "
                            f"{stderr_tail(err.text(KILL_GRACE_S))}") from None
    except BaseException:   # Ctrl-C, SIGTERM (pbrcheck.errors.Terminated)
        kill_run(proc, marker)
        raise
    kill_run(proc, marker)  # whatever the renderer left running
    return ProcessResult(proc.returncode, out.text(KILL_GRACE_S), err.text(KILL_GRACE_S),
                         time.perf_counter() - t0)


class _Server:
    """One serve-mode process of a renderer (``serve_command``): its renders one at a time; started
    in its own session with its own :data:`MARKER_VAR` and killed like :func:`run_process`'s run."""

    def __init__(self, argv: list[str], cwd: Path, label: str):
        self.label = label
        self.marker = uuid.uuid4().hex
        try:
            self.proc = subprocess.Popen(argv, cwd=cwd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         stderr=subprocess.PIPE, start_new_session=True,
                                         env={**os.environ, MARKER_VAR: self.marker})
        except OSError as e:
            raise RendererError(f"{label}: serve_command: cannot start {argv[0]!r}: {e.strerror or e}") from None
        self.replies: queue.Queue = queue.Queue()
        self.err = _Tail(self.proc.stderr)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        try:
            for line in self.proc.stdout:
                self.replies.put(line)
        except (OSError, ValueError):
            pass
        self.replies.put(None)   # end of stdout: the process is gone

    @property
    def alive(self) -> bool:
        return self.proc.returncode is None and self.proc.poll() is None

    def render(self, argv: list[str], timeout: float) -> ProcessResult:
        """One render of command line ``argv``, as :func:`run_process` reports it (exit status 0 or 1,
        the render's stdout line, the stderr written during it).

        Raises
        ------
        RendererError
            The render ran past ``timeout`` (the server is killed).
        """
        t0 = time.perf_counter()
        mark = self.err.seen()
        try:
            self.proc.stdin.write((json.dumps(argv) + "\n").encode())
            self.proc.stdin.flush()
            line = self.replies.get(timeout=timeout)
        except queue.Empty:
            self.close()
            raise RendererError(f"{self.label}: timed out after {timeout:g} s (its serve process killed with its "
                                f"children); stderr: {stderr_tail(self.err.since(mark))}") from None
        except (BrokenPipeError, ValueError, OSError):
            line = None
        except BaseException:   # Ctrl-C, SIGTERM: the whole run goes
            self.close()
            raise
        seconds = time.perf_counter() - t0
        if line is None:
            self.close()
            return ProcessResult(self.proc.returncode if self.proc.returncode else 1, "",
                                 self.err.since(mark) + f"\n{self.label}: its serve process exited", seconds)
        try:
            reply = json.loads(line)
            ok = reply["ok"] is True
            text = str(reply["stdout"] if ok else reply["error"])
        except (ValueError, KeyError, TypeError):
            self.close()
            return ProcessResult(1, "", f"{self.label}: serve process answered {line[:200]!r}", seconds)
        if ok:
            return ProcessResult(0, text + "\n", self.err.since(mark), seconds)
        return ProcessResult(1, "", self.err.since(mark) + "\n" + text, seconds)

    def close(self) -> None:
        """Close its stdin and kill the whole run (:func:`kill_run`)."""
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        kill_run(self.proc, self.marker)


class _Servers:
    """The serve-mode processes of a :func:`serve_clients` block: idle ones by (serve command,
    working folder); a render takes one (or starts one) and gives it back."""

    def __init__(self):
        self.lock = threading.Lock()
        self.idle: dict[tuple, list[_Server]] = {}
        self.all: list[_Server] = []
        self.closed = False

    def render(self, cfg: RendererConfig, argv: list[str]) -> ProcessResult:
        sargv = expand(cfg, cfg.serve_command, key="serve_command")
        key = (tuple(sargv), str(cfg.config_dir))
        with self.lock:
            if self.closed:
                raise RendererError(f"{cfg.label}: the run is ending")
            pool = self.idle.setdefault(key, [])
            while pool and not pool[-1].alive:
                pool.pop()
            server = pool.pop() if pool else None
            if server is None:
                server = _Server(sargv, cfg.config_dir, cfg.label)
                self.all.append(server)
        r = server.render(argv, cfg.timeout)
        with self.lock:
            if server.alive and not self.closed:
                self.idle[key].append(server)
        return r

    def close(self) -> None:
        with self.lock:
            self.closed = True
            servers, self.all, self.idle = self.all, [], {}
        for s in servers:
            s.close()


_servers: _Servers | None = None
_servers_lock = threading.Lock()


@contextlib.contextmanager
def serve_clients(enabled: bool = True):
    """``with serve_clients():`` -- the block's renders of renderers with a ``serve_command`` go to
    one process per client, kept across renders and killed when the block ends (however it ends)
    and at exit. Nested blocks share the outer one's processes. ``enabled=False``: the block's
    renders each run their own process (``pbrcheck bench serve``'s "before"); an enclosing block's
    processes stay for after it."""
    global _servers
    if not enabled:
        with _servers_lock:
            saved, _servers = _servers, None
        try:
            yield
        finally:
            with _servers_lock:
                _servers = saved
        return
    with _servers_lock:
        outer = _servers is not None
        if not outer:
            _servers = _Servers()
    if outer:
        yield
        return
    try:
        yield
    finally:
        with _servers_lock:
            servers, _servers = _servers, None
        servers.close()


@atexit.register
def _close_servers() -> None:
    if _servers is not None:
        _servers.close()


def idle_serve_pids() -> list[int]:
    """The process ids of the current :func:`serve_clients` block's serve processes that are idle
    (not rendering now): their browsers' memory is no render's (``compare.fidelity``'s usage)."""
    servers = _servers
    if servers is None:
        return []
    with servers.lock:
        return [s.proc.pid for pool in servers.idle.values() for s in pool if s.alive]


def serve_processes_started() -> int:
    """Serve processes started so far in the current :func:`serve_clients` block (0 outside one)."""
    servers = _servers
    return len(servers.all) if servers is not None else 0


def _run_render(cfg: RendererConfig, argv: list[str]) -> ProcessResult:
    """One render of ``cfg``: by its serve process inside :func:`serve_clients`, else :func:`run_process`."""
    servers = _servers
    if servers is not None and cfg.serve_command:
        return servers.render(cfg, argv)
    return run_process(argv, cwd=cfg.config_dir, timeout=cfg.timeout, label=cfg.label)


def read_output(path: Path, fmt: str, width: int, height: int, label: str) -> np.ndarray:
    """The renderer's output ``path`` in format ``fmt`` as (H, W, 3) float32, row 0 at the top
    (``png-srgb``: display values in [0, 1]).

    Raises
    ------
    RendererError
        No file, unreadable, wrong size, or NaN/Inf.
    """
    if not path.is_file():
        raise RendererError(f"{label}: wrote no output file (expected {path.name}, format {fmt})")
    try:
        rgb = read_png_srgb(path) if fmt == "png-srgb" else read_float_image(path)
    except ImageIOError as e:
        raise RendererError(f"{label}: unreadable output ({e.problem})") from None
    if rgb.shape[:2] != (height, width):
        raise RendererError(f"{label}: output is {rgb.shape[1]}x{rgb.shape[0]}, expected {width}x{height}")
    bad = ~np.isfinite(rgb)
    if bad.any():
        n = int(bad.any(axis=-1).sum())
        raise RendererError(f"{label}: output has {n} pixel(s) with NaN/Inf")
    return np.ascontiguousarray(rgb, dtype=np.float32)


def _estimate(cfg: RendererConfig, images: list[np.ndarray], var_out: Path, width: int, height: int
              ) -> tuple[np.ndarray, np.ndarray | None, str]:
    """(image, its per-pixel variance or None, how the variance was obtained) of a renderer's runs:
    one run as it is (with ``variance = true`` its variance file, validated like the image and
    refused where negative); N > 1 runs: their mean, and the unbiased sample variance over N (the
    variance of the mean of N independent estimates)."""
    label = cfg.label
    if len(images) > 1:
        stack = np.stack([x.astype(np.float64) for x in images])
        n = len(images)
        return (stack.mean(axis=0).astype(np.float32), (stack.var(axis=0, ddof=1) / n).astype(np.float32),
                f"{n} independent renders (sample variance / {n})")
    if not cfg.variance:
        return images[0], None, ""
    var = read_output(var_out, cfg.output, width, height, f"{label}: variance")
    if (var < 0).any():
        raise RendererError(f"{label}: variance: {int((var < 0).any(axis=-1).sum())} pixel(s) with a negative "
                            "variance")
    return images[0], var, "the renderer's variance image"


def renderer_version(cfg: RendererConfig) -> str:
    """The first stdout line of the renderer's ``version_command`` ("unknown" without one or when
    it fails: a version is recorded, never required)."""
    if not cfg.version_command:
        return "unknown"
    key = (cfg.name, cfg.version_command, cfg.lockfile_hash())
    if key not in _versions:
        argv = expand(cfg, cfg.version_command, key="version_command")
        try:
            r = run_process(argv, cwd=cfg.config_dir, timeout=VERSION_TIMEOUT_S, label=cfg.label,
                            key="version_command")
            line = r.stdout.strip().splitlines()[0] if r.returncode == 0 and r.stdout.strip() else ""
            _versions[key] = line or f"unknown (version command exited {r.returncode}: {stderr_tail(r.stderr)})"
        except RendererError as e:
            _versions[key] = f"unknown ({e})"
    return _versions[key]


def ray_distances(obj, o: np.ndarray, d: np.ndarray) -> np.ndarray | None:
    """The distance from ``o`` along each unit ray ``d`` (..., 3) to ``obj``'s first hit in front of
    ``o`` (inf: a miss), in float64, for a sphere or a rectangle; None for any other object."""
    if isinstance(obj, Sphere):
        oc = o - np.asarray(obj.center, float)
        b = d @ oc
        c = oc @ oc - obj.radius ** 2
        disc = b * b - c
        sq = np.sqrt(np.maximum(disc, 0.0))
        t = np.where(-b - sq > 0, -b - sq, -b + sq)
        return np.where((disc >= 0) & (t > 0), t, np.inf)
    if isinstance(obj, Plane):
        tg, bt, n = (np.asarray(v, float) for v in plane_frame(obj.normal))
        denom = d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((np.asarray(obj.center, float) - o) @ n) / denom
        p = o + d * t[..., None] - np.asarray(obj.center, float)
        inside = (np.abs(p @ tg) <= obj.size[0] / 2) & (np.abs(p @ bt) <= obj.size[1] / 2)
        return np.where((np.abs(denom) > 1e-12) & (t > 0) & inside, t, np.inf)
    return None


def object_ids(scene: Scene) -> np.ndarray:
    """(H, W) float32 object index seen through each pixel centre (-1: background), by ray casting
    the scene's spheres and rectangles in float64 (the ``object`` AOV of external images)."""
    o, d = primary_rays(scene.camera)
    best = np.full(d.shape[:2], np.inf)
    ids = np.full(d.shape[:2], -1.0, np.float32)
    for obj in scene.objects:
        t = ray_distances(obj, o, d)
        if t is None:  # meshes below; the loader expands grids
            continue
        closer = t < best
        best = np.where(closer, t, best)
        ids[closer] = obj.id
    if getattr(scene, "assets", ()):  # meshes: pixel-centre rasterization (pbrcheck.gltf_export)
        from pbrcheck.gltf_export import mesh_object_ids
        best = np.ascontiguousarray(best)
        mesh_object_ids(scene, ids, best)
    return ids


def cache_key_for(scene: Scene, cfg: RendererConfig, env_hash: str) -> str:
    """The cache key of one external render: scene hash, renderer config (with the lockfile's and
    the inputs' hashes), the export format and the renderer's version line (:func:`renderer_version`,
    once per process: the built-in clients print the engine's, Chromium's and node's versions).
    The version is there for what no lockfile pins: the system's Chromium (its SwiftShader rasterizes
    the pixels), upgraded by the package manager under an unchanged lockfile."""
    # a scene with unmodelled features: its export has their material extensions removed (since
    # pbrcheck.unmodelled), so its renders are not those of an earlier, unstripped export; every
    # other scene keeps its key (and its cached renders)
    um = getattr(scene, "unmodelled", ())
    stripped = {"unmodelled_removed": sorted({u.feature for u in um})} if um else {}
    return cache_key(kind="external", scene=scene_hash(scene, env_hash), renderer=cfg.cache_dict(),
                     export_format=EXPORT_FORMAT_VERSION, version=renderer_version(cfg), **stripped)


def render_external(scene: Scene, name: str, *, renderers_file: str | Path | None = None,
                    use_cache: bool = True, progress: bool = False) -> Image:
    """Render ``scene`` with the external renderer ``name`` (``threejs`` or ``ext:threejs``).

    Parameters
    ----------
    scene : Scene
        The scene.
    name : str
        A renderer of :func:`clients.config.load_renderers`.
    renderers_file : str or Path, optional
        The user renderers file (default: :func:`clients.config.default_renderers_file`).
    use_cache : bool, optional
        Read and write the render cache (default True).
    progress : bool, optional
        Show progress on stderr.

    Returns
    -------
    Image
        ``R G B`` (linear radiance; display values for ``png-srgb``) and ``object``; metadata
        ``renderer``, ``version``, ``command``, ``seconds``, ``output``, ``display_referred``,
        ``timings`` (``{"frame": seconds}``), ``timed_on``, ``scene_hash``.

    Raises
    ------
    RendererError, RendererConfigError, EnvironmentMapError
    """
    cfg = get_renderer(name, renderers_file)
    label = cfg.label
    env = load_environment(scene)
    key = cache_key_for(scene, cfg, env.content_hash)
    cache = Cache(CACHE_NAMESPACE)
    if use_cache:
        hit = cache.get(key)
        if hit is not None:
            return hit
    cam = scene.camera
    version = renderer_version(cfg)
    with Progress(f"{label} {scene.name}", total=3, enabled=progress) as prog, \
            tempfile.TemporaryDirectory(prefix="pbrcheck-ext-") as tmp:
        folder = Path(tmp) / "scene"
        exp = export_scene(scene, folder, output=cfg.output, env=env)
        prog.update(1, "exported")
        runs = []
        for k in range(cfg.renders):  # one run, or renders independent ones ({seed} = k)
            suffix = OUTPUT_SUFFIX[cfg.output]
            out = Path(tmp) / (f"output{suffix}" if cfg.renders == 1 else f"output_{k}{suffix}")
            var_out = Path(tmp) / f"variance{suffix}"
            extra = {"variance": var_out} if cfg.variance else {}
            if cfg.renders > 1:
                extra["seed"] = k
            argv = expand(cfg, cfg.command, scenario=exp.files["scenario.json"], out=out, dir=folder,
                          width=cam.width, height=cam.height, **extra)
            r = _run_render(cfg, argv)
            if r.returncode != 0:
                raise RendererError(f"{label}: exited with status {r.returncode}; stderr: {stderr_tail(r.stderr)}")
            runs.append((r, read_output(out, cfg.output, cam.width, cam.height, label)))
        prog.update(1, "rendered")
        rgb, variance, how = _estimate(cfg, [x for _, x in runs], var_out, cam.width, cam.height)
        r = runs[-1][0]
        seconds = sum(x.seconds for x, _ in runs)
        prog.update(1, "validated")
    meta = {"renderer": label, "kind": "external", "version": version, "command": json.dumps(list(cfg.command)),
            "seconds": f"{seconds:.3f}", "output": cfg.output,
            "display_referred": "1" if cfg.output == "png-srgb" else "0",
            "timings": json.dumps({"frame": round(seconds, 4)}), "timed_on": cfg.timed_on or "unstated",
            "scene_hash": scene_hash(scene, env.content_hash), "pbrcheck_version": __version__,
            "renderer_stdout": r.stdout.strip().splitlines()[-1][:500] if r.stdout.strip() else ""}
    extra = {}
    if variance is not None:  # the engine's own noise: the comparator subtracts it (compare.metrics)
        meta[ENGINE_VARIANCE_META] = how
        extra = {c: variance[..., i] for i, c in enumerate(VARIANCE)}
    img = Image.from_rgb(rgb, meta, object=object_ids(scene), **extra)
    if use_cache:
        cache.put(key, img)
    return img
