// Fitted roughness -> LOD mapping (pbrcheck fit-lod), valid for a 256^2 cube
// with 7 mips, on a chain baked with the linear mapping: lod = sum c_k b_k(r),
// b = (r, r^2, r^3, r^4, sqrt(r), r (2 - r)), c_k >= 0 (monotone, lod(0) = 0).
float roughnessToLodFitted(float r) {
    r = clamp(r, 0.0, 1.0);
    float lod = r * (2.34872713 + r * (1.5424351 + r * (5.70747658e-14 + r * 1.02831814))) + 1.45821258 * sqrt(r)
              + 0.179895474 * r * (2.0 - r);
    return clamp(lod, 0.0, 6.0);
}
