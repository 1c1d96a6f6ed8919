"""Shader hooks: a user's GLSL file replaces pieces of the real-time frame pass.

``pbrcheck realtime SCENE --shader FILE.glsl`` (or the option ``shader=FILE.glsl``, or a renderer
name ``PRESET+FILE.glsl`` wherever a preset is named) compiles the frame pass with the user's file
appended. Each hook below that the file defines replaces the built-in piece; the others keep the
preset's. The file may call every built-in function and read every uniform of the frame pass
(``prefiltered``, ``max_lod``, ``cube_log2``, ``dfg_lut``, ``dfg_lookup``, ``EnvBRDFApprox``, ``D_GGX``,
``G_SmithGGXCorrelated``, ``F_Schlick``, ``alpha_from_roughness``, ``lod_quadratic`` ... see
``realtime/shaders``). Hooks apply to ``shading = material`` (the article compositions are fixed
reproductions); compile errors name the user's ``FILE.glsl:line``.

:data:`HOOKS` is the closed list (name, GLSL signature, the define that switches it, what it
replaces); ``realtime/shaders/hooks.glsl`` declares the prototypes under those defines and
docs/hooks.md documents them (a test checks both against this list).

API
---
- :data:`HOOKS` -- the hooks, in documentation order.
- :func:`load_hook_file` -- read and parse a hook file: :class:`HookFile` (text, SHA-256, hooks).
- :class:`HookError` -- a hook file that cannot be used (missing, no hook, wrong signature).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

from pbrcheck.errors import PbrcheckError, read_user_text


class HookError(PbrcheckError):
    """A hook file that cannot be used; names the file (and the function where one is at fault)."""


@dataclass(frozen=True)
class Hook:
    """One hook: GLSL function ``name`` with ``signature``, switched on by ``#define <define>``."""

    name: str
    returns: str
    params: str
    replaces: str

    @property
    def define(self) -> str:
        return "HOOK_" + self.name[len("hook_"):].upper()

    @property
    def signature(self) -> str:
        return f"{self.returns} {self.name}({self.params})"


HOOKS: tuple[Hook, ...] = (
    Hook("hook_specular_ibl", "vec3", "vec3 n, vec3 v, float roughness, vec3 F0",
         "the whole specular image-based lighting (split sum or runtime sampling, energy compensation "
         "included): outgoing radiance towards v"),
    Hook("hook_diffuse_ibl", "vec3", "vec3 n",
         "the diffuse irradiance lookup: E(n) / pi (cube or SH9); the Lambert weight stays the preset's"),
    Hook("hook_dfg", "vec2", "float NoV, float roughness",
         "the DFG term (A, B) of the split sum: specular albedo = F0 A + B"),
    Hook("hook_lod", "float", "float roughness, float max_lod, float cube_log2",
         "the roughness -> prefiltered mip level mapping (max_lod = last level, cube_log2 = log2 face size)"),
    Hook("hook_energy_compensation", "vec3", "vec3 F0, float A, float B, float roughness",
         "the multiple-scattering energy compensation: a factor on the split sum's specular and on the "
         "point lights' specular lobe (the preset's compensation, scale or added lobe, is then off)"),
    Hook("hook_D", "float", "float NoH, float roughness",
         "the normal distribution D (point lights and runtime sampling)"),
    Hook("hook_G", "float", "float NoV, float NoL, float roughness",
         "the geometry term G (point lights and runtime sampling)"),
    Hook("hook_F", "vec3", "float VoH, vec3 F0",
         "the Fresnel term F (point lights, runtime sampling and the point lights' diffuse weight 1 - F)"),
    Hook("hook_specular_aa", "float", "float roughness, float normal_length, float normal_lod",
         "the raster pass's specular anti-aliasing on a normal-mapped fragment: the widened perceptual "
         "roughness from the normal map's mip-filtered length (before normalisation) and the level it "
         "is read at (textureQueryLod; 0 with normal_sampling = lod0); the option specular_aa is then off"),
)

_BY_NAME = {h.name: h for h in HOOKS}
# A definition: return type, name, parameter list, then an opening brace (a prototype ends in ';').
_DEF = re.compile(r"\b(void|float|vec[234]|int|bool)\s+(hook_\w+)\s*\(([^)]*)\)\s*\{")


def _norm_params(params: str) -> list[str]:
    out = []
    for p in params.split(","):
        words = [w for w in p.split() if w not in ("in", "const", "highp", "mediump", "lowp")]
        if words:
            out.append(words[0])
    return out


@dataclass(frozen=True)
class HookFile:
    """A parsed hook file: its path, text, SHA-256 and the hooks it defines (in :data:`HOOKS` order)."""

    path: str
    text: str
    sha256: str
    hooks: tuple[str, ...]

    @property
    def defines(self) -> dict[str, int]:
        """``HOOK_<NAME> = 1`` for every hook the file defines."""
        return {_BY_NAME[h].define: 1 for h in self.hooks}


def load_hook_file(path: str | Path) -> HookFile:
    """Read ``path`` and find its hook definitions.

    Raises
    ------
    HookError
        The file is missing or unreadable, defines a ``hook_*`` function that is not a hook or has
        another signature than :data:`HOOKS` states, or defines no hook at all.
    """
    p = Path(path)
    text = read_user_text(p, HookError, "shader hook file")
    # Comments out first, so a commented-out hook does not count (line count unchanged).
    code = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    code = re.sub(r"//[^\n]*", "", code)
    found = []
    for m in _DEF.finditer(code):
        ret, name, params = m.groups()
        line = code.count("\n", 0, m.start()) + 1
        h = _BY_NAME.get(name)
        if h is None:
            raise HookError(f"{p}:{line}: {name} is not a hook; hooks are: {', '.join(_BY_NAME)}")
        if ret != h.returns or _norm_params(params) != _norm_params(h.params):
            raise HookError(f"{p}:{line}: {name} must be declared as `{h.signature}`")
        found.append(name)
    if not found:
        raise HookError(f"{p}: defines no hook (expected one of: {', '.join(h.signature for h in HOOKS)})")
    order = [h.name for h in HOOKS if h.name in found]
    return HookFile(str(p), text, hashlib.sha256(text.encode()).hexdigest(), tuple(order))
