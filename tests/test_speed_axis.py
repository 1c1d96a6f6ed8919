"""The report's speed axis names the GL renderer and the clock its timings were taken with."""

from __future__ import annotations

from compare.report.sweep import plot_speed_error, timed_on, timed_on_label
from pbrcheck.exr import Image


def test_timed_on_label():
    rows = [{"gl_renderer": "llvmpipe (LLVM 19.1.7, 256 bits)", "timing_clock": "wall"},
            {"gl_renderer": "llvmpipe (LLVM 19.1.7, 256 bits)", "timing_clock": "wall"}]
    assert timed_on_label(rows) == "on llvmpipe (LLVM 19.1.7, 256 bits) (wall)"
    rows.append({"gl_renderer": "NVIDIA H100 80GB HBM3/PCIe/SSE2", "timing_clock": "gl_timer_query"})
    assert timed_on_label(rows) == ("on NVIDIA H100 80GB HBM3/PCIe/SSE2 (gl timer query); "
                                    "on llvmpipe (LLVM 19.1.7, 256 bits) (wall)")
    assert timed_on_label([{"preset": "x"}]) == ""


def test_timed_on_reads_image_metadata():
    import numpy as np

    img = Image({"R": np.zeros((2, 2))}, {"gl_renderer": "NVIDIA X", "timing_clock": "gl_timer_query"})
    assert timed_on(img) == {"gl_renderer": "NVIDIA X", "timing_clock": "gl_timer_query"}


def test_speed_plot_labels_the_time_axes(tmp_path, monkeypatch):
    import compare.report.sweep as sw

    labels = []
    real = sw.pyplot

    def spy():
        plt = real()
        orig = plt.Axes.set_xlabel

        def set_xlabel(self, text, *a, **k):
            labels.append(text)
            return orig(self, text, *a, **k)

        monkeypatch.setattr(plt.Axes, "set_xlabel", set_xlabel)
        return plt

    monkeypatch.setattr(sw, "pyplot", spy)
    rows = [{"preset": "a", "precompute_s": 0.1, "frame_s": 0.01, "relmse": 0.1, "flip_mean": 0.2,
             "gl_renderer": "llvmpipe", "timing_clock": "wall"}]
    plot_speed_error(tmp_path / "s.png", rows, lambda r: r["preset"])
    assert labels and all("on llvmpipe (wall)" in t for t in labels)


def test_realtime_meta_names_its_clock():
    from pbrcheck.scene import load_scene
    from realtime import gl
    from realtime.render import render_realtime

    img = render_realtime(load_scene("spheres").with_camera(width=24, height=20), "default", progress=False)
    assert img.meta["timing_clock"] == gl.timing_clock()
    assert img.meta["timing_clock"] == (gl.CLOCK_WALL if gl.is_software_renderer() else gl.CLOCK_GL_TIMER)
