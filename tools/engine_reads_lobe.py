"""Does a web engine render a glTF lobe at all? Its render of a lobe's CI scene with and without the lobe.

``python tools/engine_reads_lobe.py LOBE ENGINE[,ENGINE...]`` renders compare/budgets/<LOBE>_ci.toml with
each ``ext:ENGINE`` twice: as it is (the lobe's extension exported) and with every lobe field removed
from its materials (the bare base material), and prints the mean absolute difference over the
spheres relative to the bare render's mean, and the largest one. An engine that ignores the
extension renders both alike (a difference at the level of float noise, e.g. from the ``TANGENT``
attribute pbrcheck exports with anisotropy alone); clients.toml gates an engine on a lobe scene
only where it renders the lobe (docs/renderers.md section 11). Renders go through the usual cache.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compare import renderers  # noqa: E402
from pbrcheck.lobe_params import SCENE_FIELD_EXTENSION  # noqa: E402
from pbrcheck.scene import load_scene, scene_from_dict  # noqa: E402

BUDGETS = ROOT / "compare" / "budgets"


def bare(scene):
    """``scene`` with every lobe field removed from its materials."""
    d = json.loads(json.dumps(scene.to_dict()))
    for o in d["objects"]:
        for k in [k for k in o["material"] if k in SCENE_FIELD_EXTENSION]:
            del o["material"][k]
    return scene_from_dict(d)


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    lobe, engines = argv[0], argv[1].split(",")
    scene = load_scene(BUDGETS / f"{lobe}_ci.toml")
    for e in engines:
        spec = renderers.RendererSpec.parse("ext:" + e, None)
        a, b = renderers.render_under_test(scene, spec), renderers.render_under_test(bare(scene), spec)
        on = np.rint(a.channels["object"]) >= 0
        diff = np.abs(a.rgb - b.rgb)
        print(f"{lobe} ext:{e}: mean |with - without| / mean(without) = "
              f"{diff[on].mean() / max(float(b.rgb[on].mean()), 1e-12):.3g}, max {diff.max():.3g}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
