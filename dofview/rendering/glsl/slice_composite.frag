#version 430
// Sliced depth of field: one blurred slice composited behind the nearer ones, front to back, by
// the blender (ONE_MINUS_DST_ALPHA, ONE: "over"; or ONE, ONE: the sum of visible parts) in the
// space the scene blends in. u_colour is at 1/u_scale
// resolution with flipped block rows (slice_down.frag) when u_scale > 1, upsampled bilinearly
// with pixel centres aligned and clamped at the borders (slices._upsample). The second target takes
// the slice's unblurred depth sums under the same blend, whose destination alpha is the pinhole
// coverage in front: the sliced image carries the pinhole's depth. u_masked (an unblurred slice
// into the sum of visible parts): the slice weighted by the pinhole transmittance in front of it,
// 1 − u_cover.a. u_part (an unblurred part of a shared slice): weighted by its share
// (slice_share.glsl).

uniform sampler2D u_colour;
uniform sampler2D u_depth;
uniform sampler2D u_cover;
uniform int u_scale;
uniform bool u_masked;
#include "slice_share.glsl"

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    out_depth = texelFetch(u_depth, p, 0);
    if (u_scale == 1) {
        vec4 c = texelFetch(u_colour, p, 0);
        out_colour = c * (u_masked ? 1.0 - texelFetch(u_cover, p, 0).a : 1.0) * share_part(p, c.a);
        return;
    }
    ivec2 n = textureSize(u_colour, 0);
    int row = textureSize(u_depth, 0).y - 1 - p.y;  // image row from the top
    vec2 pos = clamp((vec2(p.x, row) + 0.5) / float(u_scale) - 0.5, vec2(0.0), vec2(n - 1));
    ivec2 i0 = ivec2(floor(pos));
    ivec2 i1 = min(i0 + 1, n - 1);
    vec2 f = pos - vec2(i0);
    int r0 = n.y - 1 - i0.y, r1 = n.y - 1 - i1.y;
    vec4 upper = mix(texelFetch(u_colour, ivec2(i0.x, r0), 0), texelFetch(u_colour, ivec2(i1.x, r0), 0), f.x);
    vec4 lower = mix(texelFetch(u_colour, ivec2(i0.x, r1), 0), texelFetch(u_colour, ivec2(i1.x, r1), 0), f.x);
    out_colour = mix(upper, lower, f.y);
}
