"""The truth of light through a glTF surface (issue 37 item 1), numpy: the thin-walled microfacet BTDF
of ``KHR_materials_transmission``, the rough dielectric interface of ``KHR_materials_volume`` with
Beer-Lambert attenuation, the diffuse BTDF of ``KHR_materials_diffuse_transmission``, and the
per-wavelength IOR of ``KHR_materials_dispersion``. :mod:`reference.transmission` holds the Dr.Jit
class of each, of the same name and method (``tests/test_transmission.py`` compares them on grids
with the extremes).

Conventions (pbrt-v4's ``BxDF``, Mitsuba's ``eval``): local frame ``n = +Z`` (+Z is the outside of a
volume, the front of a thin surface), ``v`` towards the viewer (the camera side of a path), ``l`` the
other direction, arrays (..., 3) of unit vectors, float64, either on either side of the surface.
``eval(v, l)`` is the BSDF times ``|n.l|``; ``sample(v, u, uc)`` gives ``(l, weight, pdf, delta)``,
``weight = eval / pdf`` (the delta lobes' weight their limit), ``uc`` in [0, 1) choosing the lobe;
``pdf(v, l)`` the density of the non-delta part. Transport is radiance (a path from the camera): the
transmitted weight carries ``(eta_v / eta_l)^2`` [pbrt-v4 9.5.2, "TransportMode::Radiance"].

Each lobe uses the specular lobe's GGX (``alpha = roughness^2``, [glTF-B] B.3.2) and its
height-correlated Smith G2 ([Heitz14] eq. 99) with ``|n.w|`` on either side, sampled by the visible
normals [Heitz18] of whichever side ``v`` is on. The Fresnel term is glTF's (Schlick with
``f0 = ((ior - 1) / (ior + 1))^2``, [glTF-B] B.3.4 and [IOR]) of the cosine on the optically thinner
side of the microfacet, 1 past the critical angle (total internal reflection).

API
---
Constants :data:`SMOOTH_ALPHA`, :data:`HALF_VECTOR_EPS`; :func:`f0_from_ior`, :func:`fresnel_dielectric` (Schlick with total
internal reflection), :func:`film_fresnel`, :func:`interface_fresnel`, :func:`thin_fresnel` (with
``KHR_materials_iridescence``'s thin film on the interface, [Irid]), :func:`refract`, :func:`beer_lambert`, :func:`slab_transmittance`;
:class:`MicrofacetGGX` (D, Lambda, G1, G2, the visible-normal sampler on both sides);
:class:`RoughDielectric` ([Volume] "Layering": the reflection and refraction of a dielectric
boundary, [Walter07]); :class:`ThinDielectric` ([Trans] "Transmission BTDF": the specular lobe and
the thin-walled ``specular_btdf`` = the same lobe mirrored through the surface);
:class:`DiffuseBTDF` ([DiffTrans]); :class:`TransmissiveMaterial` (the glTF material of
``reference.transmission``'s ``pbr_transmissive``: eval and pdf); :func:`dispersion_iors` (the IOR at wavelengths, [Disp]),
:data:`FRAUNHOFER_RGB_NM` and :func:`channel_iors` (the reference's per-channel IORs),
:data:`SPECTRAL_RANGE_NM` and :func:`spectral_rgb_weights` (per-wavelength RGB weights from the CIE
1931 colour matching functions: a flat spectrum gives (1, 1, 1)).

References
----------
[glTF-B]    glTF 2.0 Specification, Appendix B "BRDF Implementation" (fresnel_mix, specular_brdf).
[Trans]     KHR_materials_transmission README, "Refraction", "Transmission BTDF", "Implementation
            Notes" (``H_T = normalize(V - 2 (N.L) N + L)``; the BTDF ``V_T D_T``; thin-walled: "two
            surfaces back-to-back ... there is no average refraction").
[Volume]    KHR_materials_volume README, "Refraction", "Attenuation" (``sigma_t =
            -ln(attenuationColor) / attenuationDistance``), "Layering" and "Implementation"
            (Walter's microfacet BTDF).
[IOR]       KHR_materials_ior README.
[Disp]      KHR_materials_dispersion README (``n(lambda)``, :func:`pbrcheck.transmission_params.dispersion_ior`).
[Irid]      KHR_materials_iridescence README, "Dielectric Base Material" (``iridescent_dielectric_layer``:
            the film's Fresnel in place of ``fresnel_mix``'s; "For transmissive base materials, the
            diffuse_brdf(...) will be replaced by the mix between a diffuse_brdf(...) and a
            specular_btdf(...)"), "Iridescence Fresnel".
[DiffTrans] KHR_materials_diffuse_transmission README, "Implementation" (``diffuse_btdf = color / pi``
            on the opposite hemisphere).
[Walter07]  B. Walter, S. Marschner, H. Li, K. Torrance, "Microfacet Models for Refraction through
            Rough Surfaces", EGSR 2007 (eq. 16 generalized half vector, eq. 21 BTDF, eq. 38-41 sampling).
[pbrt-v4]   M. Pharr, W. Jakob, G. Humphreys, Physically Based Rendering 4th ed., 9.5 "Dielectric BSDF"
            and 9.7 "Rough Dielectric BSDF" (``DielectricBxDF``: the generalized half vector's
            orientation, the discarded back-facing microfacets, the PDF's Jacobian).
[Heitz14]   E. Heitz, "Understanding the Masking-Shadowing Function", JCGT 2014.
[Heitz18]   E. Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4) 2018.
"""

from __future__ import annotations

import numpy as np

from pbrcheck.lobes import CIE_CMFS, FILM_WAVELENGTHS, XYZ_TO_REC709, AnisotropicGGX, f0_from_ior, schlick
from pbrcheck.terms import COS_EPS, MIN_ALPHA
from pbrcheck.transmission_params import dispersion_ior

PI = np.pi

#: Below this alpha a lobe is its delta limit ([pbrt-v4] ``TrowbridgeReitzDistribution::EffectivelySmooth``,
#: alpha < 1e-3): roughness < 0.0316. A GGX narrower than that holds its mass in a cone of 1e-3 rad,
#: which no environment texel resolves, and its density (~1 / alpha^2) overflows float32's useful range.
SMOOTH_ALPHA = 1e-3
#: A generalized half vector within this of the horizon (``|h.z|``) is dropped: its orientation (which
#: side it faces, hence whether v and l see it) is float32 rounding there; such microfacets are a set
#: of measure zero of the pairs (v, l) (e.g. a refraction from inside at the critical angle's edge).
HALF_VECTOR_EPS = 1e-5
#: Wavelengths of the spectral estimates (nm): the CIE table's range.
SPECTRAL_RANGE_NM = (380.0, 780.0)
#: The wavelengths (nm) at which the reference's RGB channels refract a dispersive volume: Fraunhofer's
#: C (red), d (yellow, where ``ior`` is given) and F (blue) lines, the three of the Abbe number's
#: definition in [Disp] (``V_d = (n_d - 1) / (n_F - n_C)``).
FRAUNHOFER_RGB_NM = (656.3, 587.6, 486.1)

__all__ = ["SMOOTH_ALPHA", "HALF_VECTOR_EPS", "SPECTRAL_RANGE_NM", "f0_from_ior", "fresnel_dielectric", "refract", "beer_lambert",
           "slab_transmittance", "MicrofacetGGX", "RoughDielectric", "ThinDielectric", "DiffuseBTDF",
           "TransmissiveMaterial", "dispersion_iors", "FRAUNHOFER_RGB_NM", "channel_iors", "spectral_rgb_weights"]


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def _normalize(x):
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300)


def _reflect(v, h):
    return 2.0 * _dot(v, h)[..., None] * h - v


def _mirror(w):
    """``w`` through the surface plane (z -> -z): [Trans]'s ``L - 2 (N.L) N``."""
    return w * np.array([1.0, 1.0, -1.0])


def fresnel_dielectric(c, eta, f0):
    """Schlick's Fresnel of a dielectric microfacet ([glTF-B] B.3.4 with ``f0`` of [IOR]) seen from
    the side of cosine ``c = v.h`` (``h`` towards the outside: ``c > 0`` outside, ``c < 0`` inside)
    for the relative index ``eta = ior_inside / ior_outside``: Schlick of the cosine on the thinner
    side (outside for ``eta >= 1``), 1 past the critical angle. Reciprocal: the two directions of a
    refraction share the thinner side's cosine. ``eta = 0`` (``ior`` 0, [IOR]): 1 everywhere."""
    c = np.asarray(c, dtype=np.float64)
    e = np.where(c >= 0.0, eta, 1.0 / max(eta, 1e-300))       # ior of the far side / ior of v's side
    ci = np.abs(c)
    sin2_t = (1.0 - ci * ci) / np.maximum(e * e, 1e-300)
    ct = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    thin = np.where(e >= 1.0, ci, ct)
    F = schlick(thin, f0)
    return np.where((sin2_t >= 1.0) | (eta == 0.0), 1.0, F)


#: The film's RGB reflectance is clipped to [0, 1] per channel on a transmissive interface: a
#: saturated interference colour integrates to a negative Rec.709 channel (-0.02 at 400 nm, film IOR
#: 1.3 on glass, normal incidence), which would make that channel's reflection negative and its
#: transmission above 1; [Irid]'s own RGB evaluation clamps the same way (``max(I, 0)``), and the
#: transmitted ``1 - F`` of the clipped F keeps ``R + T = 1`` per channel.
FILM_CLIP = (0.0, 1.0)


def film_fresnel(c_out, F, strength, thickness, film_ior, f0):
    """[Irid] on a transmissive material's interface: ``mix(F, film(c_out), strength)`` per channel
    (..., 3), ``film`` the thin film's reflectance over a base of Fresnel F0 ``f0`` evaluated spectrally
    (:func:`pbrcheck.lobes.iridescence_spectral`, the opaque lobes' film) at the outside cosine
    ``c_out`` (``thickness`` nm, one value), ``F`` the plain (Schlick) Fresnel there. The interface
    transmits ``1 - film_fresnel`` per channel: the film and the base are non-absorbing dielectrics, so
    per wavelength what the stack does not reflect it transmits (``R + T = 1``), and the RGB
    integration is linear and white-balanced (a flat 1 integrates to 1), so ``T_rgb = 1 - R_rgb`` per
    channel exactly; the reflected and transmitted parts of a white furnace sum to 1 per channel."""
    from pbrcheck.lobes import iridescence_spectral

    R = iridescence_spectral(np.abs(np.asarray(c_out, dtype=np.float64)), float(thickness), float(film_ior),
                             np.broadcast_to(np.asarray(f0, dtype=np.float64), (3,)))
    R = np.clip(R, *FILM_CLIP)
    return np.asarray(F, dtype=np.float64)[..., None] * (1.0 - strength) + R * strength


def interface_fresnel(c, eta, f0, film=None):
    """(reflectance, the probability the interface's sampler reflects with) of a dielectric of relative
    index ``eta`` at ``c = v.h`` (as :func:`fresnel_dielectric`): without ``film`` that Fresnel twice;
    with ``film = (strength, thickness, film_ior)`` :func:`film_fresnel` at the thinner side's cosine
    (..., 3; 1 past the critical angle, from either side) and the channels' mean. The film sits on the
    interface and is seen at the outside cosine from either side (the cosine Schlick takes; a lossless
    stack reflects alike from both sides at corresponding angles, Stokes' relations)."""
    if film is None or eta == 0.0:
        F = fresnel_dielectric(c, eta, f0)
        return F, F
    c = np.asarray(c, dtype=np.float64)
    e = np.where(c >= 0.0, eta, 1.0 / eta)
    ci = np.abs(c)
    sin2_t = (1.0 - ci * ci) / (e * e)
    thin = np.where(e >= 1.0, ci, np.sqrt(np.maximum(1.0 - sin2_t, 0.0)))
    F = np.where((sin2_t >= 1.0)[..., None], 1.0, film_fresnel(thin, schlick(thin, f0), *film, f0))
    return F, F.mean(axis=-1)


def thin_fresnel(c, f0, film=None):
    """:func:`interface_fresnel` of a thin-walled interface (outside on both sides: Schlick at ``|c|``)."""
    F = schlick(c, f0)
    if film is None:
        return F, F
    F = film_fresnel(np.abs(np.asarray(c, dtype=np.float64)), F, *film, f0)
    return F, F.mean(axis=-1)


def refract(v, h, e):
    """The direction refracted from ``v`` through the microfacet ``h`` (oriented to ``v``'s side,
    ``v.h > 0``) with ``e = ior of the far side / ior of v's side``; zeros past the critical angle."""
    c = _dot(v, h)
    sin2_t = (1.0 - c * c) / (e * e)
    ct = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    l = -v / e[..., None] + (c / e - ct)[..., None] * h
    return np.where((sin2_t < 1.0)[..., None], l, 0.0)


def beer_lambert(sigma_t, distance):
    """[Volume]: the transmittance ``exp(-sigma_t d)`` (0 where sigma_t is inf)."""
    return np.exp(-np.asarray(sigma_t, dtype=np.float64) * np.asarray(distance, dtype=np.float64))


def slab_transmittance(ior, sigma_t, thickness):
    """The transmittance at normal incidence of a smooth slab of ``thickness`` and extinction
    ``sigma_t`` (its two faces parallel), all orders of its internal reflections: with ``R`` the
    interface's reflectance at normal incidence (``f0``, the same from either side) and ``a =
    exp(-sigma_t d)``, ``T = (1 - R)^2 a sum_k (R^2 a^2)^k = (1 - R)^2 a / (1 - R^2 a^2)``."""
    R = f0_from_ior(ior)
    a = beer_lambert(sigma_t, thickness)
    return (1.0 - R) ** 2 * a / (1.0 - R * R * a * a)


class MicrofacetGGX:
    """The isotropic GGX of the specular lobe ([glTF-B] B.3.2, ``alpha = max(roughness^2, MIN_ALPHA)``)
    for directions on either side: ``D`` of microfacets ``h`` with ``h.z > 0``, Smith's ``Lambda`` of
    ``|w.z|``, ``G2 = 1 / (1 + Lambda(v) + Lambda(l))`` [Heitz14] eq. 99, and the visible normals of
    ``v`` or ``-v``, whichever is above [Heitz18] listing 1 (pbrt-v4's ``Sample_wm`` flips the
    stretched direction alike)."""

    def __init__(self, roughness):
        r = float(roughness)
        self.alpha = max(r * r, MIN_ALPHA)
        self.smooth = self.alpha < SMOOTH_ALPHA
        self._vndf = AnisotropicGGX(r)

    def D(self, h):
        # cos^2 (a^2 - 1) + 1 in the stable form sin^2 + cos^2 a^2 (sin^2 = h.x^2 + h.y^2): float32 loses
        # a^2 to cancellation near the normal otherwise (reference.terms' forms)
        a2 = self.alpha * self.alpha
        c = h[..., 2]
        t = np.maximum(h[..., 0] ** 2 + h[..., 1] ** 2 + c * c * a2, 1e-150)   # h = 0: no microfacet
        return np.where(c > 0.0, a2 / (PI * t * t), 0.0)

    def Lambda(self, w):
        z2 = np.maximum(w[..., 2] ** 2, COS_EPS * COS_EPS)
        return 0.5 * (np.sqrt(1.0 + self.alpha * self.alpha * (1.0 - z2) / z2) - 1.0)

    def G1(self, w):
        return 1.0 / (1.0 + self.Lambda(w))

    def G2(self, v, l):
        return 1.0 / (1.0 + self.Lambda(v) + self.Lambda(l))

    def visible_D(self, v, h):
        """The density of :meth:`sample_h` in ``h``: ``G1(v) |v.h| D(h) / |n.v|`` where h faces v."""
        vh = _dot(v, h)
        ok = vh * v[..., 2] > 0.0
        return np.where(ok, self.G1(v) * np.abs(vh) * self.D(h) / np.maximum(np.abs(v[..., 2]), COS_EPS), 0.0)

    def sample_h(self, v, u):
        """A microfacet normal (``h.z >= 0``) visible from ``v`` or ``-v``, whichever is above: the
        specular lobe's own sampler (:meth:`pbrcheck.lobes.AnisotropicGGX.sample_h` at strength 0,
        [Heitz18] listing 1)."""
        v = np.broadcast_to(v, u.shape[:-1] + (3,))
        return self._vndf.sample_h(np.where((v[..., 2] < 0.0)[..., None], -v, v), u)


class RoughDielectric:
    """The boundary of a ``KHR_materials_volume`` (transmission 1, white, not metallic): ``F`` of the
    specular lobe plus ``(1 - F)`` of Walter's BTDF ([Volume] "Implementation", [Walter07] eq. 21)::

        f_r = F D G2 / (4 |n.v| |n.l|)                              (v, l on one side)
        f_t = |v.h| |l.h| eta_v^2 (1 - F) D G2 / (|n.v| |n.l| (eta_v v.h + eta_l l.h)^2)

    with ``h`` the (generalized) half vector ``-(eta_v v + eta_l l)`` towards +Z [Walter07] eq. 16, the
    microfacets facing away from either direction discarded [pbrt-v4], ``F`` of
    :func:`fresnel_dielectric` at ``v.h``. ``eta_v^2`` (not [Volume]'s ``ior_o^2``) is the radiance
    form: ``f_t(v, l) / eta_v^2`` is symmetric (reciprocity of a BTDF between media). Sampled by
    the visible normals of ``v``, reflection with probability ``F``; below :data:`SMOOTH_ALPHA` a
    delta reflection and refraction; at ``ior`` 1 the refraction passes straight (a delta)."""

    def __init__(self, roughness, ior):
        self.ggx = MicrofacetGGX(roughness)
        self.eta = float(ior)
        self.f0 = float(f0_from_ior(self.eta)) if self.eta > 0 else 1.0
        self.matched = self.eta == 1.0   # index-matched: the refraction is the straight line

    def _etas(self, v):
        outside = v[..., 2] > 0.0
        return np.where(outside, 1.0, self.eta), np.where(outside, self.eta, 1.0)

    def _terms(self, v, l):
        """(reflect?, h, F, the shared factors) of a pair."""
        refl = v[..., 2] * l[..., 2] > 0.0
        eta_v, eta_l = self._etas(v)
        ht = -(eta_v[..., None] * v + eta_l[..., None] * l)
        h = _normalize(np.where(refl[..., None], v + l, ht))
        h = np.where((h[..., 2] < 0.0)[..., None], -h, h)
        vh, lh = _dot(v, h), _dot(l, h)
        ok = (vh * v[..., 2] > 0.0) & (lh * l[..., 2] > 0.0) & (np.abs(v[..., 2]) > 0) & (np.abs(l[..., 2]) > 0)
        ok &= h[..., 2] > HALF_VECTOR_EPS
        ok &= np.where(refl, True, (vh * lh < 0.0) & ~np.bool_(self.matched))
        F = fresnel_dielectric(vh, self.eta, self.f0)
        return refl, h, vh, lh, eta_v, eta_l, F, ok

    def eval(self, v, l):
        if self.ggx.smooth:
            return np.zeros(np.broadcast_shapes(v.shape, l.shape)[:-1])
        refl, h, vh, lh, eta_v, eta_l, F, ok = self._terms(v, l)
        g = self.ggx
        cv, cl = np.maximum(np.abs(v[..., 2]), COS_EPS), np.maximum(np.abs(l[..., 2]), COS_EPS)
        DG = g.D(h) * g.G2(v, l)
        fr = F * DG / (4.0 * cv * cl)
        den = np.maximum((eta_v * vh + eta_l * lh) ** 2, 1e-300)
        ft = np.abs(vh * lh) * eta_v * eta_v * (1.0 - F) * DG / (cv * cl * den)
        return np.where(ok, np.where(refl, fr, ft) * np.abs(l[..., 2]), 0.0)

    def pdf(self, v, l):
        if self.ggx.smooth:
            return np.zeros(np.broadcast_shapes(v.shape, l.shape)[:-1])
        refl, h, vh, lh, eta_v, eta_l, F, ok = self._terms(v, l)
        Dv = self.ggx.visible_D(v, h)
        pr = Dv / np.maximum(4.0 * np.abs(vh), 1e-300) * F
        pt = Dv * eta_l * eta_l * np.abs(lh) / np.maximum((eta_v * vh + eta_l * lh) ** 2, 1e-300) * (1.0 - F)
        return np.where(ok, np.where(refl, pr, pt), 0.0)

    def sample(self, v, u, uc):
        v = np.broadcast_to(np.asarray(v, dtype=np.float64), np.shape(u)[:-1] + (3,))
        u, uc = np.asarray(u, dtype=np.float64), np.asarray(uc, dtype=np.float64)
        h = np.broadcast_to(np.array([0.0, 0.0, 1.0]), v.shape) if self.ggx.smooth else self.ggx.sample_h(v, u)
        vh = _dot(v, h)
        F = fresnel_dielectric(vh, self.eta, self.f0)
        hs = np.where((vh < 0.0)[..., None], -h, h)                  # the microfacet towards v
        eta_v, eta_l = self._etas(v)
        lt = refract(v, hs, eta_l / eta_v)
        lr = _reflect(v, hs)
        refl = uc < F
        l = np.where(refl[..., None], lr, lt)
        side = np.where(refl, l[..., 2] * v[..., 2] > 0.0, l[..., 2] * v[..., 2] < 0.0)
        g = self.ggx
        wr = np.ones_like(F) if g.smooth else g.G2(v, l) / g.G1(v)
        ratio = (eta_v / eta_l) ** 2
        delta_t = g.smooth or self.matched
        wt = ratio * (1.0 if delta_t else wr)
        if self.matched:                                             # straight through (h plays no part)
            lt, wt = -v, np.ones_like(F)
            l = np.where(refl[..., None], lr, lt)
            side = np.where(refl, side, True)
        weight = np.where(side, np.where(refl, wr, wt), 0.0)
        delta = np.where(refl, g.smooth, delta_t)
        pdf = np.where(delta | ~side, 0.0, self.pdf(v, l))    # an invalid sample: no density
        weight = np.where((delta & side) | (pdf > 0.0), weight, 0.0)   # (a microfacet at the horizon: none)
        return l, weight, pdf, delta & side


class ThinDielectric:
    """A thin-walled ``KHR_materials_transmission`` surface (transmission 1, white, not metallic),
    [Trans] "Transmission BTDF": ``fresnel_mix(layer = specular_brdf, base = specular_btdf)`` where
    ``specular_btdf(v, l) = V_T D_T`` is the specular lobe of ``v`` and ``l`` mirrored through the
    surface (``H_T = normalize(V - 2 (N.L) N + L)``) -- the spec's two uncorrelated back-to-back
    interfaces without average refraction. ``F`` is Schlick at ``v.H`` (both interfaces face the
    same outside medium: no total internal reflection); ``ior`` enters through ``f0`` only. Two-sided:
    ``v`` may be below. Sampled as the specular lobe, mirrored with probability ``1 - F``."""

    def __init__(self, roughness, ior):
        self.ggx = MicrofacetGGX(roughness)
        self.f0 = float(f0_from_ior(ior)) if float(ior) > 0 else 1.0

    def _lobe(self, v, lr):
        f, p, vh = self.lobe(v, lr)
        return f, p, schlick(vh, self.f0)

    def lobe(self, v, lr):
        """(specular lobe ``D G2 / (4 |n.v||n.l|)`` times ``|n.l|``, its visible-normal pdf, ``v.h``) at
        the pair ``v``, ``lr`` (``lr`` on ``v``'s side)."""
        g = self.ggx
        h = _normalize(v + lr)
        h = np.where((h[..., 2] < 0.0)[..., None], -h, h)
        vh = _dot(v, h)
        ok = (v[..., 2] * lr[..., 2] > 0.0) & (vh * v[..., 2] > 0.0) & (_dot(lr, h) * lr[..., 2] > 0.0)
        cv = np.maximum(np.abs(v[..., 2]), COS_EPS)
        f = g.D(h) * g.G2(v, lr) / (4.0 * cv)
        p = g.visible_D(v, h) / np.maximum(4.0 * np.abs(vh), 1e-300)
        return np.where(ok, f, 0.0), np.where(ok, p, 0.0), vh

    def _split(self, v, l):
        same = v[..., 2] * l[..., 2] > 0.0
        f, p, F = self._lobe(v, np.where(same[..., None], l, _mirror(l)))
        w = np.where(same, F, 1.0 - F)
        return f * w, p * w

    def eval(self, v, l):
        if self.ggx.smooth:
            return np.zeros(np.broadcast_shapes(v.shape, l.shape)[:-1])
        return self._split(v, l)[0]

    def pdf(self, v, l):
        if self.ggx.smooth:
            return np.zeros(np.broadcast_shapes(v.shape, l.shape)[:-1])
        return self._split(v, l)[1]

    def sample(self, v, u, uc):
        v = np.broadcast_to(np.asarray(v, dtype=np.float64), np.shape(u)[:-1] + (3,))
        g = self.ggx
        h = np.broadcast_to(np.array([0.0, 0.0, 1.0]), v.shape) if g.smooth else g.sample_h(v, np.asarray(u, dtype=np.float64))
        vh = _dot(v, h)
        lr = _reflect(v, h)
        F = schlick(vh, self.f0)
        refl = np.asarray(uc) < F
        l = np.where(refl[..., None], lr, _mirror(lr))
        ok = lr[..., 2] * v[..., 2] > 0.0
        weight = np.where(ok, np.ones_like(F) if g.smooth else g.G2(v, lr) / g.G1(v), 0.0)
        delta = np.full(F.shape, g.smooth) & ok
        pdf = np.where(delta | ~ok, 0.0, self.pdf(v, l))
        return l, weight, pdf, delta


class DiffuseBTDF:
    """[DiffTrans]'s ``diffuse_btdf``: ``1 / pi`` where ``v`` and ``l`` lie on opposite sides (the
    colour is the material's ``diffuseTransmissionColor``, applied by the caller); cosine-sampled on
    the far side. ``f(v, l) = f(l, v)``."""

    def eval(self, v, l):
        return np.where(v[..., 2] * l[..., 2] < 0.0, np.abs(l[..., 2]) / PI, 0.0)

    pdf = eval

    def sample(self, v, u, uc=None):
        u = np.asarray(u, dtype=np.float64)
        r = np.sqrt(u[..., 0])
        phi = 2.0 * PI * u[..., 1]
        z = np.sqrt(np.maximum(1.0 - u[..., 0], 0.0))
        side = np.where(np.asarray(v)[..., 2] > 0.0, -1.0, 1.0)
        l = np.stack([r * np.cos(phi), r * np.sin(phi), side * z], axis=-1)
        return l, np.ones(z.shape), self.pdf(np.broadcast_to(v, l.shape), l), np.zeros(z.shape, bool)


class TransmissiveMaterial:
    """The glTF transmissive material of the reference's ``pbr_transmissive`` (``reference.transmission``,
    whose docstring states the model; this is its numpy twin for ``eval`` and ``pdf``):
    ``mix(dielectric, metal, metallic)``, the dielectric ``F specular_brdf + (1 - F) mix(mix(
    diffuse_brdf(base_color), diffuse_btdf(dt_color), diffuse_transmission), specular_btdf base_color,
    transmission)`` ([Trans], [DiffTrans] "Combining ..."); the interface :class:`RoughDielectric` where
    ``volume`` (one per RGB channel at :func:`channel_iors` where ``dispersion`` > 0), else
    :class:`ThinDielectric`. ``eval(v, l)`` (..., 3) is the BSDF times ``|n.l|`` of the non-delta
    lobes; ``pdf`` the sampling mixture's density (lobes chosen with their albedos at ``n.v``)."""

    def __init__(self, base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=0.5, ior=1.5, transmission=0.0,
                 diffuse_transmission=0.0, diffuse_transmission_color=(1.0, 1.0, 1.0), volume=False, dispersion=0.0):
        self.base_color = np.asarray(base_color, dtype=np.float64)
        self.metallic, self.transmission, self.dt = float(metallic), float(transmission), float(diffuse_transmission)
        self.dt_color = np.asarray(diffuse_transmission_color, dtype=np.float64)
        self.f0 = float(f0_from_ior(ior)) if float(ior) > 0 else 1.0
        iors = channel_iors(ior, dispersion) if volume and dispersion > 0.0 and ior > 1.0 else (float(ior),)
        self.ifaces = [RoughDielectric(roughness, n) for n in iors] if volume else [ThinDielectric(roughness, ior)]
        self.spec = ThinDielectric(roughness, ior)

    def _probs(self, v):
        m, t, bc = self.metallic, self.transmission, np.mean(self.base_color)
        Fv = schlick(np.abs(v[..., 2]), self.f0)
        w = [m * np.mean(schlick(np.abs(v[..., 2])[..., None], self.base_color), axis=-1),
             (1.0 - m) * (Fv + (1.0 - Fv) * t * bc),
             (1.0 - m) * (1.0 - Fv) * (1.0 - t) * (1.0 - self.dt) * bc,
             (1.0 - m) * (1.0 - Fv) * (1.0 - t) * self.dt * np.mean(self.dt_color)]
        total = w[0] + w[1] + w[2] + w[3]
        ok = total > 0.0
        return [np.where(ok, x / np.maximum(total, 1e-300), 1.0 if k == 1 else 0.0) for k, x in enumerate(w)]

    def _eval_pdf(self, v, l):
        m, t = self.metallic, self.transmission
        same = v[..., 2] * l[..., 2] > 0.0
        f_spec, p_spec, vh = self.spec.lobe(v, np.where(same[..., None], l, _mirror(l)))
        smooth = self.spec.ggx.smooth
        metal = np.where(same[..., None], schlick(vh[..., None], self.base_color) * f_spec[..., None], 0.0) * (not smooth)
        if len(self.ifaces) == 1:
            iface = self.ifaces[0].eval(v, l)[..., None]
            iface_pdf = self.ifaces[0].pdf(v, l)
        else:
            iface = np.stack([f.eval(v, l) for f in self.ifaces], axis=-1)
            iface_pdf = sum(f.pdf(v, l) for f in self.ifaces) / 3.0
        tint = np.where(same[..., None], 1.0, t * self.base_color)
        Fd = schlick(vh, self.f0)[..., None]
        cos_l = np.abs(l[..., 2]) / PI
        diff = np.where(same[..., None], (1.0 - self.dt) * self.base_color * cos_l[..., None],
                        self.dt * self.dt_color * cos_l[..., None])
        value = m * metal + (1.0 - m) * (iface * tint + (1.0 - Fd) * (1.0 - t) * diff)
        pm, pi, pd, pdt = self._probs(v)
        pdf = (pm * np.where(same, p_spec, 0.0) * (not smooth) + pi * iface_pdf + pd * np.where(same, cos_l, 0.0)
               + pdt * np.where(same, 0.0, cos_l))
        return value, pdf

    def eval(self, v, l):
        return self._eval_pdf(v, l)[0]

    def pdf(self, v, l):
        return self._eval_pdf(v, l)[1]


def dispersion_iors(ior: float, dispersion: float, wavelengths_nm):
    """[Disp]: the IOR at each wavelength (nm), clamped at 1 (``ior`` where ``dispersion`` is 0)."""
    lam = np.asarray(wavelengths_nm, dtype=np.float64)
    return np.maximum(dispersion_ior(float(ior), float(dispersion), lam), 1.0)


def channel_iors(ior: float, dispersion: float) -> tuple[float, float, float]:
    """The (R, G, B) IORs of a dispersive volume: :func:`dispersion_iors` at :data:`FRAUNHOFER_RGB_NM`
    (``n_F - n_C = (n_d - 1) / V_d`` exactly; G is ``ior`` to the Cauchy fit's 2e-4)."""
    return tuple(float(n) for n in dispersion_iors(ior, dispersion, FRAUNHOFER_RGB_NM))  # type: ignore[return-value]


def spectral_rgb_weights(wavelengths_nm):
    """Per-wavelength linear Rec. 709 weights ``w_c(lambda)`` (the CIE 1931 colour matching functions
    through ``XYZ_TO_REC709``, linearly interpolated, 0 outside :data:`SPECTRAL_RANGE_NM`), each
    channel normalised to integrate to 1 over the range: with ``lambda`` uniform on the range (pdf
    ``1 / 400``), ``E[w_c(lambda) / pdf L_c] = L_c`` for a light independent of the wavelength, so a
    spectral estimate of an RGB scene without dispersion is the RGB one; with dispersion the path at
    ``lambda`` refracts with ``n(lambda)``."""
    def rgb(lam):
        xyz = np.stack([np.interp(lam, FILM_WAVELENGTHS, CIE_CMFS[:, k], left=0.0, right=0.0) for k in range(3)], axis=-1)
        return xyz @ XYZ_TO_REC709.T

    grid = np.linspace(*SPECTRAL_RANGE_NM, 4001)
    return rgb(np.asarray(wavelengths_nm, dtype=np.float64)) / np.trapezoid(rgb(grid), grid, axis=0)
