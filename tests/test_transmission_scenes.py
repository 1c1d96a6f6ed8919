"""The built-in transmission scenes ``slabs`` and ``prism`` (issue 37 item 3; pbrcheck/scene_assets.py,
pbrcheck/scenes/slabs.toml, prism.toml): the committed glTF assets are what the builder writes; the scenes
are listed and load; their geometry is what the scene files say (the slabs' thicknessFactor is each box's
true height, the prism's camera and sun lie on its minimum-deviation ray); both render small in the
reference's path mode and the real-time raster pipeline. Known answers: an index-matched (IOR 1) slab
grid seen head-on in a constant background keeps ``background x exp(-sigma_t d)`` per channel (path truth
and the real-time thickness attenuation alike); the shipped IOR-1.5 slabs in a white environment equal
the slab closed form with the Fresnel of both faces; the prism's red, green and blue suns stand where
Snell's law at the KHR_materials_dispersion README's IORs puts them, and coincide at dispersion 0."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pbrcheck import scene_assets as SA
from pbrcheck.camera import primary_rays
from pbrcheck.scene import Camera, builtin_scene_names, load_scene, scene_from_dict

#: Standard deviations a rendered mean may sit from its known answer and the path mode's settings (as
#: tests/test_reference_transmission.py's Z and PATH; copies, so that another branch's edit of that file
#: leaves these tests as they are).
Z = 5.0
PATH = dict(mode="path", max_depth=8, progress=False, seed=1)
#: Cheap real-time options in the raster pipeline (tests/test_realtime_transmission.py's SMALL).
SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 256, "supersample": 1, "pipeline": "raster"}
#: The real-time IOR-1 slab's own split-sum specular (F0 0: the DFG LUT's B, small head-on), as that
#: file's SHEET_RTOL (measured here: under 1e-5 relative).
RT_RTOL = 2e-3


def _rgb(img):
    return np.stack([img.channels[c] for c in "RGB"], -1)


# ---- the assets and the scene files --------------------------------------------------------------

def test_committed_scene_assets_are_what_the_builder_writes(tmp_path):
    """pbrcheck/scenes/assets/*.gltf are byte for byte what pbrcheck.scene_assets writes now (no images:
    the text is deterministic); regenerate with ``python -m pbrcheck.scene_assets``."""
    written = SA.write_scene_assets(tmp_path)
    assert [p.name for p in written] == list(SA.SCENE_ASSETS)
    for p in written:
        assert (SA.ASSETS_DIR / p.name).read_bytes() == p.read_bytes(), p.name


def test_slabs_and_prism_are_built_in_and_listed():
    """Listed as built-in scenes (what ``pbrcheck scenes`` prints: name and one-line description)."""
    assert {"slabs", "prism", "glass"} <= set(builtin_scene_names())
    for name, ext in (("slabs", "KHR_materials_volume"), ("prism", "KHR_materials_dispersion")):
        s = load_scene(name)
        assert s.name == name and ext in s.description and "\n" not in s.description
        assert s.environment.type == "sky" and len(s.assets) == 1


def test_slab_grid_thickness_factor_is_each_box_true_height():
    """9 slabs (3 thicknesses x 3 attenuations) and the 64 ground tiles; each slab's glTF material has
    thicknessFactor = its box's height (the layout's thickness), its row's colour and distance."""
    s = load_scene("slabs")
    meshes = [o for o in s.objects if o.type == "mesh"]
    assert len(meshes) == 9 and sum(o.type == "plane" for o in s.objects) == 64
    asset = s.assets[0].asset
    layout = SA.slab_layout()
    assert len(asset.primitives) == len(layout) == 9
    for prim, (name, x, z, d, color, dist) in zip(asset.primitives, layout):
        lo, hi = prim.positions.min(axis=0), prim.positions.max(axis=0)
        m = asset.material(prim.material)
        assert prim.name.startswith(name + "/") and m.name == name
        assert m.volume.thickness == d and hi[1] - lo[1] == pytest.approx(d, abs=1e-7) and lo[1] == 0.0
        assert np.allclose([(lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2], [x, z], atol=1e-7)
        assert m.volume.attenuation_color == color and m.volume.attenuation_distance == dist
        assert m.transmission.factor == 1.0 and m.roughness == 0.0 and m.ior == SA.SLAB_IOR
    # the transmittances the grid spans (exp(-sigma_t d) = colour^(d / distance))
    t = [c ** (d / dist) for _, _, _, d, color, dist in layout for c in color]
    assert min(t) < 0.1 and max(t) > 0.9


def _refract(d, n, eta):
    """Snell's law in vector form: ``d`` unit, ``n`` the unit normal against ``d``, ``eta = n_i / n_t``."""
    c = -float(d @ n)
    k = 1.0 - eta * eta * (1.0 - c * c)
    assert k > 0.0, "total internal reflection"
    return eta * d + (eta * c - math.sqrt(k)) * n


def _through_prism(d, n, reverse=False):
    """The exit direction of a ray of direction ``d`` (x, y, z) through the prism of IOR ``n``: in by
    the front face, out by the back one (``reverse``: in by the back, out by the front)."""
    f = SA.prism_faces()
    front, back = (np.array([0.0, *f[k]]) for k in ("front", "back"))
    first, second = (back, front) if reverse else (front, back)
    inside = _refract(np.asarray(d, float), first, 1.0 / n)       # entering: the outward normal faces the ray
    return _refract(inside, -second, n)                             # leaving: the inward normal does


def test_prism_camera_and_sun_lie_on_its_minimum_deviation_ray():
    """The prism scene's camera looks at the placed prism's centroid along the minimum-deviation ray at
    n_d = 1.5, and its sun is where that ray leaves: Snell's law through the two faces."""
    s = load_scene("prism")
    cam, env = s.camera, s.environment
    assert s.assets[0].translation == (0.0, 0.6, 0.0) and cam.target == (0.0, 0.6, 0.0)
    view = np.subtract(cam.target, cam.origin)
    view /= np.linalg.norm(view)
    phi = math.radians(SA.min_deviation_elevation())
    assert np.allclose(view, [0.0, -math.sin(phi), -math.cos(phi)], atol=1e-6)
    out = _through_prism(view, SA.PRISM_IOR)
    assert np.allclose(out, env.sun_direction, atol=1e-6)
    assert math.degrees(2 * phi) == pytest.approx(37.1808, abs=1e-4)      # D_min of 1.5 at 60 degrees
    m = s.assets[0].asset.materials[0]
    assert m.dispersion.dispersion == SA.PRISM_DISPERSION and m.volume.thickness == pytest.approx(2 / 3)


# ---- known answers: the slabs -------------------------------------------------------------------

#: The head-on view of the slab grid: far above it, narrow (rays within 6 degrees of the vertical).
HEAD_ON = {"origin": [0.0, 20.0, 0.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 0.0, -1.0], "fov": 8.6,
           "width": 40, "height": 40}
#: A coloured constant background (so "background x transmittance" is checked per channel).
BACKGROUND = (0.6, 0.9, 1.2)
#: Sub-pixel rays per side for a pixel's expected value (as the ball test of test_reference_transmission).
SUB = 4


def _slab_scene(asset: Path, background=BACKGROUND):
    return scene_from_dict({"camera": HEAD_ON, "environment": {"type": "constant", "radiance": list(background)},
                            "objects": [{"type": "gltf", "path": str(asset)}]}, file="slabs-head-on.toml")


def _slab_pixels(scene):
    """Per slab: (mask of the pixels all of whose sub-pixel rays cross its top and bottom faces inside the
    footprint with a 0.05 margin, mean over each pixel's rays of 1 / |cos theta| (the path-length factor
    through the slab at IOR 1))."""
    cam = Camera(**{k: tuple(v) if isinstance(v, list) else v for k, v in HEAD_ON.items()})
    g = (np.arange(SUB) + 0.5) / SUB
    out = []
    for _, x, z, d, _, _ in SA.slab_layout():
        ok = np.ones((cam.height, cam.width), bool)
        stretch = np.zeros((cam.height, cam.width))
        for ox in g:
            for oy in g:
                o, dirs = primary_rays(cam, (ox, oy))
                for y in (0.0, d):
                    t = (y - o[1]) / dirs[..., 1]
                    px, pz = o[0] + t * dirs[..., 0], o[2] + t * dirs[..., 2]
                    ok &= (np.abs(px - x) < SA.SLAB_SIDE / 2 - 0.05) & (np.abs(pz - z) < SA.SLAB_SIDE / 2 - 0.05)
                stretch += 1.0 / np.abs(dirs[..., 1]) / SUB ** 2
        assert ok.sum() >= 9
        out.append((ok, stretch))
    return out


def _sigma(color, dist):
    return -np.log(np.asarray(color)) / dist


def test_index_matched_slabs_keep_the_background_times_beer_lambert(tmp_path):
    """The slab grid at IOR 1 (F0 0: no reflection, no refraction) seen head-on against a constant
    background: each slab's pixels are ``background exp(-sigma_t d / |cos theta|)`` per channel (the path
    travelled; head-on |cos theta| > 0.994), the per-slab mean within Z of its standard error (path mode,
    volpath's free-flight walk through the homogeneous interior); and the real-time raster pipeline,
    which attenuates by thicknessFactor (the true thickness), gives ``background exp(-sigma_t d)``."""
    from reference.render import render_uncached
    from realtime.render import render_realtime

    s = _slab_scene(SA.slabs_asset(tmp_path / "slabs_ior1.gltf", ior=1.0))
    img = render_uncached(s, spp=64, **PATH)
    rt = render_realtime(s, "default", SMALL, progress=False)
    bg = np.asarray(BACKGROUND)
    for (name, _, _, d, color, dist), (mask, stretch) in zip(SA.slab_layout(), _slab_pixels(s)):
        sigma = _sigma(color, dist)
        want = bg * np.exp(-sigma[None, :] * d * stretch[mask][:, None])      # per pixel, per channel
        for k, c in enumerate("RGB"):
            got = img.channels[c][mask]
            sd = math.sqrt(img.channels["variance." + c][mask].sum()) / mask.sum()
            assert abs(got.mean() - want[:, k].mean()) <= Z * sd + 1e-3, (name, c, got.mean(), want[:, k].mean(), sd)
        np.testing.assert_allclose(_rgb(rt)[mask], np.broadcast_to(bg * np.exp(-sigma * d), (int(mask.sum()), 3)),
                                   rtol=RT_RTOL, atol=1e-4, err_msg=name)


def test_glass_slabs_equal_the_slab_closed_form_with_both_faces_fresnel():
    """The shipped slabs (IOR 1.5, F0 0.04) head-on in a white environment: each slab's centre is the
    smooth slab with all its internal orders, ``R + (1 - R)^2 a / (1 - R^2 a^2) + (1 - R)^2 R a^2 /
    (1 - R^2 a^2)``, ``a = exp(-sigma_t d)``, ``R = 0.04`` (the front reflection, everything through,
    everything back out: the glass ball test's form; within 6 degrees of normal incidence the Fresnel
    stays 0.04 to 1e-5 and the path 1 / cos theta_t < 1.003 of d)."""
    from pbrcheck.transmission import slab_transmittance
    from reference.render import render_uncached

    s = _slab_scene(SA.ASSETS_DIR / "slabs.gltf", background=(1.0, 1.0, 1.0))
    img = render_uncached(s, spp=64, **PATH)
    Rf = ((SA.SLAB_IOR - 1) / (SA.SLAB_IOR + 1)) ** 2
    for (name, _, _, d, color, dist), (mask, _) in zip(SA.slab_layout(), _slab_pixels(s)):
        for k, c in enumerate("RGB"):
            sig = float(_sigma(color, dist)[k])
            a = math.exp(-sig * d)
            want = Rf + slab_transmittance(SA.SLAB_IOR, sig, d) + (1 - Rf) ** 2 * Rf * a * a / (1 - Rf * Rf * a * a)
            got = img.channels[c][mask]
            sd = math.sqrt(img.channels["variance." + c][mask].sum()) / mask.sum()
            assert abs(got.mean() - want) <= Z * sd + 2e-3, (name, c, got.mean(), want, sd)


# ---- known answers: the prism -------------------------------------------------------------------

#: KHR_materials_dispersion README: the Abbe number's Fraunhofer lines C, d, F (nm), where the reference
#: evaluates the red, green and blue channels' IORs (docs/reference.md, "Dispersion").
FRAUNHOFER_CDF_NM = (656.3, 587.6, 486.1)
#: The prism's view: from this far along the minimum-deviation ray, this narrow (degrees), this many pixels
#: (0.125 degrees a pixel: the 1-degree sun is 8 pixels across, the red and blue suns 2.2 degrees apart).
PRISM_VIEW = (4.0, 6.0, 48)
#: A 1-degree sun alone (sky, horizon and ground black), rasterized finely (0.18 degrees a texel, its
#: coverage anti-aliased: pbrcheck.environment).
SUN_ONLY = {"type": "sky", "sun_angular_diameter": 1.0, "sun_radiance": [1.0, 1.0, 1.0], "sky_radiance": [0, 0, 0],
            "horizon_radiance": [0, 0, 0], "ground_radiance": [0, 0, 0], "resolution": [2048, 1024]}
#: How far (degrees) a channel's sun centroid may sit from Snell's law's prediction: a third of a pixel
#: (measured at 64 spp, seeds 1 to 4: at most 0.016 degrees, the path tracer's noise; the red and green suns
#: are 0.65 degrees apart).
SUN_CENTROID_TOL_DEG = 0.04


def _readme_ior(n_d: float, dispersion: float, lam_nm: float) -> float:
    """KHR_materials_dispersion README: ``n(lambda) = max(n_d + (n_d - 1) / V_d (523655 / lambda^2 -
    1.5168), 1)``, ``V_d = 20 / dispersion`` (written out here, not the package's function)."""
    if dispersion == 0.0:
        return n_d
    v_d = 20.0 / dispersion
    return max(n_d + (n_d - 1.0) / v_d * (523655.0 / lam_nm ** 2 - 1.5168), 1.0)


def _prism_scene(asset: Path):
    dist, fov, px = PRISM_VIEW
    phi = math.radians(SA.min_deviation_elevation())
    sun = _through_prism(np.array([0.0, -math.sin(phi), -math.cos(phi)]), SA.PRISM_IOR)
    return scene_from_dict({"camera": {"origin": [0.0, dist * math.sin(phi), dist * math.cos(phi)],
                                       "target": [0.0, 0.0, 0.0], "fov": fov, "width": px, "height": px},
                            "environment": SUN_ONLY | {"sun_direction": [float(v) for v in sun]},
                            "objects": [{"type": "gltf", "path": str(asset)}]}, file="prism-sun.toml")


def _elevations(scene):
    """Per pixel, the camera ray's angle (degrees) above the view axis, in the prism's principal plane."""
    from pbrcheck.camera import camera_frame

    _, up, fwd = camera_frame(scene.camera)
    _, d = primary_rays(scene.camera)
    return np.degrees(np.arctan2(d @ up, d @ fwd)), (up, fwd)


def _sun_centroids(img, elev):
    return [float((img.channels[c] * elev).sum() / img.channels[c].sum()) for c in "RGB"]


def _predicted(scene, dispersion, frame):
    """Per channel, the camera ray's elevation (degrees) that leaves the prism towards the sun: the sun's
    direction reversed, in by the back face and out by the front at that channel's IOR (Snell's law)."""
    up, fwd = frame
    sun = np.asarray(scene.environment.sun_direction)
    out = []
    for lam in FRAUNHOFER_CDF_NM:
        u = -_through_prism(-sun, _readme_ior(SA.PRISM_IOR, dispersion, lam), reverse=True)
        out.append(math.degrees(math.atan2(u @ up, u @ fwd)))
    return out


def test_prism_splits_the_sun_by_snells_law_at_the_readme_iors(tmp_path):
    """The shipped prism (IOR 1.5, dispersion 1: V_d 20) seen along its minimum-deviation ray with a
    1-degree sun where that ray leaves: each channel's sun (the intensity-weighted mean elevation of the
    camera rays) stands where Snell's law through the two faces at that channel's IOR (the README's Cauchy
    form at the C, d, F lines) puts it, within SUN_CENTROID_TOL_DEG: red highest (least deviated), blue
    lowest, about 0.65 and 1.5 degrees from green. At dispersion 0 the three coincide with green's."""
    from reference.render import render_uncached

    s = _prism_scene(SA.ASSETS_DIR / "prism.gltf")
    flat = _prism_scene(SA.prism_asset(tmp_path / "prism_d0.gltf", dispersion=0.0))
    elev, frame = _elevations(s)
    want = _predicted(s, SA.PRISM_DISPERSION, frame)
    assert want[0] > want[1] + 0.5 and want[1] > want[2] + 1.2 and abs(want[1]) < 1e-3
    got = _sun_centroids(render_uncached(s, spp=64, **PATH), elev)
    got0 = _sun_centroids(render_uncached(flat, spp=64, **PATH), elev)
    assert got[0] > got[1] > got[2]
    np.testing.assert_allclose(got, want, atol=SUN_CENTROID_TOL_DEG)
    np.testing.assert_allclose(got0, _predicted(s, 0.0, frame), atol=SUN_CENTROID_TOL_DEG)
    assert max(got0) - min(got0) < SUN_CENTROID_TOL_DEG


# ---- smoke: each scene renders small in both renderers ------------------------------------------

@pytest.mark.parametrize("name", ["slabs", "prism"])
def test_scene_renders_small_in_the_reference_path_mode_and_the_raster_pipeline(name):
    """32 x 24: the reference's path mode (4 spp) and the real-time raster pipeline (cheap bakes) give
    finite, non-negative images in which the glTF asset's objects are seen; the raster pipeline renders
    their transmission (no ``transmission_unmodelled`` warning)."""
    from reference.render import render_uncached
    from realtime.render import render_realtime

    s = load_scene(name).with_camera(width=32, height=24)
    ids = {o.id for o in s.objects if o.type == "mesh"}
    ref = render_uncached(s, spp=4, **PATH)
    rt = render_realtime(s, "default", SMALL, progress=False)
    assert rt.meta["pipeline"] == "raster" and "transmission_unmodelled" not in rt.meta["warnings"]
    for img in (ref, rt):
        rgb = _rgb(img)
        assert np.isfinite(rgb).all() and rgb.min() >= 0.0 and rgb.max() > 0.1
        seen = np.isin(img.channels["object"], list(ids))
        assert seen.sum() >= 20, (name, int(seen.sum()))
