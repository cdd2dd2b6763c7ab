#version 430
// The bilateral operator's guide, once per frame before its two filter passes: log2 L of the exposed
// image (r), log2 camera z (g), covered (b: alpha > COVERED_ALPHA) and has-depth (a) per pixel, so
// each filter tap is one texel fetch. Twin: tonemap/bilateral.py:Bilateral.base's inputs.

#include "tonemap_input.glsl"
uniform sampler2D u_depth;    // alpha-weighted depth (r) and weight (a)

out vec4 out_guide;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = texelFetch(u_colour, p, 0);
    vec4 d = texelFetch(u_depth, p, 0);
    float z = d.a > 1e-6 ? d.r / d.a : 0.0;
    out_guide = vec4(log2(max(dot(exposed_linear(c), LUMINANCE), 1e-30)), z > 0.0 ? log2(z) : 0.0,
                     c.a > COVERED_ALPHA ? 1.0 : 0.0, z > 0.0 ? 1.0 : 0.0);
}
