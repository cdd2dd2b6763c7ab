// A projected splat as the compute rasteriser stores it (tiles_preprocess.comp writes it,
// tiles_blend.comp reads it), in window coordinates (y up, pixel centres at +0.5) like quads.frag:
// a = (centre, axis1), b = (axis2, opacity o', camera z), c = (colour, support bound r2 on q);
// axis = e / sqrt(l), so dot(d, axis) is in standard deviations (lens.glsl: splat_alpha).
struct Splat { vec4 a; vec4 b; vec4 c; };
