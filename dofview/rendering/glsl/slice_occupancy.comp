#version 430
// Sliced depth of field, per layer, at its level, before its gather: which 8 × 8 tiles of the
// gather can receive light, i.e. hold a texel of the prepared layer with coverage within u_reach
// of them (the image's edge texels stand for what the gather repeats beyond it), so that
// slice_gather.frag leaves the others at once. Exact: a texel without coverage carries no colour
// (premultiplied) and no visible part. A layer is a thin depth range of the scene: most of its box
// is empty.
layout(local_size_x = 8, local_size_y = 8) in;

layout(r32f, binding = 0) uniform writeonly image2D u_occupied;
uniform sampler2D u_a;   // the prepared layer: colour / N(ρ)
uniform ivec4 u_tiles;   // (x0, y0, x1, y1) tiles, ends exclusive
uniform int u_reach;     // the taps' largest offset along an axis, texels

void main() {
    ivec2 t = u_tiles.xy + ivec2(gl_GlobalInvocationID.xy);
    if (t.x >= u_tiles.z || t.y >= u_tiles.w) return;
    ivec2 last = textureSize(u_a, 0) - 1;
    ivec2 lo = clamp(t * 8 - u_reach, ivec2(0), last);
    ivec2 hi = clamp(t * 8 + 7 + u_reach, ivec2(0), last);
    float lit = 0.0;
    for (int y = lo.y; y <= hi.y && lit == 0.0; ++y) {
        for (int x = lo.x; x <= hi.x; ++x) {
            if (texelFetch(u_a, ivec2(x, y), 0).a > 0.0) {
                lit = 1.0;
                break;
            }
        }
    }
    imageStore(u_occupied, t, vec4(lit));
}
