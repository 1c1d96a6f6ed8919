// Fitted roughness -> LOD mapping (pbrcheck fit-lod), valid for a 256^2 cube
// with 7 mips, on a chain baked with the linear mapping: lod = sum c_k b_k(r),
// b = (r, r^2, r^3, r^4, sqrt(r), r (2 - r)), c_k >= 0 (monotone, lod(0) = 0).
float roughnessToLodFitted(float r) {
    r = clamp(r, 0.0, 1.0);
    float lod = r * (5.51922033 + r * (0.521772599 + r * (0.000161548606 + r * 0.000318709867))) + 0.000482132398 * sqrt(r)
              + 4.67347686e-05 * r * (2.0 - r);
    return clamp(lod, 0.0, 6.0);
}
