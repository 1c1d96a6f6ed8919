"""The honesty contract's lobe list is what both renderers render (issue 36).

The core (``pbrcheck.lobe_params.MODELLED_LOBE_EXTENSIONS``) cannot import the renderers, so this test
holds it to the intersection of the reference's and the real-time renderer's own sets: an extension
one renderer drops must leave the list (and be named as unmodelled again)."""
from __future__ import annotations

from pbrcheck import lobe_params as lp
from pbrcheck.gltf import MODELLED_EXTENSIONS
from pbrcheck.scene import load_scene
from pbrcheck.unmodelled import scene_unmodelled
from realtime.lobes import REALTIME_LOBES
from reference.lobe_bsdf import REFERENCE_LOBES


def test_modelled_lobes_are_what_both_renderers_render():
    assert set(lp.MODELLED_LOBE_EXTENSIONS) == set(REFERENCE_LOBES) & set(REALTIME_LOBES)
    assert set(lp.MODELLED_LOBE_EXTENSIONS) == set(lp.LOBE_EXTENSIONS)  # all five, today
    assert set(lp.MODELLED_LOBE_EXTENSIONS) <= set(MODELLED_EXTENSIONS)


def test_the_built_in_lobe_scenes_are_judged():
    for name in ("clearcoat", "sheen", "specular", "anisotropy", "iridescence"):
        scene = load_scene(name)
        assert any(lp.scene_features(o.material) for o in scene.objects if hasattr(o, "material")), name
        assert not scene_unmodelled(scene), (name, scene_unmodelled(scene))
