#version 430
// Sliced depth of field, the last pass (slices.resolve is the twin): the "over" composite of the
// blurred layers, scaled up to the sum of their blurred visible coverages where its coverage falls
// short, and down to full coverage where it exceeds that. Where a surface is cut between two
// layers "over" of their complementary blurred parts loses coverage and the visible sum does not;
// where a blurred foreground edge reveals what it hid, "over" has the more coverage and stays as
// it is; where the blur radius changes across a surface neighbouring kernels overlap (each keeps
// its own light), which full coverage caps. The frame is cut out of the guarded image (u_guard
// pixels on every side), with the pinhole's depth sums accumulated beside it.

uniform sampler2D u_over;
uniform sampler2D u_visible;
uniform sampler2D u_depth;
uniform int u_guard;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) + u_guard;
    vec4 o = texelFetch(u_over, p, 0);
    float target = min(max(o.a, texelFetch(u_visible, p, 0).r), 1.0);
    out_colour = o.a > 0.0 ? o * (target / o.a) : o;
    vec4 depth = texelFetch(u_depth, p, 0);
    out_depth = vec4(depth.xy, 0.0, depth.w);  // (the third component held the layers' visibility)
}
