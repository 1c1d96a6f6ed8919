"""The scene's material model as a Mitsuba 3 BSDF (``pbr_material``), written in Python over Dr.Jit.

Same model and the same term names as the numpy ground truth :mod:`pbrcheck.brdf` (the equations
cited there)::

    F0 = mix(specular, base_color, metallic),   alpha = max(roughness^2, MIN_ALPHA)
    f(l, v) = (1 - F(v.h)) (1 - metallic) base_color / pi  +  D(h) G(l, v) F(v.h) / (4 (n.l)(n.v))

(``metallic_blend = "gltf"``: the diffuse under ``1 - F`` of ``F0 = specular``, glTF 2.0 Appendix B)
with the terms of :mod:`reference.terms` (one Dr.Jit class per NDF, G and Fresnel term, chosen by the
scene's ``[brdf]`` names through that module's registries): ``D`` GGX [Walter07 eq. 33], Beckmann
[Walter07 eq. 25], BlinnPhong [Walter07 eq. 30, n = 2/alpha^2 - 2]; ``G`` SmithGGXCorrelated [Heitz14
eq. 99], SmithBeckmannCorrelated [Heitz14 eq. 99 with eq. 80], SmithGGX [Heitz14 eq. 98 with eq.
43/72], SchlickGGX with k = alpha/2 (ibl) or (roughness+1)^2/8 (direct) [Karis13 eq. 4]; ``F`` Schlick
[Schlick94 eq. 15] or ``none`` (F = 1, so the diffuse (1 - F) term vanishes). All computations are in
the local shading frame (n = +Z), the NDFs in their numerically stable forms (reference.terms).

Sampling: the specular lobe is chosen with probability ``P_spec = S / (S + Dif)`` where
``S = mean_rgb F(n.v)`` (1 without Fresnel) and ``Dif = mean_rgb (1 - F(n.v)) (1 - metallic)
base_color`` (0 without Fresnel), the lobes' albedos estimated at h = n; the diffuse lobe is sampled
with the cosine, ggx by visible normals [Heitz18] (pdf ``G1(v) max(0, v.h) D(h) / (n.v) / (4 v.h)``,
with the Smith GGX G1 of the sampler whatever the ``geometry`` term is), beckmann and blinn_phong by
``D(h) cos(theta_h)`` (pdf ``D(h) (n.h) / (4 v.h)``) [Walter07 eq. 28 and sec. 5.2]. ``pdf`` and
``eval_pdf`` return the exact mixture ``P_spec pdf_spec + (1 - P_spec) cos / pi``, and ``sample``
returns ``f cos / pdf`` of that mixture.

Roughness 0: when ``alpha < pbrcheck.brdf.DELTA_LOBE_ALPHA`` (roughness < 0.01, e.g. 0 or 1e-4) the
specular lobe is replaced by its mirror limit, a Dirac delta component (``DeltaReflection``): it is
sampled as the mirror direction with discrete probability ``P_spec`` and weight
``F(n.v) G(v, v) / P_spec`` (the limit of ``int D G F / (4 n.l n.v) cos dl`` as alpha -> 0, with
v.h = n.v); ``eval``/``pdf`` then return the diffuse lobe only (a delta cannot be evaluated). The
choice is made from the roughness in the scene (and re-made in ``parameters_changed``).

Multiple scattering: ``multiscatter = "random_walk"`` (props ``multiscatter``, ``multiscatter_seed``)
routes the non-delta specular lobe through :mod:`reference.multiscatter` (two hooks: ``_eval_pdf``
adds the walk's orders >= 2 and its approximate pdf, ``sample`` samples the walk).

The glTF extensions' lobes (clearcoat, sheen, specular, anisotropy, iridescence; props named as the
scene file's fields, :data:`reference.lobe_bsdf.LOBE_DEFAULTS`): where a material has any, ``lobes``
holds them and ``_eval_pdf`` / ``sample`` hand over to :mod:`reference.lobe_bsdf` (two hooks; the
material is then never a delta); where it has none, ``lobes`` is None and nothing of them is traced.

Differentiable parameters ``base_color``, ``metallic``, ``roughness`` (and ``specular``,
:data:`MATERIAL_PARAMS`) are exposed by ``traverse`` (:func:`traverse_material`, shared with
``pbr_textured``); ``parameters_changed`` makes them opaque (:func:`make_material_opaque`) so a new
value does not rebuild the kernel.

Calling a scene's BSDFs per lane: :class:`MaterialView` (every ``pbr_material`` gathered, the lobes
traced once) and :class:`SceneCalls` (any BSDFs or area emitters, ``dr.switch`` over the scene's own
instead of Mitsuba's process-wide pointer call).
"""

from __future__ import annotations

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)
from pbrcheck.brdf import COS_EPS, DELTA_LOBE_ALPHA, METALLIC_BLENDS, MIN_ALPHA
from pbrcheck.scene import FRESNEL_NAMES, GEOMETRIC_ROUGHNESS_NAMES, GEOMETRY_NAMES, MULTISCATTER_NAMES, NDF_NAMES

from . import lobe_bsdf
from .material_tables import material_table, shape_lookup, table_indices
from . import multiscatter
from . import terms
from .terms import INV_PI, fresnel_term, geometry_term

import drjit as dr
import mitsuba as mi

PLUGIN_NAME = "pbr_material"


def _divide(a, b):
    """a / b; a seam so that a test can emulate CUDA's inexact division on the CPU."""
    return a / b


def _mean(c):
    return (c.x + c.y + c.z) * (1.0 / 3.0)


class PBRLobes:
    """The material model's lobes over parameters that are either one BSDF instance's (scalars:
    :class:`PBRMaterial`) or per-lane arrays gathered by the shape each lane hit
    (:class:`MaterialView`). Attributes read: ``base_color`` (Color3f), ``metallic``, ``roughness``,
    ``specular`` (Float), ``ndf``, ``geometry``, ``fresnel``, ``multiscatter``, ``ms_seed`` (the
    scene-wide model), ``lobes`` (None, or the :class:`reference.lobe_bsdf.LobeParams` of the glTF
    extensions' lobes: then :mod:`reference.lobe_bsdf` evaluates and samples) and ``delta``: the mirror limit, a Python bool for an instance (decided from its
    roughness, so the other lobe is not even traced) or a per-lane mask (both traced, selected)."""

    # ---- shared pieces ---------------------------------------------------------------------
    def _nondelta(self):
        """Where the specular lobe is glossy: ``True`` / ``False`` for one instance, else a mask."""
        return (not self.delta) if isinstance(self.delta, bool) else ~self.delta

    def _alpha(self):
        return dr.maximum(self.roughness * self.roughness, MIN_ALPHA)

    def _glossy_alpha(self, nd):
        """alpha for the glossy lobe's terms: where a lane is a mirror (its glossy terms are computed
        and discarded by a select) alpha 1 keeps them finite, so no inf * 0 reaches a gradient."""
        a = self._alpha()
        return a if isinstance(nd, bool) else dr.select(nd, a, 1.0)

    def _f0(self):
        return self.specular * (1.0 - self.metallic) + self.base_color * self.metallic

    def _diffuse_f0(self, F0):
        """The F0 whose Fresnel weights the diffuse lobe: the mixed ``F0`` (``metallic_blend = "f0"``)
        or the dielectric's own ``specular`` (``"gltf"``: glTF 2.0 Appendix B; pbrcheck.brdf.brdf_eval)."""
        return F0 if self.metallic_blend == "f0" else mi.Color3f(self.specular)

    def _p_spec(self, NoV, F0):
        """Probability of choosing the specular lobe: its albedo estimate over the total."""
        if self.fresnel == "none":
            return dr.full(mi.Float, 1.0, dr.width(NoV))
        F = fresnel_term(self.fresnel, NoV, F0)
        s = _mean(F)
        Fd = F if self.metallic_blend == "f0" else fresnel_term(self.fresnel, NoV, self._diffuse_f0(F0))
        d = _mean((1.0 - Fd) * self.base_color) * (1.0 - self.metallic)
        # Exact at the ends, whatever the division's rounding: on CUDA s / s is an approximate
        # reciprocal times s (1 - 1e-7), which gave a delta-only metal a diffuse pdf of ~1e-8.
        ratio = _divide(s, dr.maximum(s + d, 1e-20))
        return dr.select(d <= 0, 1.0, dr.select(s <= 0, 0.0, dr.clip(ratio, 0.0, 1.0)))

    def _spec_pdf(self, wi, wo, h, alpha):
        """Density in wo of the specular sampler (valid for reflections with v.h > 0)."""
        jac = 1.0 / dr.maximum(4.0 * dr.abs(dr.dot(wo, h)), 1e-20)
        return terms.ndf(self.ndf).pdf(wi, h, alpha) * jac

    def _sample_h(self, wi, u, alpha):
        return terms.ndf(self.ndf).sample(wi, u, alpha)

    def _eval_pdf(self, si, wo, active):
        """(f cos, pdf) of the non-delta part, local frame."""
        if self.lobes is not None:  # hook: the glTF extensions' lobes (reference.lobe_bsdf)
            return lobe_bsdf.eval_pdf(self, si, wo, active)
        wi = si.wi
        NoV = mi.Frame3f.cos_theta(wi)
        NoL = mi.Frame3f.cos_theta(wo)
        valid = active & (NoV > 0) & (NoL > 0)
        F0 = self._f0()
        h = dr.normalize(wi + wo)
        VoH = dr.clip(dr.dot(wi, h), 0.0, 1.0)
        F = fresnel_term(self.fresnel, VoH, F0)
        p_spec = self._p_spec(dr.clip(NoV, 0, 1), F0)
        value = mi.Color3f(0.0)
        pdf = mi.Float(0.0)
        if self.fresnel != "none":
            Fd = F if self.metallic_blend == "f0" else fresnel_term(self.fresnel, VoH, self._diffuse_f0(F0))
            value += (1.0 - Fd) * (1.0 - self.metallic) * self.base_color * (INV_PI * NoL)
            pdf += (1.0 - p_spec) * INV_PI * NoL
        nd = self._nondelta()
        if nd is not False:
            alpha = self._glossy_alpha(nd)
            D = terms.ndf(self.ndf).eval(h, alpha)
            G = geometry_term(self.geometry, NoV, NoL, self.roughness, alpha)
            spec = F * (D * G / (4.0 * dr.maximum(NoV, COS_EPS)))  # D G F / (4 NoL NoV) * NoL
            spec_pdf = self._spec_pdf(wi, wo, h, alpha)
            if self.multiscatter != "none":  # hook: the walk's orders >= 2, approximate pdf
                ms, spec_pdf = multiscatter.eval_pdf_hook(self, si, wo, spec_pdf, alpha, F0, valid)
                spec += ms
            if nd is not True:  # per lane: mirror lanes have no glossy lobe
                spec = dr.select(nd, spec, 0.0)
                spec_pdf = dr.select(nd, spec_pdf, 0.0)
            value += spec
            pdf += p_spec * spec_pdf
        return dr.select(valid, value, 0.0), dr.select(valid, pdf, 0.0)

    # ---- the BSDF interface -------------------------------------------------------------------
    def eval(self, ctx, si, wo, active=True):
        return self._eval_pdf(si, wo, active)[0]

    def pdf(self, ctx, si, wo, active=True):
        return self._eval_pdf(si, wo, active)[1]

    def eval_pdf(self, ctx, si, wo, active=True):
        return self._eval_pdf(si, wo, active)

    def sample(self, ctx, si, sample1, sample2, active=True):
        if self.lobes is not None:  # hook: the glTF extensions' lobes (reference.lobe_bsdf)
            return lobe_bsdf.sample(self, ctx, si, sample1, sample2, active)
        nd = self._nondelta()
        if self.multiscatter != "none" and nd is not False:  # hook: the random walk's sampling
            walk = multiscatter.sample_hook(self, ctx, si, sample1, sample2, active)
            if nd is True:
                return walk
            # mirror lanes: the mirror-limit sampler alone (its glossy branch would trace a walk
            # evaluation at a direction that depends on the parameters: a loop AD cannot reverse)
            single = self._sample_single(ctx, si, sample1, sample2, mi.Bool(active) & ~nd, nd=False)
            return dr.select(nd, walk[0], single[0]), dr.select(nd, walk[1], single[1])
        return self._sample_single(ctx, si, sample1, sample2, active)

    def _sample_single(self, ctx, si, sample1, sample2, active=True, nd=None):
        """Single-scattering sampling of the mixture (module docstring); ``nd``: the lanes' glossy
        mask (default :meth:`_nondelta`; ``False`` samples every lane as a mirror limit)."""
        wi = si.wi
        NoV = mi.Frame3f.cos_theta(wi)
        active = mi.Bool(active) & (NoV > 0)
        F0 = self._f0()
        p_spec = self._p_spec(dr.clip(NoV, 0, 1), F0)
        choose_spec = sample1 < p_spec
        nd = self._nondelta() if nd is None else nd

        bs = dr.zeros(mi.BSDFSample3f)
        bs.eta = 1.0
        wo_diff = mi.warp.square_to_cosine_hemisphere(sample2)
        mirror = mi.Vector3f(-wi.x, -wi.y, wi.z)
        if nd is False:
            wo_spec = mirror
        else:
            h = self._sample_h(wi, sample2, self._glossy_alpha(nd))
            wo_spec = 2.0 * dr.dot(wi, h) * h - wi
            if nd is not True:
                wo_spec = dr.select(nd, wo_spec, mirror)
        bs.wo = dr.select(choose_spec, wo_spec, wo_diff)
        NoL = mi.Frame3f.cos_theta(bs.wo)
        active &= NoL > 0

        glossy, mirror_t = mi.UInt32(+mi.BSDFFlags.GlossyReflection), mi.UInt32(+mi.BSDFFlags.DeltaReflection)
        spec_type = glossy if nd is True else (mirror_t if nd is False else dr.select(nd, glossy, mirror_t))
        bs.sampled_type = dr.select(choose_spec, spec_type, mi.UInt32(+mi.BSDFFlags.DiffuseReflection))
        bs.sampled_component = dr.select(choose_spec, mi.UInt32(0), mi.UInt32(1))

        value, pdf = self._eval_pdf(si, bs.wo, active)
        bs.pdf = pdf
        weight = value / dr.maximum(pdf, 1e-20)
        if nd is not True:
            # Mirror limit: weight F(n.v) G(v, v) / P_spec, pdf = the discrete probability.
            F = fresnel_term(self.fresnel, dr.clip(NoV, 0, 1), F0)
            G = geometry_term(self.geometry, NoV, NoV, self.roughness, self._alpha())
            w_spec = F * G / dr.maximum(p_spec, 1e-20)
            d_pdf = dr.select(choose_spec, p_spec, pdf)
            d_weight = dr.select(choose_spec, w_spec, weight)
            if nd is False:
                bs.pdf, weight = d_pdf, d_weight
            else:
                bs.pdf = dr.select(nd, bs.pdf, d_pdf)
                weight = dr.select(nd, weight, d_weight)
        active &= bs.pdf > 0
        return bs, dr.select(active, weight, 0.0)


#: The differentiable parameters of a material BSDF (``pbr_material``, and ``pbr_textured`` of
#: :mod:`reference.textured`): the factors, whatever textures multiply them.
MATERIAL_PARAMS = ("base_color", "metallic", "roughness", "specular")


def traverse_material(bsdf, callback) -> None:
    """``traverse`` of a material BSDF: each of :data:`MATERIAL_PARAMS` as a differentiable parameter."""
    for name in MATERIAL_PARAMS:
        callback.put(name, getattr(bsdf, name), mi.ParamFlags.Differentiable)


def make_material_opaque(bsdf) -> None:
    """``parameters_changed``'s part common to the material BSDFs: :data:`MATERIAL_PARAMS` made
    opaque (``dr.make_opaque``), so a new value does not rebuild the kernel."""
    dr.make_opaque(*[getattr(bsdf, name) for name in MATERIAL_PARAMS])


class PBRMaterial(mi.BSDF):
    """``{"type": "pbr_material", "base_color": [r,g,b], "metallic", "roughness", "specular",
    "ndf", "geometry", "fresnel"}``."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)

        def get(name, default):
            return props.get(name, default) if hasattr(props, "get") else (props[name] if name in props else default)

        bc = get("base_color", [1.0, 1.0, 1.0])
        if isinstance(bc, (int, float)):
            bc = [bc] * 3
        self.base_color = mi.Color3f(*[float(x) for x in bc])
        self.metallic = mi.Float(float(get("metallic", 0.0)))
        self.roughness = mi.Float(float(get("roughness", 0.5)))
        self.specular = mi.Float(float(get("specular", 0.04)))
        self.ndf = str(get("ndf", "ggx"))
        self.geometry = str(get("geometry", "smith_ggx_correlated"))
        self.fresnel = str(get("fresnel", "schlick"))
        if self.ndf not in NDF_NAMES or self.geometry not in GEOMETRY_NAMES or self.fresnel not in FRESNEL_NAMES:
            raise ValueError(f"pbr_material: bad model {(self.ndf, self.geometry, self.fresnel)}")
        # Multiple scattering (reference.multiscatter): "none" or "random_walk", and its hash seed.
        self.multiscatter = str(get("multiscatter", "none"))
        self.ms_seed = int(get("multiscatter_seed", 0))
        if self.multiscatter not in MULTISCATTER_NAMES:
            raise ValueError(f"pbr_material: bad multiscatter {self.multiscatter!r}")
        multiscatter.check_model(self.ndf, self.geometry, self.multiscatter)
        # [brdf] metallic_blend: "f0" or "gltf" (PBRLobes._diffuse_f0)
        self.metallic_blend = str(get("metallic_blend", "f0"))
        if self.metallic_blend not in METALLIC_BLENDS:
            raise ValueError(f"pbr_material: bad metallic_blend {self.metallic_blend!r}")
        # [brdf] geometric_roughness (reference.integrator.GEOMETRIC_ROUGHNESS): added per lane by the
        # local estimator, which knows the camera ray's differentials; (name, supersample)
        self.geometric = (str(get("geometric_roughness", "none")), int(get("geometric_roughness_supersample", 1)))
        if self.geometric[0] not in GEOMETRIC_ROUGHNESS_NAMES or self.geometric[1] < 1:
            raise ValueError(f"pbr_material: bad geometric roughness {self.geometric!r}")
        # the glTF extensions' lobes (reference.lobe_bsdf): None where the props name none
        self.lobes = lobe_bsdf.LobeParams.from_props(get)
        if self.lobes is not None:
            lobe_bsdf.check_model(self.ndf, self.geometry, self.fresnel, self.multiscatter, self.lobes.used)
        self._update()

    # ---- parameters ------------------------------------------------------------------------
    def _update(self):
        r = float(dr.slice(self.roughness)) if dr.width(self.roughness) == 1 else 0.5
        self.delta = bool(is_mirror_limit(r)) and self.lobes is None   # lobes: never a delta (lobe_bsdf)
        spec = mi.BSDFFlags.DeltaReflection if self.delta else mi.BSDFFlags.GlossyReflection
        comps = [spec | mi.BSDFFlags.FrontSide]
        flags = spec | mi.BSDFFlags.FrontSide
        if self.fresnel != "none":
            comps.append(mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide)
            flags = flags | mi.BSDFFlags.DiffuseReflection
        self.m_components = comps
        self.m_flags = flags

    def traverse(self, callback):
        traverse_material(self, callback)
        if self.lobes is not None:   # the lobes' factors (reference.lobe_bsdf.LobeParams)
            self.lobes.traverse(callback)

    def parameters_changed(self, keys=None):
        self._update()
        make_material_opaque(self)
        if self.lobes is not None:
            self.lobes.make_opaque()

    def to_string(self):
        return (f"PBRMaterial[ndf={self.ndf}, geometry={self.geometry}, fresnel={self.fresnel}, "
                f"delta={self.delta}, base_color={self.base_color}, metallic={self.metallic}, "
                f"roughness={self.roughness}, specular={self.specular}]")

    def model(self) -> tuple:
        """The scene-wide part of the model (equal for every material of a scene): ndf, geometry,
        fresnel, multiscatter, its seed, the geometric roughness (name, supersample) and the metallic blend."""
        return (self.ndf, self.geometry, self.fresnel, self.multiscatter, self.ms_seed, self.geometric,
                self.metallic_blend)

    def eval_diffuse_reflectance(self, si, active=True):
        return (1.0 - self.metallic) * self.base_color


# The lobes of PBRMaterial are PBRLobes' functions, shared by reference: a nanobind class takes one
# base class, so PBRLobes cannot be a mixin of it.
LOBE_METHODS = ("_nondelta", "_alpha", "_glossy_alpha", "_f0", "_diffuse_f0", "_p_spec", "_spec_pdf", "_sample_h", "_eval_pdf",
                "_sample_single", "eval", "pdf", "eval_pdf", "sample")
for _name in LOBE_METHODS:
    setattr(PBRMaterial, _name, getattr(PBRLobes, _name))


def is_mirror_limit(roughness):
    """Whether the specular lobe is the Dirac mirror limit (alpha below DELTA_LOBE_ALPHA): a Python
    bool for a float, a mask for a Dr.Jit array (the same formula both ways)."""
    if isinstance(roughness, (int, float)):
        return max(roughness * roughness, MIN_ALPHA) < DELTA_LOBE_ALPHA
    return dr.maximum(roughness * roughness, MIN_ALPHA) < DELTA_LOBE_ALPHA


class MaterialView(PBRLobes):
    """Every ``pbr_material`` of a scene as one set of per-lane parameters, gathered by the shape
    each lane hit, so the lobes are traced once per call site instead of once per material.

    Mitsuba dispatches a BSDF call on a wavefront as a virtual call that traces the method of every
    instance: on the spheres scene (30 materials) each of the local estimator's BSDF calls traced 30
    copies of the same Python maths, which dominated small renders and every differentiable step
    (``pbrcheck bench reference`` prints both). The maths is the same :class:`PBRLobes`; the mirror
    limit becomes a per-lane mask. Gradients flow to each instance's parameters through the scatter
    into the tables and the gather (both differentiable)."""

    def __init__(self, model: tuple, base_color, metallic, roughness, specular, lobes=None):
        self.model = tuple(model)
        self.ndf, self.geometry, self.fresnel, self.multiscatter, self.ms_seed = model[:5]
        self.geometric = model[5] if len(model) > 5 else ("none", 1)
        self.metallic_blend = model[6] if len(model) > 6 else "f0"
        self.base_color, self.metallic, self.roughness, self.specular = base_color, metallic, roughness, specular
        self.lobes = lobes  # reference.lobe_bsdf.LobeParams per lane, or None
        self.delta = dr.detach(is_mirror_limit(roughness)) if lobes is None else False

    def with_roughness(self, roughness) -> "MaterialView":
        """The same materials shading ``roughness`` per lane (the mirror limit decided anew)."""
        return MaterialView(self.model, self.base_color, self.metallic, roughness, self.specular, self.lobes)

    @staticmethod
    def table(scene):
        """``(model, shape registry id -> material index lookup, materials)`` for a scene whose shapes
        all carry a ``pbr_material`` of one model, else None (then the caller dispatches per BSDF)."""
        shapes = scene.shapes()
        mats = [s.bsdf() for s in shapes]
        if not mats or not all(isinstance(m, PBRMaterial) for m in mats):
            return None
        model = mats[0].model()
        if any(m.model() != model for m in mats):
            return None
        return model, shape_lookup(scene, list(range(len(mats)))), mats

    @classmethod
    def gather(cls, table, si, active):
        """The view of the materials hit by ``si`` (lanes outside ``active`` read material 0)."""
        model, lut, mats = table
        n = len(mats)
        idx = dr.gather(mi.UInt32, lut, dr.reinterpret_array(mi.UInt32, si.shape), active)

        # The tables: entry k = material k's value, built by selects (one kernel for the four, where a
        # scatter per material launched a kernel each: 120 per view, ~400 per differentiable step on
        # spheres, measured with Dr.Jit's kernel history); differentiable like the scatters were.
        ij = table_indices(n)

        def table_of(tp, name):
            return material_table(tp, [getattr(m, name) for m in mats], ij)

        names = ((mi.Color3f, "base_color"), (mi.Float, "metallic"), (mi.Float, "roughness"), (mi.Float, "specular"))
        tables = [table_of(tp, name) for tp, name in names]
        lobes = lobe_bsdf.view_tables(mats, ij)   # the lobes some material uses (materials without: neutral)
        dr.eval(*tables, *(lobes[1].values() if lobes else ()))
        view = cls(model, *(dr.gather(tp, t, idx, active) for (tp, _), t in zip(names, tables)))
        if lobes:
            view.lobes = lobe_bsdf.gather_view(lobes, idx, active)
            view.delta = False
        return view



class SceneCalls:
    """The BSDFs (or area emitters) of one scene's shapes, each lane's called through ``dr.switch``
    over the scene's own.

    A call through Mitsuba's ``BSDFPtr`` / ``EmitterPtr`` (``si.bsdf(ray).eval(...)``) is a Dr.Jit
    virtual call that traces the method of every live instance of the variant's registry, not only
    the scene's: with ``spheres`` loaded in the same process (30 materials, as in the bench) a
    one-material glTF asset's local kernel grew from 3.2k to 17.7k operations (docs/reference.md).
    This dispatcher indexes the scene's distinct objects by shape (a lookup table from the shape's
    registry id; shapes without one, e.g. no emitter, are outside every call) and calls each lane's
    with ``dr.switch``, which traces each of them once; lanes outside ``active`` are not passed and
    return zeros, as through the pointer. One object: no call at all, and an object with ``bind(si,
    active, shape)`` (:class:`reference.textured.TexturedMaterial`: its textures read once per
    interaction) is bound to ``si`` and, where one shape alone has it, to that shape (its vertex
    attributes read directly, not through ``si.shape``'s virtual call). The same functions on the same arguments: the values are the virtual
    call's (tested bit-identical). Methods: those of the objects called (``eval``, ``pdf``,
    ``eval_pdf``, ``sample``, ``eval_null_transmission``)."""

    def __init__(self, table, si, active):
        lut, self.objects, owners = table
        index = dr.gather(mi.UInt32, lut, dr.reinterpret_array(mi.UInt32, si.shape), mi.Bool(active))
        self.active = mi.Bool(active) & (index > 0)   # 0: the shape has none
        self.index = index - 1
        self.one = None
        if len(self.objects) == 1:  # no call: the object itself, bound to si where it can be
            o = self.objects[0]
            self.one = o.bind(si, self.active, owners[0]) if hasattr(o, "bind") else o

    @staticmethod
    def table(scene, kind: str = "bsdf", keep=None):
        """``(shape registry id -> 1 + index lookup, the scene's distinct objects, each object's
        one shape or None where several shapes share it)`` of ``kind`` (``"bsdf"`` or ``"emitter"``:
        the shape's method of that name). An object bound with its one shape reads that shape's
        attributes directly (a call through ``si.shape`` is a virtual call over every live shape of
        the process: :class:`SceneCalls`). ``keep(object)``: where false, the shape is outside every
        call (its lanes return zeros, as a shape without the object), e.g. the opaque BSDFs of the
        alpha layers' ``eval_null_transmission`` (0 for them anyway)."""
        objects, index, owners = [], [], []
        for s in scene.shapes():
            o = getattr(s, kind)()
            if o is not None and keep is not None and not keep(o):
                o = None
            k = -1 if o is None else next((i for i, x in enumerate(objects) if x is o), None)
            if k is None:
                k = len(objects)
                objects.append(o)
                owners.append(s)
            elif k >= 0:
                owners[k] = None
            index.append(k + 1)
        return shape_lookup(scene, index), objects, owners

    def _call(self, name, args):
        *args, mask = args  # the mask: always the last argument
        mask = self.active & mask
        if self.one is not None:  # lanes outside the mask: zeros, as dr.switch returns them
            out = getattr(self.one, name)(*args, mask)
            zero = (lambda x: dr.select(mask, x, dr.zeros(type(x))))
            return tuple(zero(x) for x in out) if isinstance(out, tuple) else zero(out)
        return dr.switch(self.index, [getattr(o, name) for o in self.objects], *args, mask)

    def eval(self, *args):
        """BSDF ``eval(ctx, si, wo, active)`` or emitter ``eval(si, active)``."""
        return self._call("eval", args)

    def pdf(self, ctx, si, wo, active):
        return self._call("pdf", (ctx, si, wo, active))

    def eval_pdf(self, ctx, si, wo, active):
        return self._call("eval_pdf", (ctx, si, wo, active))

    def sample(self, ctx, si, sample1, sample2, active):
        return self._call("sample", (ctx, si, sample1, sample2, active))

    def eval_null_transmission(self, si, active):
        return self._call("eval_null_transmission", (si, active))


_REGISTERED: set[str] = set()


def register() -> None:
    """Register ``pbr_material`` for the current Mitsuba variant (idempotent)."""
    v = mi.variant()
    if v not in _REGISTERED:
        mi.register_bsdf(PLUGIN_NAME, lambda props: PBRMaterial(props))
        _REGISTERED.add(v)


def material_dict(material, brdf) -> dict:
    """Mitsuba dict of a :class:`pbrcheck.scene.Material` under a :class:`pbrcheck.scene.BRDFModel`."""
    # [brdf] roughness_floor: the material shades max(roughness, floor) (pbrcheck.scene.BRDFModel)
    return {"type": PLUGIN_NAME, "base_color": list(material.base_color), "metallic": material.metallic,
            "roughness": max(material.roughness, brdf.roughness_floor), "specular": material.specular,
            "ndf": brdf.ndf, "geometry": brdf.geometry, "fresnel": brdf.fresnel,
            "multiscatter": brdf.multiscatter, "geometric_roughness": brdf.geometric_roughness,
            "geometric_roughness_supersample": brdf.geometric_roughness_supersample,
            "metallic_blend": brdf.metallic_blend,
            **lobe_bsdf.lobes_of_material(material)}   # only the lobes the material sets: none, no key
