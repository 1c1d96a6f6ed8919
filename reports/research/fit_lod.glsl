// Fitted roughness -> LOD mapping (pbrcheck fit-lod), valid for a 256^2 cube
// with 7 mips, on a chain baked with the quadratic mapping: lod = sum c_k b_k(r),
// b = (r, r^2, r^3, r^4, sqrt(r), r (2 - r)), c_k >= 0 (monotone, lod(0) = 0).
float roughnessToLodFitted(float r) {
    r = clamp(r, 0.0, 1.0);
    float lod = r * (0 + r * (0 + r * (0 + r * 0.314703151))) + 0.186967477 * sqrt(r)
              + 5.47530742 * r * (2.0 - r);
    return clamp(lod, 0.0, 6.0);
}
