#version 430
// Sliced depth of field, per layer, at its level 1/u_scale (the last step of slices.prepare): each
// texel's signed blur ρ is the CoC c of its mean inverse depth (Σw/z over Σw), shrunk by what the
// level's own down- and upsampling spread (|ρ| = sqrt(c² − u_shrink) / u_scale level px, at most
// u_rmax); its colour and visible coverage (slice_visible.comp) are divided by the kernel's
// N(ρ) = Σ_taps w(d, ρ), so that the gather keeps every pixel's light. The kernel and the taps are
// uniform arrays (slice_kernel.glsl): on llvmpipe 4× faster to loop over than a storage buffer.

#include "slice_kernel.glsl"

uniform sampler2D u_colour;
uniform sampler2D u_depth;

uniform int u_scale;
uniform bool u_blur;       // false: a layer drawn blurred already (radius 0)
uniform float u_aperture;  // A at the frame's size, px·scene unit
uniform float u_inv_focus;
uniform float u_shrink;    // 4β(s² − 1), px²
uniform float u_rmax;      // the layer's largest radius, level px

layout(location = 0) out vec4 out_a;  // colour / N(ρ)
layout(location = 1) out vec2 out_b;  // (ρ, visible coverage / N(ρ))

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 colour = texelFetch(u_colour, p, 0);
    vec4 depth = colour.a > 0.0 ? texelFetch(u_depth, p, 0) : vec4(0.0);
    float rho = 0.0;
    if (u_blur && depth.w > 0.0) {
        float c = 0.5 * u_aperture * (depth.y / depth.w - u_inv_focus);
        rho = sign(c) * min(sqrt(max(c * c - u_shrink, 0.0)) / float(u_scale), u_rmax);
    }
    float norm = 0.0;
    for (int i = 0; i < u_taps; ++i) norm += kernel_weight(tap(i), rho);
    out_a = colour / norm;
    out_b = vec2(rho, depth.z / norm);
}
