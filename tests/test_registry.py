"""The closed lists are registries (pbrcheck.registry, realtime.registry; the LOD mappings' and the DFG
LUT strategies' beside their numpy functions): the docs' tables, the options' choices, the scene
model, the three languages' implementations, the generated GLSL and the shaders agree with them;
each LOD mapping's GLSL pair matches its numpy twin on a grid including roughness 0, 1e-6 and 1;
``pbrcheck shaders --dump`` writes what every program compiles."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from pbrcheck import lodmap, registry, scene
from realtime import generated, presets
from realtime import registry as rt_registry
from realtime.gl import SHADER_DIR, assemble

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "realtime.md"
# float32 against float64 (see test_realtime_glsl.RTOL_F32), plus log2/exp2 of llvmpipe.
RTOL_F32 = 2e-5
ATOL_F32 = 2e-5


def _doc_row(first_cell: str) -> list[str]:
    for line in DOC.read_text().splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
        if cells and cells[0] == first_cell:
            return cells
    raise AssertionError(f"docs/realtime.md has no table row for {first_cell}")


@pytest.mark.parametrize("define", list(rt_registry.REGISTRIES))
def test_docs_registry_table_lists_every_member_in_order(define):
    cells = _doc_row(f"`{define}`")
    assert re.findall(r"`([^`]+)`", cells[1]) == list(rt_registry.REGISTRIES[define].names)


def _options_rows() -> dict[str, tuple[int, list[str]]]:
    """docs/realtime.md's options table: each option named in a row's first cell, with its position
    among the row's options and the row's cells (a grouped row names several: `lut_size`, ...)."""
    rows = {}
    for line in DOC.read_text().splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
        names = re.findall(r"`([a-z0-9_]+)`", cells[0]) if len(cells) == 3 else []
        for i, name in enumerate(names):
            if name in presets.OPTIONS:
                rows.setdefault(name, (i, cells))
    return rows


def test_docs_options_table_names_every_choice():
    """Every choice option has a row of the options table. A row of its own lists the option's
    choices (its registry's); a grouped row (`ndf`, `geometry`, `fresnel` | scene) gives each
    option's default at the option's place in the values cell (one value: shared by all)."""
    rows = _options_rows()
    choice = [name for name, opt in presets.OPTIONS.items() if opt.kind == "choice"]
    assert not set(choice) - set(rows), sorted(set(choice) - set(rows))
    grouped = 0
    for name in choice:
        i, cells = rows[name]
        choices = [c for c in presets.OPTIONS[name].choices if c != "scene"]
        values = cells[1].split(", ")
        if len(re.findall(r"`([a-z0-9_]+)`", cells[0])) == 1:
            listed = [c.strip() for c in cells[1].split("(")[0].split("\\|")]
            assert [c for c in listed if c in choices] == choices, (name, listed, choices)
        else:
            grouped += 1
            value = values[i] if len(values) > 1 else values[0]
            listed = [c.strip() for c in value.split("\\|")]
            default = presets.OPTIONS[name].default
            assert str(default) in listed, (name, value, default)
    assert grouped >= 8  # lut_format, lut_geometry, lut_sampling, runtime_sampling, ndf, geometry, fresnel, tonemap


def test_options_and_scene_read_the_registry():
    assert presets.OPTIONS["shading"].choices == rt_registry.SHADINGS.names
    assert presets.OPTIONS["lod_mapping"].choices == lodmap.BUILTIN_LOD_MAPPINGS
    assert presets.OPTIONS["geometry"].choices == ("scene", *registry.GEOMETRIES.names)
    assert scene.NDF_NAMES == registry.NDFS.scene_names
    assert scene.GEOMETRY_NAMES == registry.GEOMETRIES.scene_names and "schlick_beckmann" not in scene.GEOMETRY_NAMES


def _switch_comparisons(sources: dict[str, str]) -> tuple[list[str], list[str]]:
    """(named, bare): each ``#if``/``#elif SWITCH == X`` line on a registry switch of ``sources`` (name
    -> text), X a constant or an integer."""
    named, bare = [], []
    for name, text in sources.items():
        for i, line in enumerate(text.splitlines(), 1):
            m = re.match(r"\s*#\s*(el)?if\s+([A-Z_]+)\s*==\s*(\w+)", line)
            if m and m.group(2) in rt_registry.REGISTRIES:
                (bare if m.group(3).isdigit() else named).append(f"{name}:{i}: {line.strip()}")
    return named, bare


def test_shaders_switch_on_named_constants_only():
    """No ``#if SWITCH == <integer>`` is left in the shaders or the generated includes: every
    comparison names a constant (and there are comparisons to check: the check itself finds an
    integer one)."""
    sources = {p.name: p.read_text() for p in SHADER_DIR.iterdir()} | generated.glsl_generated()
    named, bare = _switch_comparisons(sources)
    assert not bare, bare
    assert len(named) > 40, named  # the generated dispatch alone compares every member of every switch
    assert _switch_comparisons({"x.glsl": "#if NDF == 1\n"})[1] == ["x.glsl:1: #if NDF == 1"]


def test_every_shader_gets_every_constant():
    src = assemble("render.comp", registry.GEOMETRIES.select("smith_ggx")).text
    for k, v in generated.glsl_defines().items():
        assert f"#define {k} {v}\n" in src
    assert "#define GEOMETRY GEOMETRY_SMITH_GGX\n" in src


def test_lod_dispatch_is_generated_for_every_builtin_mapping():
    text = generated.glsl_generated()["lod_dispatch.glsl"]
    for name in lodmap.BUILTIN_LOD_MAPPINGS:
        assert f"return lod_{name}(r, max_lod, cube_log2);" in text
        assert f"return roughness_{name}(lod, max_lod, cube_log2);" in text
        roles = lodmap.LOD_MAPPINGS[name].roles
        assert [roles["lod"].glsl, roles["roughness"].glsl] == [f"lod_{name}", f"roughness_{name}"]
        assert getattr(lodmap, roles["lod"].glsl) is roles["lod"].numpy


@pytest.mark.parametrize("name", lodmap.BUILTIN_LOD_MAPPINGS)
def test_lod_mapping_glsl_matches_numpy_twin(name):
    from realtime.glsl_harness import run_glsl

    r = np.array([0.0, 1e-6, 1e-3, 0.01, 0.1, 0.25, 0.5, 0.75, 0.99, 1.0, 1.5])
    for max_lod, cube_log2 in ((6.0, 8.0), (8.0, 9.0), (4.0, 4.0)):
        roles = lodmap.LOD_MAPPINGS[name].roles
        want = roles["lod"].numpy(r, max_lod, cube_log2)
        got = run_glsl(f"lod_{name}(x0, x1, x2)", r, max_lod, cube_log2)
        np.testing.assert_allclose(got, want, rtol=RTOL_F32, atol=ATOL_F32)
        lods = np.linspace(0.0, max_lod, 13)
        want = roles["roughness"].numpy(lods, max_lod, cube_log2)
        got = run_glsl(f"roughness_{name}(x0, x1, x2)", lods, max_lod, cube_log2)
        np.testing.assert_allclose(got, want, rtol=RTOL_F32, atol=ATOL_F32)


@pytest.mark.parametrize("name", lodmap.BUILTIN_LOD_MAPPINGS)
def test_dispatch_selects_the_mapping(name):
    from realtime.glsl_harness import run_glsl

    r = np.array([0.0, 0.3, 1.0])
    got = run_glsl("lod_from_roughness(x0, x1, x2)", r, 6.0, 8.0, defines=lodmap.LOD_MAPPINGS.select(name))
    np.testing.assert_allclose(got, lodmap.builtin_lod(name, r, 6.0, 8.0), rtol=RTOL_F32, atol=ATOL_F32)


def test_registry_rejects_unknown_members():
    with pytest.raises(KeyError):
        registry.GEOMETRIES.constant("smith_typo")
    with pytest.raises(lodmap.LodFitError, match="lod_mapping"):
        lodmap.builtin_lod("fitted", [0.5], 6.0, 8.0)


#: Each term registry's Dr.Jit twin (reference.terms), by GLSL switch.
DRJIT_TERMS = {"NDF": "NDFS", "GEOMETRY": "GEOMETRIES", "FRESNEL": "FRESNELS"}


@pytest.mark.parametrize("define", list(rt_registry.TERM_REGISTRIES))
def test_every_term_has_its_three_implementations(define):
    """Each member of a term registry holds its numpy class (pbrcheck.terms) with the methods of its
    kind; the reference's registry (reference.terms) keys the same members, each with the Dr.Jit class
    of the numpy class's name and the same methods; the GLSL names the class holds are functions of
    brdf.glsl (an NDF's sampler of sampling.glsl) that the generated dispatch calls; the GLSL harness
    twins every member (tests/test_realtime_glsl.py's test_ndf_twins, test_g2_twins and
    test_fresnel_twins are parametrized by these entries)."""
    import test_realtime_glsl as harness
    from pbrcheck import brdf
    from reference.variant import ensure_variant
    ensure_variant()
    from reference import terms as drjit_terms
    reg = rt_registry.TERM_REGISTRIES[define][0]
    drjit_reg = getattr(drjit_terms, DRJIT_TERMS[define])
    assert list(drjit_reg) == list(reg.names)
    brdf_glsl = (SHADER_DIR / "brdf.glsl").read_text()
    sampling_glsl = (SHADER_DIR / "sampling.glsl").read_text()
    dispatch = generated.glsl_generated()["terms_dispatch.glsl"]
    methods = {"NDF": ("eval", "sample", "pdf", "theta_h", "cdf_theta_h"), "GEOMETRY": ("eval", "width"),
               "FRESNEL": ("eval",)}[define]
    drjit_methods = {"NDF": ("eval", "sample", "pdf", "sample_cos"), "GEOMETRY": ("eval", "width"),
                     "FRESNEL": ("eval",)}[define]
    for e in reg:
        t, d = e.term, drjit_reg[e.name]
        assert isinstance(t, type) and d.__name__ == t.__name__, (e.name, t, d)
        assert all(callable(getattr(t, m)) for m in methods), (e.name, methods)
        assert all(callable(getattr(d, m)) for m in drjit_methods), (e.name, drjit_methods)
        assert re.search(rf"^\w+ {t.glsl}\(", brdf_glsl, re.M), (e.name, t.glsl)
        assert getattr(brdf, t.glsl, t.eval) is t.eval, f"{e.name}: pbrcheck.brdf's {t.glsl} is another function"
        if t.glsl_width:
            assert t.width.__name__ == t.glsl_width and re.search(rf"^float {t.glsl_width}\(", brdf_glsl, re.M)
        assert f"{reg.constant(e.name)}\n    return {t.glsl}(" in dispatch
        if define == "NDF":  # its sampler's GLSL twin, explain's exact runtime strategy, the random walk
            from pbrcheck import sampling
            assert getattr(sampling, t.glsl_sample, t.sample) is t.sample, t.glsl_sample
            assert re.search(rf"^vec3 {t.glsl_sample}\(", sampling_glsl, re.M), t.glsl_sample
            assert "runtime_sampling" not in e.extra or e.extra["runtime_sampling"] in rt_registry.RUNTIME_SAMPLINGS
            walk = "walk_geometry" in e.extra
            assert not walk or e.extra["walk_geometry"] in registry.GEOMETRIES, e.name
            assert (t.Lambda is not None) >= walk and (d.Lambda is not None, d.sample_visible is not None) >= (walk, walk)
    twins = {"NDF": harness.test_ndf_twins, "GEOMETRY": harness.test_g2_twins,
             "FRESNEL": harness.test_fresnel_twins}[define]
    params = [m.args for m in twins.pytestmark if m.name == "parametrize"][0][1]
    assert {p.name for p in params} == set(reg.names)


def test_term_dispatch_matches_the_registry_in_numpy():
    """pbrcheck.brdf's dispatch is the registry's: each member's class at its width."""
    from pbrcheck import brdf
    c, r = np.linspace(0.05, 1.0, 7), np.linspace(0.0, 1.0, 7)
    for e in registry.GEOMETRIES:
        np.testing.assert_array_equal(brdf.geometry_term(e.name, c, c[::-1], r), e.term.eval(c, c[::-1], e.term.width(r)))
    for e in registry.NDFS:
        np.testing.assert_array_equal(brdf.ndf_term(e.name, c, r), e.term.eval(c, brdf.alpha_from_roughness(r)))
    with pytest.raises(ValueError, match="unknown geometry term 'nope'"):
        brdf.geometry_term("nope", c, c, r)


# The role registries' languages: the numpy module of the members' functions, the one of the numpy
# dispatch by name (the registry's module), the reference's Dr.Jit table (None: a real-time
# approximation the reference does not make), the GLSL file.
ROLE_HOMES = {"ENERGY_COMPENSATION": ("pbrcheck.energy", "realtime.dispatch", "reference.energy.ROLES", "energy.glsl"),
              "RUNTIME_SAMPLING": ("pbrcheck.sampling", "realtime.dispatch", "reference.sampling.RUNTIME_ROLES",
                                   "sampling.glsl"),
              "LUT_SAMPLING": ("pbrcheck.sampling", "pbrcheck.sampling", "reference.sampling.LUT_ROLES", "sampling.glsl"),
              "SPECULAR_OCCLUSION": ("pbrcheck.occlusion", "realtime.dispatch", None, "occlusion.glsl"),
              "HORIZON_OCCLUSION": ("pbrcheck.occlusion", "realtime.dispatch", None, "occlusion.glsl"),
              "SPECULAR_AA": ("pbrcheck.specular_aa", "realtime.dispatch", None, "specular_aa.glsl")}
#: The real-time-only role registries, twinned by test_realtime_role_twins below.
REALTIME_ROLES = [d for d, (_, _, dr, _) in ROLE_HOMES.items() if dr is None]


def _offered(option: str, value) -> bool:
    o = presets.OPTIONS[option]
    return value in o.choices if o.kind == "choice" else o.lo <= value <= o.hi


def test_requirements_name_options_and_resolve_options_enforces_them():
    """A member's requirements (Entry.requires) and an option value's (Option.requires: msaa,
    alpha_to_coverage) name real-time options and values they offer; resolve_options accepts the
    value with them and refuses it, naming it, without them (a DEFERRED value, pipeline=auto, is
    left to the render)."""
    checked = 0
    chosen = [(name, e.name, e.name, e.requires) for name, reg in presets.OPTION_REGISTRIES.items() for e in reg]
    on = {"bool": True, "int": 4}
    chosen += [(name, on[o.kind], str(on[o.kind]).lower(), o.requires) for name, o in presets.OPTIONS.items()
               if o.requires]
    for name, reg in presets.OPTION_REGISTRIES.items():
        assert set(presets.OPTIONS[name].choices) - {"scene"} <= set(reg.names), name
    for name, value, shown, requires in chosen:
        for k, accepted in requires.items():
            assert accepted and all(_offered(k, a) for a in accepted), (name, value, k)
            presets.resolve_options("default", {name: value, **{r: v[0] for r, v in requires.items()}})
            other = next(c for c in (presets.OPTIONS[k].choices or (1,)) if c not in accepted
                         and presets.DEFERRED.get(k) != c)
            # refused naming the value, or a value it requires that needs the same (a2c's msaa: the pipeline)
            named = "|".join([f"{name}: {shown}", *(f"{r}: \\S+" for r in requires)])
            with pytest.raises(presets.OptionError, match=rf"^option ({named}) needs .*{k}=.*, found .*{k}={other}"):
                presets.resolve_options("default", {name: value, **{r: v[0] for r, v in requires.items()}, k: other})
            checked += 1
    assert checked >= 9  # compositions' ibl, compensations' shading and ibl, screen_space's, msaa's, a2c's pipeline


def test_a_deferred_requirement_is_checked_once_resolved():
    """pipeline=auto accepts the raster-only values; the render refuses them where auto resolves to
    the ray-cast pipeline (analytic scenes) and accepts them where it resolves to raster."""
    from realtime.render import check_pipeline_options
    for over in ({"specular_aa": "screen_space"}, {"msaa": 4}, {"msaa": 2, "alpha_to_coverage": True}):
        o = presets.resolve_options("default", {"pipeline": "auto", **over})
        check_pipeline_options("raster", o)
        with pytest.raises(presets.OptionError, match=r"needs pipeline=raster.*, found pipeline=raycast"):
            check_pipeline_options("raycast", o)


def test_every_closed_list_owns_its_implementations_or_says_where_it_applies():
    """Each member of every registry carries its functions (a term class, or roles) or its list states
    where it applies and why it has none (a switch of one renderer's own code)."""
    assert set(ROLE_HOMES) == set(rt_registry.ROLE_REGISTRIES)
    for define, reg in rt_registry.REGISTRIES.items():
        owned = [e.name for e in reg if e.term is not None or e.roles]
        if define == "LOD_MAPPING":  # the built-in mappings' lod and roughness (the fitted one reads a file)
            assert owned == list(lodmap.BUILTIN_LOD_MAPPINGS) and len(reg.applies_to) > 20
        elif define in rt_registry.TERM_REGISTRIES or define in rt_registry.ROLE_REGISTRIES:
            assert not reg.applies_to, define
            assert all(e.name in owned or e.applies_to for e in reg), (define, owned)
        else:
            assert not owned and len(reg.applies_to) > 20, (define, reg.applies_to)


@pytest.mark.parametrize("define", list(rt_registry.ROLE_REGISTRIES))
def test_every_role_member_has_its_three_implementations(define):
    """Each role of each member holds its numpy function (in the module that holds the list) and
    names its GLSL twin of the same name, which the generated dispatch calls; the reference's table
    (where it has one) keys the same members and roles with Dr.Jit twins of that name; a member
    without a role states where it applies; the
    GLSL harness twins every (member, role) (tests/test_energy.py's test_role_twins and
    tests/test_realtime_sampling.py's test_strategy_twins are parametrized by these)."""
    import importlib

    import test_energy
    import test_realtime_sampling
    from reference.variant import ensure_variant
    ensure_variant()
    reg, include, _, roles = rt_registry.ROLE_REGISTRIES[define]
    np_mod, dispatch_mod, dr_table, glsl_file = ROLE_HOMES[define]
    numpy_mod, dispatcher = importlib.import_module(np_mod), importlib.import_module(dispatch_mod)
    drjit_mod, drjit = (None, None)
    if dr_table:  # the reference's table of the same members (reference.energy.ROLES, ...)
        mod, table = dr_table.rsplit(".", 1)
        drjit_mod = importlib.import_module(mod)
        drjit = getattr(drjit_mod, table)
        assert list(drjit) == list(reg.names) and all(set(drjit[e.name]) == set(e.roles) for e in reg), define
    home = "realtime.registry" if dispatch_mod == "realtime.dispatch" else dispatch_mod  # where the list lives
    assert getattr(importlib.import_module(home), reg.define + "S") is reg
    glsl = (SHADER_DIR / glsl_file).read_text()
    dispatch = generated.glsl_generated()[include]
    assert f'#include "{include}"' in glsl
    for role, (signature, identity) in roles.items():
        assert signature + " {" in dispatch
        assert callable(getattr(dispatcher, role)) and (not drjit_mod or callable(getattr(drjit_mod, role))), role
    for e in reg:
        assert set(e.roles) <= set(roles), e.name
        missing = set(roles) - set(e.roles)
        assert not missing or (e.applies_to and all(roles[r][1] for r in missing)), (e.name, missing)
        for role, r in e.roles.items():
            assert r.numpy.__name__ == r.glsl and r.glsl.startswith(f"{role}_"), r
            assert getattr(numpy_mod, r.glsl) is r.numpy, r.glsl
            if drjit:  # the Dr.Jit twin has the GLSL twin's name
                assert drjit[e.name][role].__name__ == r.glsl, (e.name, role, drjit[e.name][role])
            else:  # the entry says why the reference has none
                assert "no Dr.Jit function" in e.applies_to, (e.name, e.applies_to)
            params = [p.split()[-1] for p in roles[role][0].split("(")[1][:-1].split(",")]
            assert [p for p in params if p in r.args] == list(r.args), r.args  # in the dispatch's order
            assert re.search(rf"^\w+ {r.glsl}\(", glsl, re.M), r.glsl
            assert f"{reg.constant(e.name)}\n    return {r.glsl}(" in dispatch
    twins = {"ENERGY_COMPENSATION": test_energy.test_role_twins}.get(
        define, test_realtime_role_twins if define in REALTIME_ROLES else test_realtime_sampling.test_strategy_twins)
    params = [m.args for m in twins.pytestmark if m.name == "parametrize"][0][1]
    covered = {p if len(p) == 2 else p[1:] for p in params if len(p) == 2 or p[0] == define}
    assert covered == {(e.name, r) for e in reg for r in e.roles}


#: The real-time roles' parameters on grids including the extremes (roughness, n.v, ao 0..1 with
#: 1e-4 and 0.999; r.n_g -1..1 with the fade's end and +-1e-6; normal length 1e-4..1.5; variances 0..4).
_UNIT = np.concatenate([np.linspace(0.0, 1.0, 11), [1e-4, 0.999]])
PARAM_GRIDS = {"NoV": _UNIT, "ao": _UNIT, "roughness": _UNIT,
               "RoNg": np.concatenate([np.linspace(-1.0, 1.0, 41), [-1 / 1.3, -1e-6, 0.0, 1e-6]]),
               "normal_length": np.array([1e-4, 0.01, 0.5, 0.95, 1.0, 1.001, 1.5]),
               "variance": np.array([0.0, 1e-8, 1e-4, 0.1, 1.0, 4.0]), "dn2": np.array([0.0, 1e-6, 0.01, 0.5, 4.0])}


@pytest.mark.parametrize("define, name, role", [(d, e.name, r) for d in REALTIME_ROLES
                                                for e in rt_registry.ROLE_REGISTRIES[d][0] for r in e.roles])
def test_realtime_role_twins(define, name, role):
    """Each real-time approximation's role function (GLSL) against its numpy twin of the same name,
    and the generated GLSL dispatch selecting the member against the numpy dispatch looping the
    registry, on grids including the extremes (test_occlusion's and test_specular_aa's tolerances)."""
    import importlib

    import test_occlusion
    import test_specular_aa
    from realtime.glsl_harness import run_glsl
    reg, _, _, roles = rt_registry.ROLE_REGISTRIES[define]
    impl = reg[name].roles[role]
    params = [p.split()[-1] for p in roles[role][0].split("(")[1][:-1].split(",")]
    grids = dict(zip(params, np.meshgrid(*(PARAM_GRIDS[p] for p in params), indexing="ij")))
    dispatcher = importlib.import_module(ROLE_HOMES[define][1])
    atol = {"gtso": test_occlusion.GTSO_ATOL}.get(name, min(test_occlusion.GLSL_ATOL, test_specular_aa.GLSL_ATOL))
    own = [grids[a] for a in impl.args or params]
    got = run_glsl(f"{impl.glsl}({', '.join(f'x{i}' for i in range(len(own)))})", *own)
    np.testing.assert_allclose(got, impl.numpy(*own), rtol=0, atol=atol)
    got = run_glsl(f"{role}({', '.join(f'x{i}' for i in range(len(params)))})", *grids.values(),
                   defines=reg.select(name))
    np.testing.assert_allclose(got, getattr(dispatcher, role)(*grids.values(), name), rtol=0, atol=atol)


#: The real-time approximations' GLSL term files (issue 23): each one's numpy home and the test files
#: whose GLSL harness calls (``run_glsl("NAME(...)"``) compare a function that is no role member's.
APPROXIMATION_TERM_FILES = {"occlusion.glsl": ("pbrcheck.occlusion", ("test_occlusion.py",)),
                            "specular_aa.glsl": ("pbrcheck.specular_aa", ("test_specular_aa.py",)),
                            "coverage.glsl": ("pbrcheck.coverage", ("test_specular_aa.py",)),
                            "texcoord.glsl": ("pbrcheck.gltf", ("test_gltf_wrap.py",))}
#: raster.frag's own functions: pipeline plumbing with no closed form to twin (texture lookups through
#: derivatives and the fragment's varyings, textureQueryLod, the raster pipeline's absent shadow rays).
#: A closed-form term goes to a term file above, with its twin.
RASTER_PLUMBING = {"occluded", "lookup", "normal_map_lod", "slot", "main"}


@pytest.mark.parametrize("glsl_file", list(APPROXIMATION_TERM_FILES))
def test_every_approximation_glsl_function_has_a_harness_compared_twin(glsl_file):
    """Every function an approximation's GLSL file defines has a numpy twin of the same name, and is
    compared with it by the GLSL harness: as a role member (test_realtime_role_twins, parametrized by
    the registry) or by a ``run_glsl("NAME(`` call of the listed tests. A function added without
    both fails here."""
    import importlib
    np_mod, test_files = APPROXIMATION_TERM_FILES[glsl_file]
    module = importlib.import_module(np_mod)
    glsl = re.sub(r"//[^\n]*", "", (SHADER_DIR / glsl_file).read_text())
    names = re.findall(r"^\w+\s+(\w+)\s*\([^;{)]*\)\s*\{", glsl, re.M)
    assert names, glsl_file
    roles = {impl.glsl for d in REALTIME_ROLES for e in rt_registry.ROLE_REGISTRIES[d][0] for impl in e.roles.values()}
    calls = "\n".join((ROOT / "tests" / f).read_text() for f in test_files)
    for name in names:
        assert callable(getattr(module, name, None)), f"{glsl_file}: {name} has no numpy twin in {np_mod}"
        assert name in roles or re.search(rf'run_glsl\(\s*f?"{name}\(', calls), \
            f"{glsl_file}: {name} is compared with its twin by no GLSL harness test ({', '.join(test_files)})"


def test_the_raster_pass_defines_plumbing_only():
    """Every function raster.frag defines is RASTER_PLUMBING's (its terms live in the term files that
    the harness compiles and test_every_approximation_glsl_function_has_a_harness_compared_twin checks)."""
    frag = re.sub(r"//[^\n]*", "", (SHADER_DIR / "raster.frag").read_text())
    assert set(re.findall(r"^\w+\s+(\w+)\s*\([^;{)]*\)\s*\{", frag, re.M)) == RASTER_PLUMBING


def test_the_generated_normal_roughness_hook_is_harness_compared():
    """The hook_specular_aa that ``pbrcheck fit-normal-roughness`` writes (NormalRoughnessTable.glsl) is
    compared with NormalRoughnessTable.__call__ by the harness on tables of one and several levels."""
    import test_fit_normal_roughness as fit
    params = [m.args for m in fit.test_generated_hook_glsl_matches_its_numpy_twin.pytestmark
              if m.name == "parametrize"][0][1]
    assert any(len(t) == 1 for t in params) and any(len(t) > 2 for t in params)
    assert any(0.0 in t for t in params) and max(max(t) for t in params) >= 1.0
    assert fit.TWIN_LODS.min() < 0 and fit.TWIN_LODS.max() > max(len(t) for t in params)
    assert {0.0, 1.0} <= set(fit.TWIN_ROUGHNESS)


@pytest.mark.parametrize("define", list(rt_registry.ROLE_REGISTRIES))
def test_role_dispatch_selects_each_member_and_no_hand_ladder_is_left(define):
    """The shaders select a role registry's member only in its generated dispatch (no hand
    ``#if SWITCH == MEMBER`` ladder; shading.glsl's ``!= ENERGY_COMPENSATION_NONE`` guard remains)."""
    for p in SHADER_DIR.iterdir():
        assert not re.search(rf"^\s*#\s*(el)?if\b.*\b{define}\s*==", p.read_text(), re.M), p.name
    reg, include, default, roles = rt_registry.ROLE_REGISTRIES[define]
    text = generated.glsl_generated()[include]
    reads = any(i.args for e in reg for i in e.roles.values())  # and the SWITCH_READS_<INPUT> block
    assert text.count(f"== {define}_") == len(reg.names) * (len(roles) + reads)
    assert f"#define {define} {reg.constant(default)}\n" in text


def test_docs_role_table_lists_every_member_and_its_functions():
    """docs/realtime.md's role table: one row per member of a role registry, naming its functions."""
    for define, (reg, *_rest) in rt_registry.ROLE_REGISTRIES.items():
        for e in reg:
            cells = _doc_row(f"{define}: {e.name}")
            listed = [f for f in re.findall(r"`([^`]+)`", cells[1]) if "." not in f]
            assert listed == list(dict.fromkeys(i.glsl for i in e.roles.values())), (define, e.name, listed)


def test_composition_dispatch_is_generated_and_no_shading_ladder_is_left():
    """shading.glsl defines shade_<name> and light_brdf_<name> for every composition; the generated
    shade_composition / light_brdf call them (the pixel seed to the seeded ones); no shader holds a
    hand ``#if SHADING ==`` ladder."""
    text = generated.glsl_generated()["shading_dispatch.glsl"]
    shading = (SHADER_DIR / "shading.glsl").read_text()
    assert '#include "shading_dispatch.glsl"' in shading
    for e in rt_registry.SHADINGS:
        seed = ", pixel_seed" if e.extra["seeded"] else ""
        assert re.search(rf"^vec3 shade_{e.name}\(Shading c{', uint pixel_seed' if seed else ''}\)", shading, re.M)
        assert re.search(rf"^vec3 light_brdf_{e.name}\(Shading c, vec3 l, float NoL\)", shading, re.M)
        assert f"{rt_registry.SHADINGS.constant(e.name)}\n    return shade_{e.name}(c{seed});" in text
        assert f"{rt_registry.SHADINGS.constant(e.name)}\n    return light_brdf_{e.name}(c, l, NoL);" in text
    for p in SHADER_DIR.iterdir():
        assert not re.search(r"^\s*#\s*(el)?if\b.*\bSHADING\s*==", p.read_text(), re.M), p.name


def _expand_from(folder: Path, name: str, seen: set) -> list[str]:
    """``name``'s lines with every ``#include`` expanded once from ``folder`` alone (assemble's rule)."""
    if name in seen:
        return []
    seen.add(name)
    out = []
    for line in (folder / name).read_text().splitlines():
        m = re.match(r'^\s*#\s*include\s+"([^"]+)"\s*$', line)
        out += [*_expand_from(folder, m.group(1), seen), f"// end of {m.group(1)}"] if m else [line]
    return out


def test_shaders_dump_writes_what_every_program_compiles(tmp_path):
    """``pbrcheck shaders --dump DIR`` writes every shader file, every generated include and the
    registries' defines: each entry program assembled from the dumped folder alone is the text
    realtime.gl.assemble compiles; a second dump replaces the files; a file in the way is exit 2."""
    from pbrcheck_cli import main
    from realtime.gl import DEFINES_FILE
    out = tmp_path / "glsl"
    assert main(["shaders", "--dump", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {p.name for p in SHADER_DIR.iterdir()} | set(generated.glsl_generated()) | {DEFINES_FILE, "README.txt"}
    assert "registry_defines.glsl" in (out / "README.txt").read_text()
    entries = sorted(p.name for p in SHADER_DIR.iterdir() if p.suffix in (".comp", ".vert", ".frag"))
    assert len(entries) >= 14
    for entry in entries:
        text = (out / DEFINES_FILE).read_text() + "\n".join(_expand_from(out, entry, set())) + "\n"
        assert text == assemble(entry).text, entry
    (out / "brdf.glsl").write_text("stale")
    assert main(["shaders", "--dump", str(out)]) == 0
    assert (out / "brdf.glsl").read_text() == (SHADER_DIR / "brdf.glsl").read_text()
    (tmp_path / "file").write_text("x")
    assert main(["shaders", "--dump", str(tmp_path / "file")]) == 2
