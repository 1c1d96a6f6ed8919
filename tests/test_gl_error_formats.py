"""Driver compile-error formats mapped back to the original file and line (no GL context needed).

The messages are captured from real drivers: Mesa (llvmpipe) and NVIDIA (H100, driver 5xx), both for
the same broken ``lib.glsl`` (``return x +;`` on its line 3) assembled at line 6.
"""

from realtime import gl

MESA = ("GLSL Compiler failed\n\ncompute_shader\n==============\n"
        "0:6(15): error: syntax error, unexpected ';'\n")
NVIDIA = ("GLSL Compiler failed\n\ncompute_shader\n==============\n"
          "0(6) : error C0000: syntax error, unexpected ';', expecting \"::\" at token \";\"\n"
          "0(7) : error C1503: undefined variable \"x\"\n")


def _source():
    lmap = [("<generated>", 1), ("<registry>", 1), ("<defines>", 2), ("entry.comp", 1),
            ("lib.glsl", 2), ("lib.glsl", 3), ("lib.glsl", 4), ("entry.comp", 3)]
    return gl.Source("\n".join(f"line {k}" for k in range(len(lmap))) + "\n", lmap)


def test_mesa_format_maps_to_file_line_and_column():
    assert gl.map_errors(MESA, _source()) == "lib.glsl:3(15): error: syntax error, unexpected ';'"


def test_nvidia_format_maps_to_file_and_line():
    out = gl.map_errors(NVIDIA, _source())
    assert out.startswith("lib.glsl:3 : error C0000: syntax error")
    assert "; lib.glsl:4 : error C1503" in out
    assert "0(6)" not in out


def test_unknown_format_is_kept_whole_and_out_of_range_lines_unchanged():
    assert gl.map_errors("something broke", _source()) == "something broke"
    assert gl.map_errors("0(99) : error C0000: x", _source()) == "0(99) : error C0000: x"
    assert gl.map_errors("0:99(1): error: x", _source()) == "0:99(1): error: x"
    # a number in parentheses inside the text is not a location
    assert gl.map_errors("0:6(2): error: f(3) : bad", _source()) == "lib.glsl:3(2): error: f(3) : bad"


# ---- timing clocks ------------------------------------------------------------------------------

class _FakeQuery:
    elapsed = 2_500_000  # ns

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class _FakeCtx:
    def __init__(self):
        self.queries = 0
        self.finished = 0

    def query(self, time=False, **kw):
        assert time
        self.queries += 1
        return _FakeQuery()

    def finish(self):
        self.finished += 1


def test_timing_clock_by_renderer():
    assert gl.timing_clock("llvmpipe (LLVM 19.1.7, 256 bits)") == gl.CLOCK_WALL
    assert gl.timing_clock("softpipe") == gl.CLOCK_WALL
    assert gl.timing_clock("NVIDIA H100 80GB HBM3/PCIe/SSE2") == gl.CLOCK_GL_TIMER
    assert gl.timing_clock("AMD Radeon RX 7900 (radeonsi, navi31, LLVM 17)") == gl.CLOCK_GL_TIMER


def test_timed_uses_a_timer_query_on_a_gpu_and_the_wall_clock_on_llvmpipe():
    ctx = _FakeCtx()
    out, s = gl.timed(ctx, lambda: 7, clock=gl.CLOCK_GL_TIMER)
    assert (out, s, ctx.queries, ctx.finished) == (7, 2.5e-3, 1, 1)
    out, s = gl.timed(ctx, lambda: 8, clock=gl.CLOCK_WALL)
    assert out == 8 and 0 <= s < 1 and ctx.queries == 1 and ctx.finished == 2
