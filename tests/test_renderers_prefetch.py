"""``compare.renderers.prefetch_external``: external renderers' images rendered in a background thread,
taken by ``render_under_test``; their errors surface where the image is used; nothing leaks out of
the context."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import compare.renderers as renderers
from clients.run import RendererError
from pbrcheck.exr import Image
from pbrcheck.scene import load_scene

# External renderers that no renderers.toml defines (the fixture replaces their render): specs made
# directly, as RendererSpec.parse would make them for a configured name.
ONE = renderers.RendererSpec("ext:one", "ext:one")
BROKEN = renderers.RendererSpec("ext:broken", "ext:broken")


@pytest.fixture
def fake_external(monkeypatch):
    calls = []

    def render_external(scene, name, *, progress=False, **kw):
        calls.append((scene.camera.width, name, threading.current_thread().name))
        if name == "ext:broken":
            raise RendererError(f"{name}: exited with status 1")
        time.sleep(0.05)
        return Image.from_rgb(np.full((scene.camera.height, scene.camera.width, 3), 0.5, np.float32),
                              {"renderer": name})

    monkeypatch.setattr(renderers._clients, "render_external", render_external)
    return calls


def test_prefetched_images_come_from_the_background_thread(fake_external):
    a = load_scene("spheres").with_camera(width=16, height=12)
    b = a.with_camera(width=20, height=12)
    with renderers.prefetch_external([(a, ONE), (b, ONE), (a, renderers.RendererSpec.parse("default"))]) as pre:
        ctx = renderers.RenderContext(prefetch=pre)
        img = renderers.render_under_test(a, ONE, context=ctx)
        img2 = renderers.render_under_test(load_scene("spheres").with_camera(width=20, height=12), ONE, context=ctx)
        # used once: a second request renders (through the renderer's own cache) in this thread
        again = renderers.render_under_test(a, ONE, context=ctx)
    assert img.shape == (12, 16) and img2.shape == (12, 20) and again.shape == (12, 16)
    threads = [t for _, _, t in fake_external]
    assert threads[:2] == ["pbrcheck-prefetch_0"] * 2 and threads[2] == threading.current_thread().name
    assert [c[0] for c in fake_external] == [16, 20, 16]  # only the external renderers were prefetched
    assert pre.take(b, ONE) is None  # nothing is left behind after the block


def test_without_the_prefetch_in_its_context_a_render_renders(fake_external):
    a = load_scene("spheres").with_camera(width=16, height=12)
    with renderers.prefetch_external([(a, ONE)]) as pre:
        renderers.render_under_test(a, ONE)  # DIRECT: this thread renders
        assert pre.take(a, ONE) is not None  # the background render is still there
    assert [t for _, _, t in fake_external].count(threading.current_thread().name) == 1


def test_a_failed_prefetch_raises_where_the_image_is_used(fake_external):
    a = load_scene("spheres").with_camera(width=16, height=12)
    with renderers.prefetch_external([(a, BROKEN)]) as pre:
        with pytest.raises(RendererError, match="exited with status 1"):
            renderers.render_under_test(a, BROKEN, context=renderers.RenderContext(prefetch=pre))


def test_unused_prefetches_are_cancelled_or_finished_on_exit(fake_external):
    scenes = [load_scene("spheres").with_camera(width=8 + k, height=8) for k in range(6)]
    with renderers.prefetch_external([(s, ONE) for s in scenes]):
        pass
    # the context waited for what had started and cancelled the rest: no thread left running
    assert len(fake_external) < len(scenes)
    assert not [t for t in threading.enumerate() if t.name.startswith("pbrcheck-prefetch")]
