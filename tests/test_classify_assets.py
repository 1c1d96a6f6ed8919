"""tools/classify_assets.py: faithful / named (with the features and materials) / refused (with the
loader's reason), on a folder of small assets built here."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from tests.test_unmodelled import COAT, coated_asset

_spec = importlib.util.spec_from_file_location("classify_assets",
                                               Path(__file__).resolve().parents[1] / "tools" / "classify_assets.py")
classify_assets = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(classify_assets)


@pytest.mark.usefixtures("lobes_unmodelled")  # the lobes as unmodelled extensions
def test_classify_a_folder(tmp_path, capsys):
    coated_asset(tmp_path / "plain.gltf", used=("KHR_xmp",), coat=False)       # metadata only: faithful
    coated_asset(tmp_path / "sub" / "coated.gltf")
    req = coated_asset(tmp_path / "required.gltf", used=("KHR_materials_sheen",), coat=False)
    doc = json.loads(req.read_text())
    doc["extensionsRequired"] = ["KHR_materials_sheen"]
    req.write_text(json.dumps(doc))
    (tmp_path / "junk.glb").write_bytes(b"glTF\x02\x00\x00\x00junk")
    (tmp_path / "notes.txt").write_text("not an asset")
    rows = classify_assets.classify_folder(tmp_path)
    assert [(r["asset"], r["class"]) for r in rows] == [
        ("junk.glb", "refused"), ("plain.gltf", "faithful"), ("required.gltf", "refused"), ("sub/coated.gltf", "named")]
    assert rows[3]["features"] == [(COAT, ("coated",))] and rows[3]["triangles"] == 4 and rows[1]["features"] == []
    assert "required extension KHR_materials_sheen is not supported" in rows[2]["reason"]
    assert classify_assets.main([str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| sub/coated.gltf | named | 4 | KHR\\_materials\\_clearcoat (coated) |" in out
    assert "| required.gltf | refused |  | required.gltf: /extensionsRequired/0: required extension" in out
    assert out.endswith("4 assets: 1 faithful, 1 named, 2 refused.\n")
    assert classify_assets.main([str(tmp_path / "notes.txt")]) == 2
