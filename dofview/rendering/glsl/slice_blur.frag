#version 430
// Sliced depth of field: one slice gathered with the aperture kernel (slices.aperture_kernel's
// non-zero taps, offsets in texels of this level, weights summing to 1). Samples beyond the
// border repeat the edge pixel: the replicate guard band, so a surface crossing the frame border
// keeps its coverage there. u_masked: each sample weighted by the pinhole transmittance in front of
// the slice, 1 − u_cover.a (the "visible" part), and u_part: by its share (slice_share.glsl); full
// resolution only, slice_down.frag weights the rest.

layout(std430, binding = 0) readonly buffer Taps { vec4 taps[]; };  // (dx, dy, weight, -)

uniform sampler2D u_src;
uniform sampler2D u_cover;
uniform int u_taps;
uniform bool u_masked;
#include "slice_share.glsl"

out vec4 out_colour;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 last = textureSize(u_src, 0) - 1;
    vec4 sum = vec4(0.0);
    for (int i = 0; i < u_taps; ++i) {
        vec4 t = taps[i];
        ivec2 q = clamp(p + ivec2(t.xy), ivec2(0), last);
        vec4 s = texelFetch(u_src, q, 0);
        sum += t.z * s * (u_masked ? 1.0 - texelFetch(u_cover, q, 0).a : 1.0) * share_part(q, s.a);
    }
    out_colour = sum;
}
