"""Run any GLSL expression of the shader library on numpy arrays (a compute shader).

``run_glsl("D_GGX(x0, x1)", NoH, alpha)`` broadcasts the (up to 8) input arrays, hands element k to
the shader as floats ``x0`` .. ``x7`` (and its index as ``uint idx``), evaluates the expression
(float, vec2, vec3 or vec4) and returns float32 ``(..., 4)`` (or ``(...)`` / ``(..., n)`` with
``components``). Every file of ``realtime/shaders`` that defines terms (brdf, sampling, ibl, env,
energy, lights, occlusion, specular_aa, coverage, texcoord, lobes_coat, lobes_sheen,
lobes_anisotropy, lobes_iridescence) is included, so the tests compare each GLSL term
with its numpy twin of the same name. ``hook`` (a :class:`realtime.hooks.HookFile`, e.g. the table
``pbrcheck fit-normal-roughness`` writes) is appended as the frame pass appends it (its
``HOOK_<NAME>`` defines set, ``hooks.glsl``'s prototypes declared), so a generated hook is compared
with its numpy twin too.
"""

from __future__ import annotations

import numpy as np

from .gl import compile_source, get_context, groups



def run_glsl(expr: str, *inputs, components: int = 1, defines: dict | None = None, uniforms: dict | None = None,
             textures: dict | None = None, hook=None) -> np.ndarray:
    """Evaluate GLSL expression ``expr`` of the shader library on up to 8 broadcast numpy inputs
    (``x0`` .. ``x7``); returns float32 ``(...)`` or ``(..., components)``. ``defines`` select
    variants (registry constants), ``uniforms`` and ``textures`` are bound by name; ``hook`` (a
    :class:`realtime.hooks.HookFile`) is appended with its defines, so ``expr`` may call its hooks."""
    if len(inputs) > 8:
        raise ValueError("at most 8 inputs")
    arrs = np.broadcast_arrays(*[np.asarray(x, dtype=np.float32) for x in inputs]) if inputs else [np.zeros(1, np.float32)]
    shape = arrs[0].shape
    n = int(np.prod(shape)) if shape else 1
    packed = np.zeros((n, 8), np.float32)
    for k, a in enumerate(arrs[:8] if inputs else []):
        packed[:, k] = a.reshape(-1)
    names = "\n".join(f"    float x{k} = {'ab'[k // 4]}.{'xyzw'[k % 4]};" for k in range(8))
    extra = f"{names}\n    out_v[i] = _pad({expr});"
    if hook is not None:
        defines = {**(defines or {}), **hook.defines}
    prog = compile_source("harness.comp", extra, defines, name=f"<harness: {expr}>",
                          user=(hook.path, hook.text) if hook is not None else None)
    ctx = get_context()
    a = ctx.buffer(np.ascontiguousarray(packed[:, :4]).tobytes())
    b = ctx.buffer(np.ascontiguousarray(packed[:, 4:]).tobytes())
    out = ctx.buffer(reserve=max(n, 1) * 16)
    a.bind_to_storage_buffer(0)
    b.bind_to_storage_buffer(1)
    out.bind_to_storage_buffer(2)
    for unit, (name, tex) in enumerate((textures or {}).items()):
        tex.use(unit)
        try:
            prog[name].value = unit
        except KeyError:
            pass
    for k, v in (uniforms or {}).items():
        try:
            prog[k].value = v
        except KeyError:
            pass
    prog["count"].value = n
    prog.run(groups(n, 64))
    ctx.memory_barrier()  # SSBO writes are incoherent (GL 4.6 core, 7.13.2): visible to the read-back after it
    res = np.frombuffer(out.read(), np.float32).reshape(n, 4).copy()
    for buf in (a, b, out):
        buf.release()
    res = res.reshape(*shape, 4)
    if components == 1:
        return res[..., 0]
    return res[..., :components]
