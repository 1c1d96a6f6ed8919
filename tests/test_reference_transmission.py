"""reference/transmission.py (issue 37 item 1): the Dr.Jit twins equal pbrcheck/transmission.py's numpy
classes on grids with the extremes (both sides, grazing to normal, roughness 0.01 to 1, IOR 1 to 2.4),
samples included; the ``pbr_transmissive`` material's sampling weight is its eval / pdf; ``local``
mode refuses a transmissive object in one typed line."""

from __future__ import annotations

import numpy as np
import pytest

from pbrcheck import transmission as N
from pbrcheck.unmodelled import REFERENCE_REFUSED
from pbrcheck.errors import SceneError
from pbrcheck.scene import scene_from_dict
from tests.test_lobes import TWIN_DIR_ATOL, _close, _V   # the lobes' twin tolerances and helpers
from tests.test_transmission import _pairs, _sphere_dirs, make

TWINS = [("dielectric", 0.01, 1.5), ("dielectric", 0.3, 1.5), ("dielectric", 1.0, 2.4), ("dielectric", 0.5, 1.0),
         ("dielectric", 0.0, 1.33), ("thin", 0.05, 1.5), ("thin", 0.6, 1.0), ("thin", 1.0, 2.0), ("diffuse", 1.0, 1.0)]


@pytest.fixture(scope="module")
def R():
    from reference.variant import ensure_variant

    ensure_variant()
    from reference import transmission

    return transmission


@pytest.mark.parametrize("kind,r,ior", TWINS)
def test_twins_eval_pdf_sample(R, kind, r, ior):
    import mitsuba as mi

    v, l = _pairs()
    ln, lr = make(kind, r, ior), make(kind, r, ior, R)
    _close(ln.eval(v, l), np.array(lr.eval(_V(v), _V(l))))
    _close(ln.pdf(v, l), np.array(lr.pdf(_V(v), _V(l))))
    g = np.array([0.0, 1e-4, 0.25, 0.5, 0.75, 0.9999])
    u = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    d = _sphere_dirs()[::2]
    vv, uu = np.repeat(d, len(u), axis=0), np.tile(u, (len(d), 1))
    uc = np.tile(np.array([0.0, 0.3, 0.97]), len(uu) // 3 + 1)[:len(uu)]
    ls, ws, ps, ds = ln.sample(vv, uu, uc)
    lsr, wsr, psr, dsr = lr.sample(_V(vv), mi.Point2f(mi.Float(uu[:, 0]), mi.Float(uu[:, 1])), mi.Float(uc))
    lsr = np.array(lsr).T
    # a float32 direction at the horizon, or a Fresnel choice within rounding of uc, may fall the other way
    valid = ws > 0     # the numpy sample is a direction of the lobe
    ok = valid & (np.abs(ls[:, 2]) > 5e-4) & (np.abs(lsr[:, 2]) > 5e-4) & (np.sign(ls[:, 2]) == np.sign(lsr[:, 2]))
    assert ok.sum() > 0.9 * valid.sum() and valid.sum() > len(ws) // 2
    assert np.all(np.array(wsr)[~valid & (np.abs(ls[:, 2]) > 5e-4)] == 0)
    np.testing.assert_allclose(lsr[ok], ls[ok], atol=TWIN_DIR_ATOL)
    _close(ws[ok], np.array(wsr)[ok])
    if r >= 0.1:   # a lobe narrower than that: its ~1 / alpha^2 density moves with the float32 direction's error
        _close(ps[ok], np.array(psr)[ok])
    assert np.array_equal(np.array(dsr, dtype=bool)[ok], np.broadcast_to(ds, ok.shape)[ok])


def _material(R, **kw):
    import mitsuba as mi

    R.register()
    return mi.load_dict({"type": R.PLUGIN_NAME, **kw})


MATERIALS = [dict(transmission=1.0, roughness=0.4, ior=1.5, volume=True),
             dict(transmission=0.6, roughness=0.5, ior=1.5, base_color=[0.9, 0.5, 0.2], metallic=0.3),
             dict(transmission=0.0, diffuse_transmission=0.7, roughness=0.3, diffuse_transmission_color=[1.0, 0.2, 0.1]),
             dict(transmission=0.5, diffuse_transmission=0.5, roughness=0.8, ior=1.33, volume=True),
             dict(transmission=1.0, roughness=0.3, ior=1.5, volume=True, dispersion=0.6)]


def sample_and_eval(bsdf, mu, n, rng):
    """``n`` samples of ``bsdf`` at ``v`` of cosine ``mu`` (local frame ``n = +Z``) and its eval_pdf at
    the sampled directions: (weight (n, 3), value (n, 3), pdf, the sample's pdf), numpy."""
    import drjit as dr
    import mitsuba as mi

    v = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = _V(np.broadcast_to(v, (n, 3)))
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    ctx = mi.BSDFContext()
    u = rng.random((n, 3)).astype(np.float32)
    bs, w = bsdf.sample(ctx, si, mi.Float(u[:, 0]), mi.Point2f(mi.Float(u[:, 1]), mi.Float(u[:, 2])))
    value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
    return np.array(w).T, np.array(value).T, np.array(pdf), np.array(bs.pdf)


@pytest.mark.parametrize("kw", MATERIALS, ids=[f"m{k}" for k in range(len(MATERIALS))])
def test_material_sample_weight_is_eval_over_pdf(R, kw):
    bsdf = _material(R, **kw)
    rng = np.random.default_rng(2)
    n = 4096
    for mu in (0.8, 0.2, -0.6):
        w, value, pdf, bpdf = sample_and_eval(bsdf, mu, n, rng)
        glossy = (pdf > 0) & (np.abs(bpdf - pdf) <= 1e-4 * pdf)
        assert glossy.mean() > 0.5
        np.testing.assert_allclose(w[glossy], value[glossy] / pdf[glossy, None], rtol=1e-3, atol=1e-6)
        assert np.all(np.isfinite(w)) and np.all(w >= 0)
        # (no energy bound here: glTF's fresnel_mix, with F(v.h) per direction, exceeds 1 at grazing
        # with a diffuse base -- 1.197 at n.v 0.2 for m2 -- the spec's model, as the opaque material's)


def test_local_mode_refuses_a_transmissive_object_in_one_line(R):
    s = scene_from_dict({"environment": {"type": "constant"}, "camera": {"width": 8, "height": 8},
                         "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1,
                                      "material": {"transmission": 1.0}}]}, file="glass.toml")
    with pytest.raises(SceneError) as e:
        R.check_local(s)
    assert str(e.value).startswith("glass.toml: objects[0].material.transmission: expected no transmission in the "
                                   "reference's local mode") and "\n" not in str(e.value)
    R.check_local(scene_from_dict({"environment": {"type": "constant"}, "objects": [
        {"type": "sphere", "center": [0, 0, 0], "radius": 1}]}))   # an opaque scene passes


# ---- path mode: known answers ------------------------------------------------------------------------

#: Standard deviations a rendered mean may sit from its known answer (tests/test_reference_render.py's Z).
Z = 5.0
#: A sky whose sun lies behind the camera: a sheet that reflects shows it (the sky without the sun is
#: symmetric in z, so its mirror image through a sheet facing the camera equals what lies behind it).
SUN_BEHIND = {"type": "sky", "sun_direction": [0.1, 0.15, 0.98], "sun_angular_diameter": 20.0,
              "sun_radiance": [4, 4, 3.5], "resolution": [128, 64]}
PATH = dict(mode="path", max_depth=8, progress=False, seed=1)


def _sheet(center, normal=(0, 0, 1), **material):
    from pbrcheck.scene import scene_from_dict as sfd

    m = {"transmission": 1.0, "specular": 0.0, "roughness": 0.0, "metallic": 0.0, "base_color": [1, 1, 1]} | material
    return sfd({"camera": {"origin": [0, 0, 4], "fov": 40, "width": 16, "height": 16}, "environment": SUN_BEHIND,
                "objects": [{"type": "plane", "center": list(center), "normal": list(normal), "size": [4, 4],
                             "material": m}]})


def test_thin_sheet_of_transmission_one_and_ior_one_is_invisible(R):
    """A thin-walled sheet (transmission 1, IOR 1: specular F0 0, roughness 0) filling the view renders
    the environment behind it: the image equals the same scene with the sheet out of view (its only
    reflection is Schlick's (1 - n.v)^5 < 1e-6 at these angles). The same sheet at IOR 1.5 shows the
    sun behind the camera (the test can fail)."""
    from reference.render import render_uncached

    seen = render_uncached(_sheet((0, 0, 1)), spp=16, **PATH)
    away = render_uncached(_sheet((50, 0, 0), (1, 0, 0)), spp=16, **PATH)
    glass = render_uncached(_sheet((0, 0, 1), specular=0.04), spp=16, **PATH)
    assert seen.channels["coverage"].min() == 1.0 and away.channels["coverage"].max() == 0.0
    for c in ("R", "G", "B"):
        np.testing.assert_allclose(seen.channels[c], away.channels[c], atol=1e-5)
        assert np.abs(glass.channels[c] - away.channels[c]).max() > 0.1
        assert away.channels[c].std() > 0.1          # a structured environment, not a flat colour


def _ball(ior_f0, size, fov, color=(0.5, 0.8, 0.2)):
    from pbrcheck.scene import scene_from_dict as sfd

    return sfd({"camera": {"origin": [0, 0, 4], "fov": fov, "width": size, "height": size},
                "environment": {"type": "constant", "radiance": [1, 1, 1]},
                "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": {
                    "transmission": 1.0, "specular": ior_f0, "roughness": 0.0, "metallic": 0.0,
                    "base_color": [1, 1, 1], "thickness": 1.0, "attenuation_distance": 1.0,
                    "attenuation_color": list(color)}}]})


def _mean_and_sd(img, c):
    x = img.channels[c]
    return float(x.mean()), float(np.sqrt(img.channels["variance." + c].sum()) / x.size)


def test_attenuation_through_an_index_matched_ball_is_beer_lambert_along_each_chord(R):
    """IOR 1 (no refraction) ball of radius 1, attenuation colour c at distance 1, constant white
    environment: each camera ray keeps ``c^chord`` with ``chord = 2 sqrt(1 - b^2)`` at its distance b
    from the centre (Beer-Lambert along the path travelled); expected per pixel over its area."""
    from pbrcheck.camera import primary_rays
    from reference.render import render_uncached

    s = _ball(0.0, 8, 20.0)
    img = render_uncached(s, spp=256, **PATH)
    g = (np.arange(8) + 0.5) / 8
    want = np.zeros((8, 8, 3))
    for ox in g:
        for oy in g:
            o, d = primary_rays(s.camera, (ox, oy))
            t = -(d @ o)                                          # closest approach to the centre
            b2 = np.maximum(o @ o - t * t, 0.0)
            chord = np.where(b2 < 1.0, 2.0 * np.sqrt(np.maximum(1.0 - b2, 0.0)), 0.0)
            want += np.power(np.array([0.5, 0.8, 0.2]), chord[..., None]) / 64
    assert want.min() < 0.1 and (want < 1).all()       # every pixel sees through the ball
    for k, c in enumerate("RGB"):
        got, sd = _mean_and_sd(img, c)
        assert abs(got - want[..., k].mean()) <= Z * sd + 1e-3, (c, got, want[..., k].mean(), sd)
        sd_px = np.sqrt(img.channels["variance." + c])                # per pixel: its own noise (volpath's walk)
        assert np.all(np.abs(img.channels[c] - want[..., k]) <= Z * sd_px + 1e-3)


def test_attenuation_through_a_glass_ball_equals_the_slab_closed_form(R):
    """IOR 1.5, the centre of the ball (a narrow camera: every ray within 0.04 of the axis): the
    internal reflections stay on the diameter, so the pixel is the slab of thickness 2 in a white
    environment: ``R + (1 - R)^2 a / (1 - R^2 a^2) + (1 - R)^2 R a^2 / (1 - R^2 a^2)`` (front reflection,
    all orders through, all orders back out), ``a = c^2``, ``R`` = F0 = 0.04."""
    from pbrcheck.transmission import slab_transmittance
    from reference.render import render_uncached

    img = render_uncached(_ball(0.04, 4, 1.0), spp=1024, **PATH)
    for k, c in enumerate("RGB"):
        a = (0.5, 0.8, 0.2)[k] ** 2
        Rf = 0.04
        want = Rf + slab_transmittance(1.5, -np.log((0.5, 0.8, 0.2)[k]), 2.0) + (1 - Rf) ** 2 * Rf * a * a / (1 - Rf * Rf * a * a)
        got, sd = _mean_and_sd(img, c)
        assert abs(got - want) <= Z * sd + 2e-3, (c, got, want, sd)


def _furnace_ball(roughness):
    from pbrcheck.scene import scene_from_dict as sfd

    return sfd({"camera": {"origin": [0, 0, 4], "fov": 12, "width": 8, "height": 8},
                "environment": {"type": "constant", "radiance": [1, 1, 1]},
                "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": {
                    "transmission": 1.0, "specular": 0.04, "roughness": roughness, "metallic": 0.0,
                    "base_color": [1, 1, 1], "thickness": 1.0}}]})


def test_white_glass_ball_in_a_white_furnace(R):
    """A white, non-absorbing glass ball (IOR 1.5, a volume) in a constant white environment, the
    ball's centre filling the view: smooth, it disappears (every path leaves with weight 1: the
    radiance factors (eta_v / eta_l)^2 cancel on the way out; 16 bounces leave < 1e-3 inside); rough,
    it is darker (the single-scattering microfacets' loss per crossing, docs/reference.md), never brighter."""
    from reference.render import render_uncached

    smooth = render_uncached(_furnace_ball(0.0), spp=64, **(PATH | {"max_depth": 16}))
    rough = render_uncached(_furnace_ball(0.6), spp=256, **(PATH | {"max_depth": 16}))
    assert smooth.channels["coverage"].min() == 1.0
    for c in ("R", "G", "B"):
        np.testing.assert_allclose(smooth.channels[c], 1.0, atol=2e-3)
        got, sd = _mean_and_sd(rough, c)
        assert 0.5 < got < 1.0 - Z * sd, (got, sd)


def test_dispersive_refraction_carries_one_channel_at_its_own_ior(R):
    """KHR_materials_dispersion on a smooth volume: a refracted sample carries one channel k (weight
    3 e_k times the radiance factor), its direction obeying Snell's law at that channel's IOR
    (``channel_iors``: the README's Cauchy form at Fraunhofer's C, d, F lines); dispersion 0 is the
    plain material."""
    import drjit as dr
    import mitsuba as mi

    from pbrcheck.transmission import channel_iors

    bsdf = _material(R, transmission=1.0, roughness=0.0, ior=1.5, volume=True, dispersion=1.0)
    n = 3000
    mu = 0.6
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(float(np.sqrt(1 - mu * mu)), 0.0, mu)
    u = (np.arange(n) + 0.5) / n
    bs, w = bsdf.sample(mi.BSDFContext(), si, mi.Float(u), mi.Point2f(0.3, 0.7))
    wo, w = np.array(bs.wo).T, np.array(w).T
    trans = wo[:, 2] < 0
    iors = channel_iors(1.5, 1.0)
    assert iors[2] > iors[1] > iors[0] and iors[1] == pytest.approx(1.5, abs=2e-4)
    seen = set()
    for k in range(3):
        mine = trans & (w[:, k] > 0)
        assert mine.sum() > n // 5
        np.testing.assert_array_equal(np.delete(w[mine], k, axis=1), 0.0)       # the other channels carry nothing
        sin_t = np.hypot(wo[mine, 0], wo[mine, 1])
        np.testing.assert_allclose(sin_t, np.sqrt(1 - mu * mu) / iors[k], rtol=1e-5)  # Snell at n_k
        np.testing.assert_allclose(w[mine, k], 3.0 / iors[k] ** 2, rtol=1e-5)        # 3 e_k (eta_v / eta_l)^2
        seen.add(round(float(sin_t[0]), 5))
    assert len(seen) == 3                                                         # three directions
    plain = _material(R, transmission=1.0, roughness=0.0, ior=1.5, volume=True)
    bs0, w0 = plain.sample(mi.BSDFContext(), si, mi.Float(u), mi.Point2f(0.3, 0.7))
    assert np.all(np.array(w0)[:, np.array(bs0.wo)[2] < 0] > 0)                   # every channel, one direction


def test_dispersive_glass_ball_in_a_white_furnace_is_unbiased(R):
    """A smooth dispersive ball (dispersion 1, rough 0.3 too) in a white furnace: each channel's paths are
    a smooth (rough) dielectric's at that channel's IOR, so the image is 1 (the rough one's losses) per
    channel in expectation, within its noise (the channel choice's variance)."""
    from pbrcheck.scene import scene_from_dict as sfd
    from reference.render import render_uncached

    def ball(r, disp):
        return sfd({"camera": {"origin": [0, 0, 4], "fov": 12, "width": 8, "height": 8},
                    "environment": {"type": "constant", "radiance": [1, 1, 1]},
                    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": {
                        "transmission": 1.0, "specular": 0.04, "roughness": r, "base_color": [1, 1, 1],
                        "thickness": 1.0, "dispersion": disp}}]})

    smooth = render_uncached(ball(0.0, 1.0), spp=256, **(PATH | {"max_depth": 16}))
    for c in ("R", "G", "B"):
        got, sd = _mean_and_sd(smooth, c)
        assert abs(got - 1.0) <= Z * sd + 1e-3 and sd > 1e-4, (c, got, sd)   # noisy (one channel per path), unbiased


@pytest.mark.parametrize("kw", MATERIALS, ids=[f"m{k}" for k in range(len(MATERIALS))])
def test_material_twins_eval_pdf(R, kw):
    """``pbr_transmissive``'s eval and pdf equal pbrcheck.transmission.TransmissiveMaterial's on the
    sphere grid (both sides)."""
    import drjit as dr
    import mitsuba as mi

    bsdf = _material(R, **kw)
    ref = N.TransmissiveMaterial(**kw)
    v, l = _pairs()
    si = dr.zeros(mi.SurfaceInteraction3f, len(v))
    si.wi = _V(v)
    value, pdf = bsdf.eval_pdf(mi.BSDFContext(), si, _V(l))
    _close(ref.eval(v, l), np.array(value).T)
    _close(ref.pdf(v, l), np.array(pdf))
    assert np.count_nonzero(ref.eval(v, l)) > len(v)


# ---- glTF assets -------------------------------------------------------------------------------------

def _glass_quad(tmp_path, name, ior=1.0, textured=False, volume=None, coat=False):
    from tests.gltf_build import quad_asset

    ext = {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": ior}}
    if volume:
        ext["KHR_materials_volume"] = volume
    mat = {"name": name, "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.0}, "extensions": ext}
    images = []
    if textured:
        mat["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
        images = [(np.full((2, 2, 4), 200, np.uint8), None)]
    if coat:   # a clearcoat lobe's texture: not read by the transmissive material (opaque)
        ext["KHR_materials_clearcoat"] = {"clearcoatFactor": 1.0, "clearcoatTexture": {"index": 0}}
    return quad_asset(tmp_path / f"{name}.gltf", mat, images, scale=3.0)


def _asset_scene(asset, translation=(0.0, 0.0, 0.0)):
    from pbrcheck.scene import scene_from_dict as sfd

    return sfd({"camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "fov": 30, "width": 12, "height": 12},
                "environment": SUN_BEHIND, "objects": [{"type": "gltf", "path": str(asset), "translation": list(translation)}]})


def test_a_gltf_sheet_of_transmission_one_and_ior_one_is_invisible(R, tmp_path):
    """A glTF quad with KHR_materials_transmission 1, KHR_materials_ior 1, roughness 0 (constant factors:
    the reference's pbr_transmissive) filling the view renders the environment behind it (path mode);
    at IOR 1.5 it shows the sun behind the camera; ``local`` mode refuses it in one line."""
    from reference.render import render_uncached

    sheet = _glass_quad(tmp_path, "clear")
    seen = render_uncached(_asset_scene(sheet), spp=8, **PATH)
    away = render_uncached(_asset_scene(sheet, (50.0, 0.0, 0.0)), spp=8, **PATH)
    glass = render_uncached(_asset_scene(_glass_quad(tmp_path, "glass", 1.5)), spp=8, **PATH)
    assert seen.channels["coverage"].min() == 1.0 and away.channels["coverage"].max() == 0.0
    for c in ("R", "G", "B"):
        np.testing.assert_allclose(seen.channels[c], away.channels[c], atol=1e-5)
        assert np.abs(glass.channels[c] - away.channels[c]).max() > 0.1
    with pytest.raises(SceneError, match=r"objects\[0\] \(.*\): its glTF material's KHR_materials_transmission: "
                                         "expected no transmission in the reference's local mode"):
        R.check_local(_asset_scene(sheet))


def test_only_constant_factor_gltf_materials_take_the_transmissive_bsdf(R, tmp_path, capsys):
    """A transmissive glTF material with a texture the reference does not read per hit (here a
    clearcoat lobe's) keeps the opaque textured material (its transmission named as unmodelled on
    stderr, the reference rendering it opaque); one of constant factors takes ``pbr_transmissive``
    (modelled: no notice), and a
    volume its interior medium; one with a base colour texture the textured variant, which needs the
    asset's images (none given: ``{}``); stderr says which."""
    from pbrcheck.gltf import load_asset
    from pbrcheck.scene import BRDFModel, load_scene
    from pbrcheck.transmission_params import reference_renders
    from pbrcheck.unmodelled import notice_lines

    clear = load_asset(_glass_quad(tmp_path, "clear")).materials[0]
    tex = load_asset(_glass_quad(tmp_path, "tex", textured=True)).materials[0]
    coat = load_asset(_glass_quad(tmp_path, "coat", textured=True, coat=True)).materials[0]
    vol = load_asset(_glass_quad(tmp_path, "vol", volume={"thicknessFactor": 1.0, "attenuationDistance": 2.0,
                                                           "attenuationColor": [0.5, 0.5, 0.5]})).materials[0]
    assert reference_renders(clear) and reference_renders(tex) and not reference_renders(coat) and reference_renders(vol)
    props = R.gltf_shape_props(vol, BRDFModel())
    assert props["bsdf"].volume and "interior" in props and not R.gltf_shape_props(clear, BRDFModel())["bsdf"].volume
    assert R.gltf_shape_props(tex, BRDFModel()) == {} == R.gltf_shape_props(coat, BRDFModel())
    assert notice_lines(load_asset(tmp_path / "clear.gltf")) == []
    assert REFERENCE_REFUSED.format(why="textures it does not read per hit: clearcoat") in \
        notice_lines(load_asset(tmp_path / "coat.gltf"))[0]
    load_scene(str(tmp_path / "coat.gltf"))
    R.check_local(_asset_scene(tmp_path / "coat.gltf"))   # renders opaque: local mode takes it
    with pytest.raises(SceneError, match="local mode"):
        R.check_local(_asset_scene(tmp_path / "tex.gltf"))


def test_a_diffusely_transmitting_sheet_in_a_white_environment_is_its_numpy_albedo(R):
    """A thin sheet (diffuse transmission 0.7 of colour (1, 0.5, 0.25), base colour (0.2, 0.4, 0.6),
    roughness 0.5, IOR 1.5) seen head-on in a constant white environment: one bounce, so each pixel is
    the material's albedo at n.v = 1, ``int eval dl`` over the sphere by pbrcheck.transmission's numpy
    twin (Gauss-Legendre in cos theta over [-1, 1], midpoint in phi)."""
    from pbrcheck.scene import scene_from_dict as sfd
    from reference.render import render_uncached

    mat = {"diffuse_transmission": 0.7, "diffuse_transmission_color": [1.0, 0.5, 0.25], "base_color": [0.2, 0.4, 0.6],
           "roughness": 0.5, "specular": 0.04, "metallic": 0.0}
    s = sfd({"camera": {"origin": [0, 0, 4], "fov": 1.0, "width": 4, "height": 4},
             "environment": {"type": "constant", "radiance": [1, 1, 1]},
             "objects": [{"type": "plane", "center": [0, 0, 0], "normal": [0, 0, 1], "size": [2, 2], "material": mat}]})
    img = render_uncached(s, spp=1024, **PATH)
    ref = N.TransmissiveMaterial(base_color=(0.2, 0.4, 0.6), roughness=0.5, ior=1.5, diffuse_transmission=0.7,
                                 diffuse_transmission_color=(1.0, 0.5, 0.25))
    x, w = np.polynomial.legendre.leggauss(256)
    nphi = 128
    phi = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    c, p = np.meshgrid(x, phi, indexing="ij")
    sn = np.sqrt(1 - c * c)
    l = np.stack([sn * np.cos(p), sn * np.sin(p), c], -1).reshape(-1, 3)
    f = ref.eval(np.broadcast_to([0.0, 0.0, 1.0], l.shape), l)
    albedo = (f * (np.repeat(w, nphi) * 2 * np.pi / nphi)[:, None]).sum(0)
    assert albedo[0] > 0.5 and albedo[0] != pytest.approx(albedo[2], abs=0.1)   # a coloured, bright answer
    for k, ch in enumerate("RGB"):
        got, sd = _mean_and_sd(img, ch)
        assert abs(got - albedo[k]) <= Z * sd + 2e-3, (ch, got, albedo[k], sd)
