"""MikkTSpace tangents (pbrcheck.mikktspace: the reference C implementation) and glTF's use of them
(pbrcheck.gltf.generate_tangents: per corner, vertices split where MikkTSpace splits them)."""
from __future__ import annotations

import numpy as np

from pbrcheck.gltf import generate_tangents, load_asset
from pbrcheck.mikktspace import corner_tangents

from gltf_build import Doc

# Two quads side by side in z = 0 sharing the seam x = 0 (vertices 1 and 4 shared by index); the
# UVs are mirrored about the seam: u grows to +x on the left, to -x on the right; v grows to -y.
SEAM_POS = np.array([[-1, -1, 0], [0, -1, 0], [1, -1, 0], [-1, 1, 0], [0, 1, 0], [1, 1, 0]], np.float32)
SEAM_UV = np.array([[0, 1], [1, 1], [0, 1], [0, 0], [1, 0], [0, 0]], np.float32)
SEAM_NRM = np.array([[0, 0, 1]] * 6, np.float32)
SEAM_TRI = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]], np.uint32)


def test_mirrored_seam_splits_vertices():
    tan, src, tri = generate_tangents(SEAM_POS, SEAM_NRM, SEAM_UV, SEAM_TRI)
    # 6 input vertices; the 2 on the seam are split (one per side): 8 output vertices
    assert len(tan) == 8 and sorted(src.tolist()) == [0, 1, 1, 2, 3, 4, 4, 5]
    assert np.array_equal(src[tri], SEAM_TRI)           # same triangles over the same positions
    left = tri[:2].reshape(-1)
    right = tri[2:].reshape(-1)
    assert not set(left) & set(right)                     # no vertex shared across the mirror
    # left: T = +x (du/dx > 0); right: T = -x; the bitangent (glTF: up the image, +y) is the same on
    # both sides, so the handedness flips: w (N x T) = +y -> w = +1 left, -1 right
    assert np.allclose(tan[left], [1, 0, 0, 1], atol=1e-6)
    assert np.allclose(tan[right], [-1, 0, 0, -1], atol=1e-6)


def test_affine_uvs_give_the_projected_u_direction():
    """On a bent strip with an affine UV map per face, MikkTSpace's corner tangent is dP/du
    orthogonalised against the vertex normal (the definition the reference implementation computes);
    checked here independently on a skewed map."""
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0.5]], np.float32)
    # u = x + 0.5 y, v = -y (a skewed map): dP/du solves the 2x2 system per triangle
    uv = np.stack([pos[:, 0] + 0.5 * pos[:, 1], -pos[:, 1]], axis=1).astype(np.float32)
    n = np.cross(pos[1] - pos[0], pos[3] - pos[0])
    nrm = np.tile(n / np.linalg.norm(n), (4, 1)).astype(np.float32)
    tri = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    ct = corner_tangents(pos, nrm, uv, tri)
    e1, e2 = pos[1] - pos[0], pos[3] - pos[0]
    d1, d2 = uv[1] - uv[0], uv[3] - uv[0]
    det = d1[0] * d2[1] - d2[0] * d1[1]
    dpdu = (e1 * d2[1] - e2 * d1[1]) / det
    dpdv = (e2 * d1[0] - e1 * d2[0]) / det
    t = dpdu - nrm[0] * np.dot(dpdu, nrm[0])
    t /= np.linalg.norm(t)
    assert np.allclose(ct[:, :3], t, atol=1e-5)
    sign = np.sign(np.dot(np.cross(nrm[0], t), dpdv))     # MikkTSpace's fSign: B = fSign (N x T) along +v
    assert np.allclose(ct[:, 3], sign)


def test_asset_without_tangents_splits_the_seam(tmp_path):
    doc = Doc()
    doc.image(np.full((2, 2, 3), (128, 128, 255), np.uint8))
    attrs = {"POSITION": doc.accessor(SEAM_POS, "VEC3", minmax=True), "NORMAL": doc.accessor(SEAM_NRM, "VEC3"),
             "TEXCOORD_0": doc.accessor(SEAM_UV, "VEC2")}
    doc.d["materials"] = [{"normalTexture": {"index": 0}}]
    doc.node(doc.mesh(attrs, doc.accessor(SEAM_TRI.reshape(-1), "SCALAR"), 0))
    p = load_asset(doc.write(tmp_path / "seam.gltf")).primitives[0]
    assert p.generated_tangents and len(p.positions) == 8 and len(p.texcoords[0]) == 8
    assert p.indices.shape == (4, 3)
    right = p.indices[2:].reshape(-1)
    assert np.allclose(p.tangents[right], [-1, 0, 0, -1], atol=1e-6)
    assert np.allclose(p.positions[p.indices], SEAM_POS[SEAM_TRI])
