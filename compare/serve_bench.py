"""``pbrcheck bench serve``: the web clients' renders of a small report, one browser per render
against one browser per client for the whole run (``clients.run.serve_clients``; issue 39).

API: :func:`bench_serve` (the figures as a dict), :data:`DEFAULT_SCENES`, :data:`DEFAULT_CLIENTS`.

Both modes render the same scenes with the same clients, uncached, in the same order (scene by
scene, each client in turn, as the report's prefetch does on one worker); a warm-up render of the
first scene with each client comes first in each mode and is not counted (it reads Chromium and
the engine's modules from disk into the OS's page cache, whichever mode comes first). Figures per
mode: wall seconds, CPU seconds of this process and every descendant (node, Chromium's browser,
GPU and renderer processes: ``compare.fidelity._Usage``'s polling; a descendant's last
``MEMORY_POLL_S`` is missed), peak resident memory, Chromium starts (served: one per client, started by the warm-up); and the ratios. Same pixels in
both modes (the served page renders in a fresh document): the bench checks it.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

from clients import run as client_run
from pbrcheck.scene import load_scene

from .fidelity import _Usage

#: The committed report's scenes (Makefile REPORT_SCENES) and web clients (REPORT_CLIENTS).
DEFAULT_SCENES = ("spheres", "furnace", "grazing")
DEFAULT_CLIENTS = ("threejs", "sample-viewer")


def _renders(scenes, clients) -> tuple[dict, dict]:
    """Every (scene, client) render, uncached, under a :class:`_Usage`: (images by key, figures)."""
    images = {}
    for name in clients:  # warm-up (not counted)
        client_run.render_external(scenes[0], name, use_cache=False)
    with _Usage() as u:
        for scene in scenes:
            for name in clients:
                img = client_run.render_external(scene, name, use_cache=False)
                images[(scene.name, name)] = np.stack([img.channels[c] for c in "RGB"], -1)
    served = client_run.serve_processes_started()  # the warm-up's processes: they served the counted renders
    n = len(scenes) * len(clients)
    return images, {"renders": n, "wall_s": round(u.wall, 2), "cpu_s": round(u.cpu, 2),
                    "wall_per_render_s": round(u.wall / n, 2), "cpu_per_render_s": round(u.cpu / n, 2),
                    "peak_mib": round(u.peak / 2 ** 20, 1),
                    "chromium_starts": served or n}


def bench_serve(scene_names=DEFAULT_SCENES, clients=DEFAULT_CLIENTS) -> dict:
    """The figures of both modes (module docstring) and their ratios."""
    scenes = [load_scene(s) for s in scene_names]
    load0 = os.getloadavg()[0]
    with client_run.serve_clients(enabled=False):
        before_img, before = _renders(scenes, clients)
    with client_run.serve_clients():
        after_img, after = _renders(scenes, clients)
    same = all(np.array_equal(before_img[k], after_img[k]) for k in before_img)
    return {"bench": "serve", "machine": f"{platform.node()} ({platform.machine()}, CPU only: WebGL2 on SwiftShader)",
            "when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "load_average_1min": [round(load0, 2), round(os.getloadavg()[0], 2)],  # at the start, at the end
            "scenes": list(scene_names), "clients": list(clients),
            "one_browser_per_render": before, "one_browser_per_client": after,
            "wall_ratio": round(before["wall_s"] / after["wall_s"], 2),
            "cpu_ratio": round(before["cpu_s"] / after["cpu_s"], 2),
            "same_pixels": same}
