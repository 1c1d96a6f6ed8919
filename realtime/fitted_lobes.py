"""Fitted real-time lobe tables (issue 36 item 5b), written by ``pbrcheck fit-lobes --module``
(:mod:`compare.research.fit_lobes`; do not edit by hand). The registry members that read them:
``sheen_dfg = fitted`` and ``anisotropy_bend = fitted`` (:mod:`realtime.registry`, whose entries hold
the GLSL below; :func:`realtime.lobes.sheen_dfg_fitted`, :func:`realtime.lobes.aniso_reflection_fitted`).

:data:`SHEEN_ALBEDO_TABLE`: the sheen directional albedo ``E(n.v, sheenRoughness)`` of the spec's
Charlie lobe (KHR_materials_sheen, ``int D_Charlie V_Charlie n.l dl``), 8 x 8, fitted by AD (Dr.Jit,
Adam from 0) to the quadrature so that its bilinear read matches it (docs/research.md, "pbrcheck
fit-lobes"; equal to the least-squares table, the check); the E of the albedo scaling ``1 - max(sheenColor)
E(n.v)``. Conventions (:data:`SHEEN_ALBEDO_TABLE_CONVENTIONS`): row j at sheen roughness (j + 0.5)/8 (row 0
smoothest), column i at sqrt(n.v) = (i + 0.5)/8; read bilinearly between texel centres with linear
extrapolation within half a texel of 0 and 1 and a clamp at 0 (:func:`realtime.lobes.lut_bilinear`'s
rule, written out here so that this module imports nothing of the renderer). :func:`sheen_albedo_fitted`
is the numpy reader, :data:`SHEEN_ALBEDO_GLSL` the same read in GLSL (``float sheen_albedo_fitted(float
NoV, float roughness)``).

:data:`ANISO_BEND_WEIGHT_TABLE`: the weight ``w`` of the Sample Viewer-style bent normal
``normalize(mix((b x v) x b, n, w))`` (b the anisotropy bitangent), in place of its ``(1 - s (1 -
r))^4``, fitted by AD (Dr.Jit, Adam from 0.5) against the spec's anisotropic GGX integral under test
environments (docs/research.md; within the scan's step of the scan's weights, the check); rows roughness
:data:`ANISO_ROUGHNESS`, columns strength :data:`ANISO_STRENGTH`, read bilinearly between the nodes and
clamped to them (below roughness 0.2: its first row); :func:`aniso_bend_weight_fitted`
the numpy reader, :data:`ANISO_BEND_WEIGHT_GLSL` the GLSL ``float aniso_bend_weight_fitted(float
anisotropy, float roughness)``.

API: :data:`SHEEN_ALBEDO_TABLE`, :data:`SHEEN_ALBEDO_TABLE_CONVENTIONS`, :func:`sheen_albedo_fitted`,
:data:`SHEEN_ALBEDO_GLSL`, :data:`ANISO_STRENGTH`, :data:`ANISO_ROUGHNESS`, :data:`ANISO_BEND_WEIGHT_TABLE`,
:func:`aniso_bend_weight_fitted`, :data:`ANISO_BEND_WEIGHT_GLSL`.
"""

import numpy as np

SHEEN_ALBEDO_TABLE = np.array((
    (3.278271, 0.783287, 0.270211, 0.067129, 0.018473, 0.002801, 0.000111, -0.000005),
    (1.205825, 1.202276, 0.667306, 0.286848, 0.096505, 0.021072, 0.000282, -0.000184),
    (0.972934, 0.664690, 0.511561, 0.358509, 0.217024, 0.107198, 0.034803, 0.009013),
    (0.848284, 0.738739, 0.559198, 0.401399, 0.273598, 0.169935, 0.088227, 0.035750),
    (0.863867, 0.731460, 0.589414, 0.456485, 0.337859, 0.232021, 0.143412, 0.075097),
    (0.912226, 0.794845, 0.648374, 0.513828, 0.395505, 0.287796, 0.195192, 0.118477),
    (0.986776, 0.858948, 0.708790, 0.571364, 0.450152, 0.338618, 0.241930, 0.160925),
    (0.998441, 0.871466, 0.723431, 0.588972, 0.471076, 0.362362, 0.268030, 0.189187)))

SHEEN_ALBEDO_TABLE_CONVENTIONS = {
    "axes": "row j: sheen roughness = (j + 0.5)/8, row 0 smoothest; column i: sqrt(n.v) = (i + 0.5)/8",
    "read": "bilinear between texel centres, linear extrapolation within half a texel of 0 and 1, clamped at 0",
    "value": "E = int D_Charlie V_Charlie n.l dl (KHR_materials_sheen), fitted by AD (Adam) on a "
             "25 x 25 grid of n.v in [0.02, 1] x roughness in [0, 1]",
}


def sheen_albedo_fitted(NoV, roughness):
    """E at (n.v, sheen roughness) from :data:`SHEEN_ALBEDO_TABLE` (numpy twin of the GLSL reader)."""
    x = np.sqrt(np.clip(np.asarray(NoV, np.float64), 0.0, 1.0)) * 8 - 0.5
    y = np.clip(np.asarray(roughness, np.float64), 0.0, 1.0) * 8 - 0.5
    i0, j0 = np.clip(np.floor(x).astype(int), 0, 6), np.clip(np.floor(y).astype(int), 0, 6)
    fx, fy = x - i0, y - j0
    t = SHEEN_ALBEDO_TABLE
    v0 = t[j0, i0] + (t[j0, i0 + 1] - t[j0, i0]) * fx
    v1 = t[j0 + 1, i0] + (t[j0 + 1, i0 + 1] - t[j0 + 1, i0]) * fx
    return np.maximum(v0 + (v1 - v0) * fy, 0.0)


SHEEN_ALBEDO_GLSL = """
const float SHEEN_ALBEDO_TABLE[64] = float[](
        3.278271, 0.783287, 0.270211, 0.067129, 0.018473, 0.002801, 0.000111, -0.000005,
        1.205825, 1.202276, 0.667306, 0.286848, 0.096505, 0.021072, 0.000282, -0.000184,
        0.972934, 0.664690, 0.511561, 0.358509, 0.217024, 0.107198, 0.034803, 0.009013,
        0.848284, 0.738739, 0.559198, 0.401399, 0.273598, 0.169935, 0.088227, 0.035750,
        0.863867, 0.731460, 0.589414, 0.456485, 0.337859, 0.232021, 0.143412, 0.075097,
        0.912226, 0.794845, 0.648374, 0.513828, 0.395505, 0.287796, 0.195192, 0.118477,
        0.986776, 0.858948, 0.708790, 0.571364, 0.450152, 0.338618, 0.241930, 0.160925,
        0.998441, 0.871466, 0.723431, 0.588972, 0.471076, 0.362362, 0.268030, 0.189187);

float sheen_albedo_fitted(float NoV, float roughness) {
    float x = sqrt(clamp(NoV, 0.0, 1.0)) * 8.0 - 0.5;
    float y = clamp(roughness, 0.0, 1.0) * 8.0 - 0.5;
    int i0 = clamp(int(floor(x)), 0, 6);
    int j0 = clamp(int(floor(y)), 0, 6);
    float fx = x - float(i0), fy = y - float(j0);
    float v0 = mix(SHEEN_ALBEDO_TABLE[j0 * 8 + i0], SHEEN_ALBEDO_TABLE[j0 * 8 + i0 + 1], fx);
    float v1 = mix(SHEEN_ALBEDO_TABLE[(j0 + 1) * 8 + i0], SHEEN_ALBEDO_TABLE[(j0 + 1) * 8 + i0 + 1], fx);
    return max(mix(v0, v1, fy), 0.0);
}
"""

ANISO_STRENGTH = (0.0, 0.25, 0.5, 0.75, 1.0)
ANISO_ROUGHNESS = (0.2, 0.4, 0.6, 0.8, 1.0)
ANISO_BEND_WEIGHT_TABLE = np.array((
    (1.0000, 0.9894, 0.6583, 0.6299, 0.6301),
    (1.0000, 0.9030, 0.6464, 0.5684, 0.5321),
    (1.0000, 0.8177, 0.6533, 0.5242, 0.4155),
    (1.0000, 0.5892, 0.5446, 0.4822, 0.4140),
    (1.0000, 1.0000, 1.0000, 1.0000, 1.0000)))


def aniso_bend_weight_fitted(anisotropy, roughness):
    """The fitted weight at (strength, roughness) (numpy twin of the GLSL reader; uniform node spacing)."""
    x = np.clip((np.asarray(anisotropy, np.float64) - 0.0) / 0.25, 0.0, 4.0)
    y = np.clip((np.asarray(roughness, np.float64) - 0.2) / 0.2, 0.0, 4.0)
    i0, j0 = np.minimum(np.floor(x).astype(int), 3), np.minimum(np.floor(y).astype(int), 3)
    fx, fy = x - i0, y - j0
    t = ANISO_BEND_WEIGHT_TABLE
    return ((1 - fy) * ((1 - fx) * t[j0, i0] + fx * t[j0, i0 + 1])
            + fy * ((1 - fx) * t[j0 + 1, i0] + fx * t[j0 + 1, i0 + 1]))


ANISO_BEND_WEIGHT_GLSL = """
const float ANISO_BEND_WEIGHT_TABLE[25] = float[](1.0000, 0.9894, 0.6583, 0.6299, 0.6301, 1.0000, 0.9030, 0.6464, 0.5684, 0.5321, 1.0000, 0.8177, 0.6533, 0.5242, 0.4155, 1.0000, 0.5892, 0.5446, 0.4822, 0.4140, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000);

float aniso_bend_weight_fitted(float anisotropy, float roughness) {
    float x = clamp((anisotropy - 0.000000) / 0.250000, 0.0, 4.0);
    float y = clamp((roughness - 0.200000) / 0.200000, 0.0, 4.0);
    int i0 = min(int(floor(x)), 3);
    int j0 = min(int(floor(y)), 3);
    float fx = x - float(i0), fy = y - float(j0);
    float v0 = mix(ANISO_BEND_WEIGHT_TABLE[j0 * 5 + i0], ANISO_BEND_WEIGHT_TABLE[j0 * 5 + i0 + 1], fx);
    float v1 = mix(ANISO_BEND_WEIGHT_TABLE[(j0 + 1) * 5 + i0], ANISO_BEND_WEIGHT_TABLE[(j0 + 1) * 5 + i0 + 1], fx);
    return mix(v0, v1, fy);
}
"""
