"""glTF assets in the reference: Mitsuba meshes from the decoded buffers and the textured material
``pbr_textured`` (the scene's BRDF model, :class:`reference.bsdf.PBRLobes`, with glTF's textures).

``{"type": "pbr_textured", "base_color": [r, g, b], "metallic", "roughness", "specular", "ndf",
"geometry", "fresnel", "base_color_texture": <texture>, "metallic_roughness_texture": <texture>,
"normal_texture": <texture>, "normal_scale", "double_sided"}`` where each ``<texture>`` is a
``gltf_texture`` (:class:`GltfTexture`: float32 linear pixels, colour textures sRGB-decoded on load,
:meth:`GltfImage.linear`; bilinear, nearest where the sampler's magFilter is NEAREST; the sampler's
wrapS and wrapT each on its own axis; ``KHR_texture_transform``'s matrix; no mip filtering: the
pixel's box-filter samples integrate the texture's footprint, the truth a mip chain approximates). Per lane (glTF 2.0 specification, section 3.9 and Appendix B)::

    base_color = base_color_factor * texture.rgb
    roughness  = roughness_factor * metallic_roughness.g,   metallic = metallic_factor * metallic_roughness.b
    n          = normalize(T x' + B y' + N z'),   (x', y', z') = ((2 t.rg - 1) * scale, 2 t.b - 1)
    T = normalize(t - N (N.t)), B = w (N x T)   (the interpolated vertex tangent, its sign w)

then :class:`reference.bsdf.PBRLobes` evaluates the model in the normal-mapped frame (directions are
re-expressed in it, as Mitsuba's ``normalmap`` does). ``double_sided``: a back-facing hit uses the
flipped frame (glTF: the back face's normal is the negated one); a single-sided material's back
faces are culled, as glTF says and the raster pipeline does: invisible, the ray goes on (a null
component of opacity 0 there, :func:`back_face`; ``local`` passes them deterministically,
:func:`reference.integrator.past_back_faces`, ``path`` through Mitsuba's ``volpath``). Analytic
objects keep their black back sides. The occlusion texture is not applied: ``local`` has no visibility (the
texture approximates it) and ``path`` computes it. Emission: an ``area`` emitter whose radiance is
the emissive texture (sRGB-decoded) times ``emissiveFactor`` times ``KHR_materials_emissive_strength``,
on the primitive's mesh: ``local`` adds it at the first hit, ``path`` lights the scene with it.

Alpha (glTF ``alphaMode``): ``MASK`` has opacity ``alpha >= alphaCutoff`` (0 or 1), ``BLEND`` opacity
``alpha`` (``baseColorFactor.a`` times the base colour texture's alpha), exactly: a Null component
(``eval_null_transmission = 1 - opacity``; ``sample`` passes through with that probability, weight
1; ``eval``/``pdf`` scale by the opacity). ``local`` continues camera rays through each surface with
that probability (:meth:`reference.integrator.ReferenceIntegrator._first_opaque_hit`) and shades the
surface where a ray stopped as opaque (its ``BSDFContext.type_mask`` leaves Null out); ``path``
renders such scenes with Mitsuba's ``volpath``, whose shadow rays pass null interfaces (``path``'s do
not).

``COLOR_0`` (linear RGB; its alpha is not used) multiplies the base colour, as the specification says.

``KHR_materials_unlit`` (``"unlit": true``): the material reflects nothing (``eval``, ``pdf`` 0, a
sample's weight 0; its null pass-through for alpha and culled back faces kept) and the shape's
emitter is :class:`reference.unlit.UnlitEmitter`, whose radiance is the base colour above (that
module); the emissive properties are ignored, as the extension says.

UVs: glTF's, origin at the image's top-left, v down, which is Mitsuba's bitmap lookup (row 0 at v =
0). Each texture slot reads its own ``texCoord`` set: the mesh's texcoords (``si.uv``) hold the
emissive texture's set (:func:`primary_texcoord`: the area emitter can read no other, also where it
samples positions on the mesh), the other set is a mesh attribute ``vertex_uv<k>`` (u, v, 0) read
with ``eval_attribute_3``.

API: :func:`register`, :func:`asset_shapes` (the Mitsuba shapes of a scene's assets), :func:`primary_texcoord`,
:func:`texture_dict`, :func:`back_face`, :func:`culls_back_faces`, :func:`has_alpha`, :class:`GltfTexture`,
:class:`BoundTextured`, :func:`fuse_textures`, :data:`FUSED_CHANNELS`, :data:`PLUGIN_NAME`, :data:`TEXTURE_PLUGIN`,
:func:`calls_geometric`, :class:`GeometricCalls` (``[brdf] geometric_roughness`` on assets: the local
estimator adds three.js's screen-space ``g`` to each lane's floored texel roughness, then ``min(., 1)``),
:func:`uv_normal_partials` (a mesh hit's normal partials in its position partials' parameterisation).

Per hit the base colour, metallic-roughness and normal textures that share a sampler, a size and a
texCoord set are read as one packed texture (:func:`fuse_textures`: the same values, bit for bit).

``TexturedMaterial.normal_filter`` (None: the reference): set by :func:`reference.normal_filter.attach`
for ``pbrcheck fit-normal-roughness``'s model, it replaces the normal-map texel by the raster's
trilinear mip lookup at its LOD and widens ``alpha^2`` by the per-level table (that module).
"""

from __future__ import annotations

import numpy as np

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)
from pbrcheck.gltf import WRAP_CLAMP, WRAP_MIRROR, TextureRef

import drjit as dr
import mitsuba as mi

from . import lobe_bsdf
from . import multiscatter
from .bsdf import MaterialView, SceneCalls, is_mirror_limit, make_material_opaque, traverse_material

PLUGIN_NAME = "pbr_textured"
TEXTURE_PLUGIN = "gltf_texture"
WRAP_MODES = {WRAP_CLAMP: "clamp", WRAP_MIRROR: "mirror"}   # else repeat
#: glTF's magFilter NEAREST (9728): the texel itself; LINEAR or unset: bilinear.
MAG_NEAREST = 9728
#: Shading-frame tangents shorter than this after Gram-Schmidt fall back to Mitsuba's frame.
FRAME_EPS = 1e-8
#: The texture slots a material reads at every hit, with the channels it reads of each: those that
#: share a sampler and a size are read from one packed texture (:func:`fuse_textures`).
FUSED_CHANNELS = {"base_color": (0, 1, 2), "metallic_roughness": (1, 2), "normal": (0, 1, 2)}


def _pad_axis(px: np.ndarray, axis: int, wrap: int) -> np.ndarray:
    """One texel more on each side of ``axis``: the neighbour that axis's wrap mode puts there
    (REPEAT: the opposite edge; CLAMP_TO_EDGE and MIRRORED_REPEAT, which reflects about the edge:
    the edge texel itself)."""
    widths = [(0, 0)] * px.ndim
    widths[axis] = (1, 1)
    return np.pad(px, widths, mode="wrap" if wrap not in WRAP_MODES else "edge")


#: Whether the reference's texture lookups may use the GPU's texture units (``bitmap``'s ``accel``,
#: ``Texture2f``'s ``use_accel``; no effect on the LLVM backend). Off: CUDA's texture units resolve the
#: position between texels with 8 fractional bits (Dr.Jit's ``Texture`` documentation), so a bilinear
#: lookup is off by up to 1/512 of the step between two texels -- measured on an H100: 2.30078 for
#: 2.3 (tests/test_gltf_wrap.py), and a texture-transform test 1.7e-3 off (test_gltf.py). The
#: reference interpolates in float32 arithmetic, as on the CPU.
TEXTURE_UNITS = False


def texture_dict(pixels: np.ndarray, ref: TextureRef) -> dict:
    """A ``gltf_texture`` (:class:`GltfTexture`) of float32 linear ``pixels`` (H, W, C) read as glTF
    ``ref`` reads it: its own wrapS and wrapT, transform and magFilter."""
    px = np.ascontiguousarray(pixels, dtype=np.float32)
    h, w = px.shape[:2]
    padded = _pad_axis(_pad_axis(px, 1, ref.wrap[0]), 0, ref.wrap[1])
    inner = {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(padded)), "raw": True,
             "filter_type": "nearest" if ref.mag_filter == MAG_NEAREST else "bilinear", "wrap_mode": "clamp",
             "accel": TEXTURE_UNITS}
    m = np.eye(3) if ref.transform is None else np.asarray(ref.transform, float).reshape(3, 3)
    return {"type": TEXTURE_PLUGIN, "inner": inner, "wrap_s": int(ref.wrap[0]), "wrap_t": int(ref.wrap[1]),
            "width": int(w), "height": int(h), "nearest": ref.mag_filter == MAG_NEAREST, **{f"m{k}": float(x) for k, x in enumerate(m.reshape(-1)[:6])}}


def _wrap(x, mode: int):
    """glTF's wrap of one texture coordinate into [0, 1] (specification 3.8.4.3)."""
    if mode == WRAP_CLAMP:
        return dr.clip(x, 0.0, 1.0)
    if mode == WRAP_MIRROR:
        y = x - 2.0 * dr.floor(0.5 * x)            # [0, 2)
        return dr.select(y > 1.0, 2.0 - y, y)
    return x - dr.floor(x)


class GltfTexture(mi.Texture):
    """``gltf_texture``: a glTF texture with a sampler whose wrapS and wrapT may differ (Mitsuba's
    ``bitmap`` has one ``wrap_mode``). ``{"type": "gltf_texture", "inner": <bitmap of the image padded
    by one texel per side, each axis's padding its wrap mode's neighbour, wrap_mode clamp>, "wrap_s",
    "wrap_t", "width", "height", "m0" .. "m5": the top two rows of KHR_texture_transform's matrix}``.
    Per lookup: ``(u, v) = transform (u, v, 1)``, each axis wrapped by its own mode into [0, 1], then
    read at ``((u W + 1) / (W + 2), (v H + 1) / (H + 2))`` in the padded image. Exact for bilinear and
    nearest filtering: a lookup within half a texel of an edge blends with the padding, which is the
    texel that axis's wrap mode puts beyond the edge."""

    def __init__(self, props):
        mi.Texture.__init__(self, props)
        self.inner = props.get("inner")
        self.wrap_s = int(props.get("wrap_s", 10497))
        self.wrap_t = int(props.get("wrap_t", 10497))
        self.width = int(props.get("width"))
        self.height = int(props.get("height"))
        self.m = [float(props.get(f"m{k}", float(k in (0, 4)))) for k in range(6)]
        self.nearest = bool(props.get("nearest", False))

    def sampler_key(self) -> tuple:
        """What decides where a lookup reads (size, wraps, transform, filter): textures with equal
        keys read the same texels with the same weights at every ``si``."""
        return (self.width, self.height, self.wrap_s, self.wrap_t, tuple(self.m), self.nearest)

    def coords(self, uv):
        """The lookup's coordinates in the padded image (class docstring)."""
        m = self.m
        u = m[0] * uv.x + m[1] * uv.y + m[2]
        v = m[3] * uv.x + m[4] * uv.y + m[5]
        u = (_wrap(u, self.wrap_s) * self.width + 1.0) / (self.width + 2.0)
        v = (_wrap(v, self.wrap_t) * self.height + 1.0) / (self.height + 2.0)
        return mi.Point2f(u, v)

    def _si(self, si):
        s2 = mi.SurfaceInteraction3f(si)
        s2.uv = self.coords(si.uv)
        return s2

    def eval(self, si, active=True):
        return self.inner.eval(self._si(si), active)

    def eval_1(self, si, active=True):
        return self.inner.eval_1(self._si(si), active)

    def eval_3(self, si, active=True):
        return self.inner.eval_3(self._si(si), active)

    def mean(self):
        return self.inner.mean()

    def is_spatially_varying(self):
        return True

    def to_string(self):
        return f"GltfTexture[{self.width}x{self.height}, wrap=({self.wrap_s}, {self.wrap_t})]"


class TexturedMaterial(mi.BSDF):
    """``pbr_textured`` (module docstring)."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        self.base_color = mi.Color3f(*[float(x) for x in props.get("base_color", [1.0, 1.0, 1.0])])
        self.metallic = mi.Float(float(props.get("metallic", 1.0)))
        self.roughness = mi.Float(float(props.get("roughness", 1.0)))
        # [brdf] roughness_floor: shaded roughness = max(factor * texture.g, floor) (0: none)
        self.roughness_floor = float(props.get("roughness_floor", 0.0))
        self.specular = mi.Float(float(props.get("specular", 0.04)))
        # the scene-wide model (reference.bsdf.PBRMaterial.model): the random walk per shading point
        # (multiscatter = "random_walk": the lobes of MaterialView take each hit's texel roughness,
        # metallic, base colour and normal, reference.multiscatter's hooks the walk at them)
        self.model = (str(props.get("ndf", "ggx")), str(props.get("geometry", "smith_ggx_correlated")),
                      str(props.get("fresnel", "schlick")), str(props.get("multiscatter", "none")),
                      int(props.get("multiscatter_seed", 0)), ("none", 1), str(props.get("metallic_blend", "f0")))
        multiscatter.check_model(self.model[0], self.model[1], self.model[3])
        self.normal_scale = float(props.get("normal_scale", 1.0))
        self.vertex_color = bool(props.get("vertex_color", False))   # COLOR_0 multiplies the base colour
        self.double_sided = bool(props.get("double_sided", False))
        # glTF alphaMode: 0 OPAQUE, 1 MASK (opacity = alpha >= cutoff), 2 BLEND (opacity = alpha)
        self.alpha_mode = int(props.get("alpha_mode", 0))
        self.alpha_cutoff = float(props.get("alpha_cutoff", 0.5))
        self.alpha = float(props.get("alpha", 1.0))
        self.unlit = bool(props.get("unlit", False))   # KHR_materials_unlit (reference.unlit)
        # the TEXCOORD set in the mesh's own texcoords (si.uv); the other set is the mesh attribute
        # vertex_uv<k> (asset_shapes: the emissive texture's set, which the area emitter reads as si.uv)
        self.primary_texcoord = int(props.get("primary_texcoord", 0))
        self.tex = {}
        self.uvset = {}
        for slot in ("base_color", "metallic_roughness", "normal", "alpha"):
            if f"{slot}_texture" in props:
                self.tex[slot] = props.get(f"{slot}_texture")
                self.uvset[slot] = int(props.get(f"{slot}_texcoord", 0))
        flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
        if self.double_sided:
            flags = flags | mi.BSDFFlags.BackSide
        if self.tex:
            flags = flags | mi.BSDFFlags.SpatiallyVarying
        comps = [flags]
        if self.alpha_mode or not self.double_sided:  # cut-outs, and culled back faces, pass rays through
            comps.append(mi.BSDFFlags.Null | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide)
            flags = flags | mi.BSDFFlags.Null | mi.BSDFFlags.BackSide
        self.m_components = comps
        self.m_flags = flags
        self.fused = fuse_textures(self.tex, self.uvset)
        # the glTF extensions' lobes (reference.lobe_bsdf): factors, textures; the vertex TANGENT's presence
        self.tangents = bool(props.get("tangents", False))
        lobe_bsdf.textured_init(self, props)
        # reference.normal_filter.attach sets it (fit-normal-roughness's filtered model); None: the reference
        self.normal_filter = None
        # [brdf] geometric_roughness (name, supersample): added per lane at the first hit by the local
        # estimator (reference.integrator, through GeometricCalls below; issue 40)
        self.geometric = (str(props.get("geometric_roughness", "none")),
                          int(props.get("geometric_roughness_supersample", 1)))

    def traverse(self, callback):
        traverse_material(self, callback)

    def parameters_changed(self, keys=None):
        make_material_opaque(self)

    def to_string(self):
        return f"TexturedMaterial[textures={sorted(self.tex)}, double_sided={self.double_sided}]"

    # ---- per-lane material and frame --------------------------------------------------------
    def _uv_si(self, slot, si, active, shape=None):
        """``si`` with the uv of ``slot``'s texCoord set (``shape``: the lanes' one shape, read
        directly, else ``si.shape``)."""
        k = self.uvset[slot]
        if k != self.primary_texcoord:
            s2 = mi.SurfaceInteraction3f(si)
            uv = (si.shape if shape is None else shape).eval_attribute_3(f"vertex_uv{k}", si, active)
            s2.uv = mi.Point2f(uv.x, uv.y)
            return s2
        return si

    def _lookup(self, slot, si, active):
        return self.tex[slot].eval(self._uv_si(slot, si, active), active)

    def _lookups(self, si, active, shape=None) -> dict:
        """Each slot of :data:`FUSED_CHANNELS` with a texture: its value at ``si`` (one lookup of
        the packed texture for the slots :func:`fuse_textures` packed, Color3f; the same values)."""
        out = {}
        for group in self.fused:
            texture, gltf, slots = group
            first = slots[0][0]
            ch = texture.eval(gltf.coords(self._uv_si(first, si, active, shape).uv), active)
            for slot, offset in slots:
                used = FUSED_CHANNELS[slot]
                val = [mi.Float(0.0)] * 3
                for i, c in enumerate(used):
                    val[c] = ch[offset + i]
                out[slot] = mi.Color3f(*val)
        for slot in FUSED_CHANNELS:
            if slot in self.tex and slot not in out:
                out[slot] = self.tex[slot].eval(self._uv_si(slot, si, active, shape), active)
        return out

    def _view(self, si, active, shape=None):
        """(MaterialView of the lanes, shading frame in Mitsuba's local coordinates); ``shape``:
        the one shape of every lane (its attributes read directly, not through ``si.shape``)."""
        bc = mi.Color3f(self.base_color)
        met, rough = mi.Float(self.metallic), mi.Float(self.roughness)
        tex = self._lookups(si, active, shape)
        shape = si.shape if shape is None else shape
        if "base_color" in tex:
            bc = bc * tex["base_color"]
        if self.vertex_color:
            bc = bc * shape.eval_attribute_3("vertex_color", si, active)
        if "metallic_roughness" in tex:
            mr = tex["metallic_roughness"]
            rough = rough * mr.y
            met = met * mr.z
        if self.roughness_floor > 0.0:
            rough = dr.maximum(rough, self.roughness_floor)
        if self.normal_filter is not None and "normal" in tex:
            # fit-normal-roughness's model (reference.normal_filter): the raster's trilinear normal
            # lookup at its LOD, alpha^2 widened by the per-level table
            tex["normal"], v = self.normal_filter.lookup(si, active)
            rough = self.normal_filter.widen(rough, v)
        n_local = mi.Vector3f(0.0, 0.0, 1.0)
        flip = mi.Bool(False)
        if self.double_sided:
            flip = mi.Frame3f.cos_theta(si.wi) < 0
        if "normal" in tex:
            t = tex["normal"]
            x = (2.0 * t.x - 1.0) * self.normal_scale
            y = (2.0 * t.y - 1.0) * self.normal_scale
            z = 2.0 * t.z - 1.0
            # two attributes: Mitsuba 3.9's eval_attribute_x returns zeros for a 4-channel one
            # (the frame then fell back to Mitsuba's, whose bitangent is +1 everywhere)
            tw = mi.Vector3f(shape.eval_attribute_3("vertex_tangent", si, active))
            w = dr.select(shape.eval_attribute_1("vertex_tangent_w", si, active) < 0, -1.0, 1.0)
            N = si.sh_frame.n
            T = tw - N * dr.dot(N, tw)
            ok = dr.squared_norm(T) > FRAME_EPS
            T = dr.select(ok, dr.normalize(T), si.sh_frame.s)
            B = dr.cross(N, T) * w
            n_world = dr.normalize(T * x + B * y + N * z)
            n_local = dr.normalize(si.sh_frame.to_local(n_world))
        n_local = dr.select(flip, -n_local, n_local)
        frame = mi.Frame3f(n_local)
        lobes = None
        if self.lobes_static is not None:   # hook: the lobes' textures, the tangent frame (reference.lobe_bsdf)
            lobes, frame = lobe_bsdf.textured_lobes(self, si, active, shape, n_local, flip, frame)
        view = MaterialView(self.model, bc, met, rough, mi.Float(self.specular), lobes)
        return view, frame

    def opacity(self, si, active=True):
        """glTF's coverage at the hit: 1 (OPAQUE), alpha >= cutoff (MASK) or alpha (BLEND), with
        alpha = baseColorFactor.a * baseColorTexture.a; 0 on the back face of a single-sided
        material (``doubleSided`` false: culled, :func:`culls_back_faces`)."""
        a = mi.Float(1.0)
        if self.alpha_mode:
            a = mi.Float(self.alpha)
            if "alpha" in self.tex:
                a = a * self._lookup("alpha", si, active).x
            a = dr.select(a >= self.alpha_cutoff, 1.0, 0.0) if self.alpha_mode == 1 else dr.clip(a, 0.0, 1.0)
        if not self.double_sided:
            a = dr.select(back_face(si), 0.0, a)
        return a

    @staticmethod
    def _null_enabled(ctx) -> bool:
        """Whether the context asks for the null component: no when the caller (the ``local``
        estimator) has already decided that the surface is there (``type_mask`` without Null); then
        the surface is shaded as opaque."""
        return bool(int(ctx.type_mask) & int(mi.BSDFFlags.Null))

    def eval_null_transmission(self, si, active=True):
        """The fraction that passes through (1 - opacity): Mitsuba's null interface."""
        return mi.Spectrum(1.0 - self.opacity(si, active))

    def _local_si(self, si, frame):
        s2 = mi.SurfaceInteraction3f(si)
        s2.wi = frame.to_local(si.wi)
        return s2

    def eval_pdf(self, ctx, si, wo, active=True):
        return self._eval_pdf_at(self._view(si, active), ctx, si, wo, active)

    def eval(self, ctx, si, wo, active=True):
        return self.eval_pdf(ctx, si, wo, active)[0]

    def pdf(self, ctx, si, wo, active=True):
        return self.eval_pdf(ctx, si, wo, active)[1]

    def sample(self, ctx, si, sample1, sample2, active=True):
        return self._sample_at(self._view(si, active), ctx, si, sample1, sample2, active)

    def bind(self, si, active=True, shape=None):
        """The material at one interaction ``si``, its textures read once for all the caller's calls
        there (:class:`BoundTextured`; ``reference.bsdf.SceneCalls`` uses it); ``shape``: the one
        shape of the lanes (:meth:`_view`)."""
        return BoundTextured(self, si, active, shape)

    def _eval_pdf_at(self, view_frame, ctx, si, wo, active):
        view, frame = view_frame
        s2 = self._local_si(si, frame)
        wo2 = frame.to_local(wo)
        # the geometric side: light and viewer on the same side of the surface
        same = mi.Frame3f.cos_theta(si.wi) * mi.Frame3f.cos_theta(wo) > 0
        front = self.double_sided | (mi.Frame3f.cos_theta(si.wi) > 0)
        f, pdf = view.eval_pdf(ctx, s2, wo2, active & same & front)
        if self.unlit:   # KHR_materials_unlit: no reflection (its base colour is emitted: reference.unlit)
            return mi.Spectrum(0.0), mi.Float(0.0)
        if self.alpha_mode and self._null_enabled(ctx):  # the surface is there with probability opacity
            op = self.opacity(si, active)
            f, pdf = f * op, pdf * op
        return dr.select(same & front, f, 0.0), dr.select(same & front, pdf, 0.0)

    def _sample_at(self, view_frame, ctx, si, sample1, sample2, active):
        view, frame = view_frame
        s2 = self._local_si(si, frame)
        front = self.double_sided | (mi.Frame3f.cos_theta(si.wi) > 0)
        lanes = mi.Bool(active) & front
        mixed = bool(self.alpha_mode or not self.double_sided) and self._null_enabled(ctx)
        if mixed:
            # pass through with probability 1 - opacity (weight 1), else the lobes (weight unchanged:
            # value and pdf both scale by the opacity); sample1, rescaled, still chooses the lobe
            op = self.opacity(si, active)
            through = sample1 >= op
            sample1 = dr.select(through, 0.0, sample1 / dr.maximum(op, 1e-20))
            lanes &= ~through
        bs, w = view.sample(ctx, s2, sample1, sample2, lanes)
        bs.wo = frame.to_world(bs.wo)
        ok = front & (mi.Frame3f.cos_theta(si.wi) * mi.Frame3f.cos_theta(bs.wo) > 0)
        w = dr.select(ok, w, 0.0)
        if mixed:
            bs.pdf = dr.select(through, 1.0 - op, bs.pdf * op)
            bs.wo = dr.select(through, -si.wi, bs.wo)
            bs.eta = 1.0
            bs.sampled_type = dr.select(through, mi.UInt32(+mi.BSDFFlags.Null), bs.sampled_type)
            bs.sampled_component = dr.select(through, mi.UInt32(1), bs.sampled_component)
            w = dr.select(through, 1.0, w)
        if self.unlit:   # KHR_materials_unlit: no reflection; the pass-through of alpha and culling kept
            w = dr.select(through, 1.0, 0.0) if mixed else mi.Spectrum(0.0)
        return bs, w

    def eval_diffuse_reflectance(self, si, active=True):
        view, _ = self._view(si, active)
        return (1.0 - view.metallic) * view.base_color



class BoundTextured:
    """A :class:`TexturedMaterial` bound to one interaction: its view (textures, tangent frame) read
    once with the mask ``active`` and shared by ``eval``, ``pdf``, ``eval_pdf`` and ``sample`` at
    that interaction (the same functions as the material's own methods, which read the textures per
    call; the local estimator calls three of them per hit). ``si`` and the calls' masks must lie
    within the bound ones."""

    def __init__(self, material, si, active, shape=None):
        self.material = material
        self.view_frame = material._view(si, active, shape)

    def eval_pdf(self, ctx, si, wo, active=True):
        return self.material._eval_pdf_at(self.view_frame, ctx, si, wo, active)

    def eval(self, ctx, si, wo, active=True):
        return self.eval_pdf(ctx, si, wo, active)[0]

    def pdf(self, ctx, si, wo, active=True):
        return self.eval_pdf(ctx, si, wo, active)[1]

    def sample(self, ctx, si, sample1, sample2, active=True):
        return self.material._sample_at(self.view_frame, ctx, si, sample1, sample2, active)

    def eval_null_transmission(self, si, active=True):
        return self.material.eval_null_transmission(si, active)


# ---- [brdf] geometric_roughness on glTF assets (issue 40; the model helper's block) ---------------

def calls_geometric(calls):
    """``(name, supersample)`` of ``[brdf] geometric_roughness`` where a scene's BSDF calls
    (:class:`reference.bsdf.SceneCalls`) hold a textured material that asks for it, else None (every
    material of a scene carries the scene's ``[brdf]``)."""
    for o in getattr(calls, "objects", ()):
        geo = getattr(o, "geometric", None)
        if isinstance(o, TexturedMaterial) and geo[0] != "none":
            return geo
    return None


def _raised(view_frame, g):
    """A textured material's (view, frame) shading ``min(roughness + g, 1)`` per lane: three.js r187's
    order (lights_physical_fragment: the floored roughness, ``+= geometryRoughness``, ``min(., 1)``;
    the view's roughness is already the texel's times the factor, floored)."""
    view, frame = view_frame
    return view.with_roughness(dr.minimum(view.roughness + g, 1.0)), frame


class GeometricCalls(SceneCalls):
    """A scene's BSDF calls (:class:`reference.bsdf.SceneCalls`) with ``g`` (per lane, the local
    estimator's :data:`reference.integrator.GEOMETRIC_ROUGHNESS` at the camera ray's hit) added to
    each material's roughness, then at most 1, as :meth:`reference.bsdf.MaterialView.with_roughness`
    does for the built-in objects: a textured material through its (view, frame), a
    ``pbr_material`` beside an asset through a :class:`reference.bsdf.MaterialView` of its values; any
    other object as it is. ``g`` rides in the calls' arguments (``dr.switch`` passes each callee its
    lanes of it). Methods: SceneCalls' (``eval``, ``pdf``, ``eval_pdf``, ``sample``,
    ``eval_null_transmission``), made from ``calls`` (not from a table)."""

    def __init__(self, calls, g):  # not SceneCalls.__init__: calls already hold the lanes, index and objects
        self.calls, self.g = calls, g
        self.active, self.index, self.objects = calls.active, calls.index, calls.objects
        self.one = None   # several objects (or one unbound): dr.switch over _callee
        if isinstance(calls.one, BoundTextured):   # one material: its bound view, raised once
            self.one = BoundTextured.__new__(BoundTextured)
            self.one.material, self.one.view_frame = calls.one.material, _raised(calls.one.view_frame, g)

    @staticmethod
    def _callee(o, name):
        """``o``'s ``name`` taking ``g`` just before its mask."""
        from .bsdf import PBRMaterial
        if isinstance(o, TexturedMaterial):
            at = {"eval_pdf": o._eval_pdf_at, "sample": o._sample_at}
            if name in ("eval", "pdf", "eval_pdf"):
                def f(ctx, si, wo, g, active):
                    out = at["eval_pdf"](_raised(o._view(si, active), g), ctx, si, wo, active)
                    return out if name == "eval_pdf" else out[name == "pdf"]
                return f
            if name == "sample":
                return lambda ctx, si, s1, s2, g, active: at["sample"](_raised(o._view(si, active), g), ctx, si,
                                                                       s1, s2, active)
        elif isinstance(o, PBRMaterial) and name != "eval_null_transmission":
            def f(*args):
                *a, g, active = args
                view = MaterialView(o.model(), o.base_color, o.metallic,
                                    dr.minimum(o.roughness + g, 1.0), o.specular, o.lobes)
                return getattr(view, name)(*a, active)
            return f
        return lambda *args: getattr(o, name)(*args[:-2], args[-1])

    def _call(self, name, args):
        *args, mask = args
        mask = self.active & mask
        if self.one is not None:  # as SceneCalls: zeros outside the mask
            out = getattr(self.one, name)(*args, mask)
            zero = (lambda x: dr.select(mask, x, dr.zeros(type(x))))
            return tuple(zero(x) for x in out) if isinstance(out, tuple) else zero(out)
        return dr.switch(self.index, [self._callee(o, name) for o in self.objects], *args, self.g, mask)


def uv_normal_partials(si):
    """``si`` with a mesh hit's normal partials ``dn_du``, ``dn_dv`` in the parameterisation of its
    position partials. Mitsuba's mesh (``Mesh::compute_surface_interaction`` under ``dNSdUV``) gives
    the interpolated normal's derivatives with respect to the triangle's barycentrics ``(b1, b2)``,
    but ``dp_du``, ``dp_dv`` (and so ``compute_uv_partials``' ``duv_dx``) with respect to the texture
    coordinates where the mesh has them (and ``det != 0``): ``dn/du dU/dx`` then mixes the two, wrong
    by the UV layout's scale (on DamagedHelmet's atlas ~40x too small). The chain rule through
    ``(b1, b2) = M^-1 (uv - uv0)``, ``M = [uv1 - uv0, uv2 - uv0]``, as Mitsuba's own ``dp_du``:
    ``dn/du = (dn/db1 d1.y - dn/db2 d0.y) / det`` and ``dn/dv = (dn/db2 d0.x - dn/db1 d1.x) / det``
(``d0 = uv1 - uv0``, ``d1 = uv2 - uv0``, ``det = d0.x d1.y - d0.y d1.x``). Other lanes (analytic
    shapes, meshes without texcoords, degenerate UVs) keep Mitsuba's, which already agree."""
    mesh = mi.MeshPtr(si.shape)
    valid = si.is_valid() & si.shape.is_mesh()
    valid &= mesh.has_vertex_texcoords()
    fi = mesh.face_indices(si.prim_index, valid)
    uv0, uv1, uv2 = (mesh.vertex_texcoord(fi[k], valid) for k in range(3))
    d0, d1 = uv1 - uv0, uv2 - uv0
    det = d0.x * d1.y - d0.y * d1.x
    ok = valid & (det != 0)
    inv = dr.rcp(dr.select(ok, det, 1.0))
    # db1/du = d1.y/det, db2/du = -d0.y/det, db1/dv = -d1.x/det, db2/dv = d0.x/det
    dn_du = (si.dn_du * d1.y - si.dn_dv * d0.y) * inv
    dn_dv = (si.dn_dv * d0.x - si.dn_du * d1.x) * inv
    si.dn_du = dr.select(ok, dn_du, si.dn_du)
    si.dn_dv = dr.select(ok, dn_dv, si.dn_dv)
    return si

# ---- end of the geometric_roughness block ---------------------------------------------------------


def fuse_textures(tex: dict, uvset: dict) -> list:
    """The slots of :data:`FUSED_CHANNELS` in ``tex`` (``gltf_texture`` each) grouped by texCoord
    set and :meth:`GltfTexture.sampler_key`; each group of two or more becomes one ``Texture2f``
    holding the channels read of each slot side by side (base colour rgb, metallic-roughness gb,
    normal xyz: 8 floats a texel). One lookup of it computes the weights once and gathers each
    corner as one packet, and returns, channel by channel, the values the slots' own lookups return
    (Dr.Jit's bilinear and nearest interpolation are per channel: bit-identical, tested). Returns
    ``[(Texture2f, the group's first GltfTexture, [(slot, first channel), ...]), ...]``."""
    groups: dict = {}
    for slot in FUSED_CHANNELS:
        t = tex.get(slot)
        if isinstance(t, GltfTexture):
            groups.setdefault((uvset[slot], t.sampler_key()), []).append(slot)
    fused = []
    for (_, key), slots in groups.items():
        if len(slots) < 2:
            continue
        planes, placed, offset = [], [], 0
        for slot in slots:
            data = np.asarray(mi.traverse(tex[slot].inner)["data"], dtype=np.float32)
            if data.ndim != 3 or data.shape[2] < 3:
                break
            planes.append(data[..., list(FUSED_CHANNELS[slot])])
            placed.append((slot, offset))
            offset += len(FUSED_CHANNELS[slot])
        else:
            if len({p.shape[:2] for p in planes}) != 1:
                continue
            packed = mi.TensorXf(np.ascontiguousarray(np.concatenate(planes, axis=-1)))
            mode = dr.FilterMode.Nearest if key[-1] else dr.FilterMode.Linear
            fused.append((mi.Texture2f(packed, use_accel=TEXTURE_UNITS, filter_mode=mode, wrap_mode=dr.WrapMode.Clamp),
                          tex[slots[0]], placed))
    return fused


def back_face(si):
    """Whether the hit sees the geometric back of its triangle (the side its winding turns away:
    ``si.n``, which :func:`asset_shapes` keeps on glTF's counter-clockwise front under mirroring
    placements)."""
    return dr.dot(si.n, si.to_world(si.wi)) < 0


def culls_back_faces(bsdf) -> bool:
    """Whether a shape's BSDF is a single-sided glTF material, whose back faces are culled (glTF 2.0,
    3.9.6: ``doubleSided`` false enables back-face culling): the reference lets rays pass them."""
    return isinstance(bsdf, TexturedMaterial) and not bsdf.double_sided


def has_alpha(bsdf) -> bool:
    """Whether a shape's BSDF is a glTF material with alphaMode MASK or BLEND (stochastic opacity)."""
    return isinstance(bsdf, TexturedMaterial) and bool(bsdf.alpha_mode)


_REGISTERED: set[str] = set()


def register() -> None:
    """Register ``pbr_textured`` for the current Mitsuba variant (idempotent)."""
    v = mi.variant()
    if v not in _REGISTERED:
        mi.register_bsdf(PLUGIN_NAME, lambda props: TexturedMaterial(props))
        mi.register_texture(TEXTURE_PLUGIN, lambda props: GltfTexture(props))
        _REGISTERED.add(v)


# ------------------------------------------------------------------------------------------------
# Shapes
# ------------------------------------------------------------------------------------------------

def _material_dict(asset, index: int, brdf, cache: dict, vertex_color: bool = False, primary: int = 0,
                   tangents: bool = False) -> dict:
    m = asset.material(index)
    d = {"type": PLUGIN_NAME, "vertex_color": bool(vertex_color), "primary_texcoord": int(primary), "base_color": [float(c) for c in m.base_color[:3]], "metallic": float(m.metallic),
         "roughness": float(m.roughness), "specular": float(m.specular), "ndf": brdf.ndf,
         "geometry": brdf.geometry, "fresnel": brdf.fresnel, "roughness_floor": float(brdf.roughness_floor),
         "metallic_blend": brdf.metallic_blend, "multiscatter": brdf.multiscatter,
         "geometric_roughness": brdf.geometric_roughness,
         "geometric_roughness_supersample": int(brdf.geometric_roughness_supersample),
         "normal_scale": float(m.normal_texture.scale)
         if m.normal_texture else 1.0, "double_sided": bool(m.double_sided)}
    if m.unlit:
        d["unlit"] = True
    else:   # the glTF extensions' lobes (reference.lobe_bsdf.gltf_lobe_props: none, no key)
        lobes = lobe_bsdf.gltf_lobe_props(asset, m, cache, texture_dict)
        d.update(lobes, **({"tangents": True} if lobes and tangents else {}))
    for slot, ref, srgb in (("base_color", m.base_color_texture, True),
                            ("metallic_roughness", m.metallic_roughness_texture, False),
                            ("normal", m.normal_texture, False)):
        if ref is None:
            continue
        key = (ref.image, srgb)
        if key not in cache:
            cache[key] = asset.images[ref.image].linear(srgb)[..., :3]
        d[f"{slot}_texture"] = texture_dict(cache[key], ref)
        d[f"{slot}_texcoord"] = ref.texcoord
    if m.alpha_mode != "OPAQUE":
        d.update(alpha_mode=1 if m.alpha_mode == "MASK" else 2, alpha_cutoff=float(m.alpha_cutoff),
                 alpha=float(m.base_color[3]))
        ref = m.base_color_texture
        if ref is not None:
            key = (ref.image, "alpha")
            if key not in cache:
                cache[key] = asset.images[ref.image].linear(False)[..., 3:4]
            d["alpha_texture"] = texture_dict(cache[key], ref)
            d["alpha_texcoord"] = ref.texcoord
    return d


def _emitter_dict(asset, index: int, cache: dict) -> dict | None:
    m = asset.material(index)
    if max(m.emissive) <= 0:
        return None
    if m.emissive_texture is None:
        return {"type": "area", "radiance": {"type": "rgb", "value": [float(c) for c in m.emissive]}}
    key = ("emissive", m.emissive_texture.image, m.emissive)
    if key not in cache:
        cache[key] = asset.images[m.emissive_texture.image].linear(True)[..., :3] * np.asarray(m.emissive, np.float32)
    return {"type": "area", "radiance": texture_dict(cache[key], m.emissive_texture)}


def primary_texcoord(asset, material: int, prim) -> int:
    """The TEXCOORD set a primitive's Mitsuba mesh carries as its texcoords (``si.uv``): the emissive
    texture's (Mitsuba's area emitter reads its radiance texture at ``si.uv``, also at the positions
    it samples on the mesh, where no other attribute can be interpolated), else 0; the other set is
    the mesh attribute ``vertex_uv<k>``."""
    em = asset.material(material).emissive_texture
    k = int(em.texcoord) if em is not None else 0
    return k if k < len(prim.texcoords) and prim.texcoords[k] is not None else 0


def asset_shapes(scene, shape_id, bsdf_for=None) -> dict:
    """{shape id: Mitsuba mesh} for every :class:`pbrcheck.gltf_objects.Mesh` of ``scene``, built from
    the decoded buffers (placed by their instance's matrix); ``shape_id(index)`` names a shape
    (:func:`reference.render.shape_id`); ``bsdf_for(obj)`` overrides the material."""
    from pbrcheck.gltf_objects import Mesh

    register()
    out = {}
    textures: dict = {}
    mats: dict = {}
    for obj in scene.objects:
        if not isinstance(obj, Mesh):
            continue
        inst = scene.assets[obj.instance]
        prim = inst.asset.primitives[obj.primitive]
        M = inst.matrix()
        pos = prim.positions.astype(np.float64) @ M[:3, :3].T + M[:3, 3]
        nrm = prim.normals.astype(np.float64) @ np.linalg.inv(M[:3, :3])
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-30)
        tri = prim.indices
        det = np.linalg.det(M[:3, :3])
        if det < 0:
            tri = tri[:, [0, 2, 1]]
        primary = primary_texcoord(inst.asset, obj.gltf_material, prim)
        uv0 = prim.texcoords[primary]
        props = mi.Properties()
        if bsdf_for is not None:
            bsdf = mi.load_dict(bsdf_for(obj))
        else:
            tangents = prim.tangents is not None and lobe_bsdf.needs_tangents(inst.asset.material(obj.gltf_material))
            key = (obj.instance, obj.gltf_material, prim.color is not None, primary, tangents)
            if key not in mats:
                mats[key] = mi.load_dict(_material_dict(inst.asset, obj.gltf_material, scene.brdf, textures,
                                                        vertex_color=prim.color is not None, primary=primary,
                                                        tangents=tangents))
            bsdf = mats[key]
        props["bsdf"] = bsdf
        if bsdf_for is None:  # hook (issue 37): a transmissive material (its factors or textures), its volume
            from .transmission import gltf_shape_props
            core = lambda: _material_dict(inst.asset, obj.gltf_material, scene.brdf, textures,  # noqa: E731
                                          vertex_color=prim.color is not None, primary=primary)
            for k, v in gltf_shape_props(inst.asset.material(obj.gltf_material), scene.brdf, inst.asset, core,
                                         textures, texture_dict).items():
                props[k] = v
        if bsdf_for is None and inst.asset.material(obj.gltf_material).unlit:
            from .unlit import unlit_emitter
            props["emitter"] = unlit_emitter(bsdf)   # KHR_materials_unlit: the base colour, unshaded
        else:
            em = _emitter_dict(inst.asset, obj.gltf_material, textures)
            if em is not None:
                props["emitter"] = mi.load_dict(em)
        mesh = mi.Mesh(shape_id(obj.id), int(pos.shape[0]), int(tri.shape[0]), props,
                       has_vertex_normals=True, has_vertex_texcoords=uv0 is not None)
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(pos.astype(np.float32).reshape(-1))
        params["faces"] = mi.UInt32(np.ascontiguousarray(tri, np.uint32).reshape(-1))
        params["vertex_normals"] = mi.Float(nrm.astype(np.float32).reshape(-1))
        if uv0 is not None:
            params["vertex_texcoords"] = mi.Float(np.ascontiguousarray(uv0, np.float32).reshape(-1))
        params.update()
        if prim.tangents is not None:
            t = prim.tangents.astype(np.float64)
            t3 = t[:, :3] @ M[:3, :3].T
            t3 /= np.maximum(np.linalg.norm(t3, axis=1, keepdims=True), 1e-30)
            w = t[:, 3] * (1.0 if det > 0 else -1.0)
            mesh.add_attribute("vertex_tangent", 3, mi.Float(t3.astype(np.float32).reshape(-1)))
            mesh.add_attribute("vertex_tangent_w", 1, mi.Float(w.astype(np.float32)))
        if prim.color is not None:
            mesh.add_attribute("vertex_color", 3, mi.Float(np.ascontiguousarray(prim.color[:, :3], np.float32).reshape(-1)))
        for k, uv in enumerate(prim.texcoords):
            if uv is not None and k != primary:  # the other set: read by TexturedMaterial._lookup
                uvk = np.concatenate([uv, np.zeros((uv.shape[0], 1))], 1)
                mesh.add_attribute(f"vertex_uv{k}", 3, mi.Float(uvk.astype(np.float32).reshape(-1)))
        out[shape_id(obj.id)] = mesh
    return out
