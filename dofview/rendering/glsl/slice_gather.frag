#version 430
// Sliced depth of field, per layer (slices.scatter is the twin): every pixel of the prepared layer
// spread over the kernel at its own signed CoC, as a gather: out(p) = Σ_taps a(p − d)·w(d, ρ(p − d))
// (slice_kernel.glsl), a already divided by N(ρ). Sources beyond the image repeat its edge on the
// sides u_edge names (the layer goes on beyond the guard band) and are empty elsewhere. Blended front to back into the frame's or a run's accumulators (ONE_MINUS_DST_ALPHA,
// ONE): "over" for the colour, and the sum of the visible coverages in the second target, whose
// alpha stays 0 so that the same blend adds. The prepared layer is read through image units:
// llvmpipe loads an image's texel for less than it fetches a sampler's (docs/BENCHMARKS.md,
// "Cost in rooms").

#include "slice_kernel.glsl"

layout(rgba32f, binding = 1) uniform readonly image2D u_a;  // colour / N(ρ)
layout(rg32f, binding = 2) uniform readonly image2D u_b;    // (ρ, visible coverage / N(ρ))
uniform bvec4 u_edge;   // repeat the edge beyond (left, bottom, right, top)
uniform sampler2D u_occupied;  // per 8 × 8 tile: the largest |ρ| within reach, −1: no light (slice_occupancy.comp)
uniform int u_tap_reach;  // the taps' largest offset along an axis, texels
uniform int u_prefix[MAX_PREFIX];  // taps needed where every |ρ| < (k + 1)/PREFIX_STEPS (sliced._tap_uniform)

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_visible;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    float widest = texelFetch(u_occupied, p >> 3, 0).r;
    if (widest < 0.0) discard;  // nothing of the layer reaches here
    // every tap past the table's count lies beyond the kernel of each source in reach: weight 0
    int taps = min(u_prefix[clamp(int(widest * PREFIX_STEPS), 0, MAX_PREFIX - 1)], u_taps);
    ivec2 last = imageSize(u_a) - 1;
    vec4 sum = vec4(0.0);
    float visible = 0.0;
    if (all(greaterThanEqual(p, ivec2(u_tap_reach))) && all(lessThanEqual(p, last - u_tap_reach))) {
        // every tap's source lies inside the level (most pixels): no edge to repeat or leave
        for (int i = 0; i < taps; ++i) {
            vec2 d = tap(i);
            ivec2 q = p - ivec2(d);
            vec2 b = imageLoad(u_b, q).rg;
            float w = kernel_weight(d, b.x);
            if (w > 0.0) {
                sum += w * imageLoad(u_a, q);
                visible += w * b.y;
            }
        }
    } else {
        for (int i = 0; i < taps; ++i) {
            vec2 d = tap(i);
            ivec2 q = p - ivec2(d);
            bvec4 beyond = bvec4(q.x < 0, q.y < 0, q.x > last.x, q.y > last.y);
            if (any(bvec4(ivec4(beyond) * ivec4(not(u_edge))))) continue;
            q = clamp(q, ivec2(0), last);
            vec2 b = imageLoad(u_b, q).rg;
            float w = kernel_weight(d, b.x);
            if (w > 0.0) {
                sum += w * imageLoad(u_a, q);
                visible += w * b.y;
            }
        }
    }
    out_colour = sum;
    out_visible = vec4(visible, 0.0, 0.0, 0.0);
}
