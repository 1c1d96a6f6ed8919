// coverage.glsl: alpha-to-coverage of MASK materials in the raster pass (raster.frag, option
// alpha_to_coverage with msaa > 1). Numpy twin of the same name: pbrcheck/coverage.py.

// Source: Golus 2017, "Anti-aliased Alpha Test: The Esoteric Alpha To Coverage" (the sharpened
// alpha, after Castano 2010's alpha-tested mip maps): the alpha test's edge spread over one pixel's
// alpha gradient, so that coverage is 1/2 where alpha = cutoff. Equation:
// saturate((alpha - cutoff) / max(fwidth(alpha), 1e-4) + 0.5), width = fwidth(alpha).
float alpha_to_coverage_sharpen(float alpha, float cutoff, float width) {
    return clamp((alpha - cutoff) / max(width, 1e-4) + 0.5, 0.0, 1.0);
}
