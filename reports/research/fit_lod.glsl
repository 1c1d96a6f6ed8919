// Fitted roughness -> LOD mapping (pbrcheck fit-lod), valid for a 256^2 cube
// with 7 mips, on a chain baked with the linear mapping: lod = sum c_k b_k(r),
// b = (r, r^2, r^3, r^4, sqrt(r), r (2 - r)), c_k >= 0 (monotone, lod(0) = 0).
float roughnessToLodFitted(float r) {
    r = clamp(r, 0.0, 1.0);
    float lod = r * (0.451357843 + r * (3.21168827 + r * (5.64475377e-05 + r * 4.46341186e-05))) + 5.16955549e-05 * sqrt(r)
              + 2.43056281 * r * (2.0 - r);
    return clamp(lod, 0.0, 6.0);
}
