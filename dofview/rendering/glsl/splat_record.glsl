// A projected splat as the compute rasteriser stores it (tiles_preprocess.comp writes it,
// tiles_blend.comp reads it), in window coordinates (y up, pixel centres at +0.5) like quads.frag:
// a = (centre, axis1), b = (sqrt(l1 / l2), kernel shape s, opacity o', camera z), c = (colour,
// support bound r2 on q); axis1 = e1 / sqrt(l1), so dot(d, axis) is in standard deviations
// (lens.glsl: splat_alpha), and axis2 = e2 / sqrt(l2) is perpendicular to it: splat_axis2.
struct Splat { vec4 a; vec4 b; vec4 c; };

vec2 splat_axis2(vec4 a, vec4 b) { return vec2(-a.w, a.z) * b.x; }
