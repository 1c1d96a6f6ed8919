// texcoord.glsl: texture-coordinate wrapping of the raster pass (raster.frag) that the sampler
// cannot do itself. Numpy twin of the same name: pbrcheck/gltf.py (wrap_mirror).

// Source: glTF 2.0 specification 3.8.4.3 (sampler wrapS / wrapT MIRRORED_REPEAT, 33648); OpenGL 4.6
// core specification 8.14.2. Applied to the coordinates after their derivatives are taken, so the
// mip level does not jump at a fold. Equation: 1 - |mod(x, 2) - 1| (x on [0, 1], back to 0 on [1, 2]).
float wrap_mirror(float x) {
    return 1.0 - abs(mod(x, 2.0) - 1.0);
}
