"""KHR_materials_iridescence on a transmissive material in the reference's ``path`` mode (issue 37):
the thin film's Fresnel on the interface of ``pbr_transmissive`` / ``pbr_transmissive_textured``
(reference/transmission.py; numpy twins in pbrcheck/transmission.py), reflected ``F_rgb``, transmitted
``1 - F_rgb`` per channel. Known answers: the twins agree on grids with the extremes (both sides,
grazing, past the critical angle); the sampler's density passes a chi-square test; a smooth
iridescent sheet and a smooth iridescent glass ball in a white furnace return 1 per channel (a lossless
film); a film of thickness 0 does no interference (grey); iridescenceFactor 0 is the material without
the extension bit for bit; the thickness texture is read per hit (G: min to max). IridescenceSuzanne's
glass head renders transmissive (slow, skipped where ../shared is absent)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pbrcheck import transmission as N
from pbrcheck.scene import scene_from_dict
from tests.gltf_build import quad_asset
from tests.test_lobes import _V
from tests.test_reference_transmission import PATH, SUN_BEHIND, Z, _mean_and_sd, sample_and_eval
from tests.test_transmission import CHI2_SIGNIFICANCE, _chi2, _dir

SHARED = Path(__file__).resolve().parents[2] / "shared" / "assets" / "khronos"
#: float32 film (Dr.Jit, 401 wavelengths accumulated in float32) against float64 numpy: the sum's
#: rounding, ~401 x 6e-8 relative, and the float32 cosine near the critical angle; measured 3e-5.
FILM_TWIN_ATOL = 2e-4
#: A film of thickness 400 nm on glass seen at normal incidence differs between channels by far more
#: than this (0.029 measured, of channels 0.010 to 0.039); at thickness 0 the channels agree to float32 rounding.
COLOURED = 1e-2
#: As tests/test_reference_transmission_textured.py's ASSET_MIN_CHANGE: the glass head's change.
ASSET_MIN_CHANGE = 1e-2
FILMS = [(1.0, 400.0, 1.3), (0.5, 250.0, 1.8), (1.0, 0.0, 1.33), (1.0, 600.0, 1.0)]


@pytest.fixture(scope="module")
def R():
    from reference.variant import ensure_variant

    ensure_variant()
    from reference import transmission

    return transmission


def _film(R, w, d, nf, ior):
    return R.Film(w, d, nf, R._f0(ior))


@pytest.mark.parametrize("w,d,nf", FILMS)
@pytest.mark.parametrize("eta", [1.5, 2.4, 1.0, 1.0 / 1.5])
def test_film_fresnel_twins_on_both_sides(R, w, d, nf, eta):
    """numpy's interface_fresnel / thin_fresnel equal the Dr.Jit ones (reflectance per channel and the
    sampler's mean) at cosines from -1 to 1 with 0, grazing and past the critical angle; 1 under total
    internal reflection; the transmitted part is 1 - F per channel."""
    import mitsuba as mi

    c = np.array([-1.0, -0.9, -0.6, -0.3, -0.05, -1e-3, 0.0, 1e-3, 0.05, 0.3, 0.6, 0.9, 1.0])
    f0 = float(N.f0_from_ior(eta))
    film = (w, d, nf)
    Fn, Pn = N.interface_fresnel(c, eta, f0, film)
    Fr, Pr = R.interface_fresnel(mi.Float(c), eta, f0, _film(R, w, d, nf, eta))
    np.testing.assert_allclose(np.array(Fr).T, Fn, atol=FILM_TWIN_ATOL)
    np.testing.assert_allclose(np.array(Pr), Pn, atol=FILM_TWIN_ATOL)
    np.testing.assert_allclose(Pn, Fn.mean(axis=-1), atol=1e-12)
    tir = (c < 0) & (1.0 - c * c > (1.0 / eta) ** -2) if eta > 1 else (c > 0) & (1.0 - c * c > eta ** 2)
    assert np.all(Fn[tir] == 1.0)
    assert np.all((Fn >= 0.0) & (Fn <= 1.0))
    Tn, Tr = N.thin_fresnel(c, f0, film)[0], np.array(R.thin_fresnel(mi.Float(c), f0, _film(R, w, d, nf, eta))[0]).T
    np.testing.assert_allclose(Tr, Tn, atol=FILM_TWIN_ATOL)
    # the plain interface at the same outside cosine: the film replaces it by mix(F, film, w)
    plain = N.fresnel_dielectric(c, eta, f0)
    ok = ~tir
    Rf = (Fn[ok] - (1.0 - w) * plain[ok, None]) / w
    assert np.all(Rf > -1e-9) and np.all(Rf < 1.0 + 1e-9)


def test_the_film_is_coloured_at_400_nm_and_grey_at_thickness_0():
    """The film's reflectance at normal incidence on glass: its channels differ at 400 nm (the
    interference) and agree at 0 nm (no path difference: the README's film reduces to its m = 0 term,
    the same for every wavelength). At 0 nm it is not Schlick's F0 of the base (0.0401 vs 0.04 here:
    the README's two Schlick interfaces, not Fresnel's; docs/reference.md)."""
    f0 = float(N.f0_from_ior(1.5))
    at400 = N.film_fresnel(np.array([1.0]), np.array([f0]), 1.0, 400.0, 1.3, f0)[0]
    at0 = N.film_fresnel(np.array([1.0]), np.array([f0]), 1.0, 0.0, 1.3, f0)[0]
    assert np.ptp(at400) > 2 * COLOURED and np.ptp(at0) < 1e-9
    assert abs(at0[0] - f0) < 1e-3


class _DrLobe:
    """A Dr.Jit interface in numpy's lobe interface (``sample``, ``pdf``), for tests.test_transmission's chi-square."""

    def __init__(self, lobe):
        self.lobe = lobe

    def sample(self, v, u, uc):
        import mitsuba as mi

        v = np.broadcast_to(v, (len(u), 3))
        l, w, p, d = self.lobe.sample(_V(v), mi.Point2f(mi.Float(u[:, 0].astype(np.float32)),
                                                        mi.Float(u[:, 1].astype(np.float32))), mi.Float(uc.astype(np.float32)))
        return np.array(l).T.astype(np.float64), np.array(w).T, np.array(p, dtype=np.float64), np.array(d)

    def pdf(self, v, l):
        return np.array(self.lobe.pdf(_V(np.ascontiguousarray(v)), _V(l)), dtype=np.float64)


CHI2 = [("dielectric", 0.5, 1.5, 0.7), ("dielectric", 0.3, 1.5, -0.6), ("thin", 0.4, 1.5, 0.6), ("thin", 0.3, 1.0, -0.8)]


@pytest.mark.parametrize("kind,r,ior,mu", CHI2, ids=[f"{c[0]} r{c[1]} ior{c[2]} mu{c[3]}" for c in CHI2])
def test_chi2_of_the_iridescent_interfaces(R, kind, r, ior, mu):
    """The film changes the sampler's reflect / transmit choice (the channels' mean F): its samples
    follow its pdf (tests.test_transmission's chi-square over the sphere)."""
    film = _film(R, 1.0, 400.0, 1.8, ior)
    lobe = R.RoughDielectric(r, ior, film) if kind == "dielectric" else R.ThinDielectric(r, ior, film)
    p, bins = _chi2(_DrLobe(lobe), _dir(mu))
    assert p > CHI2_SIGNIFICANCE and bins > 50, (p, bins)


MATERIALS = [dict(transmission=1.0, roughness=0.4, ior=1.5, volume=True),
             dict(transmission=0.6, roughness=0.5, ior=1.5, base_color=[0.9, 0.5, 0.2], metallic=0.3),
             dict(transmission=1.0, roughness=0.0, ior=1.5, volume=True),
             dict(transmission=1.0, roughness=0.3, ior=1.5, volume=True, dispersion=0.6)]
IRID = dict(iridescence=1.0, iridescence_ior=1.8, iridescence_thickness=400.0)


@pytest.mark.parametrize("kw", MATERIALS, ids=[f"m{k}" for k in range(len(MATERIALS))])
def test_iridescent_material_sample_weight_is_eval_over_pdf(R, kw):
    """``pbr_transmissive`` with a film: each glossy sample's weight is eval / pdf per channel, finite
    and >= 0; the delta ones (m2) carry F_k / mean(F) and (1 - F_k) / (1 - mean(F)), mean 1."""
    import mitsuba as mi

    R.register()
    bsdf = mi.load_dict({"type": R.PLUGIN_NAME, **kw, **IRID})
    rng = np.random.default_rng(2)
    n = 4096
    for mu in (0.8, 0.2, -0.6):
        w, value, pdf, bpdf = sample_and_eval(bsdf, mu, n, rng)
        assert np.all(np.isfinite(w)) and np.all(w >= 0)
        if kw["roughness"] == 0.0:   # a smooth volume: every sample a delta; the mean weight per channel
            # F_k + (1 - F_k) (eta_v / eta_l)^2 (radiance), F_k numpy's film at the outside cosine
            F = N.interface_fresnel(np.array([mu]), 1.5, float(N.f0_from_ior(1.5)), (1.0, 400.0, 1.8))[0][0]
            ratio = (1.0 / 1.5) ** 2 if mu > 0 else 1.5 ** 2
            np.testing.assert_allclose(w.mean(axis=0), F + (1.0 - F) * ratio, atol=Z * w.std(axis=0).max() / np.sqrt(n) + 1e-6)
            if mu > 0:
                assert np.ptp(w, axis=1).max() > COLOURED   # the film's channels differ
            continue
        glossy = (pdf > 0) & (np.abs(bpdf - pdf) <= 1e-4 * pdf)
        assert glossy.mean() > 0.5
        np.testing.assert_allclose(w[glossy], value[glossy] / pdf[glossy, None], rtol=1e-3, atol=1e-6)


# ---- glTF assets -------------------------------------------------------------------------------------

def _sheet(tmp_path, name, *, irid=None, images=(), roughness=0.0, ior=1.5, volume=None):
    ext = {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": ior}}
    if irid is not None:
        ext["KHR_materials_iridescence"] = irid
    if volume is not None:
        ext["KHR_materials_volume"] = volume
    mat = {"name": name, "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": roughness},
           "extensions": ext}
    return quad_asset(tmp_path / f"{name}.gltf", mat, list(images), scale=3.0)


def _scene(asset, env=SUN_BEHIND, size=12):
    return scene_from_dict({"camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "fov": 30, "width": size,
                                       "height": size}, "environment": env,
                            "objects": [{"type": "gltf", "path": str(asset)}]})


def _rgb(img):
    return np.stack([img.channels[c] for c in ("R", "G", "B")], -1)


WHITE = {"type": "constant", "radiance": [1, 1, 1]}


def test_a_smooth_iridescent_sheet_in_a_white_furnace_returns_one_per_channel(R, tmp_path):
    """A thin-walled transmissive sheet (roughness 0, IOR 1.5) with a 400 nm film in a constant white
    environment: reflected F_k plus transmitted 1 - F_k is 1 per channel (within the noise of the
    reflect / transmit choice by mean F: each sample carries F_k / mean F or (1 - F_k) / (1 - mean F)).
    The README's rgb_mix weight 1 - max3(F) on the transmission would return 1 - max3 F + F_k < 1 in
    the channels below the maximum (the test can fail); under the sun the film colours the sheet."""
    from reference.render import render_uncached

    film = {"iridescenceFactor": 1.0, "iridescenceIor": 1.8, "iridescenceThicknessMaximum": 400.0}
    img = render_uncached(_scene(_sheet(tmp_path, "irid", irid=film), WHITE, 8), spp=256, **PATH)
    assert img.channels["coverage"].min() == 1.0
    for c in ("R", "G", "B"):
        got, sd = _mean_and_sd(img, c)
        assert abs(got - 1.0) <= Z * sd + 1e-4 and sd > 1e-5, (c, got, sd)   # noisy, unbiased
    sun = _rgb(render_uncached(_scene(_sheet(tmp_path, "irid2", irid=film)), spp=16, **PATH))
    plain = _rgb(render_uncached(_scene(_sheet(tmp_path, "plain")), spp=16, **PATH))
    assert np.abs(sun - plain).max() > 0.1


def test_a_smooth_iridescent_glass_ball_in_a_white_furnace(R):
    """A smooth, non-absorbing glass ball (a volume, IOR 1.5) whose interface carries a 400 nm film, in
    a constant white environment (Mitsuba's ``path`` integrator on ``pbr_transmissive`` with the film's
    keys): every path leaves with expected weight 1 per channel (the film on the way in and on the way
    out, from inside: the reflectance at the outside cosine), so the ball disappears within the noise."""
    import mitsuba as mi

    R.register()
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": 32},
                          "emitter": {"type": "constant", "radiance": {"type": "rgb", "value": [1, 1, 1]}},
                          "sensor": {"type": "perspective", "fov": 10, "to_world": mi.ScalarTransform4f().look_at(
                              origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                              "film": {"type": "hdrfilm", "width": 8, "height": 8, "pixel_format": "rgb"},
                              "sampler": {"type": "independent", "sample_count": 256}},
                          "ball": {"type": "sphere", "bsdf": {"type": R.PLUGIN_NAME, "transmission": 1.0, "roughness": 0.0,
                                                              "ior": 1.5, "volume": True, **IRID}}})
    img = np.array(mi.render(scene, seed=1))
    n = 256
    for k in range(3):
        x = img[..., k]
        assert abs(x.mean() - 1.0) < 2e-2 and x.std() / np.sqrt(n) < 2e-2, (k, x.mean(), x.std())


def test_iridescence_factor_0_is_the_material_without_it_bit_for_bit(R, tmp_path):
    """[Irid] "If iridescenceFactor is zero, the iridescence extension has no effect": the sheet with
    the extension at factor 0 (a thickness texture too, in the textured variant) renders bit for bit as
    without it; the same sheet at factor 1 differs (the test can fail)."""
    from reference.render import render_uncached

    px = np.zeros((2, 2, 4), np.uint8)
    px[..., 1] = 128
    bc = {"index": 1}
    grey = np.full((2, 2, 4), 220, np.uint8)
    for textured in (False, True):
        images = [(px, None), (grey, None)] if textured else []

        def asset(name, factor):
            irid = {"iridescenceFactor": factor, "iridescenceThicknessMaximum": 500.0}
            if textured:
                irid["iridescenceThicknessTexture"] = {"index": 0}
            a = _sheet(tmp_path, name, irid=irid if factor is not None else None, images=images, roughness=0.3)
            if textured:   # a base colour texture: the textured variant either way
                import json
                d = json.loads(Path(a).read_text())
                d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = bc
                Path(a).write_text(json.dumps(d))
            return a

        off = _rgb(render_uncached(_scene(asset(f"off{textured}", 0.0)), spp=8, **PATH))
        none = _rgb(render_uncached(_scene(asset(f"none{textured}", None)), spp=8, **PATH))
        on = _rgb(render_uncached(_scene(asset(f"on{textured}", 1.0)), spp=8, **PATH))
        assert np.array_equal(off, none), textured
        assert np.abs(on - none).max() > 0.05, textured


def test_the_thickness_texture_is_read_per_hit(R, tmp_path):
    """A thickness texture of G = 0 on the left half and 1 on the right (nearest filtering), minimum 0
    nm and maximum 400 nm ([Irid]: ``mix(min, max, G)``): under a sky whose sun lies behind the camera
    the left half's film does no interference, so its reflection has the plain glass's chromaticity
    (grey film: each channel scaled alike), and the right half's differs (coloured)."""
    from reference.render import render_uncached

    px = np.zeros((2, 2, 4), np.uint8)
    px[:, 1, 1] = 255
    px[..., 3] = 255
    sun = {"type": "sky", "sun_direction": [0.0, 0.0, 1.0], "sun_angular_diameter": 20.0,
           "sun_radiance": [4, 4, 4], "sky_radiance": [0, 0, 0], "resolution": [128, 64]}
    film = {"iridescenceFactor": 1.0, "iridescenceIor": 1.3, "iridescenceThicknessMinimum": 0.0,
            "iridescenceThicknessMaximum": 400.0, "iridescenceThicknessTexture": {"index": 0}}
    asset = _sheet(tmp_path, "half", irid=film, images=[(px, {"magFilter": 9728, "minFilter": 9728})])
    img = _rgb(render_uncached(_scene(asset, sun, 16), spp=16, **PATH))
    plain = _rgb(render_uncached(_scene(_sheet(tmp_path, "plain"), sun, 16), spp=16, **PATH))
    lit = plain.sum(axis=-1) > 1e-3
    assert lit[4:12, 1:6].mean() > 0.5 and lit[4:12, 10:15].mean() > 0.5

    def chroma(a):
        return a / np.maximum(a.sum(axis=-1, keepdims=True), 1e-12)

    d = np.abs(chroma(img) - chroma(plain)).max(axis=-1)
    assert d[4:12, 1:6][lit[4:12, 1:6]].max() < 1e-4
    assert np.median(d[4:12, 10:15][lit[4:12, 10:15]]) > 1e-3   # 6e-3 measured (the transmitted 1 - F tinted too)


def test_reference_renders_iridescent_transmissive_materials_and_keys_their_cache(tmp_path):
    """reference_renders accepts the film's textures (no notice); a clearcoat texture still refuses;
    the scene keys its renders with the textured (2) and iridescent parts."""
    from pbrcheck.gltf import load_asset
    from pbrcheck.transmission_params import reference_refusal, reference_renders
    from pbrcheck.unmodelled import notice_lines
    from reference.render import IRIDESCENT_TRANSMISSION_CODE_VERSION, TEXTURED_TRANSMISSION_CODE_VERSION
    from reference.render import transmission_cache_parts

    px = np.full((2, 2, 4), 255, np.uint8)
    film = {"iridescenceFactor": 1.0, "iridescenceTexture": {"index": 0}, "iridescenceThicknessTexture": {"index": 0}}
    asset = _sheet(tmp_path, "irid", irid=film, images=[(px, None)])
    m = load_asset(asset).materials[0]
    assert reference_renders(m) and reference_refusal(m) == "" and notice_lines(load_asset(asset)) == []
    assert TEXTURED_TRANSMISSION_CODE_VERSION == "2"
    assert transmission_cache_parts(_scene(asset)) == {"textured_transmission_code": "2",
                                                      "iridescent_transmission_code": IRIDESCENT_TRANSMISSION_CODE_VERSION}
    const = _sheet(tmp_path, "const", irid={"iridescenceFactor": 1.0})
    assert transmission_cache_parts(_scene(const)) == {"iridescent_transmission_code": IRIDESCENT_TRANSMISSION_CODE_VERSION}
    off = _sheet(tmp_path, "off", irid={"iridescenceFactor": 0.0})
    assert transmission_cache_parts(_scene(off)) == {}


@pytest.mark.slow
def test_iridescence_suzanne_glass_head_renders_transmissive(R, monkeypatch):
    """IridescenceSuzanne loads with nothing unmodelled (its glass head, "Material" with transmission,
    volume and an iridescence thickness texture, is rendered), and a low-spp path render under a real
    environment differs from the opaque fallback (the transmissive BSDFs left out) by more than
    :data:`ASSET_MIN_CHANGE` at the 99th percentile."""
    from pbrcheck.gltf import load_asset
    from pbrcheck.scene import asset_scene
    from pbrcheck.transmission_params import is_transmissive, reference_renders
    from pbrcheck.unmodelled import notice_lines
    from reference.render import render_uncached

    path = SHARED / "IridescenceSuzanne" / "IridescenceSuzanne.gltf"
    envs = sorted((SHARED.parents[1] / "envmaps").glob("*.hdr")) if (SHARED.parents[1] / "envmaps").is_dir() else []
    if not path.exists() or not envs:
        pytest.skip(f"{path} or ../shared/envmaps is absent (the real assets live in ../shared)")
    asset = load_asset(path)
    glass = [m for m in asset.materials if is_transmissive(m)]
    assert len(glass) == 1 and glass[0].iridescence.thickness_texture is not None and reference_renders(glass[0])
    assert notice_lines(asset) == []
    sc = asset_scene(path, env=str(envs[0]), size=(48, 48))
    a = _rgb(render_uncached(sc, spp=4, **PATH))
    monkeypatch.setattr(R, "gltf_shape_props", lambda *args, **kw: {})
    b = _rgb(render_uncached(sc, spp=4, **PATH))
    assert np.isfinite(a).all()
    change = float(np.percentile(np.abs(a - b).max(axis=-1), 99))
    assert change > ASSET_MIN_CHANGE, change


def test_an_analytic_iridescent_glass_sphere_takes_the_film_and_its_cache_part(R):
    """A scene file's transmissive sphere with ``iridescence > 0`` passes the film's keys to
    ``pbr_transmissive`` and keys its renders with the iridescent part; at 0 neither (the keys of before)."""
    from types import SimpleNamespace

    from reference.render import IRIDESCENT_TRANSMISSION_CODE_VERSION, transmission_cache_parts

    brdf = SimpleNamespace(roughness_floor=0.0)   # what material_dict reads of the [brdf] config

    def scene(w):
        return scene_from_dict({"camera": {"origin": [0, 0, 4], "fov": 20, "width": 4, "height": 4},
                                "environment": WHITE, "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0,
                                                                    "material": {"transmission": 1.0, "thickness": 1.0,
                                                                                 "iridescence": w, "iridescence_thickness": 300.0}}]})

    on, off = scene(1.0), scene(0.0)
    d = R.material_dict(on.objects[0], brdf)
    assert (d["iridescence"], d["iridescence_thickness"]) == (1.0, 300.0)
    assert "iridescence" not in R.material_dict(off.objects[0], brdf)
    assert transmission_cache_parts(on) == {"iridescent_transmission_code": IRIDESCENT_TRANSMISSION_CODE_VERSION}
    assert transmission_cache_parts(off) == {}
