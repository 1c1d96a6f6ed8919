"""The glTF extensions' lobes in the reference's BSDF and integrator (reference/lobe_bsdf.py, issue 36
item 2): a material without lobes never traces them; the lobe path at neutral values reduces to the
base; Mitsuba's chi-square test per lobe; white furnaces per lobe and per layering; the per-lane
Dr.Jit maths equal reference/lobes.py's twins (themselves = numpy, tests/test_lobes.py) on grids with
the extremes; a rendered known answer (a clear coat on a black base); the shared Khronos assets."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import pbrcheck  # noqa: F401
from pbrcheck import lobes as N
from pbrcheck.scene import load_scene
from reference.variant import ensure_variant

ensure_variant()
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402
from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain  # noqa: E402

from reference import lobe_bsdf as LB  # noqa: E402
from reference import lobes as RL  # noqa: E402
from test_lobes import _pairs  # noqa: E402  (the twins' grid: n.v and n.l from 1e-3 to 1)

#: Significance of each chi-square test (Mitsuba's own tests use 0.01).
CHI2_SIGNIFICANCE = 0.01
#: The lobe path at neutral values against the base path: float32 orderings of the same formulas
#: (Schlick written out, the GGX of reference.terms); relative, with an absolute floor.
NEUTRAL_RTOL = 1e-5
NEUTRAL_ATOL = 1e-7
#: Twins (per-lane Dr.Jit here against reference/lobes.py's scalar-parameter Dr.Jit): the same
#: float32 formulas up to operation order.
TWIN_RTOL = 1e-4
TWIN_ATOL = 1e-6
#: Furnace: the MC albedo (N_FURNACE samples of the BSDF's own sampler, relative standard error
#: printed by the failure) against the quadrature of the same lobe in pbrcheck.lobes: 4 sigma of
#: the estimate, at most this fraction.
N_FURNACE = 1 << 18
FURNACE_RTOL = 1e-2
#: The energy bound of the spec's layerings (module docstring of reference.lobe_bsdf): a white
#: material's albedo is at most 1, plus the MC estimate's 4 sigma.
ENERGY_BOUND = 1.0
#: Known answer: clearcoat 1 (roughness 0) on a black base (specularFactor 0) in a constant environment of radiance 1,
#: at normal incidence: Fc(1) * albedo of the coat = 0.04 * 1; the local estimator's 16 spp at the
#: centre pixel agree to this (the coat's albedo at roughness 0.01 is 1 - 1e-4).
COAT_KNOWN_ATOL = 2e-3
#: The gradient of a lobe factor against the central difference at the same seed (the difference's
#: samples move with the lobe probabilities: 7 % measured at 16 spp).
GRAD_FD_RTOL = 0.2
#: The film's spectral sum per lane against reference.lobes.iridescence_spectral (the same sums in
#: float32, a loop against a block sum: summation order).
FILM_ATOL = 2e-5


def _mat(**kw):
    d = {"type": "pbr_material", "base_color": [0.8, 0.5, 0.3], "metallic": 0.3, "roughness": 0.4,
         "specular": 0.04, "ndf": "ggx", "geometry": "smith_ggx_correlated", "fresnel": "schlick"}
    d.update(kw)
    return d


def _si(wi, n):
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(*[mi.Float(np.asarray(c, np.float32)) for c in wi]) if np.ndim(wi[0]) else \
        dr.normalize(mi.Vector3f(*wi))
    return si


def _v3(a):
    return mi.Vector3f(*[mi.Float(np.ascontiguousarray(a[:, k], np.float32)) for k in range(3)])


def _np(x):
    a = np.array(x)
    return a.T if a.ndim == 2 and a.shape[0] == 3 else a


# ---- a material without lobes --------------------------------------------------------------------

def test_scene_without_lobes_never_traces_them(monkeypatch):
    """The spheres and furnace scenes' materials carry no lobe props, and their renders, local and
    path, never call reference.lobe_bsdf (its entry points raise here)."""
    from reference.bsdf import material_dict
    from reference.render import render_uncached

    def boom(*a, **k):
        raise AssertionError("lobe path traced")

    monkeypatch.setattr(LB, "eval_pdf", boom)
    monkeypatch.setattr(LB, "sample", boom)
    for name in ("spheres", "furnace"):
        sc = load_scene(name)
        for o in sc.objects:
            assert not set(material_dict(o.material, sc.brdf)) & {p for ps in LB.LOBE_DEFAULTS.values() for p in ps}
        sc = dataclasses.replace(sc, camera=dataclasses.replace(sc.camera, width=16, height=8))
        for mode in ("local", "path"):
            img = render_uncached(sc, spp=2, mode=mode, progress=False, aovs=False)
            assert np.isfinite(img.channels["R"]).all() and img.channels["R"].max() > 0


@pytest.mark.parametrize("lobe", list(LB.LOBE_DEFAULTS))
def test_neutral_scene_fields_give_todays_material(lobe):
    """Each lobe's scene-file fields at their neutral values: material_dict is today's, key for key."""
    from reference.bsdf import material_dict

    sc = load_scene("spheres")
    m = sc.objects[0].material
    base = material_dict(m, sc.brdf)
    m2 = dataclasses.replace(m, **{k: v for k, v in LB.LOBE_DEFAULTS[lobe].items()})
    assert material_dict(m2, sc.brdf) == base
    # a disabled layer's other fields change nothing either (clearcoat 0 with a roughness, ...)
    others = {"clearcoat": dict(clearcoat_roughness=0.5), "sheen": dict(sheen_roughness=0.5),
              "specular": {}, "anisotropy": dict(anisotropy_rotation=1.0),
              "iridescence": dict(iridescence_ior=2.0, iridescence_thickness=100.0)}[lobe]
    assert material_dict(dataclasses.replace(m, **others), sc.brdf) == base
    b = mi.load_dict(base)
    assert b.lobes is None


@pytest.mark.parametrize("blend", ["f0", "gltf"])
@pytest.mark.parametrize("rough", [0.05, 0.4, 1.0])
def test_lobe_path_at_neutral_values_is_the_base(rough, blend):
    """Every lobe's props present at their neutral values (the lobe path traced): eval, pdf equal the
    base path's (today's material) to float32 rounding."""
    v, l = _pairs()
    n = len(v)
    base = mi.load_dict(_mat(roughness=rough, metallic_blend=blend))
    neutral = {p: (list(d) if isinstance(d, tuple) else d) for ps in LB.LOBE_DEFAULTS.values() for p, d in ps.items()}
    lob = mi.load_dict(_mat(roughness=rough, metallic_blend=blend, **neutral))
    assert lob.lobes is not None and lob.lobes.used == LB.LOBES
    si = _si((v[:, 0], v[:, 1], v[:, 2]), n)
    f0, p0 = base.eval_pdf(mi.BSDFContext(), si, _v3(l))
    f1, p1 = lob.eval_pdf(mi.BSDFContext(), si, _v3(l))
    np.testing.assert_allclose(_np(f1), _np(f0), rtol=NEUTRAL_RTOL, atol=NEUTRAL_ATOL)
    # pdf: the mixture's weights are the base's (diffuse, specular), the sheen's and coat's 0
    ok = _np(p0) > 0
    assert ok.sum() > n // 3
    rel = np.abs(_np(p1)[ok] / _np(p0)[ok] - 1.0)
    assert rel.max() < 5e-3, rel.max()


# ---- sampling: Mitsuba's chi-square per lobe ----------------------------------------------------

CHI2_MATERIALS = {
    "clearcoat": dict(clearcoat=1.0, clearcoat_roughness=0.3),
    "sheen": dict(sheen_color=[0.9, 0.7, 0.5], sheen_roughness=0.5, roughness=0.6),
    "specular": dict(specular_factor=0.5, specular_color=[1.0, 0.5, 2.0]),
    "anisotropy": dict(anisotropy_strength=0.8, anisotropy_rotation=0.6, roughness=0.3),
    "iridescence": dict(iridescence=1.0, iridescence_thickness=300.0, iridescence_ior=1.8, roughness=0.5),
    "all": dict(clearcoat=0.7, clearcoat_roughness=0.2, sheen_color=[0.5, 0.5, 0.8], sheen_roughness=0.3,
                anisotropy_strength=0.5, anisotropy_rotation=1.0, roughness=0.5),
}


@pytest.mark.parametrize("name", list(CHI2_MATERIALS))
def test_chi2_per_lobe(name):
    """The sampler's histogram against the integrated pdf (Mitsuba's ChiSquareTest) at 40 degrees."""
    t = math.radians(40.0)
    sf, pf = BSDFAdapter("pbr_material", _mat(**CHI2_MATERIALS[name]), wi=[math.sin(t), 0.0, math.cos(t)])
    chi = ChiSquareTest(domain=SphericalDomain(), sample_func=sf, pdf_func=pf, sample_dim=3)
    assert chi.run(CHI2_SIGNIFICANCE, quiet=True), chi.messages[-1500:]


# ---- furnaces -----------------------------------------------------------------------------------

def _mc_albedo(d, mu, n=N_FURNACE, seed=7):
    b = mi.load_dict(d)
    rng = np.random.default_rng(seed)
    si = _si((math.sqrt(1 - mu * mu), 0.0, mu), n)
    bs, w = b.sample(mi.BSDFContext(), si, mi.Float(rng.random(n)), mi.Point2f(rng.random(n), rng.random(n)))
    w = _np(w)
    return w.mean(axis=0), w.std(axis=0) / math.sqrt(n)


@pytest.mark.parametrize("mu", [1.0, 0.5, 0.1])
def test_furnace_sheen_alone(mu):
    """A black base (specularFactor 0) under white sheen: the albedo is sheenColor E(n.v), E by pbrcheck.lobes' quadrature."""
    d = _mat(base_color=[0, 0, 0], metallic=0.0, specular_factor=0.0, sheen_color=[1.0, 1.0, 1.0], sheen_roughness=0.5)
    got, se = _mc_albedo(d, mu)
    want = N.SheenCharlie(0.5).albedo(mu)
    assert np.all(np.abs(got - want) < max(4 * se.max(), FURNACE_RTOL * want)), (got, want, se)


@pytest.mark.parametrize("mu", [1.0, 0.5, 0.1])
@pytest.mark.parametrize("rough", [0.0, 0.3])
def test_furnace_coat_alone(mu, rough):
    """A black base (specularFactor 0: f0 = f90 = 0) under clearcoat 1: the albedo is Fc(n.v) times the
    coat GGX's albedo."""
    d = _mat(base_color=[0, 0, 0], metallic=0.0, specular_factor=0.0, clearcoat=1.0, clearcoat_roughness=rough)
    got, se = _mc_albedo(d, mu)
    want = float(N.fresnel_coat(mu)) * N.AnisotropicGGX(max(rough, 0.01)).albedo(mu)
    assert np.all(np.abs(got - want) < max(4 * se.max(), FURNACE_RTOL * want)), (got, want, se)


@pytest.mark.parametrize("mu", [1.0, 0.5, 0.1])
def test_furnace_anisotropy_white_metal(mu):
    """A white metal (F = 1) with anisotropy: the anisotropic GGX's albedo of pbrcheck.lobes."""
    d = _mat(base_color=[1, 1, 1], metallic=1.0, roughness=0.5, anisotropy_strength=0.7, anisotropy_rotation=0.4)
    got, se = _mc_albedo(d, mu)
    v = N._view(mu)
    want = N.AnisotropicGGX(0.5, 0.7, 0.4).albedo(mu)
    assert np.all(np.abs(got - want) < max(4 * se.max(), FURNACE_RTOL * want)), (got, want, se, v)


LAYERED = {
    "metal+sheen+coat": (dict(base_color=[1, 1, 1], metallic=1.0, roughness=0.3),
                         dict(sheen_color=[1, 1, 1], sheen_roughness=0.3, clearcoat=1.0, clearcoat_roughness=0.1)),
    "dielectric+sheen": (dict(base_color=[1, 1, 1], metallic=0.0, roughness=0.3, metallic_blend="gltf"),
                         dict(sheen_color=[1, 1, 1], sheen_roughness=0.8)),
    "dielectric+coat": (dict(base_color=[1, 1, 1], metallic=0.0, roughness=0.6),
                        dict(clearcoat=1.0, clearcoat_roughness=0.0)),
}


@pytest.mark.parametrize("mu", [1.0, 0.3, 0.05])
@pytest.mark.parametrize("name", list(LAYERED))
def test_furnace_layering_bound(name, mu):
    """The spec's layerings conserve energy: a layered white material reflects at most
    ``max(1, albedo of its base)`` (the coat's ``(1 - c Fc) A + c Fc A_coat``, the sheen's
    ``E(v) + (1 - E(v)) A`` bound it; reference.lobe_bsdf's docstring). The base itself may exceed 1:
    glTF's dielectric (``(1 - F(v.h))`` diffuse beside ``F(v.h)`` specular) does at grazing view."""
    base, lobes = LAYERED[name]
    a_base, se_b = _mc_albedo(_mat(**base), mu)
    got, se = _mc_albedo(_mat(**base, **lobes), mu)
    assert np.all(got <= np.maximum(ENERGY_BOUND, a_base) + 4 * (se + se_b)), (got, a_base, se)
    assert np.all(got > 0.5), got


# ---- per-lane maths = the twins -----------------------------------------------------------------

@pytest.mark.parametrize("rough,strength,rot", [(0.01, 0.0, 0.0), (0.3, 0.5, 0.7), (1.0, 1.0, -2.0), (0.05, 0.95, 3.1)])
def test_aniso_per_lane_equals_twin(rough, strength, rot):
    v, l = _pairs()
    n = len(v)
    twin = RL.AnisotropicGGX(rough, strength, rot)
    at, ab = mi.Float(twin.at), mi.Float(twin.ab)
    c, s = mi.Float(math.cos(rot)), mi.Float(math.sin(rot))
    V, L = _v3(v), _v3(l)
    h = dr.normalize(V + L)
    if not twin.isotropic:
        np.testing.assert_allclose(np.array(LB.aniso_D(h, at, ab, c, s)), np.array(twin.D(h)), rtol=TWIN_RTOL,
                                   atol=TWIN_ATOL * float(dr.max(twin.D(h))[0]))
        np.testing.assert_allclose(np.array(LB.aniso_G2(V, L, at, ab, c, s)), np.array(twin.G2(V, L)),
                                   rtol=TWIN_RTOL, atol=TWIN_ATOL)
    rng = np.random.default_rng(2)
    u = mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n)))
    np.testing.assert_allclose(_np(LB.aniso_sample_h(V, u, at, ab, c, s)), _np(twin.sample_h(V, u)), atol=1e-5)


@pytest.mark.parametrize("rough", [0.01, 0.3, 1.0])
def test_sheen_per_lane_equals_twin(rough):
    v, l = _pairs()
    n = len(v)
    twin = RL.SheenCharlie(rough)
    a = mi.Float(twin.alpha)
    V, L = _v3(v), _v3(l)
    ref = np.array(twin.eval(V, L))
    np.testing.assert_allclose(np.array(LB.sheen_eval(V, L, a)), ref, rtol=TWIN_RTOL, atol=TWIN_ATOL * ref.max())
    refp = np.array(twin.pdf(V, L))
    np.testing.assert_allclose(np.array(LB.sheen_pdf(V, L, a)), refp, rtol=TWIN_RTOL, atol=TWIN_ATOL * refp.max())
    rng = np.random.default_rng(4)
    u = mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n)))
    np.testing.assert_allclose(_np(LB.sheen_sample(V, u, a)), _np(twin.sample(V, u)[0]), atol=1e-5)


@pytest.mark.parametrize("d,nf,f0", [(0.0, 1.3, (0.04,) * 3), (300.0, 1.3, (0.04,) * 3), (1200.0, 2.0, (0.95, 0.64, 0.54)),
                                     (100.0, 1.0, (0.0, 0.5, 1.0))])
def test_film_per_lane_equals_twin(d, nf, f0):
    cos = np.array([1e-3, 0.05, 0.2, 0.5, 0.8, 1.0], np.float32)
    n = len(cos)
    got = _np(LB.film_spectral(mi.Float(cos), mi.Float(np.full(n, d, np.float32)), mi.Float(np.full(n, nf, np.float32)),
                               mi.Color3f(*f0)))
    ref = N.iridescence_spectral(cos.astype(np.float64), d, nf, f0)
    np.testing.assert_allclose(got, ref, atol=FILM_ATOL)


def test_sheen_table_interpolation():
    """The bilinear sheen albedo at the table cells' centres against the quadrature, over the range
    SHEEN_TABLE_TOL is stated for (n.v >= 1/128, roughness >= SHEEN_TABLE_TOL_ROUGHNESS)."""
    nm, nr = LB.SHEEN_TABLE_MU, LB.SHEEN_TABLE_ROUGHNESS
    mus = (np.arange(1, nm - 1, 9) + 0.5) / (nm - 1)
    j0 = int(np.ceil(LB.SHEEN_TABLE_TOL_ROUGHNESS * (nr - 1)))
    rs = (np.arange(j0, nr - 1, 9) + 0.5) / (nr - 1)
    mm, rr = np.meshgrid(mus, rs, indexing="ij")
    got = np.array(LB.sheen_albedo(mi.Float(mm.ravel()), mi.Float(rr.ravel())))
    want = np.array([N.SheenCharlie(r).albedo(m) for m, r in zip(mm.ravel(), rr.ravel())])
    err = np.abs(got - want).max()
    assert err < LB.SHEEN_TABLE_TOL, err


# ---- rendered -----------------------------------------------------------------------------------

def _known_scene(tmp_path, **lobes):
    mat = "\n".join(f"{k} = {v!r}" if not isinstance(v, (list, tuple)) else f"{k} = {list(v)}" for k, v in lobes.items())
    text = f"""
name = "coat_known"
[camera]
origin = [0.0, 0.0, 5.0]
target = [0.0, 0.0, 0.0]
fov = 20.0
width = 9
height = 9
[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]
[[objects]]
type = "sphere"
name = "ball"
center = [0.0, 0.0, 0.0]
radius = 1.0
[objects.material]
base_color = [0.0, 0.0, 0.0]
metallic = 0.0
roughness = 0.5
specular = 0.0
specular_factor = 0.0
{mat}
"""
    p = tmp_path / f"known{len(lobes)}.toml"
    p.write_text(text)
    return load_scene(p)


@pytest.mark.parametrize("mode", ["local", "path"])
def test_render_clearcoat_known_answer(mode, tmp_path):
    """Clearcoat 1 (roughness 0) on a black base (specularFactor 0: no reflection at all) in a constant
    white environment: at normal incidence the coat adds Fc(1) = F0(1.5) = 0.04 of the environment;
    without it, 0."""
    from reference.render import render_uncached

    base = render_uncached(_known_scene(tmp_path), spp=16, mode=mode, progress=False, aovs=False)
    coat = render_uncached(_known_scene(tmp_path, clearcoat=1.0), spp=16, mode=mode, progress=False, aovs=False)
    c = 4
    assert base.channels["R"][c, c] == 0.0
    for ch in "RGB":
        assert abs(coat.channels[ch][c, c] - 0.04) < COAT_KNOWN_ATOL, coat.channels[ch][c, c]


@pytest.mark.parametrize("name", ["clearcoat", "sheen", "specular", "anisotropy", "iridescence"])
def test_builtin_lobe_scene_differs_from_base(name):
    """Each built-in lobe scene renders differently from itself with the lobes removed, in the rows
    that set them (finite everywhere)."""
    from reference.render import render_uncached

    sc = load_scene(name)
    sc = dataclasses.replace(sc, camera=dataclasses.replace(sc.camera, width=40, height=40))
    neutral = {k: v for ps in LB.LOBE_DEFAULTS.values() for k, v in ps.items()}
    base_objs = [dataclasses.replace(o, material=dataclasses.replace(o.material, **neutral)) for o in sc.objects]
    sb = dataclasses.replace(sc, objects=base_objs)
    a = render_uncached(sc, spp=4, mode="local", progress=False, aovs=False)
    b = render_uncached(sb, spp=4, mode="local", progress=False, aovs=False)
    A = np.stack([a.channels[c] for c in "RGB"], -1)
    B = np.stack([b.channels[c] for c in "RGB"], -1)
    assert np.isfinite(A).all()
    assert np.abs(A - B).mean() > 1e-3, np.abs(A - B).mean()


# ---- the shared Khronos assets ------------------------------------------------------------------

SHARED = __import__("pathlib").Path(__file__).resolve().parents[2] / "shared"
#: The smallest 99th percentile over pixels of max_rgb |lobes - no lobes| (linear) that each asset's
#: 64 x 64, 4 spp `local` render must show: the lobes cover a few % of the frame (measured at 128 x 128,
#: 8 spp: 0.051 ClearCoatTest, 0.039 SpecularTest, 0.25 AnisotropyRotationTest, 0.16 SheenCloth, 0.16
#: IridescenceSuzanne).
ASSET_MIN_CHANGE = 1e-2


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ClearCoatTest", "SheenCloth", "SpecularTest", "AnisotropyStrengthTest",
                                  "AnisotropyRotationTest", "IridescenceSuzanne"])
def test_shared_asset_lobes_change_the_image(name, monkeypatch):
    """A low-spp render of each shared Khronos lobe asset under a real environment changes where the
    lobes are modelled (against the same render with the lobes' props left out)."""
    from pbrcheck.scene import asset_scene
    from reference.render import render_uncached

    path = SHARED / "assets" / "khronos" / name / f"{name}.gltf"
    envs = sorted((SHARED / "envmaps").glob("*.hdr")) if (SHARED / "envmaps").is_dir() else []
    if not path.exists() or not envs:
        pytest.skip(f"{path} or ../shared/envmaps is absent (the real assets live in ../shared)")
    sc = asset_scene(path, env=str(envs[0]), size=(64, 64))
    # IridescenceSuzanne's glass head is transmissive (the film on its interface, issue 37): local mode
    # refuses a transmissive material it renders, so that asset renders in path mode
    mode = "path" if name == "IridescenceSuzanne" else "local"
    a = render_uncached(sc, spp=4, mode=mode, progress=False, aovs=False)
    monkeypatch.setattr(LB, "gltf_lobe_props", lambda *args, **kw: {})
    b = render_uncached(sc, spp=4, mode=mode, progress=False, aovs=False)
    A = np.stack([a.channels[c] for c in "RGB"], -1)
    B = np.stack([b.channels[c] for c in "RGB"], -1)
    assert np.isfinite(A).all()
    change = float(np.percentile(np.abs(A - B).max(axis=-1), 99))
    assert change > ASSET_MIN_CHANGE, change


def test_textured_clearcoat_known_answer(tmp_path):
    """A glTF quad, black base with specularFactor 0 (no reflection), clearcoatFactor 1 times a
    clearcoatTexture whose R is 1 on the image's left half and 0 on its right, read through
    KHR_texture_transform's offset (0.5, 0), which swaps the halves: the quad's right half (u > 0.5)
    shows the coat, 0.04 of the constant environment near normal incidence, its left half 0."""
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from gltf_build import quad_asset, quad_scene
    from reference.render import render_uncached

    px = np.zeros((2, 4, 3), np.uint8)
    px[:, :2, 0] = 255
    tex = {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0]}}}
    mat = {"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0, "roughnessFactor": 0.5},
           "extensions": {"KHR_materials_specular": {"specularFactor": 0.0},
                          "KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatTexture": tex}}}
    asset = quad_asset(tmp_path / "coat.gltf", mat, [(px, {"magFilter": 9728, "minFilter": 9728})])
    sc = load_scene(quad_scene(tmp_path, asset, size=(16, 8), fov=30.0))
    img = render_uncached(sc, spp=4, mode="local", progress=False, aovs=False)
    R = img.channels["R"]
    assert np.abs(R[3:5, 1:6]).max() == 0.0, R[3:5, 1:6]          # left half: no coat, no base reflection
    np.testing.assert_allclose(R[3:5, 10:15], 0.04, atol=COAT_KNOWN_ATOL)   # right half: Fc(~1) = 0.04


@pytest.mark.parametrize("name,obj", [("clearcoat", 24), pytest.param("sheen", 24, marks=pytest.mark.slow),
                                      ("iridescence", 24), pytest.param("anisotropy", 24, marks=pytest.mark.slow)])
def test_lobe_scene_is_differentiable(name, obj):
    """`local` differentiates through the lobes (the thin film's loop included): the red image mean's
    gradient w.r.t. a layered sphere's base_color (red) is finite and positive."""
    from pbrcheck.lobe_params import scene_features
    from reference.diff import load_differentiable_scene, param_key, render_with_gradient

    sc = load_scene(name)
    sc = dataclasses.replace(sc, camera=dataclasses.replace(sc.camera, width=24, height=24))
    ms, params = load_differentiable_scene(sc, spp=4)
    key = param_key(obj, "base_color")
    assert scene_features(sc.objects[obj].material)
    _, _, g = render_with_gradient(ms, params, [key], lambda img: dr.mean(img[..., 0], axis=None), spp=4)
    grad = np.asarray(g[key]).ravel()
    assert np.all(np.isfinite(grad)) and grad[0] > 0, grad


def test_textured_anisotropy_direction_equals_rotation(tmp_path):
    """anisotropyTexture's RG direction (2 x - 1) at angle a and B strength 1 renders as the factor
    anisotropyRotation = a without a texture (KHR_materials_anisotropy: the direction in the tangent
    frame, rotated by anisotropyRotation), and differs from the unrotated lobe."""
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from gltf_build import quad_asset, quad_scene
    from reference.render import render_uncached

    a = 1.0
    px = np.zeros((2, 2, 3), np.uint8)
    px[..., 0] = round((math.cos(a) + 1) / 2 * 255)
    px[..., 1] = round((math.sin(a) + 1) / 2 * 255)
    px[..., 2] = 255
    a_px = math.atan2(px[0, 0, 1] / 255 * 2 - 1, px[0, 0, 0] / 255 * 2 - 1)   # the 8-bit direction's angle
    base = {"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 1.0, "roughnessFactor": 0.4}}

    sky = """
[environment]
type = "sky"
sun_direction = [0.4, 0.6, 0.7]
sun_angular_diameter = 8.0
sun_radiance = [60.0, 55.0, 48.0]
sky_radiance = [0.25, 0.4, 0.8]
horizon_radiance = [0.9, 0.85, 0.8]
ground_radiance = [0.25, 0.2, 0.15]
resolution = [256, 128]
"""

    def render(ext, images=()):
        k = len(list(tmp_path.iterdir()))
        mat = dict(base, extensions={"KHR_materials_anisotropy": ext})
        asset = quad_asset(tmp_path / f"a{k}.gltf", mat, list(images))
        p = quad_scene(tmp_path, asset, size=(12, 12), name=f"s{k}.toml")
        text = p.read_text()   # the quad under a sky with a sun (a constant environment hides the direction)
        p.write_text(text[:text.index("[environment]")] + sky + text[text.index("[[objects]]"):])
        img = render_uncached(load_scene(p), spp=8, mode="local", progress=False, aovs=False)
        return np.stack([img.channels[c] for c in "RGB"], -1)

    tex = render({"anisotropyStrength": 1.0, "anisotropyTexture": {"index": 0}}, [(px, {"magFilter": 9728})])
    rot = render({"anisotropyStrength": 1.0, "anisotropyRotation": a_px})
    zero = render({"anisotropyStrength": 1.0})
    np.testing.assert_allclose(tex, rot, rtol=1e-4, atol=1e-6)
    assert np.abs(tex - zero).max() > 5e-2, np.abs(tex - zero).max()


def test_clearcoat_factor_gradient_matches_finite_difference(tmp_path):
    """The lobes' factors are differentiable parameters (``traverse``): on the black sphere under a
    coat (L = clearcoat Fc(n.v) A_coat(n.v), linear in clearcoat) the gradient of the image mean
    w.r.t. clearcoat equals the central difference (measured 0.0601 against 0.0560 at 16 spp: the
    difference's samples move with the lobe probabilities)."""
    from reference.diff import load_differentiable_scene, param_key, render_image, render_with_gradient

    ms, params = load_differentiable_scene(_known_scene(tmp_path, clearcoat=0.5), spp=16)
    key = param_key(0, "clearcoat")
    _, _, g = render_with_gradient(ms, params, [key], lambda img: dr.mean(img, axis=None), spp=16)
    vals = []
    for c in (0.4, 0.6):
        params[key] = c
        params.update()
        vals.append(render_image(ms, params, spp=16).mean())
    fd = (vals[1] - vals[0]) / 0.2
    assert fd > 0.03
    assert abs(float(np.asarray(g[key]).ravel()[0]) - fd) < GRAD_FD_RTOL * fd, (g[key], fd)
