"""Classify a folder of glTF assets by what pbrcheck does with them (issue 35's honesty contract):

- ``faithful``: it loads and every feature it uses is modelled (the reference and the real-time image
  render the asset as the file means it);
- ``named``: it loads, and uses features pbrcheck does not model (:attr:`pbrcheck.gltf.Asset.unmodelled`:
  extensions outside the modelled list, skins or morph targets until modelled): every command names
  them on stderr, the report marks them, the gate does not judge them; the table lists each with the
  materials it touches;
- ``refused``: the loader refuses it (a required extension it does not implement, a malformed file),
  one line and exit 2 in every command; the table gives that line.

There is no fourth class: a feature pbrcheck drops without naming it is a bug of
:mod:`pbrcheck.unmodelled` (its checks cover every extension and the core features of
:data:`pbrcheck.unmodelled.CORE_FEATURES`).

``python tools/classify_assets.py FOLDER`` prints the Markdown table (every ``.gltf`` / ``.glb``
under FOLDER, sorted by path, paths relative to FOLDER) and the counts; exit 0. docs/assets.md holds
its table for ``../shared/assets``.

API: :func:`classify` (one asset -> a row), :func:`classify_folder`, :func:`markdown_table`,
:data:`CLASSES`.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pbrcheck.errors import PbrcheckError  # noqa: E402
from pbrcheck.fmt import markdown_cell  # noqa: E402
from pbrcheck.gltf import load_asset  # noqa: E402
from pbrcheck.gltf_objects import is_asset_path  # noqa: E402
from pbrcheck.unmodelled import materials_text  # noqa: E402

#: The classes, in the table's order of counts.
CLASSES = ("faithful", "named", "refused")


def classify(path: Path) -> dict:
    """``{"asset", "class", "features": [(feature, materials)], "reason", "triangles"}`` of one asset."""
    try:
        a = load_asset(path)
    except PbrcheckError as e:
        return {"asset": str(path), "class": "refused", "features": [], "reason": str(e), "triangles": None}
    feats = [(u.feature, u.materials) for u in a.unmodelled]
    return {"asset": str(path), "class": "named" if feats else "faithful", "features": feats, "reason": "",
            "triangles": a.triangles}


def classify_folder(folder: Path) -> list[dict]:
    """:func:`classify` of every asset under ``folder`` (sorted by path; ``asset`` relative to it)."""
    folder = Path(folder)
    rows = []
    for p in sorted(q for q in folder.rglob("*") if q.is_file() and is_asset_path(q)):
        r = classify(p)
        r["asset"] = p.relative_to(folder).as_posix()
        rows.append(r)
    return rows


def _detail(r: dict, folder: Path) -> str:
    if r["class"] == "refused":
        return r["reason"].replace(str(Path(folder).resolve()) + "/", "").replace(str(folder) + "/", "")
    return "; ".join(f"{f} ({materials_text(ms)})" for f, ms in r["features"])


def markdown_table(rows: list[dict], folder: Path) -> str:
    """The Markdown table of ``rows`` (:func:`classify_folder`) and a line of counts."""
    out = ["| asset | class | triangles | features not modelled (materials) / reason refused |",
           "|---|---|---|---|"]
    for r in rows:
        tri = "" if r["triangles"] is None else str(r["triangles"])
        out.append(f"| {markdown_cell(r['asset'])} | {r['class']} | {tri} | {markdown_cell(_detail(r, folder))} |")
    counts = ", ".join(f"{sum(r['class'] == c for r in rows)} {c}" for c in CLASSES)
    return "\n".join(out) + f"\n\n{len(rows)} assets: {counts}.\n"


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not Path(argv[0]).is_dir():
        print("usage: python tools/classify_assets.py FOLDER", file=sys.stderr)
        return 2
    folder = Path(argv[0])
    print(markdown_table(classify_folder(folder), folder), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
